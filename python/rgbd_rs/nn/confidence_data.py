"""Training data of the confidence ConvNet: per-scene clue caches and patch datasets.

:func:`prepare` runs the fusion pipeline's own stages (``fuse``'s ToF reprojection + upsampling
and SGM, so the network sees exactly what it sees at inference) on every scene of a synthetic
dataset or on Middlebury with simulated ToF, and writes ``OUT/<name>.npz`` per scene: the raw
clues (float16), the target confidences ``1 - min(|err|, T)/T`` of the ToF and the stereo
disparity (float16, NaN where undefined) and the clues' per-scene standard deviations. Each file
is written atomically and skipped when present, so an interrupted run resumes, and ``shard=(i,
n)`` processes every n-th scene from i, so a cluster can fan the job out.

:class:`PatchDataset` cuts random ``patch x patch`` crops with random flips (deterministic by seed
and index) from the cached scenes; :class:`TileDataset` cuts a fixed grid of tiles (validation).
Both yield ``(inputs 4xPxP, target 2xPxP, mask 2xPxP)`` float32 tensors, inputs normalised by the
training sigma (eq. 3.3-3.6), targets 0 and mask 0 where undefined.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import torch
from torch.utils.data import Dataset

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.fusion._inputs import views
from rgbd_rs.fusion.clues import Clues, _normalise, _scene_sigmas, _target_confidence, compute_clues
from rgbd_rs.fusion.evaluate import ORACLE_T, Sample
from rgbd_rs.io import read_npz, write_npz

#: The clipping threshold T of the target confidence (px): the evaluation's oracle uses the same.
TARGET_T = ORACLE_T


def _scene_arrays(s: Sample, matcher: str = "opencv") -> dict[str, np.ndarray]:
    """Clues, targets and per-scene sigma of one sample (what :func:`prepare` caches), with the
    stereo disparities of ``matcher`` (``"census"`` or ``"opencv"``)."""
    from rgbd_rs.fusion import LcParams, fuse

    # The smallest LC window: only the stages before LC matter here, and fuse() runs them as
    # inference will.
    out = fuse(
        s.left,
        s.right,
        s.tof_depth,
        s.tof_amplitude,
        s.rig,
        confidence="uniform",
        params=LcParams(radius=1, stride=1),
        stereo=_validate.choice("matcher", matcher, ("census", "opencv")),  # type: ignore[arg-type]
    )
    ref_name = out.reference
    ref, tgt, _ = views(s.left, s.right, ref_name)
    tof_d = out.tof_fused  # the ToF disparities LC fuses (within the SGM search range)
    clues = compute_clues(
        ref, tgt, tof_d, out.tof.amplitude, out.stereo_disparity, reference=ref_name
    )
    target = np.stack(
        [
            _target_confidence(tof_d, s.gt_disparity, TARGET_T),
            _target_confidence(out.stereo_disparity, s.gt_disparity, TARGET_T),
        ]
    )
    return {
        "clues": clues.maps.astype(np.float16),
        "target": target.astype(np.float16),
        "sigmas": _scene_sigmas(clues),
    }


def _fingerprint(s: Sample, matcher: str) -> str:
    """What a scene's cached clues were computed from: its images, ToF, ground truth, rig and
    the matcher (a re-run into the same folder with other data or another matcher must not
    reuse them)."""
    h = hashlib.sha256(f"{matcher}|{s.rig!r}".encode())
    for a in (s.left, s.right, s.tof_depth, s.tof_amplitude, s.gt_disparity):
        arr = np.ascontiguousarray(a)
        h.update(f"{arr.shape}{arr.dtype}".encode())
        h.update(arr.tobytes())
    return h.hexdigest()[:32]


def prepare(
    samples: Iterator[Sample] | Sequence[Sample],
    out: str | Path,
    *,
    shard: tuple[int, int] = (0, 1),
    quiet: bool = False,
    matcher: str = "opencv",
) -> list[Path]:
    """Cache every sample's arrays as ``out/<sample.name>.npz``; returns the files of this shard.

    Existing files are kept (resume); ``shard = (i, n)`` takes samples i, i+n, i+2n, ...
    Each file records a fingerprint of its sample and ``matcher``: an existing file of the same
    name made from other data or with another matcher raises :class:`RgbdError` instead of
    being reused (files written before the fingerprint was kept are reused unchecked).
    """
    from tqdm import tqdm

    i, n = shard
    n = _validate.integer("shard count", n, minimum=1)
    i = _validate.integer("shard index", i, maximum=n - 1)
    folder = Path(out)
    written = []
    for k, s in enumerate(tqdm(samples, desc="clues", unit="scene", disable=quiet or None)):
        if k % n != i:
            continue
        path = folder / f"{s.name}.npz"
        fp = _fingerprint(s, matcher)
        if not path.is_file():
            stamp = np.frombuffer(bytes.fromhex(fp), np.uint8)
            write_npz(path, {**_scene_arrays(s, matcher), "fingerprint": stamp})
        else:
            had = read_npz(path).get("fingerprint")
            if had is not None and np.asarray(had, np.uint8).tobytes().hex() != fp:
                raise RgbdError(
                    f"{path}: cached from other data or another matcher than this run's "
                    f"(scene {s.name!r}, matcher {matcher!r}), expected the same; use another "
                    "output folder or delete that one"
                )
        written.append(path)
    return written


def load_scenes(paths: Sequence[Path]) -> list[dict[str, np.ndarray]]:
    """The cached arrays of ``paths`` (each checked for the keys and shapes it must hold)."""
    if not paths:
        raise InvalidArgumentError("paths: got no cached scene, expected at least one .npz")
    scenes = []
    for p in paths:
        a = read_npz(p)
        ok = {"clues", "target", "sigmas"} <= set(a)
        ok = ok and a["clues"].ndim == 3 and a["clues"].shape[0] == 4
        ok = ok and a["target"].shape == (2, *a["clues"].shape[1:])
        if not ok:
            raise RgbdError(f"{p}: not a confidence training cache (clues 4xHxW, target 2xHxW)")
        scenes.append(a)
    return scenes


def _sigmas_of(scenes: Sequence[dict[str, np.ndarray]]) -> npt.NDArray[np.float32]:
    """Eq. 3.3-3.6's sigma over the training scenes."""
    from rgbd_rs.fusion.clues import _training_sigmas

    return _training_sigmas(np.stack([s["sigmas"] for s in scenes]))


