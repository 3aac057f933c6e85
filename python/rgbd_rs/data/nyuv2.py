"""Reader for the NYU Depth v2 frames in ``../shared/data/nyuv2/frames`` (50 of the 654 official
test frames of the labeled set, Kinect v1, 640x480): ``NNNN_rgb.png`` (uint8 RGB),
``NNNN_depth.png`` (uint16 millimetres, in-painted), ``NNNN_label13.png`` and
``NNNN_label40.png`` (uint8 classes, 0 = unlabeled), NNNN the 1-based index in the 1449-frame
labeled set. The suggested split: NNNN <= 43 train (25 frames), NNNN >= 46 test (25 frames);
consecutive frames often show the same room, hence the gap.

Also the one home of the NYU colour camera's intrinsics (:data:`NYUV2_CAMERA`), the 13-class
names (:data:`LABEL13_NAMES`), the region ground truth used by the segmentation evaluation
(:func:`region_ground_truth`) and the object-instance ground truth of the full labeled set
(:func:`instance_ground_truth`). The official ``nyu_depth_v2_labeled.mat`` (all 1449 frames, the
795/654 split) is read by :mod:`rgbd_rs.data.nyuv2_mat` into the same :class:`NyuFrame`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.data.paths import data_root
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.io import read_png

__all__ = [
    "LABEL13_NAMES",
    "NYUV2_CAMERA",
    "NyuFrame",
    "instance_ground_truth",
    "load_nyuv2_frame",
    "nyuv2_frames",
    "region_ground_truth",
]

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]
U16 = npt.NDArray[np.uint16]
I32 = npt.NDArray[np.int32]

#: The NYU Depth v2 colour camera (640x480, no distortion: the labeled frames are already
#: undistorted). The dataset's standard intrinsics (cx = 325.582449, cy = 253.736166) come from
#: the MATLAB toolbox, whose pixel indices start at 1; rgbd_rs puts pixel centres at 0-based
#: integers, so the principal point here is one pixel less (the MATLAB HHA reference of
#: ../shared/data/hha matches only with this shift: tests/test_hha.py).
NYUV2_CAMERA = PinholeCamera(
    fx=518.857901, fy=519.469611, cx=324.582449, cy=252.736166, width=640, height=480
)
#: Names of the 13-class labels (``label13``), indexed by label value; 0 = unlabeled. The
#: grouping the thesis evaluates (its 14th class, "unknown", is label 0 here).
LABEL13_NAMES: tuple[str, ...] = (
    "unlabeled",
    "bed",
    "books",
    "ceiling",
    "chair",
    "floor",
    "furniture",
    "objects",
    "picture",
    "sofa",
    "table",
    "tv",
    "wall",
    "window",
)
#: Label value of unlabeled pixels in ``label13`` / ``label40``.
UNLABELED = 0
#: Region id of unlabeled pixels in :func:`region_ground_truth`.
NO_REGION = -1
#: Depth PNG units per metre (millimetres).
DEPTH_PNG_PER_METRE = 1000.0
#: Frames with NNNN <= this are the train split, NNNN >= :data:`TEST_MIN_INDEX` the test split.
TRAIN_MAX_INDEX = 43
TEST_MIN_INDEX = 46
#: Frames in the NYU Depth v2 labeled set (NNNN is 1-based).
LABELED_FRAMES = 1449
SPLITS = ("all", "train", "test")


@array_eq
@dataclass(frozen=True)
class NyuFrame:
    """One labeled frame: colour, depth in metres (float32, NaN where there is no measurement),
    and the 13- and 40-class labels (uint8, 0 = unlabeled); ``index`` is NNNN, the 1-based index
    in the 1449-frame labeled set.

    Frames of the shared PNGs (:func:`load_nyuv2_frame`) leave the last three fields ``None``;
    frames of the official ``nyu_depth_v2_labeled.mat`` (:class:`rgbd_rs.data.nyuv2_mat.
    NyuMatDataset`) set ``official_split`` (the 795/654 split), ``label894`` (the raw classes,
    uint16, 0 = unlabeled, 1..894) and ``instances`` (uint8 object-instance number within each
    raw class; see :func:`instance_ground_truth`)."""

    index: int
    rgb: U8
    depth: F32
    label13: U8
    label40: U8
    #: ``"train"`` / ``"test"`` of the official 795/654 split (``"none"`` for a frame in
    #: neither); None for the shared PNG frames, whose split is the 25/25 one.
    official_split: str | None = None
    label894: U16 | None = None
    instances: U8 | None = None

    @property
    def name(self) -> str:
        """``NNNN``, as in the file names."""
        return f"{self.index:04d}"

    @property
    def split(self) -> str:
        """The frame's split in the protocol of its source: for the shared PNG frames
        ``"train"`` (NNNN <= 43), ``"test"`` (NNNN >= 46) or ``"none"`` (44, 45); for frames of
        the official .mat, :attr:`official_split` (795 train / 654 test frames)."""
        if self.official_split is not None:
            return self.official_split
        return _split_of(self.index)

    @property
    def camera(self) -> PinholeCamera:
        """The colour camera of this frame: :data:`NYUV2_CAMERA` at 640x480; for a frame of
        another size (a resized copy) the same camera scaled to the frame's width and height."""
        h, w = self.depth.shape[:2]
        if (w, h) == (NYUV2_CAMERA.width, NYUV2_CAMERA.height):
            return NYUV2_CAMERA
        return NYUV2_CAMERA.scaled(w / NYUV2_CAMERA.width, h / NYUV2_CAMERA.height)


