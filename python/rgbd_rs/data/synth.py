"""A SYNTH3-style synthetic ToF + stereo dataset (thesis §3.5, Table 3.1): generator and reader.

Rig (thesis Table 3.1): a ZED-like rectified stereo pair (1920x1080, 3.2 mm focal length,
2.2 um pixels, 12 cm baseline) and a Kinect-v2-like ToF camera (512x424, 3.66 mm, 10 um pixels)
4 cm below the right (reference) camera with parallel axes. ``scale`` resizes the stereo pair
(0.5 = the thesis' 960x540); the ToF camera keeps its 512x424.

Layout written by :func:`write_dataset` (``rgbd synth``)::

    DIR/manifest.json          parameters, per-scene file hashes, "complete" when done
    DIR/calibration.json       the rig (rgbd_rs.data.calibration)
    DIR/{train,test}/scene_NNNN/left.png, right.png   8-bit RGB
    DIR/{train,test}/scene_NNNN/data.npz              float32 maps (NaN = invalid):
        tof_depth, tof_amplitude   the simulated ToF frame on its own lattice
        tof_gt_depth               ground-truth depth of the ToF view
        gt_depth, gt_disparity     ground truth on the reference (right) camera

Each scene is written into a temporary folder and renamed when complete, and the manifest is
rewritten after every scene, so an interrupted run loses nothing and re-running the same command
resumes. Scene ``i`` of a split depends only on ``(seed, split, i)``: outputs are bit-identical.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs._progress import bar_options
from rgbd_rs.camera import PinholeCamera, Pose, StereoRig, ToFStereoRig
from rgbd_rs.data.calibration import load_rig, save_rig
from rgbd_rs.data.synth_scene import _random_scene, _shared_meshes
from rgbd_rs.data.tof_variation import apply, random_variation
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.geometry import depth_to_disparity
from rgbd_rs.io import (
    read_json,
    read_npz,
    read_png,
    sha256,
    write_json,
    write_npz,
    write_png,
)
from rgbd_rs.meshes import Mesh
from rgbd_rs.render import RenderScene, ToFFrame, ToFModel

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]
Split = Literal["train", "test"]

FORMAT = "rgbd_rs-synth/1"
#: Full resolution of the stereo pair (Table 3.1) and the documented bounds on ``scale``: at most
#: 4 (7680x4320, four times the thesis' full HD; a rendered scene then needs ~2 GB) and at least
#: ``MIN_SIDE`` pixels high, so absurd values are refused before anything is allocated.
FULL_WIDTH, FULL_HEIGHT = 1920, 1080
MAX_SCALE = 4.0
MIN_SIDE = 16
#: Most scenes per split (a bound on the manifest, not a practical size).
MAX_SCENES = 100_000
#: Table 3.1: stereo focal 3.2 mm / 2.2 um pixels; ToF 3.66 mm / 10 um; baseline; ToF offset.
STEREO_FOCAL_PX = 3.2e-3 / 2.2e-6
TOF_FOCAL_PX = 3.66e-3 / 10e-6
BASELINE_M = 0.12
TOF_BELOW_M = 0.04
#: Colour rendering: sub-pixel rays per axis, sensor noise (8-bit levels), left-camera exposure
#: spread (real pairs differ), display gamma. Chosen, not from the thesis.
SUPERSAMPLE = 2
COLOR_NOISE = 1.5
EXPOSURE_SPREAD = 0.15
GAMMA = 2.2
_MAP_KEYS = ("tof_depth", "tof_amplitude", "tof_gt_depth", "gt_depth", "gt_disparity")


def synth3_rig(scale: float = 0.5) -> ToFStereoRig:
    """The SYNTH3 rig; ``scale`` sizes the stereo pair (0.5 -> 960x540), at most ``MAX_SCALE``."""
    s = _validate.real("scale", scale, positive=True)
    w, h = (0, 0) if s > MAX_SCALE else (round(FULL_WIDTH * s), round(FULL_HEIGHT * s))
    if s > MAX_SCALE or min(w, h) < MIN_SIDE:
        raise InvalidArgumentError(
            f"scale: got {s}, expected {MIN_SIDE / FULL_HEIGHT:.4f} <= scale <= {MAX_SCALE} "
            f"(the stereo pair is {FULL_WIDTH}x{FULL_HEIGHT} times scale, at least {MIN_SIDE} px "
            "high)"
        )
    f = STEREO_FOCAL_PX * w / 1920
    cam = PinholeCamera(f, f, (w - 1) / 2, (h - 1) / 2, w, h)
    tof = PinholeCamera(TOF_FOCAL_PX, TOF_FOCAL_PX, 255.5, 211.5, 512, 424)
    return ToFStereoRig(
        tof=tof,
        stereo=StereoRig(cam, cam, BASELINE_M),
        tof_to_reference=Pose(np.eye(3), np.array([0.0, TOF_BELOW_M, 0.0])),
        reference="right",
    )


@array_eq
@dataclass(frozen=True)
class SynthSample:
    """One scene: the stereo pair (uint8 RGB), the ToF frame and ground truth (see module doc)."""

    left: U8
    right: U8
    tof_depth: F32
    tof_amplitude: F32
    tof_gt_depth: F32
    gt_depth: F32
    gt_disparity: F32


def _rig_poses(rig: ToFStereoRig) -> tuple[Pose, Pose, Pose]:
    """World-to-camera poses of the left, right and ToF cameras; the world frame is the
    reference (right) camera's."""
    if not isinstance(rig, ToFStereoRig):
        raise InvalidArgumentError(
            f"rig: got {type(rig).__name__}, expected a rgbd_rs.ToFStereoRig"
        )
    b = rig.stereo.baseline
    to_left = Pose(np.eye(3), np.array([b, 0.0, 0.0]))
    return to_left, Pose.identity(), rig.tof_to_reference.inverse()


