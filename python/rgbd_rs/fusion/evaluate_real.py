"""``rgbd eval fusion --real SPLIT``: the default fusion on the real Middlebury split (ToF
simulated under fixed laws, :mod:`rgbd_rs.fusion.real_scenes`), scored as a user sees it
(:mod:`rgbd_rs.fusion.score`): per case the RMS of the ToF, the stereo map and the fused map on
their common non-occluded pixels, fused / better input, fused / good input, and the coverage of
each map; a Fig. 3.4 / 3.5-style figure of the first cases (colour, ground truth, ToF, SGM,
fused, fused error, P_T, P_S, each with a colour bar).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from rgbd_rs.fusion._inputs import FAR_CAMERA_WARNING, U8
from rgbd_rs.fusion.calibrate import MAX_DAMAGE
from rgbd_rs.fusion.evaluate import Sample
from rgbd_rs.fusion.fuse import FusionResult, fuse
from rgbd_rs.fusion.lc import LcParams
from rgbd_rs.fusion.score import CaseScore, score_result, summarize
from rgbd_rs.viz import as_bgr, colorize_with_bar, save_png, tile

if TYPE_CHECKING:
    from rgbd_rs.nn.confidence import ConfidenceEstimator

#: Error panel range (px).
ERROR_MAX = 3.0


def _shortfall(gap: float) -> str:
    """The coverage shortfall in words: a negative one means the fused map covers more."""
    if gap > 0:
        return f"{100 * gap:.2f} %"
    return f"none (the fused map covers {100 * -gap:.2f} % more at least)"


def markdown(scores: list[CaseScore], title: str) -> str:
    """Per-case rows and the summary against the issue's targets."""
    rows = [
        f"### {title}\n",
        "| case | ToF RMS | SGM RMS | fused RMS | fused / better | fused / good input | "
        "coverage ToF / SGM / union / fused % |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for c in scores:
        g = c.good_ratio
        cov = " / ".join(f"{100 * c.coverage[k]:.1f}" for k in ("tof", "stereo", "union", "fused"))
        rows.append(
            f"| {c.name} | {c.rms['tof']:.3f}{' (good)' if c.good['tof'] else ''} | "
            f"{c.rms['stereo']:.3f}{' (good)' if c.good['stereo'] else ''} | "
            f"{c.rms['fused']:.3f} | {c.ratio:.3f} | {'-' if g is None else f'{g:.3f}'} | {cov} |"
        )
    m = summarize(scores)
    rows.append(
        f"\nMean fused RMS {m['mean_fused']:.3f} px; mean fused / better input "
        f"**{m['mean_ratio']:.3f}** (target <= 0.85); worst fused / good input "
        f"**{m['worst_good']:.3f}** (target <= {MAX_DAMAGE:g}); largest coverage shortfall of "
        f"the fused map against the inputs' union {_shortfall(m['coverage_gap'])} (target <= "
        "0.5 %)."
    )
    if np.isfinite(m["unseen_bad2"]):
        tof = m["unseen_bad2_tof"]
        tof_text = f"{100 * tof:.1f} %" if np.isfinite(tof) else "no value there"
        rows.append(
            f"Pixels the other camera cannot see (never in the RMS above): fused "
            f"{100 * m['unseen_bad2']:.1f} % off by more than 2 px, the ToF {tof_text} (over "
            "the pixels each has a value for)."
        )
    return "\n".join(rows) + "\n"


def _title_of(out: FusionResult) -> str:
    """The confidences a fused map was made with, for a panel title."""
    return "uniform weights" if out.tof_confidence is None else "confidence-weighted"


def _case_panels(s: Sample, out: FusionResult) -> tuple[list[U8], list[str]]:
    """One case's panels: colour, ground truth, ToF, SGM, fused (one disparity scale), the fused
    error, and the two confidences."""
    gt = s.gt_disparity
    lo, hi = float(np.nanpercentile(gt, 1)), float(np.nanpercentile(gt, 99))
    name = s.name
    side = s.rig.reference
    cells = [as_bgr(s.left if side == "left" else s.right)]
    labels = [f"{name}: colour ({side})"]
    for title, d in (
        ("ground truth", gt),
        ("ToF (upsampled)", out.tof_fused),
        (f"SGM ({out.stereo_matcher})", out.stereo_disparity),
        (f"fused (LC, {_title_of(out)})", out.disparity),
    ):
        cells.append(colorize_with_bar(d, lo, hi, "px"))
        labels.append(title)
    err = np.abs(out.disparity - gt)
    cells.append(colorize_with_bar(err, 0, ERROR_MAX, "px"))
    labels.append("|fused - ground truth|")
    for title, p, src in (
        ("P_T (ToF confidence)", out.tof_confidence, out.tof_fused),
        ("P_S (stereo confidence)", out.stereo_confidence, out.stereo_disparity),
    ):
        if p is not None:
            # Where the source has no disparity its confidence is "no data", not 0.
            shown = np.where(np.isfinite(src), p, np.nan).astype(np.float32)
            cells.append(colorize_with_bar(shown, 0, 1, ""))
            labels.append(title)
    return cells, labels


def evaluate_real(
    samples: Iterable[Sample],
    out: str | Path | None,
    *,
    title: str,
    estimator: ConfidenceEstimator | None = None,
    confidence: str = "convnet",
    params: LcParams | None = None,
    figure_cases: int = 4,
    quiet: bool = False,
) -> list[CaseScore]:
    """Fuse every sample as ``fuse`` does with ``confidence`` (default: the shipped ConvNet) or
    with ``estimator`` and score it; with ``out``, write ``OUT/table.md`` and
    ``OUT/figure.png``."""
    scores: list[CaseScore] = []
    cells: list[U8] = []
    labels: list[str] = []
    per_case = 0
    with warnings.catch_warnings():
        # Fusing on the camera far from the ToF is what a `view="right"` case measures; other
        # warnings still show once per run.
        warnings.filterwarnings("ignore", FAR_CAMERA_WARNING, RuntimeWarning)
        for s in tqdm(list(samples), desc=title, disable=quiet, unit="case"):
            res = fuse(
                s.left,
                s.right,
                s.tof_depth,
                s.tof_amplitude,
                s.rig,
                confidence=confidence if estimator is None else estimator,  # type: ignore[arg-type]
                params=params,
            )
            scores.append(score_result(s, res))
            if len(scores) <= figure_cases:
                c, lab = _case_panels(s, res)
                per_case = len(c)
                cells += c
                labels += lab
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "table.md").write_text(markdown(scores, title))
        if cells:
            # Each case on two rows (4 + 4 panels, or 3 + 3 without confidences): half as wide
            # as one row, so the labels stay legible at a page's width.
            columns = max(1, per_case // 2)
            save_png(folder / "figure.png", tile(cells, labels, columns=columns, width=320))
    return scores
