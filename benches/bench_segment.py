"""The whole segmentation + labeling pipeline on 640x480 NYUv2 frames, stage by stage (issue 15
target: <= 3 s per frame on 2 cores), beside scikit-image's felzenszwalb and slic in the same run
(the peers of the evaluation table; they label nothing, so they are a floor, not an equal).

Ours: ``segment(rgb, depth, camera)`` with the shipped semantic ConvNet (features ->
over-segmentation -> spline fits -> HHA + cues + ConvNet -> Algorithm 1 merging -> majority
classes). Medians of wall and CPU seconds (all threads of this process) after a warm-up that also
loads the weights.

    python benches/bench_segment.py [--frames 46 47] [--repeats 3] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def main() -> None:
    import torch

    from rgbd_rs.data import NYUV2_CAMERA, load_nyuv2_frame
    from rgbd_rs.segmentation import segment

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[46, 47])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="torch threads (1: shared machine)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from skimage.segmentation import felzenszwalb, slic

    print("| frame | stage seconds (median) | ours wall / CPU s | felzenszwalb / slic wall s |")
    print("|---|---|---|---|")
    for index in args.frames:
        f = load_nyuv2_frame(index)
        segment(f.rgb, f.depth, NYUV2_CAMERA)  # warm-up, loads the weights
        walls, cpus, stages = [], [], []
        for _ in range(args.repeats):
            t, c = time.perf_counter(), time.process_time()
            r = segment(f.rgb, f.depth, NYUV2_CAMERA)
            walls.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
            stages.append(r.seconds)
        med = {k: statistics.median(s[k] for s in stages) for k in stages[0]}
        peers = []
        for fn in (
            lambda rgb=f.rgb: felzenszwalb(rgb, scale=300, sigma=0.8, min_size=2500),
            lambda rgb=f.rgb: slic(rgb, n_segments=15, compactness=10, start_label=0),
        ):
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                np.asarray(fn())
                times.append(time.perf_counter() - t)
            peers.append(statistics.median(times))
        stage_text = ", ".join(f"{k} {v:.2f}" for k, v in med.items())
        print(
            f"| {index:04d} | {stage_text} | {statistics.median(walls):.2f} / "
            f"{statistics.median(cpus):.2f} | {peers[0]:.2f} / {peers[1]:.2f} |"
        )


if __name__ == "__main__":
    main()
