"""Synthetic labeled indoor RGB-D frames (Kinect-v1-like) to pre-train the semantic-labeling
ConvNet of thesis §4.6 before fine-tuning on real NYUv2 frames.

Each frame is a furnished room (bedroom, living room, office, kitchen or library, 2.5-10 m:
floor, walls, ceiling, doors, windows with curtains, pictures, tables, chairs, beds, sofas,
cabinets, shelves with books, monitors / TVs, lamps, plants, boxes and clutter) rendered by the
ray-casting core (:mod:`rgbd_rs.render`), seen by a hand-held camera at 1-1.6 m looking roughly
horizontally, mostly at some furniture. Every pixel is labeled with the 13 classes of
:data:`rgbd_rs.data.nyuv2.LABEL13_NAMES` through the renderer's per-object ids (0 only where no
surface is hit: never inside a closed room). Colour gets glowing windows and lamps,
auto-exposure, white balance, sRGB gamma, vignetting, blur, sometimes motion blur, and noise;
depth gets the Kinect v1's
error model (:mod:`rgbd_rs.data.synth_indoor_sensor`): noise with sigma ~ 1.425e-3 z^2 m, disparity
quantisation, jagged edges, and holes on dark or glossy surfaces, glass, grazing angles,
projector shadows beside depth edges and beyond the working range. Every constant is drawn from
a range per frame (room, furniture, materials, lights, intrinsics around
:data:`~rgbd_rs.data.nyuv2.NYUV2_CAMERA`, sensor), so nothing is tuned to one value. (The real
NYUv2 frames' depth is in-painted; these keep the raw sensor's holes as NaN.)

Frame ``k`` of seed ``s`` depends only on ``(s, k)``: shards and resumed runs give the same bytes.
On disk (:func:`generate_indoor`, read by :class:`IndoorFrames`): ``NNNNNN_rgb.png`` (uint8 RGB),
``NNNNNN_depth.png`` (uint16 mm, 0 = hole), ``NNNNNN_label13.png`` (uint8) and
``camera_NNNNNN.json`` (:func:`rgbd_rs.data.calibration.save_camera`), like the real frames.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs._progress import bar_options
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.data.calibration import load_camera, save_camera
from rgbd_rs.data.nyuv2 import DEPTH_PNG_PER_METRE, LABEL13_NAMES
from rgbd_rs.data.synth_indoor_scene import IndoorScene, _random_indoor_scene
from rgbd_rs.data.synth_indoor_sensor import _kinect_color, _kinect_depth
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.io import _bytes_writer, _create_once, read_json, read_png, write_json, write_png
from rgbd_rs.viz import class_picture, grid, image_panel, map_panel, save_png

__all__ = [
    "LABEL13_COLORS",
    "IndoorFrame",
    "IndoorFrames",
    "class_frequencies",
    "generate_indoor",
    "label_colors",
    "render_indoor_frame",
    "write_indoor_preview",
]

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]

#: Most frames a folder holds (six-digit names).
MAX_FRAMES = 1_000_000
#: Smallest and largest image side accepted.
MIN_SIDE, MAX_SIDE = 16, 4096
#: Name of the file recording how a folder's frames were made (checked when resuming).
MANIFEST = "indoor.json"
#: The most frames any run asked for (written before a run's frames, so a reader sees them due).
REQUESTED = "requested.json"
#: Version of the generator; frames of another version are not mixed into one folder.
VERSION = 4
#: RGB colours (0-255) of the 13 classes (index = label; 0 unlabeled is black), for previews.
LABEL13_COLORS: tuple[tuple[int, int, int], ...] = (
    (0, 0, 0),
    (230, 85, 13),  # bed
    (214, 39, 40),  # books
    (174, 199, 232),  # ceiling
    (44, 160, 44),  # chair
    (140, 86, 75),  # floor
    (148, 103, 189),  # furniture
    (255, 187, 120),  # objects
    (227, 119, 194),  # picture
    (31, 119, 180),  # sofa
    (188, 189, 34),  # table
    (23, 190, 207),  # tv
    (199, 199, 199),  # wall
    (255, 240, 110),  # window (light yellow: the light blue it was read as ceiling)
)


@array_eq
@dataclass(frozen=True)
class IndoorFrame:
    """One synthetic frame, with the attribute names of :class:`rgbd_rs.data.nyuv2.NyuFrame`:
    ``rgb`` (H x W x 3 uint8), ``depth`` (H x W float32 metres, whole millimetres, NaN = hole),
    ``label13`` (H x W uint8), the ``camera`` that took it and its ``index``."""

    index: int
    rgb: U8
    depth: F32
    label13: U8
    camera: PinholeCamera

    @property
    def name(self) -> str:
        """``NNNNNN``, as in the file names."""
        return f"{self.index:06d}"


def _frame_rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([VERSION, seed, index]))


def _render(seed: int, index: int, width: int, height: int) -> tuple[IndoorFrame, IndoorScene, F32]:
    """The frame, its scene and the noise-free depth (for tests)."""
    rng = _frame_rng(seed, index)
    scene = _random_indoor_scene(rng, width, height)
    built = scene.scene.build()
    gb = built.gbuffer(scene.camera, scene.pose)
    obj = gb.object
    lut = np.array([p.label for p in scene.parts] + [0], np.uint8)  # -1 (miss) -> 0
    label13 = lut[obj]
    linear = built.color(scene.camera, scene.pose, supersample=1)
    rgb = _kinect_color(rng, linear, obj, scene)
    depth = _kinect_depth(rng, gb, built, scene)
    mm = np.round(depth * DEPTH_PNG_PER_METRE)
    mm = np.where(np.isfinite(mm) & (mm > 0) & (mm < 65536), mm, np.nan)
    depth = (mm / DEPTH_PNG_PER_METRE).astype(np.float32)
    frame = IndoorFrame(index, rgb, depth, label13, scene.camera)
    return frame, scene, gb.depth


def _seed(seed: object) -> int:
    return _validate.integer("seed", seed, maximum=2**63 - 1)


def _size(width: object, height: object) -> tuple[int, int]:
    w = _validate.integer("width", width, minimum=MIN_SIDE, maximum=MAX_SIDE)
    h = _validate.integer("height", height, minimum=MIN_SIDE, maximum=MAX_SIDE)
    return w, h


def render_indoor_frame(
    seed: int, index: int, *, width: int = 640, height: int = 480
) -> IndoorFrame:
    """Frame ``index`` of the synthetic indoor set of ``seed`` (the same whatever the shard):
    colour, Kinect-like depth (NaN holes), 13-class labels and the frame's camera (intrinsics
    drawn around the NYU camera, scaled to ``width`` x ``height``)."""
    s = _seed(seed)
    i = _validate.integer("index", index, maximum=MAX_FRAMES - 1)
    w, h = _size(width, height)
    return _render(s, i, w, h)[0]


def _names(folder: Path, index: int) -> dict[str, Path]:
    stem = f"{index:06d}"
    return {
        "rgb": folder / f"{stem}_rgb.png",
        "depth": folder / f"{stem}_depth.png",
        "label13": folder / f"{stem}_label13.png",
        "camera": folder / f"camera_{stem}.json",
    }


def _complete(folder: Path, index: int) -> bool:
    return all(p.is_file() for p in _names(folder, index).values())


def _write_frame(folder: Path, frame: IndoorFrame) -> None:
    """Write one frame's files (atomically each; the camera, written last, marks it complete)."""
    names = _names(folder, frame.index)
    write_png(names["rgb"], frame.rgb)
    mm = np.nan_to_num(frame.depth * DEPTH_PNG_PER_METRE, nan=0.0)
    write_png(names["depth"], np.clip(np.round(mm), 0, 65535).astype(np.uint16))
    write_png(names["label13"], frame.label13)
    save_camera(names["camera"], frame.camera)


