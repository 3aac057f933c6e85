"""Labeled RGB-D frames, the cue cache and the torch dataset of the semantic ConvNet (§4.6).

**Frames**: any sequence of objects with ``rgb`` (``H x W x 3`` uint8), ``depth`` (``H x W``
float32 metres, NaN = hole), ``label13`` (``H x W`` uint8, 0 = unlabeled), ``camera``
(:class:`~rgbd_rs.PinholeCamera`) and ``name`` (str). :class:`NyuFrames` serves the NYUv2
frames (:func:`rgbd_rs.data.nyuv2.load_nyuv2_frame` with :data:`~rgbd_rs.data.nyuv2.NYUV2_CAMERA`),
:class:`SyntheticFrames` the synthetic indoor frames of :func:`rgbd_rs.data.synth_indoor.
generate_indoor` (a camera per frame), :class:`FrameFolder` a folder of ``NAME_rgb.png``,
``NAME_depth.png`` (uint16 millimetres, 0 = hole), ``NAME_label13.png`` and one
``camera.json``; :func:`open_frames` picks one from a name or folder. A source that also has
``names`` (one str per frame) lets a cache be sharded without loading frames of other shards.

**Cache** (:func:`build_semantic_cache`, :class:`SemanticCache`): per frame the 9 cues of eq. 4.2
(:func:`rgbd_rs.segmentation.cues.semantic_cues`) computed at the frame's full size, then
reduced to the network's input size (default 320 x 240, §4.6): ``cues.npy`` (``N x 9 x h x w``
float16) and ``labels.npy`` (``N x h x w`` uint8), memory-mappable, plus ``done.npy`` (per
frame: 0 to do, 1 done, 2 failed), ``names.json`` and ``meta.json``. Reductions (the thesis
does not say how it reduced 640 x 480 to 320 x 240):

- cues: the area mean of each output pixel's source block (:func:`downsample_cues`);
- labels: the most frequent *labeled* class of the block, unlabeled (0) only when the block has
  no labeled pixel, ties to the smaller class (:func:`downsample_labels`); the same blocks.

A frame's rows are flushed before its ``done`` byte, so a killed run loses at most the frame in
flight and a re-run skips what is done; ``shard=(i, n)`` computes frames ``i, i + n, ...`` only,
so n processes fill one cache. A folder holding a cache built from other frames or with other
settings (size, cue function, seed) is refused.

**Dataset** (:meth:`SemanticCache.dataset`): items ``(cues float32 9 x h x w, labels int64
h x w)``; ``augment=True`` mirrors an item left-right with probability 1/2, drawn from numpy's
global generator, which :func:`rgbd_rs.nn.train.train` seeds from its config's seed and stores in
its checkpoints: training is deterministic by that seed, also when resumed (on CPU; see
:mod:`rgbd_rs.nn.train` for CUDA).
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import torch
from torch.nn import functional as F
from torch.utils.data import Dataset

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.data.nyuv2 import LABEL13_NAMES, NYUV2_CAMERA, UNLABELED
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.nn.semantic import DOWNSAMPLE, N_CUES, THESIS_INPUT_SIZE

from .._reasons import reason

__all__ = [
    "CACHE_FORMAT",
    "FrameFolder",
    "LabeledFrame",
    "NyuFrames",
    "SemanticCache",
    "SemanticFrames",
    "SyntheticFrames",
    "build_semantic_cache",
    "downsample_cues",
    "downsample_labels",
    "open_frames",
]

#: Format tag of a cache's meta.json.
CACHE_FORMAT = "rgbd_rs.semantic-cache/1"
#: The network's input size, width x height (§4.6: 320 x 240).
DEFAULT_SIZE = THESIS_INPUT_SIZE
#: ``done.npy`` codes.
TODO, DONE, FAILED = 0, 1, 2
#: Depth PNG units per metre in a :class:`FrameFolder` (millimetres, as NYUv2's).
DEPTH_PNG_PER_METRE = 1000.0
#: Float16's largest finite value: cues are clipped into it before caching.
_F16_MAX = float(np.finfo(np.float16).max)
#: How labels are reduced (recorded in the cache's metadata).
LABEL_REDUCTION = "block majority of labeled pixels"

CueFn = Callable[..., Any]


class Frame(Protocol):
    """What a frame source yields (attributes only)."""

    name: str
    rgb: np.ndarray
    depth: np.ndarray
    label13: np.ndarray
    camera: PinholeCamera


@array_eq
@dataclass(frozen=True)
class LabeledFrame:
    """One labeled RGB-D frame: ``rgb`` H x W x 3 uint8, ``depth`` H x W float32 metres (NaN =
    hole), ``label13`` H x W uint8 (0 = unlabeled), the ``camera`` of both, a ``name``."""

    name: str
    rgb: np.ndarray
    depth: np.ndarray
    label13: np.ndarray
    camera: PinholeCamera


class NyuFrames(Sequence[LabeledFrame]):
    """The NYUv2 frames of ``split`` (``"all"``, ``"train"``, ``"test"``; see
    :func:`rgbd_rs.data.nyuv2.nyuv2_frames`) in ``folder`` (default: the shared data's
    ``nyuv2/frames``), loaded on access, with :data:`~rgbd_rs.data.nyuv2.NYUV2_CAMERA`."""

    def __init__(self, split: str = "all", folder: str | os.PathLike[str] | None = None) -> None:
        from rgbd_rs.data.nyuv2 import nyuv2_frames

        self.folder = None if folder is None else _validate.path("folder", folder)
        self.split = split
        self.indices = tuple(nyuv2_frames(split, self.folder))
        self.names = tuple(f"{i:04d}" for i in self.indices)

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, i: int) -> LabeledFrame:  # type: ignore[override]
        from rgbd_rs.data.nyuv2 import load_nyuv2_frame

        k = _validate.integer("index", i, maximum=max(len(self) - 1, 0))
        f = load_nyuv2_frame(self.indices[k], self.folder)
        return LabeledFrame(f.name, f.rgb, f.depth, f.label13, NYUV2_CAMERA)

    def __iter__(self) -> Iterator[LabeledFrame]:
        return (self[i] for i in range(len(self)))


class FrameFolder(Sequence[LabeledFrame]):
    """The frames of ``folder``: every ``NAME_rgb.png`` with its ``NAME_depth.png`` (uint16
    millimetres, 0 = hole) and ``NAME_label13.png`` (uint8, 0 = unlabeled), sorted by name, and
    the camera of ``camera`` (a PinholeCamera or a calibration JSON; default
    ``folder/camera.json``). A folder without frames or camera raises :class:`RgbdError`."""

    def __init__(
        self,
        folder: str | os.PathLike[str],
        camera: PinholeCamera | str | os.PathLike[str] | None = None,
    ) -> None:
        from rgbd_rs.data.calibration import load_camera

        if not isinstance(folder, (str, os.PathLike)) or not str(folder):
            raise InvalidArgumentError(f"folder: got {folder!r}, expected a folder of frames")
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise RgbdError(f"{self.folder}: not a folder, expected a folder of frames")
        names = []
        lacking: list[str] = []
        for f in sorted(self.folder.glob("*_rgb.png")):
            stem = f.name[: -len("_rgb.png")]
            if all((self.folder / f"{stem}_{k}.png").is_file() for k in ("depth", "label13")):
                names.append(stem)
            else:
                lacking.append(stem)
        if lacking and names:
            shown = ", ".join(lacking[:3]) + (", ..." if len(lacking) > 3 else "")
            warnings.warn(
                f"{self.folder}: {len(lacking)} frame(s) without their NAME_depth.png or "
                f"NAME_label13.png ({shown}) left out",
                RuntimeWarning,
                stacklevel=2,
            )
        if not names:
            raise RgbdError(
                f"{self.folder}: no NAME_{{rgb,depth,label13}}.png frame, expected a folder of "
                "labeled frames"
            )
        self.names = tuple(names)
        if camera is None:
            file = self.folder / "camera.json"
            if not file.is_file():
                raise RgbdError(
                    f"{file}: not found; the frames' camera must be given (camera= or "
                    "--calib) or be in the folder's camera.json"
                )
            camera = file
        if isinstance(camera, PinholeCamera):
            self.camera = camera
        elif isinstance(camera, (str, os.PathLike)):
            self.camera = load_camera(Path(camera))
        else:
            raise InvalidArgumentError(
                f"camera: got {type(camera).__name__}, expected a PinholeCamera or a JSON file"
            )

    def __len__(self) -> int:
        return len(self.names)

    def __getitem__(self, i: int) -> LabeledFrame:  # type: ignore[override]
        from rgbd_rs.io import read_png

        k = _validate.integer("index", i, maximum=max(len(self) - 1, 0))
        stem = self.folder / self.names[k]
        rgb = read_png(Path(f"{stem}_rgb.png"))
        raw = read_png(Path(f"{stem}_depth.png"), rgb=False)
        lab = read_png(Path(f"{stem}_label13.png"), rgb=False)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise RgbdError(f"{stem}_rgb.png: got {rgb.dtype} {rgb.shape}, expected RGB uint8")
        if raw.ndim != 2 or raw.dtype != np.uint16:
            raise RgbdError(
                f"{stem}_depth.png: got {raw.dtype} {raw.shape}, expected uint16 millimetres"
            )
        if lab.ndim != 2 or lab.dtype != np.uint8:
            raise RgbdError(f"{stem}_label13.png: got {lab.dtype} {lab.shape}, expected uint8")
        want = (self.camera.height, self.camera.width)
        for suffix, img in (("rgb", rgb), ("depth", raw), ("label13", lab)):
            if img.shape[:2] != want:
                raise RgbdError(
                    f"{stem}_{suffix}.png: got {img.shape[1]}x{img.shape[0]} pixels, expected "
                    f"the camera's {want[1]}x{want[0]} (every image of a frame registered to it)"
                )
        depth = np.where(raw > 0, raw.astype(np.float32) / np.float32(DEPTH_PNG_PER_METRE), np.nan)
        return LabeledFrame(self.names[k], rgb, depth.astype(np.float32), lab, self.camera)

    def __iter__(self) -> Iterator[LabeledFrame]:
        return (self[i] for i in range(len(self)))


class SyntheticFrames:
    """The synthetic indoor frames of ``folder`` (:class:`rgbd_rs.data.synth_indoor.
    IndoorFrames`: ``NNNNNN_{rgb,depth,label13}.png`` and ``camera_NNNNNN.json``), with their
    ``names`` known without loading them. A folder missing frames that a run asked for (it was
    interrupted, is still running, or a shard was not run) raises :class:`RgbdError` unless
    ``partial=True`` (then: its complete frames)."""

    def __init__(self, folder: str | os.PathLike[str], *, partial: bool = False) -> None:
        from rgbd_rs.data.synth_indoor import IndoorFrames

        partial = _validate.flag("partial", partial)
        self.frames = IndoorFrames(_validate.path("folder", folder))
        self.folder = self.frames.folder
        missing = self.frames.missing
        if missing and not partial:
            shown = ", ".join(str(k) for k in missing[:5]) + (", ..." if len(missing) > 5 else "")
            raise RgbdError(
                f"{self.folder}: {len(missing)} of the {self.frames.requested} frames asked for "
                f"not complete (frames {shown}: a `rgbd synth-indoor` run interrupted, still "
                "running or a --shard not run), expected all: finish them with the same command"
            )
        if len(self.frames) == 0:
            raise RgbdError(f"{self.folder}: no complete synthetic frame")
        self.names = tuple(f"{k:06d}" for k in self.frames.indices)

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, i: int) -> Any:
        k = _validate.integer("index", i, maximum=max(len(self) - 1, 0))
        return self.frames[k]


def _frames_have_splits(  # for the CLI; not in __all__
    frames: str | os.PathLike[str], camera: PinholeCamera | str | os.PathLike[str] | None = None
) -> bool:
    """Whether :func:`open_frames` takes a ``split`` other than ``"all"`` for ``frames``: the
    shared NYUv2 frames, the official ``.mat`` and NYUv2-layout folders (without a camera)."""
    if isinstance(frames, str) and frames.lower() == "nyuv2":
        return True
    p = Path(frames)
    if p.is_file() and p.suffix.lower() == ".mat":
        return True
    return p.is_dir() and _nyu_layout(p, camera)


def _nyu_layout(p: Path, camera: object) -> bool:
    """A folder of NYUv2 frames (``NNNN_label40.png``, no camera of its own or given)."""
    return (
        camera is None
        and not (p / "camera.json").is_file()
        and any(p.glob("[0-9][0-9][0-9][0-9]_label40.png"))
    )


def open_frames(
    frames: str | os.PathLike[str],
    split: str = "all",
    camera: PinholeCamera | str | os.PathLike[str] | None = None,
) -> Any:
    """The labeled frames ``frames`` names:

    - ``"nyuv2"``: the shared NYUv2 frames (:class:`NyuFrames`, ``split`` ``"all"``,
      ``"train"`` or ``"test"``);
    - the official ``nyu_depth_v2_labeled.mat`` (:class:`rgbd_rs.data.nyuv2_mat.NyuMatDataset`:
      the thesis' 795 / 654 split, in-painted depth);
    - a folder in the NYUv2 layout (``NNNN_{rgb,depth,label13,label40}.png``, no camera);
    - a folder of synthetic indoor frames (``camera_NNNNNN.json`` per frame:
      :class:`SyntheticFrames`);
    - else a :class:`FrameFolder`.

    Folders other than NYUv2 ones take only ``split="all"``."""
    split = _validate.choice("split", split, ("all", "train", "test"))
    if not isinstance(frames, (str, os.PathLike)) or not str(frames):
        raise InvalidArgumentError(f"frames: got {frames!r}, expected 'nyuv2' or a folder")
    if isinstance(frames, str) and frames.lower() == "nyuv2":
        if camera is not None:
            raise InvalidArgumentError("camera: given with 'nyuv2', expected none (NYUV2_CAMERA)")
        return NyuFrames(split)
    p = Path(frames)
    if p.is_file() and p.suffix.lower() == ".mat":
        if camera is not None:
            raise InvalidArgumentError("camera: given with a .mat file, expected none")
        from rgbd_rs.data.nyuv2_mat import NyuMatDataset

        return NyuMatDataset(p, split)
    if not p.is_dir():
        raise InvalidArgumentError(
            f"frames: got {str(frames)!r}, expected 'nyuv2', nyu_depth_v2_labeled.mat or a folder"
        )
    if _nyu_layout(p, camera):
        return NyuFrames(split, p)
    if split != "all":
        raise InvalidArgumentError(
            f"split: got {split!r} for the folder {p}, expected 'all' (only NYUv2 frames have "
            "splits)"
        )
    if camera is None and any(p.glob("camera_[0-9]*.json")):
        return SyntheticFrames(p)
    return FrameFolder(p, camera)


# -- reductions to the network's input size ---------------------------------------------------


def _size(name: str, size: object, minimum: int = 1) -> tuple[int, int]:
    if not isinstance(size, (tuple, list)) or len(size) != 2:
        raise InvalidArgumentError(f"{name}: got {size!r}, expected (width, height)")
    w = _validate.integer(f"{name}[0]", size[0], minimum=minimum, maximum=_validate.MAX_SIDE)
    h = _validate.integer(f"{name}[1]", size[1], minimum=minimum, maximum=_validate.MAX_SIDE)
    return w, h


def _no_larger(size: tuple[int, int], hw: tuple[int, ...], what: str) -> None:
    """Refuse a target ``size`` = (w, h) beyond the ``hw`` maps: pooling would enlarge them."""
    w, h = size
    if w > hw[1] or h > hw[0]:
        raise ShapeMismatchError(
            f"size: got {w}x{h}, larger than {what} ({hw[1]}x{hw[0]}); expected at most its "
            "size (the cues are reduced to the network's input, never enlarged)"
        )


def downsample_cues(cues: npt.ArrayLike, size: tuple[int, int]) -> npt.NDArray[np.float32]:
    """``C x H x W`` maps -> ``C x h x w`` (``size`` = (w, h)): each output pixel the mean of
    its source block (torch's adaptive average pooling bins; exact 2 x 2 means at 640 x 480 ->
    320 x 240). Non-finite values count as 0."""
    x = _validate.array("cues", cues, shape=(None, None, None))
    w, h = _size("size", size)
    _no_larger((w, h), x.shape[1:], "the cue maps")
    x = np.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0)
    if x.shape[1:] == (h, w):
        return np.ascontiguousarray(x, dtype=np.float32)
    # Block sums of values near float32's limit overflow it: those are averaged in float64 (a
    # mean never exceeds the largest value, so the result fits float32 again).
    wide = x.size > 0 and float(np.abs(x).max()) > _validate.F32_MAX / x[0].size
    t = F.adaptive_avg_pool2d(torch.from_numpy(x.astype(np.float64) if wide else x)[None], (h, w))
    return np.ascontiguousarray(t[0].numpy(), dtype=np.float32)


def downsample_labels(
    labels: npt.ArrayLike, size: tuple[int, int], *, n_classes: int = len(LABEL13_NAMES)
) -> npt.NDArray[np.uint8]:
    """``H x W`` class labels -> ``h x w`` (``size`` = (w, h)): the most frequent labeled class
    among each output pixel's source block (the blocks of :func:`downsample_cues`), unlabeled
    (0) only when the block holds no labeled pixel; ties go to the smaller class."""
    lab = _validate.asarray("labels", labels)
    if lab.dtype.kind not in "iu":
        raise InvalidArgumentError(f"labels: got dtype {lab.dtype}, expected integer labels")
    lab = _validate.array("labels", lab, shape=(None, None), dtype=np.int64)
    n = _validate.integer("n_classes", n_classes, minimum=2, maximum=256)
    w, h = _size("size", size)
    _no_larger((w, h), lab.shape, "the label image")
    if lab.min() < 0 or lab.max() >= n:
        raise InvalidArgumentError(
            f"labels: got values in [{lab.min()}, {lab.max()}], expected 0..{n - 1}"
        )
    if lab.shape == (h, w):
        return lab.astype(np.uint8)
    onehot = F.one_hot(torch.from_numpy(lab), n).permute(2, 0, 1).to(torch.float32)
    share = F.adaptive_avg_pool2d(onehot[None], (h, w))[0]  # n x h x w class fractions
    share[UNLABELED] = 0.0
    best = share.argmax(dim=0)  # first maximum: the smaller class on ties
    best[share.amax(dim=0) <= 0] = UNLABELED
    return best.numpy().astype(np.uint8)


# -- the cache --------------------------------------------------------------------------------


def _cue_function(cues: CueFn | None) -> tuple[CueFn, str]:
    if cues is not None:
        if not callable(cues):
            raise InvalidArgumentError(
                f"cues: got {type(cues).__name__}, expected a function (rgb, depth, camera, "
                "*, seed) -> 9 x H x W"
            )
        return cues, f"{getattr(cues, '__module__', '?')}.{getattr(cues, '__qualname__', '?')}"
    try:
        from rgbd_rs.segmentation.cues import semantic_cues
    except ImportError as exc:
        raise RgbdError(
            f"cues: rgbd_rs.segmentation.cues.semantic_cues is not in this installation ({exc})"
        ) from None
    return semantic_cues, "rgbd_rs.segmentation.cues.semantic_cues"


def _frame_cues(
    frame: Frame, size: tuple[int, int], cues: CueFn, seed: int
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
    """One frame's cues (``9 x h x w`` float32, clipped into float16's range) and labels
    (``h x w`` uint8) at ``size``; a malformed frame raises naming its attribute."""
    name = getattr(frame, "name", "?")
    try:
        rgb, depth, label, camera = frame.rgb, frame.depth, frame.label13, frame.camera
    except AttributeError as exc:
        raise InvalidArgumentError(
            f"frame {name}: {exc}; expected rgb, depth, label13, camera and name"
        ) from None
    rgb = _validate.array(f"frame {name} rgb", rgb, shape=(None, None, 3), dtype=np.uint8)
    hw = rgb.shape[:2]
    depth = _validate.array(f"frame {name} depth", depth, shape=hw)
    lab = _validate.asarray(f"frame {name} label13", label)
    if lab.shape != hw:
        raise ShapeMismatchError(
            f"frame {name} label13: got shape {lab.shape}, expected {hw} like its rgb"
        )
    _no_larger(size, hw, f"frame {name}")
    x = np.asarray(cues(rgb, depth, camera, seed=seed))
    if x.shape != (N_CUES, *hw):
        raise ShapeMismatchError(
            f"frame {name} cues: got shape {x.shape}, expected ({N_CUES}, {hw[0]}, {hw[1]})"
        )
    small = np.clip(downsample_cues(x, size), -_F16_MAX, _F16_MAX)
    return small, downsample_labels(lab, size)


def _shard(shard: object) -> tuple[int, int]:
    return _validate.shard("shard", shard)


def _names(frames: Any) -> list[str]:
    names = getattr(frames, "names", None)
    if names is None:  # a plain sequence: its frames' own names
        names = [str(getattr(f, "name", i)) for i, f in enumerate(frames)]
    names = [str(n) for n in names]
    if len(names) != len(frames):
        raise InvalidArgumentError(
            f"frames: got {len(names)} names for {len(frames)} frames, expected one each"
        )
    if len(set(names)) != len(names):
        raise InvalidArgumentError("frames: got repeated frame names, expected unique names")
    return names


def build_semantic_cache(
    frames: Any,
    out: str | os.PathLike[str],
    *,
    size: tuple[int, int] = DEFAULT_SIZE,
    shard: tuple[int, int] = (0, 1),
    seed: int = 0,
    cues: CueFn | None = None,
    source: str | None = None,
    quiet: bool = False,
) -> SemanticCache:
    """Compute the cues and labels of every frame of ``frames`` (or of shard ``i`` of ``n``) at
    ``size`` = (width, height) into the cache folder ``out`` (layout in the module docstring),
    skipping frames already done; returns the opened cache. ``cues`` replaces
    :func:`rgbd_rs.segmentation.cues.semantic_cues` (same signature; tests, ablations) and
    ``seed`` is passed to it. ``source`` names the frames in the metadata (default: the
    sequence's type). An existing cache of other frames or settings raises :class:`RgbdError`.
    A frame whose cues cannot be computed is marked failed (a warning names it) and skipped by
    the datasets. Progress bar on stderr unless ``quiet``."""
    from tqdm import tqdm

    out = _validate.out_folder("out", out)

    quiet = _validate.flag("quiet", quiet)

    if isinstance(frames, (str, bytes)) or not (
        hasattr(frames, "__len__") and hasattr(frames, "__getitem__")
    ):
        raise InvalidArgumentError(
            f"frames: got {type(frames).__name__}, expected a sequence of labeled frames "
            "(open_frames('nyuv2'), a list, ...)"
        )
    if len(frames) == 0:
        raise InvalidArgumentError("frames: got no frames, expected at least one")
    w, h = _size("size", size, DOWNSAMPLE)  # the network's two pools need 4 pixels
    i_shard, n_shard = _shard(shard)
    seed = _validate.integer("seed", seed, maximum=2**32 - 1)
    fn, fn_name = _cue_function(cues)
    if not isinstance(out, (str, os.PathLike)) or not str(out):
        raise InvalidArgumentError(f"out: got {out!r}, expected a folder path")
    names = _names(frames)
    src = source if source is not None else type(frames).__name__
    if not isinstance(src, str):
        raise InvalidArgumentError(f"source: got {src!r}, expected a str")
    from rgbd_rs.io import _bytes_writer, _create_once, _npy_writer, _reserve

    root = Path(out)
    if not (root / "meta.json").is_file():
        # Before the cache exists: a size beyond the frames would enlarge every one of them.
        first = getattr(frames[0], "rgb", None)
        if first is not None and np.ndim(first) == 3:
            _no_larger((w, h), np.shape(first)[:2], f"frame {names[0]}")
    root.mkdir(parents=True, exist_ok=True)
    n = len(names)
    meta = {
        "format": CACHE_FORMAT,
        "source": src,
        "count": n,
        "size": [w, h],
        "classes": list(LABEL13_NAMES),
        "cues": fn_name,
        "seed": seed,
        "labels": LABEL_REDUCTION,
        "dtype": "float16",
    }
    digest = _frames_fingerprint(frames, names)
    if digest is not None:
        meta["fingerprint"] = digest
    if (root / "meta.json").is_file():
        _check_meta(root, meta, names)
    _create_once(root / "names.json", _bytes_writer(json.dumps(names).encode()))
    _create_once(root / "cues.npy", _npy_writer((n, N_CUES, h, w), np.float16))
    _create_once(root / "labels.npy", _npy_writer((n, h, w), np.uint8))
    for name in ("cues.npy", "labels.npy"):
        _reserve(root / name)
    _create_once(root / "done.npy", _npy_writer((n,), np.uint8))
    _create_once(root / "meta.json", _bytes_writer(json.dumps(meta, indent=1).encode()))
    _check_meta(root, meta, names)
    x_all = np.load(root / "cues.npy", mmap_mode="r+", allow_pickle=False)
    y_all = np.load(root / "labels.npy", mmap_mode="r+", allow_pickle=False)
    done = np.load(root / "done.npy", mmap_mode="r+", allow_pickle=False)
    mine = np.arange(i_shard, n, n_shard)
    todo = mine[done[mine] == TODO]
    desc = f"cache {src}" + (f" {i_shard}/{n_shard}" if n_shard > 1 else "")
    bar = tqdm(
        total=len(mine), initial=len(mine) - len(todo), desc=desc, unit="frame",
        disable=quiet, dynamic_ncols=True,
    )  # fmt: skip
    with bar:
        for k in todo:
            try:
                frame = frames[int(k)]
                got = str(getattr(frame, "name", names[k]))
                if got != names[k]:
                    raise RgbdError(f"frame {k}: named {got!r}, expected {names[k]!r}")
                x, y = _frame_cues(frame, (w, h), fn, seed)
            except RgbdError as exc:
                if str(exc).startswith("size: "):
                    raise  # a setting every frame shares, not one frame's fault
                warnings.warn(
                    f"frame {k} ({names[k]}): {exc}; marked failed, skipped", stacklevel=2
                )
                done[k] = FAILED
                done.flush()
                bar.update()
                continue
            x_all[k] = x.astype(np.float16)
            y_all[k] = y
            x_all.flush()
            y_all.flush()
            done[k] = DONE
            done.flush()
            bar.update()
    del x_all, y_all, done
    return SemanticCache(root)


def _frames_fingerprint(frames: Any, names: list[str]) -> str | None:
    """A digest of the files behind ``frames`` when they come from a folder (each file whose
    name holds a frame's name, by name and size: reading them all would take minutes), so a
    cache refuses to be resumed from another folder of the same name and frame names (two
    `rgbd synth-indoor` seeds); None for frames not read from a folder."""
    folder = getattr(frames, "folder", None)
    if folder is None and isinstance(frames, NyuFrames):
        from rgbd_rs.data.nyuv2 import _folder as nyu_folder

        folder = nyu_folder(None)
    if folder is None or not Path(folder).is_dir():
        return None
    wanted = set(names)
    h = hashlib.sha256(json.dumps(names).encode())
    for f in sorted(Path(folder).iterdir()):
        if f.is_file() and _of_a_frame(f.name, wanted):
            h.update(f"{f.name}:{f.stat().st_size};".encode())
    return h.hexdigest()[:16]


def _of_a_frame(file: str, names: set[str]) -> bool:
    """Whether ``file`` belongs to a frame of ``names``: ``NAME_*`` / ``NAME.*`` (names with
    ``_`` or ``.`` of their own included) or ``*_NAME.*`` (``camera_NNNNNN.json``)."""
    for i, ch in enumerate(file):
        if ch in "_." and file[:i] in names:
            return True
    tail = file.partition("_")[2]
    return bool(tail) and tail.rsplit(".", 1)[0] in names


def _check_meta(root: Path, meta: dict[str, Any], names: list[str]) -> None:
    cache = SemanticCache(root)
    if "fingerprint" not in cache.meta:  # a cache made before frames were fingerprinted
        meta = {k: v for k, v in meta.items() if k != "fingerprint"}
    if cache.meta != meta or list(cache.names) != names:
        diff = sorted(k for k in set(meta) | set(cache.meta) if meta.get(k) != cache.meta.get(k))
        if list(cache.names) != names:
            diff.append("names")
        why = " (the frames' files differ: another folder of the same name?)" * (
            diff == ["fingerprint"]
        )
        raise RgbdError(
            f"{root}: a cache of other frames or settings (differs in {diff}: "
            f"{ {k: cache.meta.get(k) for k in diff if k != 'names'} }){why}; repeat the first "
            "run's frames and settings or choose another folder"
        )


class SemanticCache:
    """An opened cache folder written by :func:`build_semantic_cache` (read-only memory maps)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        if not isinstance(path, (str, os.PathLike)) or not str(path):
            raise InvalidArgumentError(f"path: got {path!r}, expected a semantic-cache folder")
        self.path = Path(path)
        meta_path = self.path / "meta.json"
        if not meta_path.is_file():
            raise RgbdError(
                f"{self.path}: "
                + ("no such folder" if not self.path.exists() else "no meta.json")
                + ", expected a cache written by build_semantic_cache (`rgbd semantic cache`)"
            )
        try:
            meta = json.loads(meta_path.read_text())
        except (ValueError, UnicodeDecodeError) as exc:
            raise RgbdError(f"{meta_path}: not valid JSON ({reason(exc)})") from None
        if not isinstance(meta, dict) or meta.get("format") != CACHE_FORMAT:
            tag = meta.get("format") if isinstance(meta, dict) else None
            raise RgbdError(f"{meta_path}: format {tag!r}, expected {CACHE_FORMAT!r}")
        self.meta: dict[str, Any] = meta
        try:
            w, h = (int(v) for v in meta["size"])
            self.size = (w, h)
            self.classes = tuple(str(c) for c in meta["classes"])
            n = int(meta["count"])
            names = json.loads((self.path / "names.json").read_text())
        except (KeyError, TypeError, ValueError, OSError) as exc:
            raise RgbdError(f"{meta_path}: incomplete or invalid cache metadata ({exc})") from None
        self.names = tuple(str(x) for x in names)
        if len(self.names) != n:
            raise RgbdError(f"{self.path}: names.json holds {len(self.names)} names, expected {n}")

    def __len__(self) -> int:
        return len(self.names)

    def _array(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        file = self.path / f"{name}.npy"
        try:
            arr: np.ndarray = np.load(file, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise RgbdError(f"{file}: unreadable cache array ({reason(exc)})") from None
        if arr.shape != shape:
            raise RgbdError(f"{file}: shape {arr.shape}, expected {shape}")
        return arr

    @property
    def done(self) -> npt.NDArray[np.uint8]:
        """Per frame: 0 to do, 1 done, 2 failed (a fresh read of ``done.npy``)."""
        return np.array(self._array("done", (len(self),)))

    @property
    def complete(self) -> bool:
        """Every frame is done or failed."""
        return bool((self.done != TODO).all())

    def cues(self) -> np.ndarray:
        """``N x 9 x h x w`` float16 read-only memory map."""
        w, h = self.size
        return self._array("cues", (len(self), N_CUES, h, w))

    def labels(self) -> np.ndarray:
        """``N x h x w`` uint8 read-only memory map (0 = unlabeled)."""
        w, h = self.size
        return self._array("labels", (len(self), h, w))

    def indices(self) -> npt.NDArray[np.int64]:
        """The done frames, in order."""
        return np.flatnonzero(self.done == DONE).astype(np.int64)

    def require_complete(self) -> None:
        """Raise :class:`RgbdError` if any frame is still to compute; failed frames count as
        done."""
        todo = int((self.done == TODO).sum())
        if todo:
            raise RgbdError(
                f"{self.path}: {todo} of its {len(self)} frames not computed yet (the cache build "
                "was interrupted, is still running or misses a shard), expected a complete "
                "cache: finish it with `rgbd semantic cache` and the same settings"
            )

    def dataset(
        self,
        indices: npt.ArrayLike | None = None,
        *,
        augment: bool = False,
        partial: bool = False,
    ) -> SemanticFrames:
        """A torch Dataset of the done frames (or of ``indices``) yielding ``(cues, labels)``;
        ``augment`` mirrors items left-right at random (module docstring). Without ``indices``,
        a cache with frames still to compute raises :class:`RgbdError` unless ``partial=True``
        (then: its computed frames)."""
        partial = _validate.flag("partial", partial)
        if indices is None:
            idx = self.indices()
            if not partial:
                self.require_complete()
        else:
            idx = _validate.array("indices", indices, shape=(None,), dtype=np.int64)
            if idx.min() < 0 or idx.max() >= len(self):
                raise InvalidArgumentError(
                    f"indices: got values in [{idx.min()}, {idx.max()}], expected "
                    f"0..{len(self) - 1}"
                )
            bad = idx[self.done[idx] != DONE]
            if len(bad):
                raise InvalidArgumentError(
                    f"indices: got frames {bad[:5].tolist()} that are not computed, expected "
                    "done frames"
                )
        if len(idx) == 0:
            raise RgbdError(f"{self.path}: no computed frames; build the cache")
        if not isinstance(augment, bool):
            raise InvalidArgumentError(f"augment: got {augment!r}, expected a bool")
        return SemanticFrames(self, idx, augment=augment)


class SemanticFrames(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """Items ``(cues float32 9 x h x w, labels int64 h x w)`` of a :class:`SemanticCache` (see
    :meth:`SemanticCache.dataset`); the memory maps open lazily in each process."""

    def __init__(self, cache: SemanticCache, indices: np.ndarray, *, augment: bool) -> None:
        self.cache_path = cache.path
        self.indices = np.asarray(indices, np.int64)
        self.augment = augment
        self._cache = cache
        self._arrays: tuple[np.ndarray, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self.indices)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_arrays"] = None
        return state

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        if self._arrays is None:
            self._arrays = (self._cache.cues(), self._cache.labels())
        k = int(self.indices[i])
        x = np.asarray(self._arrays[0][k], np.float32)
        y = np.asarray(self._arrays[1][k], np.int64)
        if self.augment and np.random.random() < 0.5:  # noqa: NPY002 - the trainer's generator
            x, y = x[..., ::-1], y[..., ::-1]
        return torch.from_numpy(x.copy()), torch.from_numpy(y.copy())
