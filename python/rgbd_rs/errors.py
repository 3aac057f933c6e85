"""The rgbd_rs exception hierarchy.

Every error a public function raises for bad input is a subclass of :class:`RgbdError`, which is
itself a :class:`ValueError`. Messages name the argument, what was seen and what was expected.
The classes are defined by the native module so Rust and Python raise the very same types.
"""

from rgbd_rs._rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError

# The native module names them "_rgbd_rs.X", which pickle cannot import: an error raised in a
# process pool's worker reached the parent as a PicklingError, its type and message lost. Here
# they live under this module's name (tracebacks show rgbd_rs.errors.InvalidArgumentError).
for _cls in (RgbdError, InvalidArgumentError, ShapeMismatchError):
    _cls.__module__ = __name__
del _cls

__all__ = ["InvalidArgumentError", "RgbdError", "ShapeMismatchError"]