def _shard(shard: object) -> tuple[int, int]:
    return _validate.shard("shard", shard)


def _check_manifest(out: Path, seed: int, width: int, height: int) -> None:
    """Create the folder's manifest once (whichever shard comes first: a hard link cannot
    overwrite), then refuse a folder whose manifest differs from this run's."""
    want = {
        "generator": __name__,
        "version": VERSION,
        "seed": seed,
        "width": width,
        "height": height,
    }
    path = out / MANIFEST
    _create_once(path, _bytes_writer((json.dumps(want, indent=1, sort_keys=True) + "\n").encode()))
    have = read_json(path)
    if have != want:
        raise InvalidArgumentError(
            f"out: got a folder holding frames made with other settings "
            f"({_validate.differences(have, want)}); use another folder"
        )


def generate_indoor(
    out: str | Path,
    count: int,
    *,
    seed: int = 0,
    shard: tuple[int, int] = (0, 1),
    width: int = 640,
    height: int = 480,
    quiet: bool = False,
) -> list[int]:
    """Write frames ``0 .. count-1`` of ``seed`` into ``out`` (shard ``(i, n)`` writes frames
    i, i+n, ...); frames already complete are skipped (resume). Returns this shard's indices.

    A folder made with another seed, size or generator version is refused rather than mixed.
    """
    quiet = _validate.flag("quiet", quiet)
    out = _validate.out_folder("out", out)
    if not isinstance(out, (str, Path)) or not str(out):
        raise InvalidArgumentError(f"out: got {out!r}, expected a folder path")
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise InvalidArgumentError(f"out: got {folder}, which is a file, expected a folder")
    n_frames = _validate.integer("count", count, maximum=MAX_FRAMES)
    s = _seed(seed)
    i, n = _shard(shard)
    w, h = _size(width, height)
    if not isinstance(quiet, bool):
        raise InvalidArgumentError(f"quiet: got {quiet!r}, expected True or False")
    from tqdm import tqdm

    folder.mkdir(parents=True, exist_ok=True)
    _check_manifest(folder, s, w, h)
    if n_frames > (_requested(folder) or 0):
        write_json(folder / REQUESTED, {"count": n_frames})
    mine = list(range(i, n_frames, n))
    todo = [k for k in mine if not _complete(folder, k)]
    for k in tqdm(todo, desc="synth-indoor", unit="frame", **bar_options(quiet)):
        _write_frame(folder, _render(s, k, w, h)[0])
    return mine