def _split_of(index: int) -> str:
    if index <= TRAIN_MAX_INDEX:
        return "train"
    return "test" if index >= TEST_MIN_INDEX else "none"


def _folder(folder: object) -> Path:
    if folder is None:
        root = data_root(required=True)
        assert root is not None  # required=True raises instead
        return root / "nyuv2" / "frames"
    if not isinstance(folder, (str, Path)) or not str(folder):
        raise InvalidArgumentError(f"folder: got {folder!r}, expected a folder path or None")
    return Path(folder)


def nyuv2_frames(split: str = "all", folder: str | Path | None = None) -> list[int]:
    """The frame indices NNNN (sorted) of ``split`` (``"all"``, ``"train"``: NNNN <= 43,
    ``"test"``: NNNN >= 46) found in ``folder`` (default: the shared data's
    ``nyuv2/frames``); a frame counts when all four of its PNGs are there. A folder without any
    frame raises :class:`~rgbd_rs.RgbdError`."""
    split = _validate.choice("split", split, SPLITS)
    where = _folder(folder)
    if not where.is_dir():
        raise RgbdError(f"{where}: not a folder (expected the nyuv2/frames folder)")
    found = []
    for f in sorted(where.glob("[0-9][0-9][0-9][0-9]_rgb.png")):
        stem = f.name[:4]
        if all((where / f"{stem}_{k}.png").is_file() for k in ("depth", "label13", "label40")):
            found.append(int(stem))
    if not found:
        raise RgbdError(f"{where}: no NNNN_{{rgb,depth,label13,label40}}.png frame")
    return [i for i in found if split == "all" or _split_of(i) == split]


def _single(path: Path, dtype: type, what: str) -> np.ndarray:
    img = read_png(path)
    if img.ndim != 2 or img.dtype != dtype:
        raise RgbdError(
            f"{path}: got a {img.dtype} PNG of shape {img.shape}, expected single-channel "
            f"{np.dtype(dtype).name} ({what})"
        )
    return img


def load_nyuv2_frame(index: int, folder: str | Path | None = None) -> NyuFrame:
    """Read frame NNNN = ``index`` from ``folder`` (default: the shared data's
    ``nyuv2/frames``): RGB uint8, depth float32 metres (millimetres / 1000; 0 -> NaN), labels
    uint8. Missing or malformed files raise :class:`~rgbd_rs.RgbdError` naming the file."""
    i = _validate.integer("index", index, minimum=1, maximum=LABELED_FRAMES)
    where = _folder(folder)
    stem = where / f"{i:04d}"
    rgb = read_png(Path(f"{stem}_rgb.png"))
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise RgbdError(f"{stem}_rgb.png: got a {rgb.dtype} PNG of shape {rgb.shape}, expected RGB")
    raw = _single(Path(f"{stem}_depth.png"), np.uint16, "depth in millimetres")
    label13 = _single(Path(f"{stem}_label13.png"), np.uint8, "13-class labels")
    label40 = _single(Path(f"{stem}_label40.png"), np.uint8, "40-class labels")
    shapes = {a.shape[:2] for a in (rgb, raw, label13, label40)}
    if len(shapes) != 1:
        raise RgbdError(f"{stem}_*.png: image sizes differ ({sorted(shapes)})")
    if int(label13.max()) >= len(LABEL13_NAMES):
        raise RgbdError(
            f"{stem}_label13.png: got class {int(label13.max())}, expected 0..13 (13 classes)"
        )
    depth = np.where(raw > 0, raw.astype(np.float32) / np.float32(DEPTH_PNG_PER_METRE), np.nan)
    return NyuFrame(i, rgb, depth.astype(np.float32), label13, label40)


