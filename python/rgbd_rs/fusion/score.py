"""What a user of :func:`~rgbd_rs.fusion.fuse` gets on a case with ground truth, in the measures
that choose the fusion's knobs (issue: "chosen on real scenes"):

- the RMS disparity error of the ToF (as fused), the stereo map and the fused map on the pixels
  that are non-occluded, have ground truth and are valid in all three;
- whether each input is *good* there (:func:`~rgbd_rs.fusion.calibrate.is_good`: 95 % of its
  pixels within 1 px): the fusion must not damage a good input;
- the coverage of each map and of the inputs' union over all the ground truth (also the
  pixels the other camera does not see: the ToF measures them).

:func:`summarize` reduces cases to the numbers the choices are made by: the mean of fused /
better input, the worst fused / good input, and the worst coverage shortfall of the fused map
against the union of its inputs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import RgbdError
from rgbd_rs.fusion._inputs import F32, views
from rgbd_rs.fusion.calibrate import is_good
from rgbd_rs.fusion.evaluate import Sample, non_occluded, outside_target_view
from rgbd_rs.fusion.fuse import FusionResult
from rgbd_rs.metrics import rms_error

#: Map names of a case.
MAPS = ("tof", "stereo", "fused")


@dataclass(frozen=True)
class CaseScore:
    """One case: ``rms`` and ``good`` per map of :data:`MAPS` (``good`` for the inputs),
    ``coverage`` per map and ``"union"`` (shares of the ground-truth pixels), and the number of
    compared pixels."""

    name: str
    rms: dict[str, float]
    good: dict[str, bool]
    coverage: dict[str, float]
    pixels: int
    #: Per map of :data:`MAPS`: the share of the pixels the other camera cannot see (their
    #: ground truth's target lies outside its image; never in the RMS above) that the map has
    #: off by more than 2 px, over those it has a value for (NaN where it has none).
    unseen_bad2: dict[str, float] = dataclasses.field(default_factory=dict)
    #: The number of those pixels (with ground truth).
    unseen_pixels: int = 0
    #: Per map: how many of them it has a value for (the weights :func:`summarize` pools by).
    unseen_valued: dict[str, int] = dataclasses.field(default_factory=dict)

    @property
    def ratio(self) -> float:
        """Fused RMS / the better input's."""
        return self.rms["fused"] / max(min(self.rms["tof"], self.rms["stereo"]), 1e-9)

    @property
    def good_ratio(self) -> float | None:
        """The largest fused / input RMS over the good inputs (None: no good input)."""
        ratios = [self.rms["fused"] / max(self.rms[k], 1e-9) for k in ("tof", "stereo")]
        ratios = [r for r, k in zip(ratios, ("tof", "stereo"), strict=True) if self.good[k]]
        return max(ratios) if ratios else None


def score_maps(name: str, gt: F32, sign: int, tof: F32, stereo: F32, fused: F32) -> CaseScore:
    """The scores of three maps against ``gt`` (``sign``: the target view's direction).

    ``gt`` and the three maps are ``H x W`` disparities of one size (NaN = none / unknown).
    """
    gt = _validate.array("gt", gt, shape=(None, None))
    sign = _validate.sign("sign", sign)
    size = gt.shape
    tof, stereo, fused = (
        _validate.array(k, v, shape=size)
        for k, v in (("tof", tof), ("stereo", stereo), ("fused", fused))
    )
    visible = np.isfinite(gt) & non_occluded(gt, sign)
    if not visible.any():
        raise RgbdError(f"{name}: no non-occluded ground truth to score")
    maps = {"tof": tof, "stereo": stereo, "fused": fused}
    valid = {k: np.isfinite(v) & visible for k, v in maps.items()}
    common = valid["tof"] & valid["stereo"] & valid["fused"]
    if not common.any():
        raise RgbdError(f"{name}: no pixel is valid in the ToF, the stereo and the fused map")
    rms = {k: rms_error(v, gt, common) for k, v in maps.items()}
    good = {k: is_good(maps[k], gt, common) for k in ("tof", "stereo")}
    known = np.isfinite(gt)
    have = {k: np.isfinite(v) & known for k, v in maps.items()}
    n = float(known.sum())
    coverage = {k: float(v.sum()) / n for k, v in have.items()}
    coverage["union"] = float((have["tof"] | have["stereo"]).sum()) / n
    unseen = outside_target_view(gt, sign)
    valued = {k: unseen & np.isfinite(v) for k, v in maps.items()}
    bad2 = {k: _bad2(maps[k], gt, have) for k, have in valued.items()}
    counts = {k: int(have.sum()) for k, have in valued.items()}
    return CaseScore(name, rms, good, coverage, int(common.sum()), bad2, int(unseen.sum()), counts)


def _bad2(disparity: F32, gt: F32, have: npt.NDArray[np.bool_]) -> float:
    """The share of the ``have`` pixels (where the map has a value) off by more than 2 px."""
    if not have.any():
        return float("nan")
    return float(np.mean(np.abs(disparity[have] - gt[have]) > 2.0))


def score_result(s: Sample, out: FusionResult) -> CaseScore:
    """The scores of one :func:`fuse` result on its sample."""
    sign = views(s.left, s.right, out.reference)[2]
    return score_maps(
        s.name, s.gt_disparity, sign, out.tof_fused, out.stereo_disparity, out.disparity
    )


def summarize(scores: Sequence[CaseScore] | Iterable[CaseScore]) -> dict[str, float]:
    """``mean_ratio`` (fused / better input), ``worst_good`` (fused / good input; 0 if no case
    has one), ``coverage_gap`` (the largest union - fused coverage), ``mean_fused`` (RMS px)."""
    sc = list(scores)
    if not sc:
        raise RgbdError("scores: got none, expected at least one case")
    goods = [g for g in (c.good_ratio for c in sc) if g is not None]
    return {
        "mean_ratio": float(np.mean([c.ratio for c in sc])),
        "worst_good": float(max(goods)) if goods else 0.0,
        "coverage_gap": float(max(c.coverage["union"] - c.coverage["fused"] for c in sc)),
        "mean_fused": float(np.mean([c.rms["fused"] for c in sc])),
        "unseen_bad2": _pooled_unseen(sc, "fused"),
        "unseen_bad2_tof": _pooled_unseen(sc, "tof"),
    }


def _pooled_unseen(scores: list[CaseScore], key: str) -> float:
    """The share of all cases' unseen pixels that ``key`` has a value for which it has > 2 px
    off (NaN: none)."""
    pairs = [(c.unseen_bad2[key], c.unseen_valued[key]) for c in scores if key in c.unseen_bad2]
    pairs = [(b, n) for b, n in pairs if n > 0 and np.isfinite(b)]
    if not pairs:
        return float("nan")
    return float(sum(b * n for b, n in pairs) / sum(n for _, n in pairs))
