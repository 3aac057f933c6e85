"""Fit-only merging against the NYUv2 region ground truth at several over-segmentation sizes.

Usage: python tools/sweep_merge_clusters.py train|test N [N ...] [--min-size S [S ...]]

For each N (k-means clusters of the over-segmentation the merging starts from), runs
``segment(..., labeler=None, n_segments=N)`` on the split's frames and prints the mean VoI,
Rand index and final segment count, after Felzenszwalb (RGB-D) at the evaluation's tuned
parameters for comparison (README, segmentation accuracy). With ``--min-size``, also after
absorbing every final segment smaller than S pixels into the neighbour it shares the longest
boundary with, smallest first (what Felzenszwalb's ``min_size`` does to its own segments).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np

from rgbd_rs import metrics
from rgbd_rs.data.nyuv2 import (
    NYUV2_CAMERA,
    NyuFrame,
    load_nyuv2_frame,
    nyuv2_frames,
    region_ground_truth,
)
from rgbd_rs.segmentation.evaluate import felzenszwalb_rgbd
from rgbd_rs.segmentation.pipeline import segment


def absorb(labels: np.ndarray, min_size: int) -> np.ndarray:
    """Segments < ``min_size`` px merged into their longest-boundary neighbour, smallest first."""
    lab = labels.copy()
    stuck: set[int] = set()  # no labelled neighbour: left as they are
    while True:
        ids, counts = np.unique(lab[lab >= 0], return_counts=True)
        small = [
            (c, i) for i, c in zip(ids, counts, strict=True) if c < min_size and i not in stuck
        ]
        if not small or len(ids) <= 1:
            return lab
        s = min(small)[1]
        near = []
        for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):
            near += [b[(a == s) & (b != s) & (b >= 0)], a[(b == s) & (a != s) & (a >= 0)]]
        around = np.concatenate(near)
        if around.size == 0:
            stuck.add(int(s))
            continue
        u, c = np.unique(around, return_counts=True)
        lab[lab == s] = u[np.argmax(c)]


def score(name: str, frames: list[NyuFrame], run: Callable[[NyuFrame], np.ndarray]) -> None:
    v, r, c = [], [], []
    t0 = time.time()
    for f in frames:
        gt = region_ground_truth(f.label40)
        labels = run(f)
        v.append(metrics.variation_of_information(labels, gt, ignore=-1))
        r.append(metrics.rand_index(labels, gt, ignore=-1))
        c.append(len(np.unique(labels[labels >= 0])))
    print(
        f"{name}: VoI {np.mean(v):.3f} RI {np.mean(r):.3f} segments {np.mean(c):.0f} "
        f"({time.time() - t0:.0f} s)",
        flush=True,
    )


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("train", "test"):
        print(__doc__)
        return 2
    words, sizes_text = argv[1:], []
    if "--min-size" in words:
        k = words.index("--min-size")
        words, sizes_text = words[:k], words[k + 1 :]
    try:  # every number checked before the minutes of work start
        counts = [int(a) for a in words]
        sizes = [int(a) for a in sizes_text]
    except ValueError:
        print(__doc__)
        return 2
    if not counts or min(counts) < 2 or (sizes and min(sizes) < 1):
        print(__doc__)
        return 2
    frames = [load_nyuv2_frame(i) for i in nyuv2_frames(argv[0])]
    felz = felzenszwalb_rgbd(scale=300, min_size=2500, depth_weight=100)
    score("felzenszwalb (RGB-D)", frames, lambda f: felz(f.rgb, f.depth, NYUV2_CAMERA))
    for n in counts:
        merged = {
            f.index: segment(
                f.rgb, f.depth, NYUV2_CAMERA, labeler=None, n_segments=n, seed=0
            ).labels
            for f in frames
        }
        score(f"fit-only merging, {n} clusters", frames, lambda f, m=merged: m[f.index])
        for size in sizes:
            score(
                f"fit-only merging, {n} clusters, segments < {size} px absorbed",
                frames,
                lambda f, m=merged, size=size: absorb(m[f.index], size),
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
