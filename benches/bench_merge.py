"""Region-merging speed (issue 13 target: ~300 segments of a 640x480 frame, adjacency + fits +
merging <= 100 ms on 2 cores) against scikit-image's RAG + merge_hierarchical, in the same run.

Both start from the same SLIC over-segmentation (~300 segments) of real NYUv2 frames. Ours:
`rgbd_rs.segmentation.merge.merge_regions` fit-only (adjacency with the eq. 4.3-4.5 tests, spline
fits of every segment, eq. 4.8 queue) and with class PDFs (Algorithm 1; PDFs made from the
ground-truth labels, blurred, so the similarity gate has realistic work). The peer:
`skimage.graph.rag_mean_color` + `merge_hierarchical` (mean-colour merging, the skimage example's
threshold 35). They do different things; the timing is the point (what a user pays per frame for
a region-merging stage). Ours: wall and CPU (process time, all threads) per call in the same runs
after a warm-up, median and minimum (on a shared machine the wall time also counts waiting for
other processes; the merging tests upcoming couples on a second core when one is free, so its CPU
time may exceed its wall time). The peer: median wall.

    python benches/bench_merge.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import cv2
import numpy as np

from _timing import timeit
from rgbd_rs.data.paths import data_root
from rgbd_rs.segmentation.merge import adjacency, merge_regions
from rgbd_rs.surface import SegmentFits

FRAMES = ("0001", "0009")
REPEATS = 9


def _merge_mean_color(graph, src, dst):  # type: ignore[no-untyped-def]
    graph.nodes[dst]["total color"] += graph.nodes[src]["total color"]
    graph.nodes[dst]["pixel count"] += graph.nodes[src]["pixel count"]
    graph.nodes[dst]["mean color"] = (
        graph.nodes[dst]["total color"] / graph.nodes[dst]["pixel count"]
    )


def _weight_mean_color(graph, src, dst, n):  # type: ignore[no-untyped-def]
    diff = np.linalg.norm(graph.nodes[dst]["mean color"] - graph.nodes[n]["mean color"])
    return {"weight": diff}


def both(fn: Callable[[], object], repeats: int) -> tuple[float, float, float, float]:
    """Wall and CPU time (process time: all threads) of ``fn`` per call, ms, in the same runs
    after one warm-up: (median wall, min wall, median CPU, min CPU)."""
    fn()
    walls, cpus = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    med = statistics.median
    return med(walls) * 1e3, min(walls) * 1e3, med(cpus) * 1e3, min(cpus) * 1e3


def cell(t: tuple[float, float, float, float]) -> str:
    """``median wall / CPU (min wall / CPU)``."""
    return f"{t[0]:.0f} / {t[2]:.0f} ({t[1]:.0f} / {t[3]:.0f}) ms"


def row(idx: str, cam: object) -> str:
    """One frame's table row."""
    from skimage import graph as skgraph
    from skimage.segmentation import slic

    root = data_root(required=True)
    base = root / "nyuv2" / "frames" / idx
    rgb = cv2.cvtColor(cv2.imread(f"{base}_rgb.png"), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(f"{base}_depth.png", cv2.IMREAD_UNCHANGED).astype(np.float32) / 1e3
    gt = cv2.imread(f"{base}_label13.png", cv2.IMREAD_UNCHANGED)
    labels = slic(rgb, n_segments=300, compactness=10, start_label=0).astype(np.int32)
    pts = cam.depth_to_points(depth)  # type: ignore[attr-defined]
    lab = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2Lab)
    onehot = np.eye(14, dtype=np.float32)[gt]
    pdfs = cv2.GaussianBlur(onehot, (31, 31), 0) * 0.9 + 0.1 / 14
    pdfs /= pdfs.sum(axis=2, keepdims=True)
    fit_only = both(lambda: merge_regions(labels, pts, lab=lab), REPEATS)
    with_pdf = both(lambda: merge_regions(labels, pts, lab=lab, pdfs=pdfs), REPEATS)
    fits = both(lambda: SegmentFits(pts, labels, surfaces=False), REPEATS)
    adj = both(lambda: adjacency(labels, points=pts, lab=lab), REPEATS)

    def peer() -> object:
        g = skgraph.rag_mean_color(rgb, labels)
        return skgraph.merge_hierarchical(
            labels,
            g,
            thresh=35,
            rag_copy=False,
            in_place_merge=True,
            merge_func=_merge_mean_color,
            weight_func=_weight_mean_color,
        )

    sk = timeit(peer, 2)
    n = int(labels.max()) + 1
    return (
        f"| {idx} | {n} | {cell(fit_only)} | {cell(with_pdf)} "
        f"| {cell(fits)}, adjacency {cell(adj)} | {sk:.0f} ms "
        f"| {sk / fit_only[0]:.1f}x / {sk / with_pdf[0]:.1f}x |"
    )


def main() -> None:
    from rgbd_rs.data import NYUV2_CAMERA as cam

    print(
        "| frame | segments | rgbd_rs fit-only, wall / CPU (min) "
        "| rgbd_rs with PDFs, wall / CPU (min) | seam-test fits and adjacency, wall / CPU (min) "
        "| skimage RAG+merge_hierarchical (wall) | speed-up, median wall (fit-only / PDFs) |"
    )
    print("|---|---|---|---|---|---|---|")
    for idx in FRAMES:
        print(row(idx, cam))


if __name__ == "__main__":
    main()
