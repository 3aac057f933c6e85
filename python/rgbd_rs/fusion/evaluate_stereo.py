"""Stereo matchers on the real Middlebury scenes (``rgbd eval stereo``): our census SGM against
OpenCV's SGBM (HH = 8 paths, 3WAY) at several block sizes, on the same pixels.

Protocol (issue 28): the left view is the reference; pixels with ground truth that are visible
in the right view (:func:`~rgbd_rs.fusion.evaluate.non_occluded` on the ground truth) are
scored; a pixel without an output counts as bad. Measures per scene: bad-1 and bad-2 (share of
the scored pixels off by more than 1 / 2 px, or without output), RMS over the scored pixels
that have an output, coverage, and bad-1 in the edge band (scored pixels within
:data:`EDGE_RADIUS` px of a ground-truth disparity jump of more than :data:`EDGE_JUMP` px). The
search range of a scene is its manifest's largest disparity times :data:`RANGE_MARGIN`, for
every matcher alike.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs.data.stereo_scenes import StereoScene
from rgbd_rs.fusion._inputs import F32
from rgbd_rs.fusion.census import CensusParams, census_match
from rgbd_rs.fusion.evaluate import non_occluded
from rgbd_rs.fusion.stereo import _max_search, _sgbm_disparity, _sgm

#: A ground-truth disparity step above this many pixels between 4-neighbours is a depth edge.
EDGE_JUMP = 2.0
#: The edge band: pixels within this many pixels (Chebyshev) of a depth edge.
EDGE_RADIUS = 2
#: Search range = the scene's largest ground-truth disparity x this (rounded up).
RANGE_MARGIN = 1.1
#: The measures in table order.
MEASURES = ("bad1", "bad2", "rms", "coverage", "edge_bad1")

Matcher = Callable[[StereoScene, int], F32]


def edge_band(gt: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """Pixels within :data:`EDGE_RADIUS` px of a ground-truth jump of more than
    :data:`EDGE_JUMP` px (NaN neighbours are no jump)."""
    d = np.asarray(gt, np.float32)
    edge = np.zeros(d.shape, bool)
    with np.errstate(invalid="ignore"):
        jx = np.abs(d[:, 1:] - d[:, :-1]) > EDGE_JUMP
        jy = np.abs(d[1:, :] - d[:-1, :]) > EDGE_JUMP
    edge[:, 1:] |= jx
    edge[:, :-1] |= jx
    edge[1:, :] |= jy
    edge[:-1, :] |= jy
    k = np.ones((2 * EDGE_RADIUS + 1,) * 2, np.uint8)
    return np.asarray(cv2.dilate(edge.astype(np.uint8), k), bool)


def _scored_pixels(scene: StereoScene) -> npt.NDArray[np.bool_]:
    """The left view's pixels with ground truth that the right view sees."""
    gt = scene.disparity_left
    return np.isfinite(gt) & non_occluded(gt, -1)


def measures(disparity: npt.ArrayLike, scene: StereoScene) -> dict[str, float]:
    """The protocol's measures of a left-view disparity map on ``scene``."""
    d = np.asarray(disparity, np.float32)
    gt = scene.disparity_left
    mask = _scored_pixels(scene)
    err = np.abs(d - gt)
    have = np.isfinite(d) & mask
    n = max(1, int(mask.sum()))
    with np.errstate(invalid="ignore"):
        good1 = have & (err <= 1.0)
        good2 = have & (err <= 2.0)
    band = mask & edge_band(gt)
    nb = max(1, int(band.sum()))
    rms = float(np.sqrt(np.mean(err[have] ** 2))) if have.any() else math.nan
    return {
        "bad1": 1.0 - float(good1.sum()) / n,
        "bad2": 1.0 - float(good2.sum()) / n,
        "rms": rms,
        "coverage": float(have.sum()) / n,
        "edge_bad1": 1.0 - float((good1 & band).sum()) / nb,
    }


def search_range(scene: StereoScene) -> int:
    """The scene's search range (the same for every matcher)."""
    want = math.ceil(scene.max_disparity * RANGE_MARGIN)
    return int(min(want, scene.left.shape[1] - 2))


def census_matcher(params: CensusParams | None = None) -> Matcher:
    """Ours, on the left view."""

    def run(scene: StereoScene, dmax: int) -> F32:
        return census_match(
            scene.left, scene.right, reference="left", max_disparity=dmax, params=params
        ).disparity

    return run


def opencv_matcher(block_size: int, mode: str = "hh") -> Matcher:
    """OpenCV SGBM (``mode`` ``"hh"``: 8 paths, ``"3way"``) at ``block_size``, on the left view;
    the search range rounded up to OpenCV's step of 16 (within the image)."""
    if mode == "hh":

        def run(scene: StereoScene, dmax: int) -> F32:
            top = _max_search(scene.left.shape[1], 0, block_size)
            return _sgm(
                scene.left,
                scene.right,
                reference="left",
                max_disparity=min(dmax, top),
                block_size=block_size,
                method="opencv",
            )

        return run
    return _opencv_3way(block_size)


def _opencv_3way(block_size: int) -> Matcher:
    def run(scene: StereoScene, dmax: int) -> F32:
        mode = cv2.STEREO_SGBM_MODE_SGBM_3WAY
        return _sgbm_disparity(scene.left, scene.right, "left", 0, dmax, block_size, mode)

    return run


@dataclass
class StereoTable:
    """Measures per method and scene, plus seconds per method."""

    scenes: list[str]
    values: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)

    def mean(self, method: str, measure: str) -> float:
        """The mean of ``measure`` over the scenes (NaN-free scenes)."""
        v = [r[measure] for r in self.values[method] if not math.isnan(r[measure])]
        return float(np.mean(v)) if v else math.nan

    def markdown(self, title: str, per_scene: bool = True) -> str:
        """Means per method (and per-scene rows of bad-2 / edge bad-1)."""
        lines = [f"### {title}", ""]
        lines.append("| method | bad-1 % | bad-2 % | RMS px | coverage % | edge bad-1 % | s |")
        lines.append("|---|---|---|---|---|---|---|")
        for m in self.values:
            b1, b2, rms, cov, eb = (self.mean(m, k) for k in MEASURES)
            lines.append(
                f"| {m} | {100 * b1:.1f} | {100 * b2:.1f} | {rms:.2f} | {100 * cov:.1f} | "
                f"{100 * eb:.1f} | {self.seconds[m]:.1f} |"
            )
        if per_scene:
            lines += ["", "bad-2 % / edge bad-1 % per scene:", ""]
            lines.append("| scene | " + " | ".join(self.values) + " |")
            lines.append("|---|" + "---|" * len(self.values))
            for i, s in enumerate(self.scenes):
                cells = [
                    f"{100 * self.values[m][i]['bad2']:.1f} / "
                    f"{100 * self.values[m][i]['edge_bad1']:.1f}"
                    for m in self.values
                ]
                lines.append(f"| {s} | " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"


def evaluate(
    scenes: Sequence[StereoScene],
    methods: dict[str, Matcher],
    progress: Callable[[str], None] | None = None,
) -> StereoTable:
    """Every method on every scene (left reference, the protocol of the module docs)."""
    table = StereoTable([s.name for s in scenes])
    for name, run in methods.items():
        rows = []
        t0 = time.perf_counter()
        for s in scenes:
            rows.append(measures(run(s, search_range(s)), s))
            if progress is not None:
                progress(f"{name} {s.name}")
        table.seconds[name] = time.perf_counter() - t0
        table.values[name] = rows
    return table