def _requested(folder: Path) -> int | None:
    """The most frames a run asked ``folder`` for (None: a folder written before it was kept)."""
    path = folder / REQUESTED
    if not path.is_file():
        return None
    got = read_json(path)
    count = got.get("count") if isinstance(got, dict) else None
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise RgbdError(f'{path}: got {got!r}, expected {{"count": N}} with N >= 0')
    return count


class IndoorFrames:
    """The complete frames of a folder written by :func:`generate_indoor`, in index order:
    ``len(frames)``, ``frames[k]`` (an :class:`IndoorFrame`) and ``frames.indices``.
    ``requested`` is the most frames a run asked for (None for a folder written before this
    was recorded) and ``missing`` the frames below it that are not complete: a run
    interrupted, still running, or a shard not run."""

    def __init__(self, folder: str | Path) -> None:
        if not isinstance(folder, (str, Path)) or not str(folder):
            raise InvalidArgumentError(f"folder: got {folder!r}, expected a folder path")
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise RgbdError(f"{self.folder}: not a folder (expected synthetic indoor frames)")
        found = sorted(
            int(p.name[7:13]) for p in self.folder.glob("camera_[0-9]*.json") if len(p.name) == 18
        )
        self.indices = [k for k in found if _complete(self.folder, k)]
        self.requested = _requested(self.folder)
        have = set(self.indices)
        self.missing = [k for k in range(self.requested or 0) if k not in have]

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, k: int) -> IndoorFrame:
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise InvalidArgumentError(f"k: got {k!r}, expected a frame position (int)")
        if not -len(self) <= k < len(self):
            raise IndexError(f"k: got {k}, expected -{len(self)} <= k < {len(self)}")
        index = self.indices[int(k)]
        names = _names(self.folder, index)
        rgb = read_png(names["rgb"])
        raw = read_png(names["depth"])
        label = read_png(names["label13"])
        if (
            rgb.ndim != 3
            or rgb.dtype != np.uint8
            or raw.dtype != np.uint16
            or label.dtype != np.uint8
        ):
            raise RgbdError(f"{names['rgb'].parent}/{index:06d}_*.png: unexpected image types")
        if not rgb.shape[:2] == raw.shape == label.shape:
            raise RgbdError(f"{self.folder}/{index:06d}_*.png: image sizes differ")
        camera = load_camera(names["camera"])
        depth = np.where(raw > 0, raw.astype(np.float32) / np.float32(DEPTH_PNG_PER_METRE), np.nan)
        return IndoorFrame(index, rgb, depth.astype(np.float32), label, camera)


