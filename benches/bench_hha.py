"""HHA and eq. 4.1 feature speed on 640x480 NYUv2 frames, against a numpy/scipy HHA, in one run.

- Parity: rgbd_rs' HHA and the numpy peer (benches/peers/depth2hha_numpy.py, the same steps
  and array primitives as Depth2HHA-python) against Gupta's MATLAB output in ../shared/data/hha,
  mean absolute difference per channel (disparity, height, angle) in grey levels.
- Speed on that frame: HHA in rgbd_rs (median of REPEATS after a warm-up) and in the peer
  (PEER_REPEATS runs, median); "speed-up" = peer / rgbd_rs.
- "Features + HHA" on NYUv2 frame 0001 (colour + depth): ``hha_details`` then ``features``
  reusing its normals (``normals=r.normals``), i.e. what a pipeline computes per frame.

Each thread count runs in a fresh process with RAYON_NUM_THREADS set (the numpy peer is
single-threaded; OMP/OPENBLAS threads are set alike).

    python benches/bench_hha.py             # 1 and 2 threads
    python benches/bench_hha.py --markdown  # the README table
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from _timing import timeit

REPEATS = 15
PEER_REPEATS = 3
#: NYU colour intrinsics as written for the MATLAB code (1-based pixel indices).
NYU = (518.857901, 519.469611, 325.582449, 253.736166)


def cpu_ms(fn: Callable[[], object], repeats: int) -> float:
    """Mean CPU time of ``fn`` (all threads of this process), ms: on a shared machine the wall
    time also counts the time other processes hold the cores."""
    fn()
    t = time.process_time()
    for _ in range(repeats):
        fn()
    return (time.process_time() - t) / repeats * 1e3


def run_one(peer: bool) -> dict[str, object]:
    from peers.depth2hha_numpy import hha as peer_hha
    from rgbd_rs import PinholeCamera, _rgbd_rs
    from rgbd_rs.data import data_root
    from rgbd_rs.segmentation.features import features
    from rgbd_rs.segmentation.hha import hha, hha_details

    root = data_root(required=True)
    assert root is not None
    read = lambda p: cv2.imread(str(p), cv2.IMREAD_UNCHANGED)  # noqa: E731
    d = read(root / "hha" / "depth_filled.png").astype(np.float32) / 10000
    ref = read(root / "hha" / "hha_reference_matlab.png")[:, :, ::-1].astype(np.int16)
    fx, fy, cx, cy = NYU
    cam = PinholeCamera(fx, fy, cx - 1, cy - 1, 640, 480)  # rgbd_rs pixels start at 0

    def mad(img: np.ndarray) -> list[float]:
        return [float(v) for v in np.abs(img.astype(np.int16) - ref).mean(axis=(0, 1))]

    out: dict[str, object] = {"threads": _rgbd_rs.num_threads()}
    out["ours_mad"] = mad(hha(d, cam))
    out["ours_ms"] = timeit(lambda: hha(d, cam), REPEATS)
    out["ours_cpu"] = cpu_ms(lambda: hha(d, cam), REPEATS)
    if peer:
        times, cpu = [], []
        for _ in range(PEER_REPEATS):
            t, c = time.perf_counter(), time.process_time()
            res = peer_hha(d, d, NYU)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        out["peer_ms"] = statistics.median(times) * 1e3
        out["peer_cpu"] = statistics.median(cpu) * 1e3
        out["peer_mad"] = mad(res)
    frames = root / "nyuv2" / "frames"
    rgb = np.ascontiguousarray(read(frames / "0001_rgb.png")[:, :, ::-1])
    depth = read(frames / "0001_depth.png").astype(np.float32) / 1000

    def both() -> None:
        r = hha_details(depth, cam)
        features(rgb, depth, cam, normals=r.normals)

    out["both_ms"] = timeit(both, REPEATS)
    out["both_cpu"] = cpu_ms(both, REPEATS)
    out["features_ms"] = timeit(lambda: features(rgb, depth, cam), REPEATS)
    out["features_cpu"] = cpu_ms(lambda: features(rgb, depth, cam), REPEATS)
    out["load"] = os.getloadavg()[0]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--markdown", action="store_true", help="print the README table only")
    ap.add_argument("--child", choices=["peer", "ours"], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        sys.path.insert(0, str(Path(__file__).parent))
        print(json.dumps(run_one(args.child == "peer")))
        return
    res = {}
    for threads, peer in ((1, True), (2, False)):
        env = dict(
            os.environ,
            RAYON_NUM_THREADS=str(threads),
            OMP_NUM_THREADS="1",
            OPENBLAS_NUM_THREADS="1",
        )
        cmd = [sys.executable, __file__, "--child", "peer" if peer else "ours"]
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        res[threads] = json.loads(done.stdout.strip().splitlines()[-1])
    one, two = res[1], res[2]
    peer_ms, peer_cpu = float(one["peer_ms"]), float(one["peer_cpu"])

    def cell(r: dict[str, object], key: str, peer: float | None = None) -> str:
        wall, cpu = float(r[f"{key}_ms"]), float(r[f"{key}_cpu"])
        txt = f"{wall:.1f} / {cpu:.1f}"
        return txt + (f" ({peer / wall:.0f}x / {peer_cpu / cpu:.0f}x)" if peer else "")

    lv = lambda m: " / ".join(f"{v:.2g}" for v in m)  # noqa: E731
    print("| wall ms / CPU ms | numpy peer (1 thread) | rgbd_rs, 1 thread | rgbd_rs, 2 threads |")
    print("|---|---|---|---|")
    print(
        f"| HHA parity vs MATLAB, mean abs. grey levels (D / H / A) | {lv(one['peer_mad'])} "
        f"| {lv(one['ours_mad'])} | {lv(two['ours_mad'])} |"
    )
    print(
        f"| HHA, 640x480 | {peer_ms:.0f} / {peer_cpu:.0f} | {cell(one, 'ours', peer_ms)} "
        f"| {cell(two, 'ours', peer_ms)} |"
    )
    print(f"| features alone | - | {cell(one, 'features')} | {cell(two, 'features')} |")
    print(f"| features + HHA (shared normals) | - | {cell(one, 'both')} | {cell(two, 'both')} |")
    if not args.markdown:
        print(
            f"\nthreads seen by rgbd_rs: {one['threads']} and {two['threads']}; 1-min load "
            f"average during the runs: {float(one['load']):.1f} and {float(two['load']):.1f} "
            f"on {os.cpu_count()} cores. Speed-up in parentheses = numpy peer / rgbd_rs (wall, "
            "CPU). CPU ms sums all threads."
        )


if __name__ == "__main__":
    main()
