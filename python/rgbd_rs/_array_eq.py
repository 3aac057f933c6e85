"""Equality and hashing for frozen dataclasses that hold arrays.

A dataclass's generated ``__eq__`` compares its fields as a tuple, which for a numpy array
field raises numpy's "truth value of an array ... is ambiguous", and its ``__hash__`` hashes
the fields, which numpy arrays refuse. :func:`array_eq` replaces both: two instances are equal
when they are of the same class and every compared field is equal, arrays (numpy or torch)
by shape, dtype and values (NaN equal to NaN, as a copy of a depth map with holes should be),
mappings and sequences item by item; the hash is built from the same values, so equal
instances hash alike and can be set members or dict keys.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T", bound=type)


def _is_tensor(x: object) -> bool:
    return type(x).__module__.startswith("torch") and hasattr(x, "detach")


def _as_array(x: Any) -> np.ndarray | None:
    if isinstance(x, np.ndarray):
        return x
    if _is_tensor(x):
        return np.asarray(x.detach().cpu())
    return None


def same(a: object, b: object) -> bool:
    """``a == b`` for field values: arrays by shape, dtype and values (NaN equals NaN)."""
    xa, xb = _as_array(a), _as_array(b)
    if xa is not None or xb is not None:
        if xa is None or xb is None or xa.shape != xb.shape or xa.dtype != xb.dtype:
            return False
        nan_ok = xa.dtype.kind in "fc"
        return bool(np.array_equal(xa, xb, equal_nan=nan_ok))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(same, a, b))
    if _is_nan(a) and _is_nan(b):  # a score of no pixels equals itself
        return True
    return bool(a == b)


def _is_nan(x: object) -> bool:
    return isinstance(x, (float, np.floating)) and x != x


def key(x: object) -> object:
    """A hashable stand-in for ``x`` that agrees with :func:`same` (equal values, equal keys)."""
    arr = _as_array(x)
    if arr is not None:
        if arr.dtype.kind in "fc":
            # -0.0 -> 0.0 and every NaN (0/0 sets the sign bit) -> one NaN: equal values,
            # equal bytes
            arr = np.where(np.isnan(arr), np.array(np.nan, arr.dtype), arr + 0)
        return ("array", arr.shape, arr.dtype.str, np.ascontiguousarray(arr).tobytes())
    if isinstance(x, Mapping):
        return ("map", tuple(sorted((repr(k), key(v)) for k, v in x.items())))
    if isinstance(x, (list, tuple)):
        return (type(x).__name__, tuple(key(v) for v in x))
    if _is_nan(x):
        return ("nan",)
    return x


def array_eq(cls: T) -> T:
    """Class decorator (outside ``@dataclass``): array-aware ``__eq__``, and ``__hash__`` for
    a frozen class (a mutable one stays unhashable)."""
    names = tuple(f.name for f in dataclasses.fields(cls) if f.compare)

    def __eq__(self: Any, other: object) -> bool:
        if other.__class__ is not self.__class__:
            return NotImplemented
        return all(same(getattr(self, n), getattr(other, n)) for n in names)

    def __hash__(self: Any) -> int:
        return hash((self.__class__.__qualname__, *(key(getattr(self, n)) for n in names)))

    cls.__eq__ = __eq__  # type: ignore[method-assign,assignment]
    frozen = cls.__dataclass_params__.frozen  # type: ignore[attr-defined]
    # a mutable instance stays unhashable, as its dataclass made it
    cls.__hash__ = __hash__ if frozen else None  # type: ignore[method-assign,assignment]
    return cls
