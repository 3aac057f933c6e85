"""Reader for the 27 real Middlebury stereo scenes of ``../shared/data/stereo`` (2001-2006 sets)
through their manifest ``scenes.csv``: file names, the per-scene disparity scale (PNG value /
``disparity_scale`` = pixels, 0 = unknown; it cannot be told from the file names) and the
train / val / test split. Every choice is made on train/val; the test split is for reporting.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.data.paths import data_root
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.io import read_png

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]

#: The manifest's columns this reader needs.
COLUMNS = ("scene", "left", "right", "gt_left", "gt_right", "disparity_scale", "max_disparity")
SPLITS = ("train", "val", "test")


@array_eq
@dataclass(frozen=True)
class StereoScene:
    """One rectified pair (uint8 RGB) with ground-truth disparity in pixels (NaN = unknown).

    Attributes:
        name, split, year: from the manifest.
        disparity_left, disparity_right: ground truth of each view (``None`` where the set has
            none for the right view: Tsukuba).
        max_disparity: the manifest's largest ground-truth disparity (pixels).
    """

    name: str
    split: str
    year: int
    left: U8
    right: U8
    disparity_left: F32
    disparity_right: F32 | None
    scale: float
    max_disparity: float


def _folder(root: str | Path | None) -> Path:
    if root is not None:
        if not isinstance(root, (str, Path)) or not str(root):
            raise InvalidArgumentError(f"root: got {root!r}, expected a folder path or None")
        return Path(root)
    shared = data_root()
    if shared is None:
        raise RgbdError(
            "stereo scenes: the shared data was not found; set RGBD_DATA to the folder that "
            "holds stereo/scenes.csv"
        )
    return shared / "stereo"


def _manifest(root: Path) -> list[dict[str, str]]:
    path = root / "scenes.csv"
    if not path.is_file():
        raise RgbdError(
            f"{path}: no such file; expected the stereo scenes' manifest (set RGBD_DATA to the "
            "folder that holds stereo/scenes.csv)"
        )
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    missing = [c for c in COLUMNS if rows and c not in rows[0]]
    if not rows or missing:
        raise RgbdError(f"{path}: expected the columns {list(COLUMNS)}, missing {missing}")
    return rows


def _disparity(path: Path, scale: float, shape: tuple[int, ...]) -> F32:
    raw = read_png(path)
    if raw.ndim != 2 or raw.dtype != np.uint8:
        raise RgbdError(f"{path}: expected an 8-bit single-channel disparity PNG")
    if raw.shape != shape:
        raise RgbdError(f"{path}: got {raw.shape[1]}x{raw.shape[0]} pixels, expected the images'")
    return np.where(raw > 0, raw / np.float32(scale), np.nan).astype(np.float32)


def scene_names(split: str | None = None, root: str | Path | None = None) -> list[str]:
    """The scenes of ``split`` (``"train"``, ``"val"``, ``"test"`` or None = all), in manifest
    order."""
    if split is not None:
        _validate.choice("split", split, SPLITS)
    folder = _folder(root)
    return [r["scene"] for r in _manifest(folder) if split is None or r["split"] == split]


def _right_view_scenes(root: str | Path | None = None) -> list[str]:
    """The scenes with right-view ground truth (all but the 2001 sets' Tsukuba), in manifest
    order."""
    return [r["scene"] for r in _manifest(_folder(root)) if r["gt_right"]]


def load_stereo_scene(name: str, root: str | Path | None = None) -> StereoScene:
    """One scene by name (e.g. ``"Cones"``); ``root`` defaults to ``<data>/stereo``."""
    folder = _folder(root)
    rows = {r["scene"]: r for r in _manifest(folder)}
    if not isinstance(name, str) or name not in rows:
        raise InvalidArgumentError(
            f"name: got {name!r}, expected one of the {len(rows)} scenes of {folder / 'scenes.csv'}"
        )
    r = rows[name]
    d = folder / name
    scale = float(r["disparity_scale"])
    if not scale > 0:
        raise RgbdError(f"{folder / 'scenes.csv'}: {name}: disparity_scale {scale}, expected > 0")
    left, right = read_png(d / r["left"]), read_png(d / r["right"])
    if left.shape != right.shape or left.ndim != 3:
        raise RgbdError(f"{d}: expected two RGB images of one size")
    gt_l = _disparity(d / r["gt_left"], scale, left.shape[:2])
    gt_r = _disparity(d / r["gt_right"], scale, left.shape[:2]) if r["gt_right"] else None
    return StereoScene(
        name,
        r.get("split", ""),
        int(r.get("year", 0) or 0),
        left,
        right,
        gt_l,
        gt_r,
        scale,
        float(r["max_disparity"]),
    )


def load_stereo_scenes(
    split: str | None = None, root: str | Path | None = None
) -> list[StereoScene]:
    """Every scene of ``split`` (None = all 27)."""
    return [load_stereo_scene(n, root) for n in scene_names(split, root)]
