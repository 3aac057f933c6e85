"""The rgbd_rs exception hierarchy.

Every error a public function raises for bad input is a subclass of :class:`RgbdError`, which is
itself a :class:`ValueError`. Messages name the argument, what was seen and what was expected.
The classes are defined by the native module so Rust and Python raise the very same types.
"""

from rgbd_rs._rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError

__all__ = ["InvalidArgumentError", "RgbdError", "ShapeMismatchError"]
