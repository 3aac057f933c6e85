"""Small picture helpers: colourised depth, labelled tiles, PNG output (OpenCV, BGR)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.io import write_png

__all__ = ["as_bgr", "colorize", "save_png", "tile"]

U8 = npt.NDArray[np.uint8]

#: OpenCV's colour maps are numbered 0..COLORMAP_LAST.
COLORMAP_LAST = max(getattr(cv2, n) for n in dir(cv2) if n.startswith("COLORMAP_"))
#: Largest tile width accepted by :func:`tile` (pixels).
MAX_TILE_WIDTH = 8192
#: Most columns :func:`tile` lays out.
MAX_TILE_COLUMNS = 64


def colorize(
    values: npt.ArrayLike,
    vmin: float | None = None,
    vmax: float | None = None,
    colormap: int = cv2.COLORMAP_TURBO,
) -> U8:
    """Map an ``H x W`` float map to a BGR image (NaN -> black). Range defaults to the 1st-99th
    percentile of the finite values."""
    v = _validate.array("values", values, shape=(None, None))
    vmin = None if vmin is None else _validate.real("vmin", vmin)
    vmax = None if vmax is None else _validate.real("vmax", vmax)
    colormap = _validate.integer("colormap", colormap, maximum=COLORMAP_LAST)
    finite = np.isfinite(v)
    if not finite.any():
        return np.zeros((*v.shape, 3), np.uint8)
    lo = float(np.percentile(v[finite], 1)) if vmin is None else vmin
    hi = float(np.percentile(v[finite], 99)) if vmax is None else vmax
    scaled = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-12), 0, 1)
    out = cv2.applyColorMap((scaled * 255).astype(np.uint8), colormap)
    out[~finite] = 0
    return np.asarray(out, dtype=np.uint8)


def _u8_image(name: str, value: object) -> U8:
    img = _validate.asarray(name, value)
    if img.dtype != np.uint8:
        raise InvalidArgumentError(f"{name}: got dtype {img.dtype}, expected uint8")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3) or img.size == 0:
        raise ShapeMismatchError(
            f"{name}: got shape {img.shape}, expected a non-empty (H, W) or (H, W, 3) image"
        )
    return img


def as_bgr(image: npt.ArrayLike) -> U8:
    """Any ``H x W`` / ``H x W x 3`` uint8 image (RGB assumed for 3 channels) as BGR."""
    img = _u8_image("image", image)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    return np.ascontiguousarray(img[:, :, ::-1]).astype(np.uint8)


def tile(images: Sequence[U8], labels: Sequence[str], columns: int = 3, width: int = 480) -> U8:
    """Resize BGR images to a common ``width`` and tile them with captions."""
    if not isinstance(images, (Sequence, np.ndarray)) or len(images) == 0:
        raise InvalidArgumentError(
            f"images: got {type(images).__name__}, expected a non-empty list of BGR images"
        )
    if isinstance(labels, str) or not isinstance(labels, Sequence) or len(labels) != len(images):
        raise InvalidArgumentError(
            f"labels: got {labels!r}, expected {len(images)} captions (one per image)"
        )
    if not all(isinstance(label, str) for label in labels):
        raise InvalidArgumentError(f"labels: got {labels!r}, expected strings")
    columns = _validate.integer("columns", columns, minimum=1, maximum=MAX_TILE_COLUMNS)
    width = _validate.integer("width", width, minimum=1, maximum=MAX_TILE_WIDTH)
    checked = [_u8_image(f"images[{i}]", img) for i, img in enumerate(images)]
    cells = []
    for img, label in zip(checked, labels, strict=True):
        if img.ndim == 2:
            img = np.repeat(img[:, :, None], 3, axis=2)
        h = max(1, round(img.shape[0] * width / img.shape[1]))
        cell = cv2.resize(img, (width, h), interpolation=cv2.INTER_AREA)
        cell = cv2.copyMakeBorder(cell, 24, 0, 0, 0, cv2.BORDER_CONSTANT, value=(255, 255, 255))
        cv2.putText(cell, label, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        cells.append(cell)
    hmax = max(c.shape[0] for c in cells)
    cells = [cv2.copyMakeBorder(c, 0, hmax - c.shape[0], 0, 0, cv2.BORDER_CONSTANT) for c in cells]
    blank = np.zeros_like(cells[0])
    rows = []
    for i in range(0, len(cells), columns):
        row = cells[i : i + columns]
        row += [blank] * (columns - len(row))
        rows.append(np.hstack(row))
    return np.ascontiguousarray(np.vstack(rows))


def save_png(path: str | Path, image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16]) -> Path:
    """Write a BGR/grey 8-bit (or 16-bit grey) image as PNG (creating parent folders),
    atomically."""
    return write_png(path, image, rgb=False)
