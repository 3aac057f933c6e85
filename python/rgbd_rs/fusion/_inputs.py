"""Validation helpers shared by the fusion stages (private)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.camera import ToFStereoRig
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]


def rgb8(name: str, value: object, size: tuple[int, int] | None = None) -> U8:
    """An ``H x W x 3`` uint8 image (grey ``H x W`` is replicated); ``size`` = ``(W, H)``."""
    arr = _validate.asarray(name, value)
    if arr.ndim == 2:
        arr = np.repeat(arr[:, :, None], 3, axis=2)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ShapeMismatchError(f"{name}: got shape {arr.shape}, expected (H, W, 3) or (H, W)")
    if arr.dtype != np.uint8:
        raise InvalidArgumentError(f"{name}: got dtype {arr.dtype}, expected uint8 (0-255)")
    if arr.size == 0:
        raise ShapeMismatchError(f"{name}: got an empty image, expected at least 1x2 pixels")
    if size is not None and (arr.shape[1], arr.shape[0]) != size:
        raise ShapeMismatchError(
            f"{name}: got {arr.shape[1]}x{arr.shape[0]} pixels, expected {size[0]}x{size[1]} "
            "(the calibration's image size)"
        )
    return np.ascontiguousarray(arr)


def map2d(name: str, value: object, shape: tuple[int, int]) -> F32:
    """An ``H x W`` float32 map of ``shape``."""
    return np.asarray(_validate.array(name, value, shape=shape), dtype=np.float32)


def rig_arg(rig: object) -> ToFStereoRig:
    if not isinstance(rig, ToFStereoRig):
        raise InvalidArgumentError(f"rig: got {type(rig).__name__}, expected a ToFStereoRig")
    return rig


def views(left: U8, right: U8, reference: str) -> tuple[U8, U8, int]:
    """``(reference image, target image, target_sign)``: the target pixel of reference pixel x
    is ``x + sign * d`` with ``d = u_left - u_right``."""
    return (right, left, 1) if reference == "right" else (left, right, -1)
