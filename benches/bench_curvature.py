"""Speed of the curvature maps (rgbd_rs.shapes.curvature, thesis §5.3.3) and of all fifteen
inputs of one shape (issue 14: <= 20 ms at 64 x 64 views, <= 200 ms at 320 x 320, 2 cores).

Shapes: a ModelNet10 point cloud (1024 points, the training data), the ModelNet10 bathtub mesh
and the Stanford bunny of ../shared/data/meshes. Columns: the curvature maps alone; the fifteen
inputs (depth + volume + curvature, LCN, :func:`rgbd_rs.shapes.dataset.shape_inputs`); the nine
without curvature, for the share curvature adds. Each cell is ``min / median`` wall time of the
runs after a warm-up (the minimum is the least disturbed run on a shared machine) and, in
brackets, the least CPU time the process used (both threads; on 2 free cores the wall time lies
between half of it and all of it, so it is the load-independent figure), one thread pool of
``RAYON_NUM_THREADS`` (default: every core). The load average is printed: other processes on a
shared machine inflate every number.

    python benches/bench_curvature.py
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from rgbd_rs import _rgbd_rs
from rgbd_rs.data.paths import data_root
from rgbd_rs.meshes import load_mesh
from rgbd_rs.shapes.curvature import curvature_maps
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, shape_inputs

REPEATS = 15


def timeit(fn: Callable[[], object], repeats: int) -> str:
    """``min / median`` wall time and ``[min CPU time]`` (all threads of this process) of ``fn``
    in ms over ``repeats`` runs after one warm-up."""
    fn()
    times, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        times.append((time.perf_counter() - t) * 1e3)
        cpu.append((time.process_time() - c) * 1e3)
    return f"{min(times):.1f} / {statistics.median(times):.1f} [{min(cpu):.1f}]"


def main() -> None:
    root = data_root(required=True)
    pack = PointCloudSet(root / "modelnet" / "modelnet10_1024.npz")
    chair = pack.load(int(np.flatnonzero(pack.labels == pack.classes.index("chair"))[0]))
    shapes = {
        "ModelNet10 chair, 1024 points": chair,
        "ModelNet10 bathtub mesh": load_mesh(root / "meshes" / "modelnet10_bathtub_0001.off"),
        "Stanford bunny mesh": load_mesh(root / "meshes" / "stanford_bunny.off"),
    }
    load = os.getloadavg()
    print(f"threads: {_rgbd_rs.num_threads()}, load average {load[0]:.1f} {load[1]:.1f}")
    print("| shape | views | curvature maps, ms | 15 inputs, ms | 9 inputs (no curvature), ms |")
    print("|---|---|---|---|---|")
    for res in (64, 320):
        all15 = InputSpec(representations=("depth", "volume", "curvature"), view_resolution=res)
        nine = InputSpec(representations=("depth", "volume"), view_resolution=res)
        for name, shape in shapes.items():
            t_curv = timeit(lambda s=shape, r=res: curvature_maps(s, r), REPEATS)  # type: ignore[misc]
            t_all = timeit(lambda s=shape, sp=all15: shape_inputs(s, sp), REPEATS)  # type: ignore[misc]
            t_nine = timeit(lambda s=shape, sp=nine: shape_inputs(s, sp), REPEATS)  # type: ignore[misc]
            print(f"| {name} | {res} | {t_curv} | {t_all} | {t_nine} |")
    load = os.getloadavg()
    print(f"load average after: {load[0]:.1f} {load[1]:.1f}")


if __name__ == "__main__":
    main()
