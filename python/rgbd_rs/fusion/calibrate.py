"""Calibrating the confidence ConvNet's stereo weights for the LC fusion, on validation scenes.

The network is trained to predict ``1 - min(|err|, 3)/3`` per source (thesis §3.7), but LC weighs
whole windows of hypotheses: a stereo map that is wrong by 2-4 px over a patch, with the
network's ``P_S`` ~0.75 there, outvotes a correct ToF (measured on the synthetic test set and
Middlebury Cones: README "Design choices"). :func:`calibrate_stereo_power` fuses validation
scenes (never the test set) with ``P_S ** p`` for a few powers ``p`` and picks the one with the
lowest mean ratio of the fused RMS to the better input's, among those that never make a *good*
input (:data:`GOOD_SHARE` of its pixels within 1 px) more than :data:`MAX_DAMAGE` times worse; if
none qualifies, the one with the least damage. :func:`write_calibrated` stores the choice in a
copy of the checkpoint, where :class:`~rgbd_rs.nn.confidence.ConfidenceEstimator` reads it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.fusion._inputs import views
from rgbd_rs.fusion.evaluate import Sample, non_occluded
from rgbd_rs.fusion.fuse import fuse
from rgbd_rs.fusion.lc import LcParams, lc_fuse
from rgbd_rs.fusion.sources import _fill_single_source
from rgbd_rs.metrics import bad_pixel_rate, rms_error

if TYPE_CHECKING:
    from rgbd_rs.nn.confidence import ConfidenceEstimator

#: Powers tried by default.
POWERS = (1.0, 1.5, 2.0, 3.0, 4.0)
#: An input is "good" on a scene when at least this share of its pixels is within 1 px (issue 12).
GOOD_SHARE = 0.95
#: ... and this is "within" (px).
GOOD_WITHIN = 1.0
#: The fused RMS may exceed a good input's by at most this factor (issue 12: 5 %).
MAX_DAMAGE = 1.05


def is_good(d: npt.NDArray[np.float32], gt: npt.NDArray[np.float32], mask: npt.ArrayLike) -> bool:
    """Whether the map ``d`` is a good input on ``mask``: at least :data:`GOOD_SHARE` of its
    pixels there within :data:`GOOD_WITHIN` px of ``gt``."""
    return 1.0 - bad_pixel_rate(d, gt, GOOD_WITHIN, mask) >= GOOD_SHARE


@dataclass(frozen=True)
class PowerScore:
    """One power over the validation scenes: ``mean_rms`` of the fused map, ``mean_ratio`` (fused
    RMS / the better input's, averaged over scenes) and ``worst_damage`` (the largest fused RMS /
    a good input's RMS; 0 when no scene has a good input)."""

    power: float
    mean_rms: float
    mean_ratio: float
    worst_damage: float


@dataclass(frozen=True)
class Calibration:
    """The chosen power and every power's score."""

    power: float
    scores: tuple[PowerScore, ...]
    scenes: int

    @property
    def within_limit(self) -> bool:
        """Whether the chosen power keeps every good validation input within
        :data:`MAX_DAMAGE` (False: none did, and the least damaging one was chosen)."""
        return any(s.power == self.power and s.worst_damage <= MAX_DAMAGE for s in self.scores)

    def markdown(self) -> str:
        """The scores as a markdown table (the chosen power in bold)."""
        rows = [
            f"| {'**' if s.power == self.power else ''}{s.power:g}"
            f"{'**' if s.power == self.power else ''} | {s.mean_rms:.3f} | {s.mean_ratio:.3f} | "
            f"{s.worst_damage:.3f} |"
            for s in self.scores
        ]
        head = (
            f"Stereo confidence power on {self.scenes} validation scenes (fused RMS / better "
            f"input; worst fused / good input, limit {MAX_DAMAGE:g})\n\n"
            "| power | mean RMS (px) | mean ratio | worst damage |\n|---:|---:|---:|---:|"
        )
        return "\n".join([head, *rows]) + "\n"


def choose(scores: Sequence[PowerScore]) -> float:
    """The lowest mean ratio among the powers within :data:`MAX_DAMAGE`, else the least damage."""
    return best_score(scores).power


def best_score(scores: Sequence[PowerScore]) -> PowerScore:
    """The score :func:`choose` picks (also across networks: tools/choose_confidence_real.py)."""
    if not scores:
        raise InvalidArgumentError("scores: got none, expected at least one power's score")
    safe = [s for s in scores if s.worst_damage <= MAX_DAMAGE]
    if safe:
        return min(safe, key=lambda s: (s.mean_ratio, s.power))
    return min(scores, key=lambda s: (s.worst_damage, s.power))


@array_eq
@dataclass(frozen=True)
class SceneInputs:
    """One scene's two inputs measured against its ground truth on ``mask``: what a fused map
    is compared with (the better input, and the inputs that are good: :data:`GOOD_SHARE` of
    their pixels within 1 px)."""

    gt: npt.NDArray[np.float32]
    mask: npt.NDArray[np.bool_]
    rms: tuple[float, ...]
    good: tuple[float, ...]

    @classmethod
    def of(
        cls,
        inputs: Sequence[npt.NDArray[np.float32]],
        gt: npt.NDArray[np.float32],
        mask: npt.NDArray[np.bool_],
    ) -> SceneInputs:
        """The inputs' RMS on ``mask`` (bool ``H x W``), and which of them are good."""
        rms = tuple(rms_error(d, gt, mask) for d in inputs)
        good = tuple(e for d, e in zip(inputs, rms, strict=True) if is_good(d, gt, mask))
        return cls(gt, mask, rms, good)

    def score(self, fused: npt.NDArray[np.float32]) -> tuple[float, float, float]:
        """``(fused RMS, fused / better input, fused / best good input or 0 without one)``."""
        e = rms_error(fused, self.gt, self.mask & np.isfinite(fused))
        damage = e / max(min(self.good), 1e-9) if self.good else 0.0
        return e, e / max(min(self.rms), 1e-9), damage


def calibrate_stereo_power(
    estimator: ConfidenceEstimator,
    samples: Iterable[Sample],
    *,
    powers: Sequence[float] = POWERS,
    params: LcParams | None = None,
    quiet: bool = False,
) -> Calibration:
    """Score every power on ``samples`` (validation scenes with ground truth) and choose one."""
    ps = [_validate.real(f"powers[{i}]", p, positive=True) for i, p in enumerate(powers)]
    if not ps:
        raise InvalidArgumentError("powers: got none, expected at least one positive power")
    raw = estimator.with_stereo_power(1.0)
    rms: dict[float, list[float]] = {p: [] for p in ps}
    ratio: dict[float, list[float]] = {p: [] for p in ps}
    damage: dict[float, list[float]] = {p: [] for p in ps}
    scenes = 0
    for s in tqdm(list(samples), desc="calibrate", disable=quiet, unit="scene"):
        # fuse() with the raw network gives the stages, both confidences and the power-1 result.
        out = fuse(
            s.left, s.right, s.tof_depth, s.tof_amplitude, s.rig, confidence=raw, params=params
        )
        ref, tgt, sign = views(s.left, s.right, s.rig.reference)
        tof_d, st_d = out.tof_fused, out.stereo_disparity
        p_t, p_s = out.tof_confidence, out.stereo_confidence
        if p_t is None or p_s is None:  # an estimator always gives both maps
            raise RgbdError(f"{s.name}: the estimator returned no confidence maps")
        gt = s.gt_disparity
        mask = np.isfinite(gt) & non_occluded(gt, sign) & np.isfinite(tof_d) & np.isfinite(st_d)
        if not mask.any():
            continue
        scenes += 1
        scene = SceneInputs.of((tof_d, st_d), gt, mask)
        for p in ps:
            if p == 1.0:
                fused = out.disparity
            else:
                # Scored as fuse() would return it: LC, then the pixels it left empty filled.
                conf_s = (p_s**p).astype(np.float32)
                lc_d, lc_p = lc_fuse(
                    ref, tgt, [tof_d, st_d], [p_t, conf_s], target_sign=sign, params=params
                )
                fused = _fill_single_source(
                    lc_d,
                    lc_p,
                    tof_d,
                    st_d,
                    p_t,
                    conf_s,
                    cross_check=params is not None and params.cross_check,
                )[0]
            e, r, dmg = scene.score(fused)
            rms[p].append(e)
            ratio[p].append(r)
            damage[p].append(dmg)
    if scenes == 0:
        raise RgbdError("samples: no scene had pixels valid in both inputs and the ground truth")
    scores = tuple(
        PowerScore(p, float(np.mean(rms[p])), float(np.mean(ratio[p])), float(max(damage[p])))
        for p in ps
    )
    return Calibration(choose(scores), scores, scenes)


def write_calibrated(checkpoint: str | Path, power: float, out: str | Path) -> Path:
    """Copy ``checkpoint`` to ``out`` with ``power`` stored as its stereo calibration."""
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.nn.confidence import ARCH, STEREO_POWER_KEY

    p = _validate.real("power", power, positive=True)
    ckpt = load_checkpoint(checkpoint, arch=ARCH, normalisation_keys=("sigmas",))
    norm = dict(ckpt.normalisation) | {STEREO_POWER_KEY: p}
    return save_checkpoint(replace(ckpt, normalisation=norm), out)
