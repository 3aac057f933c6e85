"""Input validation shared by every public function (private).

Each helper raises an :class:`~rgbd_rs.errors.RgbdError` subclass whose message names the
argument, what it got and what it expected, and returns a C-contiguous, aligned array of the
working dtype (copying once only when the input is not already one: Fortran-ordered, strided and
unaligned arrays are copied, never refused or misread).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

#: Largest image side any kernel accepts (defined once, in crates/rgbd-error).
MAX_SIDE: int = _rgbd_rs.MAX_SIDE


def _describe_shape(shape: Sequence[int | None]) -> str:
    """``(N, 3)`` for a list of points, ``(H, W)`` / ``(H, W, 3)`` for an image (two free
    leading axes, and at most a fixed channel count after them), numbers where the length is
    fixed."""
    names = ["N"] * len(shape)
    image = len(shape) == 2 or (len(shape) == 3 and shape[2] is not None)
    if image and shape[0] is None and shape[1] is None:
        names[:2] = ["H", "W"]
    return (
        "(" + ", ".join(n if s is None else str(s) for n, s in zip(names, shape, strict=True)) + ")"
    )


def asarray(name: str, value: object) -> np.ndarray:
    """``np.asarray(value)``; ragged or non-array input raises naming ``name``. A masked array
    is refused (its mask would be dropped), an ``np.matrix`` read as the plain array it holds,
    and an array of more than :data:`MAX_ELEMENTS` refused before anything copies it."""
    if isinstance(value, np.ma.MaskedArray):
        raise InvalidArgumentError(
            f"{name}: got a masked array, expected a plain numpy array (mark missing values "
            "with NaN, or pass .filled(...))"
        )
    if isinstance(value, np.ndarray):
        return _bounded(name, value if type(value) is np.ndarray else value.view(np.ndarray))
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged lists and the like
        what = type(value).__name__
        if isinstance(value, (list, tuple)):
            what += " with rows of different lengths (ragged)"
        raise InvalidArgumentError(
            f"{name}: got {what}, which cannot be read as one array; expected a rectangular "
            "array of numbers"
        ) from None
    return _bounded(name, arr)


def _bounded(name: str, arr: np.ndarray) -> np.ndarray:
    """``arr``, refused when it holds more than :data:`MAX_ELEMENTS` (before anything copies)."""
    if arr.size > MAX_ELEMENTS:
        raise ShapeMismatchError(
            f"{name}: got {arr.size} elements (shape {tuple(arr.shape)}), expected at most "
            f"{MAX_ELEMENTS} (2**31)"
        )
    return arr


def array(
    name: str,
    value: object,
    *,
    shape: Sequence[int | None],
    dtype: npt.DTypeLike = np.float32,
    finite: bool = False,
    allow_empty: bool = False,
    fix: str = "",
) -> np.ndarray:
    """Validate ``value`` as a real numeric array of ``shape`` (None = any length).

    Returns it as a C-contiguous array of ``dtype``. ``finite`` rejects NaN/inf; ``fix``, when
    given, is appended to that message (how to make the input finite).
    """
    value = asarray(name, value)
    if value.dtype.kind not in "iuf":
        raise InvalidArgumentError(
            f"{name}: got dtype {value.dtype}, expected a real numeric array (int/uint/float)"
        )
    if value.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(value.shape, shape, strict=False)
    ):
        raise ShapeMismatchError(
            f"{name}: got shape {tuple(value.shape)}, expected {_describe_shape(shape)}"
        )
    if value.size == 0 and not allow_empty:
        raise ShapeMismatchError(
            f"{name}: got an empty array of shape {tuple(value.shape)}, "
            "expected at least one element"
        )
    # np.ascontiguousarray keeps an unaligned buffer as it is; the kernels need aligned memory.
    try:
        with np.errstate(over="ignore"):  # overflow in the cast is reported below, by name
            out = np.require(value, dtype=dtype, requirements=["C_CONTIGUOUS", "ALIGNED"])
    except MemoryError:
        need = value.size * np.dtype(dtype).itemsize
        raise MemoryError(
            f"{name}: out of memory copying shape {tuple(value.shape)} to a contiguous "
            f"{np.dtype(dtype)} array ({need / 2**30:.1f} GiB)"
        ) from None
    if finite and out.size and not np.isfinite(out).all():
        bad = int(np.size(out) - np.count_nonzero(np.isfinite(out)))
        if out.dtype != value.dtype and value.dtype.kind == "f" and np.isfinite(value).all():
            top = float(np.abs(value).max())
            raise InvalidArgumentError(
                f"{name}: got {bad} values beyond {np.dtype(dtype)}'s range (up to {top:.3g}), "
                f"expected magnitudes below {float(np.finfo(dtype).max):.3g}"
            )
        raise InvalidArgumentError(
            f"{name}: got {bad} non-finite values, expected finite values"
            + (f"; {fix}" if fix else "")
        )
    return out


def real(
    name: str,
    value: object,
    *,
    positive: bool = False,
    nonnegative: bool = False,
    f32: bool = False,
) -> float:
    """Validate a finite real scalar (optionally > 0 or >= 0; ``f32``: one a float32 kernel
    receives, so it must survive float32 without overflowing or flushing to 0)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidArgumentError(f"{name}: got {value!r}, expected a real number")
    try:
        v = float(value)
    except OverflowError:  # an int beyond the float range, e.g. 2**1100
        digits = len(str(abs(int(value))))
        raise InvalidArgumentError(
            f"{name}: got an integer of {digits} digits (beyond float64), expected a finite number"
        ) from None
    if not math.isfinite(v):
        raise InvalidArgumentError(f"{name}: got {v}, expected a finite number")
    if positive and v <= 0:
        raise InvalidArgumentError(f"{name}: got {v}, expected a number > 0")
    if nonnegative and v < 0:
        raise InvalidArgumentError(f"{name}: got {v}, expected a number >= 0")
    if f32 and v != 0 and not (F32_TINY <= abs(v) <= F32_MAX):
        raise InvalidArgumentError(
            f"{name}: got {v}, expected a magnitude within float32's range "
            f"[{F32_TINY:.3g}, {F32_MAX:.3g}] (the kernel computes in float32)"
        )
    return v