def region_ground_truth(label40: npt.ArrayLike) -> I32:
    """Region ground truth from a class-label image: the 4-connected components of equal label,
    numbered 0..n-1 in raster order of their first pixel; unlabeled pixels (label 0) are -1.

    These are *semantic* regions, not object instances: two touching chairs form one region,
    while one object split by an occluder forms two. (The thesis evaluates on NYUv2's instance
    masks, which only the full ``nyu_depth_v2_labeled.mat`` holds.)
    """
    lab = _validate.asarray("label40", label40)
    if lab.dtype.kind not in "iu":
        raise InvalidArgumentError(
            f"label40: got dtype {lab.dtype}, expected an integer label image (uint8)"
        )
    if lab.ndim != 2 or lab.size == 0:
        raise ShapeMismatchError(
            f"label40: got shape {tuple(lab.shape)}, expected a non-empty (H, W) label image"
        )
    if int(lab.min()) < 0 or int(lab.max()) > 255:
        raise InvalidArgumentError(
            f"label40: got labels in [{int(lab.min())}, {int(lab.max())}], expected 0..255"
        )
    h, w = lab.shape
    _validate.size("label40 height", h)
    _validate.size("label40 width", w)
    img = np.ascontiguousarray(np.repeat(lab.astype(np.uint8)[:, :, None], 3, axis=2))
    regions, n = _rgbd_rs.label_regions(img, 0.0)
    regions = regions.reshape(h, w)
    labelled = lab != UNLABELED
    # Renumber the labelled components 0..n-1 (raster order kept); unlabeled ones become -1.
    keep = np.zeros(n, bool)
    keep[regions[labelled]] = True
    lut = np.where(keep, np.cumsum(keep) - 1, NO_REGION).astype(np.int32)
    return np.asarray(lut[regions], dtype=np.int32)


def instance_ground_truth(label894: npt.ArrayLike, instances: npt.ArrayLike) -> I32:
    """Object-instance ground truth of a frame of the official labeled set, as the NYU toolbox's
    ``get_instance_masks``: one region per distinct (raw class, instance number) pair among the
    labelled pixels, numbered 0..n-1 in raster order of their first pixel; unlabeled pixels
    (class 0) are -1. ``label894`` and ``instances`` are :attr:`NyuFrame.label894` and
    :attr:`NyuFrame.instances` (any integer dtype, same (H, W) shape). Unlike
    :func:`region_ground_truth`, two touching chairs are two regions and one object split by an
    occluder is one (the ground truth the thesis evaluates VoI / RI on)."""
    lab = _validate.asarray("label894", label894)
    ins = _validate.asarray("instances", instances)
    for name, a in (("label894", lab), ("instances", ins)):
        if a.dtype.kind not in "iu":
            raise InvalidArgumentError(
                f"{name}: got dtype {a.dtype}, expected an integer label image"
            )
        if a.ndim != 2 or a.size == 0:
            raise ShapeMismatchError(
                f"{name}: got shape {tuple(a.shape)}, expected a non-empty (H, W) image"
            )
        if int(a.min()) < 0 or int(a.max()) > 65535:
            raise InvalidArgumentError(
                f"{name}: got values in [{int(a.min())}, {int(a.max())}], expected 0..65535"
            )
    if lab.shape != ins.shape:
        raise ShapeMismatchError(
            f"instances: got shape {tuple(ins.shape)}, expected {tuple(lab.shape)} like label894"
        )
    key = lab.astype(np.int64).ravel() * 65536 + ins.astype(np.int64).ravel()
    labelled = lab.ravel() != UNLABELED
    out = np.full(key.shape, NO_REGION, np.int32)
    if labelled.any():
        _, first, inverse = np.unique(key[labelled], return_index=True, return_inverse=True)
        # np.unique numbers the pairs by key; renumber them by their first pixel (raster order).
        order = np.argsort(first, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(order.size)
        out[labelled] = rank[inverse].astype(np.int32)
    return out.reshape(lab.shape)