def label_colors(label13: npt.ArrayLike) -> U8:
    """A BGR picture of a 13-class label image (:data:`LABEL13_COLORS`)."""
    lab = _validate.asarray("label13", label13)
    if lab.dtype != np.uint8 or lab.ndim != 2 or lab.size == 0:
        raise InvalidArgumentError(
            f"label13: got {lab.dtype} array of shape {lab.shape}, expected a 2-D uint8 label image"
        )
    lut = np.zeros((256, 3), np.uint8)
    lut[: len(LABEL13_COLORS)] = np.array(LABEL13_COLORS, np.uint8)[:, ::-1]
    return np.ascontiguousarray(lut[lab])


def write_indoor_preview(path: str | Path, frames: Sequence[IndoorFrame], width: int = 320) -> Path:
    """A PNG grid, one row per frame: colour | depth (a colour bar in metres, holes in the "no
    data" grey) | labels (with the 13 classes' legend)."""
    if (
        not isinstance(frames, Sequence)
        or not frames
        or not all(isinstance(f, IndoorFrame) for f in frames)
    ):
        raise InvalidArgumentError(f"frames: got {frames!r:.60}, expected a list of IndoorFrame")
    panels = []
    for f in frames:
        panels += [
            image_panel(np.ascontiguousarray(f.rgb[:, :, ::-1]), f"{f.name} colour", width=width),
            map_panel(f.depth, "depth", unit="m", vmin=0.5, vmax=6.0, width=width),
            class_picture(
                f.label13.astype(np.int64), LABEL13_NAMES, LABEL13_COLORS, "label13", width=width
            ),
        ]
    return save_png(path, grid(panels, columns=3))


def class_frequencies(labels: Iterable[npt.ArrayLike]) -> npt.NDArray[np.float64]:
    """Fraction of pixels of each class 0..13 over label images (sums to 1)."""
    if isinstance(labels, (str, bytes)) or not isinstance(labels, Iterable):
        raise InvalidArgumentError(
            f"labels: got {type(labels).__name__}, expected an iterable of label images"
        )
    counts = np.zeros(len(LABEL13_NAMES), np.float64)
    for k, lab in enumerate(labels):
        arr = _validate.asarray(f"labels[{k}]", lab)
        if arr.dtype != np.uint8:
            raise InvalidArgumentError(f"labels[{k}]: got dtype {arr.dtype}, expected uint8")
        counts += np.bincount(arr.ravel(), minlength=256)[: len(LABEL13_NAMES)]
    if counts.sum() == 0:
        raise InvalidArgumentError("labels: got no labeled pixel, expected label images")
    return np.asarray(counts / counts.sum(), np.float64)
