"""Fit-only merging against the NYUv2 region ground truth over the merging's own thresholds.

Usage: python tools/sweep_merge_thresholds.py train|test [--clusters N ...] [--tc T ...]
       [--td D ...] [--theta A ...] [--tolerance K ...] [--test-spacing S ...]
       [--feature-weight F ...] [--spatial-weight P ...] [--min-size S ...]

For every frame of the split and every N (and the over-segmentation's k-means ``feature_weight``
and ``spatial_weight``), the features, the over-segmentation and the adjacency normals are
computed once; then ``merge_regions`` (fit-only) runs at every
combination of the colour test ``T_c`` (Lab distance, eq. 4.4; the thesis' 10), the depth test
``T_d`` (metres, eq. 4.3; 0.2), the normal test ``T_theta`` (degrees, eq. 4.5; 4), the seam
test's ``tolerance`` and ``test_spacing`` (:class:`rgbd_rs.surface.SegmentFits`). Prints the
mean VoI (and its two terms: H(S|G), the ground truth's regions split, and H(G|S), segments
that straddle regions), Rand index and segment count per combination, best VoI first, after
Felzenszwalb (RGB-D) at the evaluation's tuned parameters. ``--min-size`` (0 = off) then
absorbs final segments smaller than S px as tools/sweep_merge_clusters.py does. Default values:
the pipeline's.
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from rgbd_rs import metrics
from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame, nyuv2_frames, region_ground_truth
from rgbd_rs.segmentation import features, oversegment
from rgbd_rs.segmentation.evaluate import felzenszwalb_rgbd
from rgbd_rs.segmentation.hha import square_normals
from rgbd_rs.segmentation.merge import T_C, T_D, T_THETA_DEG, merge_regions
from rgbd_rs.segmentation.oversegment import DEFAULT_FEATURE_WEIGHT, DEFAULT_SPATIAL_WEIGHT
from rgbd_rs.segmentation.pipeline import ADJACENCY_NORMAL_RADIUS
from rgbd_rs.surface import DEFAULT_TEST_SPACING, DEFAULT_TOLERANCE, SegmentFits
from sweep_merge_clusters import absorb

KEYS = (
    "clusters",
    "feature_weight",
    "spatial_weight",
    "tc",
    "td",
    "theta",
    "tolerance",
    "test_spacing",
    "min_size",
)


def voi_terms(seg: np.ndarray, gt: np.ndarray) -> tuple[float, float]:
    """``(H(S|G), H(G|S))`` in nats over the pixels labelled in both (their sum is the VoI)."""
    m = (seg >= 0) & (gt >= 0)
    _, si = np.unique(seg[m], return_inverse=True)
    _, gi = np.unique(gt[m], return_inverse=True)
    joint = np.bincount(si * (gi.max() + 1) + gi).astype(np.float64) / si.size

    def h(p: np.ndarray) -> float:
        p = p[p > 0]
        return float(-np.sum(p * np.log(p)))

    hj = h(joint)
    hs = h(np.bincount(si).astype(np.float64) / si.size)
    hg = h(np.bincount(gi).astype(np.float64) / si.size)
    return hj - hg, hj - hs


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("split", choices=("train", "test"))
    p.add_argument("--clusters", type=int, nargs="+", default=[30])
    p.add_argument("--feature-weight", type=float, nargs="+", default=[DEFAULT_FEATURE_WEIGHT])
    p.add_argument("--spatial-weight", type=float, nargs="+", default=[DEFAULT_SPATIAL_WEIGHT])
    p.add_argument("--tc", type=float, nargs="+", default=[T_C])
    p.add_argument("--td", type=float, nargs="+", default=[T_D])
    p.add_argument("--theta", type=float, nargs="+", default=[T_THETA_DEG])
    p.add_argument("--tolerance", type=float, nargs="+", default=[DEFAULT_TOLERANCE])
    p.add_argument("--test-spacing", type=float, nargs="+", default=[DEFAULT_TEST_SPACING])
    p.add_argument("--min-size", type=int, nargs="+", default=[0])
    a = p.parse_args(argv)
    if min(a.clusters) < 2:
        p.error("--clusters: expected integers >= 2")
    return a


def main(argv: list[str] | None = None) -> int:
    a = parse(argv)
    frames = [load_nyuv2_frame(i) for i in nyuv2_frames(a.split)]
    gts = [region_ground_truth(f.label40) for f in frames]
    felz = felzenszwalb_rgbd(scale=300, min_size=2500, depth_weight=100)
    fv = np.mean(
        [
            voi_terms(felz(f.rgb, f.depth, NYUV2_CAMERA), g)
            for f, g in zip(frames, gts, strict=True)
        ],
        0,
    )
    print(
        f"felzenszwalb (RGB-D): VoI {fv.sum():.3f} (H(S|G) {fv[0]:.3f} H(G|S) {fv[1]:.3f})",
        flush=True,
    )
    combos = list(itertools.product(a.tc, a.td, a.theta, a.tolerance, a.test_spacing))
    scores: dict[tuple[float, ...], list[tuple[float, float, float, int]]] = {}
    t0 = time.time()
    for f, gt in zip(frames, gts, strict=True):
        feats = features(f.rgb, f.depth, NYUV2_CAMERA)
        normals = square_normals(f.depth, NYUV2_CAMERA, radius=ADJACENCY_NORMAL_RADIUS)
        for n, fw, sw in itertools.product(a.clusters, a.feature_weight, a.spatial_weight):
            over = oversegment(feats.vectors, n, seed=0, feature_weight=fw, spatial_weight=sw)
            for tc, td, theta, tol, ts in combos:
                fits = SegmentFits(
                    feats.points, over, surfaces=False, tolerance=tol, test_spacing=ts
                )
                m = merge_regions(
                    over,
                    feats.points,
                    lab=feats.lab,
                    normals=normals,
                    fits=fits,
                    max_depth_step=td,
                    max_color_distance=tc,
                    max_normal_angle=theta,
                )
                for size in a.min_size:
                    labels = absorb(m.labels, size) if size > 0 else m.labels
                    scores.setdefault((n, fw, sw, tc, td, theta, tol, ts, size), []).append(
                        (
                            *voi_terms(labels, gt),
                            metrics.rand_index(labels, gt, ignore=-1),
                            len(np.unique(labels[labels >= 0])),
                        )
                    )
        print(f"frame {f.index:04d} done ({time.time() - t0:.0f} s)", flush=True)
    rows = sorted(
        (float(np.mean([s[0] + s[1] for s in v])), k, np.mean(v, 0)) for k, v in scores.items()
    )
    for voi, k, (split, straddle, ri, segs) in rows:
        setting = " ".join(f"{name}={x:g}" for name, x in zip(KEYS, k, strict=True))
        print(
            f"{setting}: VoI {voi:.3f} (H(S|G) {split:.3f} H(G|S) {straddle:.3f}) "
            f"RI {ri:.3f} segments {segs:.0f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
