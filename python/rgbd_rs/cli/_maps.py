"""How the CLI writes disparity and depth maps as 16-bit PNGs (disparity x 256, millimetres), 0
meaning "none" and nothing else."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: A PNG value is the disparity times this (the KITTI convention: 1/256-px steps, up to
#: 255.996 px).
DISPARITY_PNG_SCALE = 256.0


def disparity_png16(disparity: npt.NDArray[np.floating]) -> npt.NDArray[np.uint16]:
    """``disparity`` (px, NaN = none) as 16-bit PNG values: rounded to 1/256 px, 0 only where
    there is none. A measured disparity below 1/512 px (0, or negative) is written as 1 and one
    above 255.996 px as 65535, so that no measured pixel reads back as "none"."""
    d = np.asarray(disparity, np.float64)
    have = np.isfinite(d)
    scaled = np.rint(np.where(have, d, 0.0) * DISPARITY_PNG_SCALE)
    return np.where(have, np.clip(scaled, 1, 65535), 0).astype(np.uint16)


def disparity_png_note(disparity: npt.NDArray[np.floating], npz: str) -> str | None:
    """A warning where some of ``disparity`` lies beyond what :func:`disparity_png16` holds
    (255.996 px: those pixels read 65535), naming ``npz``, the file that holds them exactly;
    None where none does."""
    d = np.asarray(disparity, np.float64)
    with np.errstate(invalid="ignore"):
        over = np.isfinite(d) & (d * DISPARITY_PNG_SCALE > 65535.5)
    if not over.any():
        return None
    return (
        f"rgbd: warning: disparity.png: {int(over.sum())} pixels ({over.mean():.1%}) lie beyond "
        f"{65535 / DISPARITY_PNG_SCALE:.3f} px, the most a 16-bit PNG in 1/256 px holds, and read "
        f"65535 there (up to {float(d[over].max()):.1f} px); {npz} holds them exactly"
    )


def depth_mm_png16(depth: npt.NDArray[np.floating]) -> npt.NDArray[np.uint16]:
    """``depth`` (metres, NaN = none) as 16-bit millimetres, rounded: 0 only where there is none.
    A measured depth below 1 mm is written as 1 and one beyond 65.535 m (an infinite one, from
    a zero disparity, included) as 65535."""
    d = np.asarray(depth, np.float64)
    have = ~np.isnan(d)
    with np.errstate(invalid="ignore", over="ignore"):
        mm = np.rint(np.where(have, d, 0.0) * 1000.0)
    return np.where(have, np.clip(np.nan_to_num(mm, posinf=65535, neginf=1), 1, 65535), 0).astype(
        np.uint16
    )