def retarget(target: npt.NDArray[np.float32], t: float) -> npt.NDArray[np.float32]:
    """Cached targets (clipped at :data:`TARGET_T`) re-expressed for a threshold ``t <=
    TARGET_T``: the error is ``TARGET_T (1 - target)`` below the clip, so no recomputation."""
    if t == TARGET_T:
        return target
    err = TARGET_T * (1 - target)
    return np.asarray(1 - np.minimum(err, t) / t, dtype=np.float32)


def _check_t(t: float) -> float:
    v = _validate.real("target_t", t, positive=True)
    if v > TARGET_T:
        raise InvalidArgumentError(
            f"target_t: got {v}, expected at most {TARGET_T} (the caches clip errors there)"
        )
    return v


def _item(
    scene: dict[str, np.ndarray],
    sig: npt.NDArray[np.float32],
    y: int,
    x: int,
    p: int,
    flip: int,
    target_t: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    clues = Clues(scene["clues"][:, y : y + p, x : x + p].astype(np.float32))
    inp = _normalise(clues, sig)
    tgt = retarget(scene["target"][:, y : y + p, x : x + p].astype(np.float32), target_t)
    mask = np.isfinite(tgt)
    tgt = np.where(mask, tgt, 0)
    arrays = [inp, tgt, mask.astype(np.float32)]
    if flip & 1:
        arrays = [a[:, :, ::-1] for a in arrays]
    if flip & 2:
        arrays = [a[:, ::-1, :] for a in arrays]
    t = [torch.from_numpy(np.ascontiguousarray(a)) for a in arrays]
    return t[0], t[1], t[2]


class PatchDataset(Dataset[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]):
    """``per_scene`` random ``patch``-pixel crops of each scene with random h/v flips.

    Crop ``k`` depends only on ``(seed, k)``: every epoch, process and resumed run sees the same
    crops (the trainer shuffles their order)."""

    def __init__(
        self,
        scenes: Sequence[dict[str, np.ndarray]],
        sigmas: npt.ArrayLike,
        *,
        patch: int = 64,
        per_scene: int = 30,
        seed: int = 0,
        target_t: float = TARGET_T,
    ) -> None:
        self.scenes = list(scenes)
        self.target_t = _check_t(target_t)
        self.sigmas = _validate.array("sigmas", sigmas, shape=(4,), finite=True)
        self.patch = _validate.integer("patch", patch, minimum=8)
        self.per_scene = _validate.integer("per_scene", per_scene, minimum=1)
        self.seed = _validate.integer("seed", seed, maximum=2**32 - 1)
        for s in self.scenes:
            if min(s["clues"].shape[1:]) < self.patch:
                raise InvalidArgumentError(
                    f"patch: got {self.patch}, expected at most the smallest scene side "
                    f"{min(s['clues'].shape[1:])}"
                )

    def __len__(self) -> int:
        return len(self.scenes) * self.per_scene

    def __getitem__(self, k: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        scene = self.scenes[k // self.per_scene]
        rng = np.random.default_rng([self.seed, k])
        h, w = scene["clues"].shape[1:]
        y = int(rng.integers(0, h - self.patch + 1))
        x = int(rng.integers(0, w - self.patch + 1))
        flip = int(rng.integers(0, 4))
        return _item(scene, self.sigmas, y, x, self.patch, flip, self.target_t)


class TileDataset(Dataset[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]):
    """Every whole ``tile``-pixel tile of each scene (a fixed validation set)."""

    def __init__(
        self,
        scenes: Sequence[dict[str, np.ndarray]],
        sigmas: npt.ArrayLike,
        *,
        tile: int = 128,
        target_t: float = TARGET_T,
    ) -> None:
        self.scenes = list(scenes)
        self.target_t = _check_t(target_t)
        self.sigmas = _validate.array("sigmas", sigmas, shape=(4,), finite=True)
        t = _validate.integer("tile", tile, minimum=8)
        self.tiles = [
            (k, y, x)
            for k, s in enumerate(self.scenes)
            for y in range(0, s["clues"].shape[1] - t + 1, t)
            for x in range(0, s["clues"].shape[2] - t + 1, t)
        ]
        self.tile = t

    def __len__(self) -> int:
        return len(self.tiles)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        k, y, x = self.tiles[i]
        return _item(self.scenes[k], self.sigmas, y, x, self.tile, 0, self.target_t)


def _masked_mse(output: torch.Tensor, batch: Sequence[torch.Tensor]) -> torch.Tensor:
    """§3.7's MSE between the estimated and target confidences, over defined pixels only."""
    _, target, mask = batch[0], batch[1], batch[2]
    diff = (output - target) * mask
    return diff.square().sum() / mask.sum().clamp(min=1.0)


class DisagreementMSE:
    """:func:`_masked_mse` with the pixels where the two sources disagree weighted ``1 + weight``.

    A pixel disagrees when both targets are defined and the sources' errors differ by more than
    ``DISAGREE_PX`` (``|t_T - t_S| > DISAGREE_PX / target_t``): there the two confidences decide
    which hypothesis LC keeps, elsewhere both sources say the same and their weights matter
    little. Our addition (``rgbd train confidence --disagreement-weight``); ``weight=0`` is §3.7.
    """

    def __init__(self, weight: float, target_t: float = TARGET_T) -> None:
        self.weight = _validate.real("weight", weight, nonnegative=True)
        self.threshold = DISAGREE_PX / _check_t(target_t)

    def __call__(self, output: torch.Tensor, batch: Sequence[torch.Tensor]) -> torch.Tensor:
        _, target, mask = batch[0], batch[1], batch[2]
        both = mask[:, 0] * mask[:, 1]
        apart = both * ((target[:, 0] - target[:, 1]).abs() > self.threshold).to(mask.dtype)
        w = mask * (1.0 + self.weight * apart.unsqueeze(1))
        return ((output - target).square() * w).sum() / w.sum().clamp(min=1.0)


#: Error difference (px) above which the two sources disagree (:class:`DisagreementMSE`).
DISAGREE_PX = 1.0