def _expose(radiance: F32, gain: float, rng: np.random.Generator) -> U8:
    v = np.clip(radiance * gain, 0, 1) ** (1 / GAMMA) * 255
    v = v + rng.normal(0, COLOR_NOISE, v.shape)
    return np.asarray(np.clip(np.round(v), 0, 255), dtype=np.uint8)


def render_sample(
    scene: RenderScene,
    rig: ToFStereoRig,
    rng: np.random.Generator,
    model: ToFModel | None = None,
    tof_seed: int = 0,
) -> tuple[SynthSample, ToFFrame]:
    """Render the stereo pair, ToF frame and ground truth of a built scene (``rng`` draws the
    exposure and colour noise, ``tof_seed`` the ToF noise and multipath rays)."""
    to_left, to_right, to_tof = _rig_poses(rig)
    right = scene.color(rig.stereo.right, to_right, supersample=SUPERSAMPLE)
    left = scene.color(rig.stereo.left, to_left, supersample=SUPERSAMPLE)
    # Auto-exposure on the reference image (median -> 40 % grey), the left one off by a bit.
    lum = right.mean(axis=2)
    gain = 0.4**GAMMA / max(float(np.median(lum[lum > 0])) if (lum > 0).any() else 1.0, 1e-6)
    left_gain = gain * float(1 + rng.uniform(-EXPOSURE_SPREAD, EXPOSURE_SPREAD))
    tof = scene.tof(rig.tof, to_tof, model or ToFModel(), seed=tof_seed)
    gt = scene.depth(rig.reference_camera, to_right)
    sample = SynthSample(
        left=_expose(left, left_gain, rng),
        right=_expose(right, gain, rng),
        tof_depth=tof.depth,
        tof_amplitude=tof.amplitude,
        tof_gt_depth=tof.truth,
        gt_depth=gt,
        gt_disparity=depth_to_disparity(gt, rig.stereo.baseline, rig.stereo.focal),
    )
    return sample, tof


def _scene_rng(seed: int, split: Split, index: int, stream: int = 0) -> np.random.Generator:
    """Generator ``stream`` of scene ``index`` of ``split`` (independent of every other scene):
    stream 0 draws the scene and colour noise, stream 1 the ToF seed, stream 2 the varied ToF
    sensor of a ``vary_tof`` dataset."""
    s = _validate.integer("seed", seed, maximum=_validate.MAX_SEED)
    sp = _validate.choice("split", split, ("train", "test"))
    i = _validate.integer("index", index)
    k = _validate.integer("stream", stream)
    return np.random.default_rng([s, 0 if sp == "train" else 1, i, k])


def tof_seed(seed: int, split: Split, index: int) -> int:
    """The ToF simulator's seed for scene ``index`` of ``split``."""
    return int(_scene_rng(seed, split, index, 1).integers(2**62))


