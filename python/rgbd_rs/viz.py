"""Small picture helpers: colourised depth, labelled tiles, PNG output (OpenCV, BGR)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate

U8 = npt.NDArray[np.uint8]


def colorize(
    values: npt.ArrayLike,
    vmin: float | None = None,
    vmax: float | None = None,
    colormap: int = cv2.COLORMAP_TURBO,
) -> U8:
    """Map an ``H x W`` float map to a BGR image (NaN -> black). Range defaults to the 1st-99th
    percentile of the finite values."""
    v = _validate.array("values", values, shape=(None, None))
    finite = np.isfinite(v)
    if not finite.any():
        return np.zeros((*v.shape, 3), np.uint8)
    lo = float(np.percentile(v[finite], 1)) if vmin is None else float(vmin)
    hi = float(np.percentile(v[finite], 99)) if vmax is None else float(vmax)
    scaled = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-12), 0, 1)
    out = cv2.applyColorMap((scaled * 255).astype(np.uint8), colormap)
    out[~finite] = 0
    return np.asarray(out, dtype=np.uint8)


def as_bgr(image: npt.ArrayLike) -> U8:
    """Any ``H x W`` / ``H x W x 3`` uint8 image (RGB assumed for 3 channels) as BGR."""
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    return np.ascontiguousarray(img[:, :, ::-1]).astype(np.uint8)


def tile(images: Sequence[U8], labels: Sequence[str], columns: int = 3, width: int = 480) -> U8:
    """Resize BGR images to a common ``width`` and tile them with captions."""
    cells = []
    for img, label in zip(images, labels, strict=True):
        h = round(img.shape[0] * width / img.shape[1])
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


def save_png(path: str | Path, image: U8) -> Path:
    """Write a BGR/grey uint8 image as PNG (creating parent folders), atomically."""
    from rgbd_rs.data.files import write_png

    return write_png(path, image, rgb=False)