#: The range of magnitudes a float32 kernel parameter keeps (normal float32 numbers).
F32_TINY = float(np.finfo(np.float32).tiny)
F32_MAX = float(np.finfo(np.float32).max)

#: The most elements an array argument may hold (8 GiB of float32): a larger one, e.g. a
#: zero-stride view of a huge shape, is refused before a copy is attempted.
MAX_ELEMENTS = 2**31

#: The largest integer a parameter takes unless it says otherwise (counts, sizes, strides,
#: indices: what Rust's i32/u32 and numpy's shapes hold); seeds pass ``maximum=MAX_SEED``.
MAX_INT = 2**31 - 1
#: The largest seed (numpy's and Rust's u64 generators take any 63-bit integer).
MAX_SEED = 2**63 - 1


def within(
    name: str, value: object, bounds: tuple[float, float], what: str, unit: str = ""
) -> float:
    """A positive real in the closed ``bounds``; the message calls it ``what`` (e.g. "a focal
    length") and prints ``unit`` beside the numbers."""
    v = real(name, value, positive=True)
    lo, hi = bounds
    if not lo <= v <= hi:
        u = f" {unit}" if unit else ""
        raise InvalidArgumentError(
            f"{name}: got {v:.3g}{u}, expected {what} in [{lo:g}, {hi:g}]{u}"
        )
    return v


def integer(name: str, value: object, *, minimum: int = 0, maximum: int | None = MAX_INT) -> int:
    """Validate an integer in ``[minimum, maximum]`` (``maximum`` defaults to :data:`MAX_INT`:
    a count beyond it would overflow the kernels or allocate without bound)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidArgumentError(f"{name}: got {value!r}, expected an integer")
    v = int(value)
    if maximum is not None and maximum < minimum:
        raise InvalidArgumentError(f"{name}: got {v}, but no value is allowed here")
    if v < minimum or (maximum is not None and v > maximum):
        hi = "" if maximum is None else f" and <= {maximum}"
        raise InvalidArgumentError(f"{name}: got {v}, expected an integer >= {minimum}{hi}")
    return v


def sign(name: str, value: object) -> int:
    """Validate a direction: the integer +1 or -1 (not a bool, not a float)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value not in (1, -1):
        raise InvalidArgumentError(f"{name}: got {_short(value)}, expected +1 or -1")
    return int(value)