def generate(
    seed: int,
    split: Split,
    index: int,
    rig: ToFStereoRig,
    meshes: list[Mesh] | None = None,
    *,
    vary_tof: bool = False,
) -> tuple[SynthSample, RenderScene]:
    """Build and render scene ``index`` of ``split``; ``vary_tof`` draws the scene's own ToF
    sensor (:mod:`rgbd_rs.data.tof_variation`, from a stream of its own)."""
    rng = _scene_rng(seed, split, index)
    scene = _random_scene(rng, _shared_meshes() if meshes is None else meshes).build()
    if not vary_tof:
        return render_sample(scene, rig, rng, tof_seed=tof_seed(seed, split, index))[0], scene
    vrng = _scene_rng(seed, split, index, 2)
    variation = random_variation(vrng)
    sample, _ = render_sample(
        scene, rig, rng, model=variation.model, tof_seed=tof_seed(seed, split, index)
    )
    depth, amplitude = apply(sample.tof_depth, sample.tof_amplitude, variation, vrng)
    return replace(sample, tof_depth=depth, tof_amplitude=amplitude), scene


def _write_scene(folder: Path, s: SynthSample) -> dict[str, str]:
    tmp = folder.with_name(folder.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    write_png(tmp / "left.png", s.left)
    write_png(tmp / "right.png", s.right)
    write_npz(tmp / "data.npz", {k: getattr(s, k) for k in _MAP_KEYS})
    hashes = {p.name: sha256(p) for p in sorted(tmp.iterdir())}
    shutil.rmtree(folder, ignore_errors=True)
    tmp.rename(folder)
    return hashes


def write_dataset(
    out: str | Path,
    *,
    train: int = 40,
    test: int = 15,
    seed: int = 0,
    scale: float = 0.5,
    vary_tof: bool = False,
    quiet: bool = False,
) -> Path:
    """Generate (or resume) a dataset in ``out``; returns the manifest path.

    ``vary_tof`` gives every scene its own randomised ToF sensor (frequency, power, noise,
    multipath, mixed pixels, amplitude unit, flying pixels; :mod:`rgbd_rs.data.tof_variation`),
    the training data of the confidence ConvNet.

    Re-running with the same arguments skips scenes already written (verified by hash) and
    completes the rest; other arguments on an existing dataset raise RgbdError.
    """
    from tqdm import tqdm

    vary_tof = _validate.flag("vary_tof", vary_tof)
    quiet = _validate.flag("quiet", quiet)
    out = _validate.out_folder("out", out)

    if not isinstance(out, (str, Path)) or not str(out):
        raise InvalidArgumentError(f"out: got {out!r}, expected a folder path")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InvalidArgumentError(f"out: got {out}, a file; expected a dataset folder")
    n_train = _validate.integer("train", train, maximum=MAX_SCENES)
    n_test = _validate.integer("test", test, maximum=MAX_SCENES)
    seed = _validate.integer("seed", seed, maximum=2**32 - 1)
    rig = synth3_rig(scale)
    meshes = _shared_meshes()
    params = {
        "seed": seed,
        "scale": float(scale),
        "train": n_train,
        "test": n_test,
        "meshes": len(meshes),
    }
    if vary_tof:  # only then: datasets made before the option keep their parameters
        params["vary_tof"] = True
    manifest_path = out / "manifest.json"
    manifest: dict[str, Any] = {"format": FORMAT, "params": params, "complete": False, "scenes": {}}
    if manifest_path.exists():
        old = read_manifest(manifest_path)
        if old["params"] != params:
            raise RgbdError(
                f"{out}: holds a dataset made with other settings "
                f"({_validate.differences(old.get('params'), params)}); use another --out or "
                "delete it"
            )
        manifest["scenes"] = old["scenes"]
    out.mkdir(parents=True, exist_ok=True)
    save_rig(out / "calibration.json", rig)
    todo = [("train", i) for i in range(n_train)] + [("test", i) for i in range(n_test)]
    bar = tqdm(todo, desc="rgbd synth", unit="scene", **bar_options(quiet))
    for split, i in bar:
        key = f"{split}/scene_{i:04d}"
        folder = out / key
        known = manifest["scenes"].get(key)
        if known and all(
            (folder / f).is_file() and sha256(folder / f) == h for f, h in known.items()
        ):
            continue
        sample, _ = generate(seed, split, i, rig, meshes, vary_tof=bool(vary_tof))
        manifest["scenes"][key] = _write_scene(folder, sample)
        write_json(manifest_path, manifest)
    manifest["complete"] = True
    return write_json(manifest_path, manifest)


def read_manifest(path: Path) -> dict[str, Any]:
    """The manifest at ``path``, checked for the structure :func:`write_dataset` writes; anything
    else (a list, missing or mistyped entries) raises RgbdError naming the file."""
    m = read_json(path)
    problem = None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        problem = f"not an rgbd_rs synthetic dataset manifest (expected format {FORMAT!r})"
    elif not isinstance(m.get("params"), dict) or not all(
        isinstance(m["params"].get(k), int) and not isinstance(m["params"].get(k), bool)
        for k in ("train", "test")
    ):
        problem = "params must hold integer train and test counts"
    elif not isinstance(m.get("scenes"), dict) or not all(
        isinstance(k, str)
        and isinstance(files, dict)
        and all(isinstance(f, str) and isinstance(h, str) for f, h in files.items())
        for k, files in m["scenes"].items()
    ):
        problem = "scenes must map scene keys to {file name: SHA-256} objects"
    elif not isinstance(m.get("complete", False), bool):
        problem = "complete must be true or false"
    if problem is not None:
        raise RgbdError(f"{path}: {problem}")
    checked: dict[str, Any] = m
    return checked


class SynthDataset:
    """Reader of a dataset written by :func:`write_dataset`.

    Refuses an incomplete (interrupted) dataset unless ``allow_partial``; every file error names
    the file. The first access of each scene checks its files against the manifest's SHA-256
    hashes, so a replaced or swapped file raises instead of loading silently. ``dataset[i]`` is
    a :class:`SynthSample`; ``dataset.rig`` the calibration.
    """

    def __init__(self, root: str | Path, split: Split = "train", *, allow_partial: bool = False):
        if not isinstance(root, (str, Path)) or not str(root):
            raise InvalidArgumentError(f"root: got {root!r}, expected a dataset folder path")
        self.root = Path(root)
        allow_partial = _validate.flag("allow_partial", allow_partial)
        self.split = _validate.choice("split", split, ("train", "test"))
        manifest = read_manifest(self.root / "manifest.json")
        p = manifest["params"]
        expected = int(p[self.split])
        self.keys = sorted(k for k in manifest["scenes"] if k.startswith(self.split + "/"))
        if not manifest.get("complete") and not allow_partial:
            raise RgbdError(
                f"{self.root}: incomplete dataset ({len(manifest['scenes'])} of "
                f"{p['train'] + p['test']} scenes); re-run `rgbd synth` with the same arguments "
                "to finish it (from Python, allow_partial=True reads the scenes done)"
            )
        if manifest.get("complete") and len(self.keys) != expected:
            raise RgbdError(
                f"{self.root}: manifest lists {len(self.keys)} {split} scenes, expected {expected}"
            )
        self.rig = load_rig(self.root / "calibration.json")
        self._hashes: dict[str, dict[str, str]] = manifest["scenes"]
        self._verified: set[str] = set()

    def __len__(self) -> int:
        return len(self.keys)

    def _verify(self, key: str, folder: Path) -> None:
        """Compare the scene's files with the manifest's hashes (once per scene and reader)."""
        files = self._hashes[key]
        for name in ("left.png", "right.png", "data.npz"):
            if name not in files:
                raise RgbdError(
                    f"{self.root / 'manifest.json'}: lists no hash for {key}/{name}; "
                    "regenerate the dataset with `rgbd synth`"
                )
        for name, want in files.items():
            got = sha256(folder / name)
            if got != want:
                raise RgbdError(
                    f"{folder / name}: SHA-256 {got[:12]}... differs from the manifest's "
                    f"{want[:12]}... (the file was replaced or corrupted); regenerate it by "
                    "re-running `rgbd synth` with the same arguments"
                )
        self._verified.add(key)

    def __iter__(self) -> Iterator[SynthSample]:
        return (self[i] for i in range(len(self)))

    def __getitem__(self, i: int) -> SynthSample:
        key = self.keys[_validate.integer("i", i, maximum=len(self) - 1)]
        folder = self.root / key
        if key not in self._verified:
            self._verify(key, folder)
        maps = read_npz(folder / "data.npz", _MAP_KEYS)
        left, right = read_png(folder / "left.png"), read_png(folder / "right.png")
        stereo = (self.rig.stereo.right.height, self.rig.stereo.right.width)
        tof = (self.rig.tof.height, self.rig.tof.width)
        shapes = {
            "left.png": left.shape[:2],
            "right.png": right.shape[:2],
            "tof_depth": maps["tof_depth"].shape,
            "tof_amplitude": maps["tof_amplitude"].shape,
            "tof_gt_depth": maps["tof_gt_depth"].shape,
            "gt_depth": maps["gt_depth"].shape,
            "gt_disparity": maps["gt_disparity"].shape,
        }
        for name, shape in shapes.items():
            want = tof if name.startswith("tof") else stereo
            if tuple(shape) != want:
                raise RgbdError(f"{folder}: {name} is {tuple(shape)}, calibration says {want}")
        return SynthSample(left, right, **{k: maps[k].astype(np.float32) for k in _MAP_KEYS})
