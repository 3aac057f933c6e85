"""Stereo matching speed and memory: our census SGM (``crates/rgbd-stereo``) against OpenCV's
SGBM (MODE_HH, 7x7 blocks: the matcher ``fuse()`` used) on the rendered 960x540 test scene 1,
128 disparities, measured in one run:

- wall time on 1 and 2 threads (each in its own process: rayon's pool size is fixed at start;
  OpenCV gets ``cv2.setNumThreads`` of the same count), ours with the cost-curve statistics
  (best / second-best aggregated cost) and without;
- time against pixels x disparities (480x270 to 1920x1080, 64 to 256 disparities): ours should
  be linear, i.e. a constant ns per pixel-disparity;
- the peak extra memory of one call (the process's peak RSS during it less its RSS just
  before, in a fresh process; on Linux the peak is reset before the call), beside OpenCV's and
  beside one u16 volume (2 W H D bytes).

    python benches/bench_stereo.py             # tables on stdout
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from _timing import timeit

REPEATS = 5
D = 128


#: The rendered pair, written once by the parent process for the children (so a child's peak
#: memory holds no rendering).
PAIR = Path(tempfile.gettempdir()) / "rgbd_bench_stereo_pair.npz"


def render_pair() -> None:
    from rgbd_rs.data.synth import generate, synth3_rig

    s, _ = generate(0, "test", 1, synth3_rig(0.5))
    np.savez(PAIR, left=s.left, right=s.right)


def scene() -> tuple[np.ndarray, np.ndarray]:
    with np.load(PAIR) as z:
        return z["left"], z["right"]


def resized(img: np.ndarray, w: int, h: int) -> np.ndarray:
    return np.ascontiguousarray(cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA))


def opencv(left: np.ndarray, right: np.ndarray, nd: int) -> np.ndarray:
    """OpenCV's SGBM-HH 7x7 as ``sgm(method="opencv")`` configures it, raw output."""
    from rgbd_rs.fusion.stereo import _sgbm_matcher

    return np.asarray(_sgbm_matcher(0, nd - 1, 7).compute(left, right))


def ours(left: np.ndarray, right: np.ndarray, nd: int, stats: bool) -> object:
    from rgbd_rs.fusion.census import census_match

    return census_match(left, right, reference="left", max_disparity=nd - 1, stats=stats)


def _status(field: str) -> int | None:
    """A ``/proc/self/status`` size in bytes (Linux), else None."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def peak_reset() -> int:
    """Resets the process's peak RSS to its current RSS where Linux allows it (then the peak of
    the next call is measured from here, not from an earlier peak); returns the baseline."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        rss = _status("VmRSS")
        if rss is not None:
            return rss
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def peak() -> int:
    """The process's peak RSS in bytes."""
    hwm = _status("VmHWM")
    return hwm if hwm is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def child(mode: str, threads: int) -> None:
    """Runs in a subprocess with the pool sizes set; prints one JSON line."""
    cv2.setNumThreads(threads)
    left, right = scene()
    if mode == "memory":
        out = {}
        for name in ("ours", "opencv"):
            # A fresh process per matcher keeps the other's allocations out of the peak.
            r = subprocess.run(
                [sys.executable, __file__, "--child", f"memory-{name}", "--threads", "1"],
                capture_output=True,
                text=True,
                check=True,
            )
            out[name] = json.loads(r.stdout.strip().splitlines()[-1])[name]
        print(json.dumps(out))
        return
    if mode.startswith("memory-"):
        name = mode.split("-", 1)[1]
        g_l = cv2.cvtColor(left, cv2.COLOR_RGB2GRAY)
        g_r = cv2.cvtColor(right, cv2.COLOR_RGB2GRAY)
        # The matchers' modules are imported first: their import is not the call's memory.
        import rgbd_rs.fusion.census
        import rgbd_rs.fusion.stereo  # noqa: F401

        before = peak_reset()
        if name == "ours":
            ours(g_l, g_r, D, True)
        else:
            opencv(left, right, D)
        print(json.dumps({name: peak() - before}))
        return
    res: dict[str, float] = {}
    res["opencv"] = timeit(lambda: opencv(left, right, D), REPEATS)
    res["ours"] = timeit(lambda: ours(left, right, D, False), REPEATS)
    res["ours_stats"] = timeit(lambda: ours(left, right, D, True), REPEATS)
    if mode == "scaling":
        for w, h in ((480, 270), (960, 540), (1920, 1080)):
            lft, rgt = resized(left, w, h), resized(right, w, h)
            for nd in (64, 128, 256):
                if nd < w // 2:
                    res[f"{w}x{h}x{nd}"] = timeit(
                        lambda lft=lft, rgt=rgt, nd=nd: ours(lft, rgt, nd, True), 3
                    )
    print(json.dumps(res))


def run_child(mode: str, threads: int) -> dict[str, float]:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
    r = subprocess.run(
        [sys.executable, __file__, "--child", mode, "--threads", str(threads)],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    return dict(json.loads(r.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--child")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.threads)
        return
    render_pair()
    print(f"960x540, {D} disparities, rendered test scene 1; median of {REPEATS} runs")
    print("| threads | OpenCV SGBM-HH 7x7 ms | census SGM ms | + statistics ms | speed-up |")
    print("|---|---|---|---|---|")
    scaling = {}
    for t in (1, 2):
        r = run_child("scaling" if t == 2 else "time", t)
        print(
            f"| {t} | {r['opencv']:.0f} | {r['ours']:.0f} | {r['ours_stats']:.0f} | "
            f"{r['opencv'] / r['ours_stats']:.2f}x |"
        )
        if t == 2:
            scaling = {k: v for k, v in r.items() if "x" in k and k[0].isdigit()}
    print("\nours (with statistics, 2 threads) against pixels x disparities:")
    print("| size x disparities | ms | ns per pixel-disparity |")
    print("|---|---|---|")
    for k, ms in scaling.items():
        w, h, nd = (int(v) for v in k.split("x"))
        print(f"| {k} | {ms:.0f} | {ms * 1e6 / (w * h * nd):.2f} |")
    m = run_child("memory", 1)
    vol = 2 * 960 * 540 * D
    print("\npeak extra memory of one call (960x540, 128 disparities):")
    print("| matcher | MiB | x one u16 volume (2 W H D) |")
    print("|---|---|---|")
    for name, label in (("opencv", "OpenCV SGBM-HH 7x7"), ("ours", "census SGM")):
        print(f"| {label} | {m[name] / 2**20:.0f} | {m[name] / vol:.2f} |")


if __name__ == "__main__":
    main()