def flag(name: str, value: object) -> bool:
    """Validate a yes/no switch: a bool (numpy's included), nothing truthy in its place."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidArgumentError(f"{name}: got {_short(value)}, expected True or False")
    return bool(value)


def path(name: str, value: object) -> Path:
    """Validate a file-system path: a non-empty str or os.PathLike without NUL characters."""
    if isinstance(value, (str, os.PathLike)):
        text = os.fspath(value)
        if isinstance(text, str) and "\0" in text:
            raise InvalidArgumentError(
                f"{name}: got {text!r}, which holds a NUL character; expected a file path"
            )
        if isinstance(text, str) and text:
            long = [p for p in Path(text).parts if len(os.fsencode(p)) > NAME_MAX]
            if long:
                raise InvalidArgumentError(
                    f"{name}: got a name of {len(os.fsencode(long[0]))} bytes "
                    f"({long[0][:20]!r}...), expected names of at most {NAME_MAX} bytes (the "
                    "file systems' limit)"
                )
            return Path(text)
    raise InvalidArgumentError(f"{name}: got {_short(value)}, expected a file or folder path")


#: The longest file or folder name (bytes) the common file systems hold (ext4, NTFS, APFS).
NAME_MAX = 255


def out_folder(name: str, value: object) -> Path:
    """Validate an output folder path: :func:`path`, and not an existing file."""
    p = path(name, value)
    if p.exists() and not p.is_dir():
        raise InvalidArgumentError(f"{name}: got {p}, a file; expected a folder")
    return p


def _short(value: object) -> str:
    """A value for a message: its repr, or its type and shape when that would be long."""
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    text = repr(value)
    return text if len(text) <= 80 else f"a {type(value).__name__}"


def size(name: str, value: object) -> int:
    """Validate an image side in pixels: an integer in ``1..=MAX_SIDE``."""
    return integer(name, value, minimum=1, maximum=MAX_SIDE)


def choice(name: str, value: object, options: Sequence[str]) -> str:
    """Validate a string option."""
    if not isinstance(value, str) or value not in options:
        raise InvalidArgumentError(f"{name}: got {value!r}, expected one of {list(options)}")
    return value


def image(name: str, value: object) -> tuple[np.ndarray, bool]:
    """Validate an ``H x W`` or ``H x W x C`` image; return it as ``H x W x C`` float32.

    The flag says whether the input was 2-D (so callers can squeeze the result back).
    """
    value = asarray(name, value)
    if value.ndim == 2:
        return array(name, value[:, :, None], shape=(None, None, None)), True
    if value.ndim == 3:
        return array(name, value, shape=(None, None, None)), False
    raise ShapeMismatchError(
        f"{name}: got shape {tuple(value.shape)}, expected (H, W) or (H, W, C)"
    )


def shard(name: str, value: object) -> tuple[int, int]:
    """A shard ``(i, n)`` of a long job: integers with ``0 <= i < n`` (``--shard i/n``)."""
    ok = (
        isinstance(value, tuple)
        and len(value) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        and value[1] >= 1
        and 0 <= value[0] < value[1]
    )
    if not ok:
        raise InvalidArgumentError(f"{name}: got {value!r}, expected (i, n) with 0 <= i < n")
    assert isinstance(value, tuple)
    return int(value[0]), int(value[1])


def device(name: str, value: object, *, auto: bool = False, available: bool = True) -> str:
    """A torch device string: ``"cpu"``, ``"cuda"`` or ``"cuda:N"`` (and ``"auto"`` when
    ``auto``). With ``available`` a CUDA device must exist on this machine (torch is imported
    only then), so a bad value fails here with its name instead of deep inside torch."""
    options = ("auto", "cpu", "cuda", "cuda:N") if auto else ("cpu", "cuda", "cuda:N")
    ok = isinstance(value, str) and (
        value in options[:-1] or (value.startswith("cuda:") and value[5:].isdigit())
    )
    if not ok:
        raise InvalidArgumentError(f"{name}: got {value!r}, expected one of {list(options)}")
    assert isinstance(value, str)
    if available and value.startswith("cuda"):
        import torch

        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0:
            raise InvalidArgumentError(f"{name}: got {value!r} but CUDA is not available here")
        if value[5:] and int(value[5:]) >= count:
            raise InvalidArgumentError(
                f"{name}: got {value!r}, expected an index below this machine's {count} CUDA "
                "device(s)"
            )
    return value


def differences(there: object, now: object) -> str:
    """The keys two settings dicts disagree on, with both values (``"scale: 0.25 there, 0.3
    now"``), in sorted key order: what a refusal to mix two runs' outputs names."""
    a = there if isinstance(there, dict) else {}
    b = now if isinstance(now, dict) else {}
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    return "; ".join(f"{k}: {a.get(k)!r} there, {b.get(k)!r} now" for k in keys)


def metric_points(name: str, points: np.ndarray, uses: str | None, escape: str = "") -> None:
    """Refuse ``H x W x 3`` points (z = depth) with no finite point, or (unless ``uses`` is None)
    whose median positive z is beyond ``HHA_MAX_MEDIAN_DEPTH_M`` (50 m: millimetres; the limit
    ``segment()`` applies): ``uses`` names the metric constants that would misread them."""
    z = points[..., 2]
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(points).all(axis=-1) & (z > 0)
    if not valid.any():
        raise InvalidArgumentError(
            f"{name}: got no point with finite coordinates and a positive depth (z), expected "
            "at least one (NaN marks a pixel without depth)"
        )
    med = float(np.median(z[valid]))
    if uses is not None and med > _rgbd_rs.HHA_MAX_MEDIAN_DEPTH_M:
        raise InvalidArgumentError(
            f"{name}: got a median depth (z) of {med:.4g}, expected metres (at most "
            f"{_rgbd_rs.HHA_MAX_MEDIAN_DEPTH_M:g} for a Kinect-class scene): the points look like "
            f"millimetres (divide by 1000); {uses} in metres"
            + (f" (for a scene this far in metres, {escape})" if escape else "")
        )


def metric_depth(name: str, value: object) -> None:
    """Refuse an integer (or boolean) depth array: a raw depth image holds millimetres (or
    another sensor unit), and read as metres it would be silently 1000x too far."""
    if isinstance(value, (np.ndarray, np.generic)) and value.dtype.kind in "iub":
        raise InvalidArgumentError(
            f"{name}: got dtype {value.dtype}, expected float depth in metres (a raw 16-bit "
            "depth image is usually millimetres: pass depth_mm / 1000)"
        )
