"""Camera-geometry speed: rgbd_rs against OpenCV, measured in the same run.

Each configuration runs in a fresh process with both libraries limited to the same thread count
(RAYON_NUM_THREADS for rgbd_rs, cv2.setNumThreads for OpenCV). Times are the median of repeated
runs after a warm-up. "speed-up" = OpenCV time / rgbd_rs time (> 1: rgbd_rs is faster).

    python benches/bench_geom.py            # 1 and 2 threads
    python benches/bench_geom.py --markdown # the README table
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections.abc import Callable

import numpy as np

from _timing import timeit

REPEATS = 7
N_POINTS = 1_000_000
SIZE = (1920, 1080)
COEFFS = {
    "brown5": [-0.28, 0.07, 1e-3, -5e-4, -0.008],
    "rational8": [0.3301, -2.4894, -1.618e-4, -1.294e-4, 1.4537, 0.2089, -2.3029, 1.3751],
}


def bench_model(
    model: str, coeffs: list[float], rng: np.random.Generator
) -> list[dict[str, object]]:
    """Time the four operations for one lens model."""
    import cv2

    from rgbd_rs import Distortion, PinholeCamera, Pose

    w, h = SIZE
    cam = PinholeCamera(1400.0, 1400.0, 959.5, 539.5, w, h, Distortion.from_opencv(coeffs))
    k, d = cam.K, cam.distortion.to_opencv()[: len(coeffs)]
    u = rng.uniform(0, w - 1, N_POINTS)
    v = rng.uniform(0, h - 1, N_POINTS)
    z = rng.uniform(0.5, 5, N_POINTS)
    pts = np.column_stack([(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z])
    rvec = np.array([0.01, -0.02, 0.005])
    tvec = np.array([0.05, 0.0, 0.01])
    pose = Pose(cv2.Rodrigues(rvec)[0], tvec)
    px = cam.project(pts)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    img = rng.uniform(0, 255, (h, w, 3)).astype(np.float32)
    cases: list[tuple[str, Callable[[], object], Callable[[], object]]] = [
        (
            "project 1M points",
            lambda: cam.project(pts, pose),
            lambda: cv2.projectPoints(pts, rvec, tvec, k, d),
        ),
        (
            "undistort 1M points to 1e-12",
            lambda: cam.undistort_points(px),
            lambda: cv2.undistortPoints(px.reshape(-1, 1, 2), k, d, P=k, criteria=crit),
        ),
        (
            "undistort map 1920x1080",
            lambda: cam.undistort_map(),
            lambda: cv2.initUndistortRectifyMap(k, d, None, k, SIZE, cv2.CV_32FC1),
        ),
        (
            "undistort image 1920x1080x3 f32",
            lambda: cam.undistort_image(img),
            lambda: cv2.undistort(img, k, d),
        ),
    ]
    return [
        {
            "op": f"{name} ({model})",
            "rgbd_ms": timeit(ours, REPEATS),
            "opencv_ms": timeit(theirs, REPEATS),
        }
        for name, ours, theirs in cases
    ]


def worker(threads: int) -> list[dict[str, object]]:
    import cv2

    from rgbd_rs import _rgbd_rs

    cv2.setNumThreads(threads)
    assert _rgbd_rs.num_threads() == threads, _rgbd_rs.num_threads()
    rng = np.random.default_rng(0)
    rows = [r for model, coeffs in COEFFS.items() for r in bench_model(model, coeffs, rng)]
    for r in rows:
        r["threads"] = threads
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker)))
        return 0
    rows = []
    for t in args.threads:
        env = dict(os.environ, RAYON_NUM_THREADS=str(t), OMP_NUM_THREADS=str(t))
        out = subprocess.run(
            [sys.executable, __file__, "--worker", str(t)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        rows += json.loads(out.stdout.strip().splitlines()[-1])
    if args.markdown:
        print("| operation | threads | rgbd_rs ms | OpenCV ms | speed-up |")
        print("|---|---:|---:|---:|---:|")
    for r in rows:
        ratio = float(r["opencv_ms"]) / float(r["rgbd_ms"])
        if args.markdown:
            print(
                f"| {r['op']} | {r['threads']} | {r['rgbd_ms']:.1f} | {r['opencv_ms']:.1f} "
                f"| {ratio:.2f}x |"
            )
        else:
            print(
                f"{r['op']:<45} threads={r['threads']}  rgbd_rs {r['rgbd_ms']:8.1f} ms  "
                f"OpenCV {r['opencv_ms']:8.1f} ms  speed-up {ratio:5.2f}x"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
