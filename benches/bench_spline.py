"""Spline-fitting speed: rgbd_rs.surface against scipy's LSQBivariateSpline, in the same run.

scipy fits one scalar graph surface z(u, v) (FITPACK, one thread); rgbd_rs fits the three
coordinates X, Y, Z of an organised point cloud with the same knot count, which is strictly more
work. Each configuration runs in a fresh process with RAYON_NUM_THREADS set. Times are medians
after a warm-up (rgbd_rs: also the minimum, the least disturbed run on a shared machine).
"vs scipy" = scipy time / rgbd_rs median time (> 1: rgbd_rs is faster).

A fit's maps are computed when first read (``SurfaceFit``), inside the segment's box only: the
segment rows time the fit alone and then the fit with its maps read (box-sized with
``crop=True``, and image-sized); the view rows read the curvature maps (``fit.k1``), so they time
fit + maps as scipy's column times its fit.

    python benches/bench_spline.py            # 1 and 2 threads
    python benches/bench_spline.py --markdown # the README table
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

import numpy as np

from _timing import timeit

REPEATS = 15


def ours_ms(fn: Callable[[], object], repeats: int = REPEATS) -> dict[str, float]:
    """rgbd_rs's median and minimum wall time (ms) of ``fn`` after one warm-up: on a shared
    machine the minimum is the least disturbed run."""
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t) * 1e3)
    return {"ours": statistics.median(times), "min": min(times)}


def cloud(w: int, h: int) -> np.ndarray:
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    z = 2.0 + 0.3 * np.sin(u / 40.0) * np.cos(v / 30.0)
    x, y = (u - w / 2) / 525.0 * z, (v - h / 2) / 525.0 * z
    return np.ascontiguousarray(np.stack([x, y, z], -1), dtype=np.float32)


def run_one() -> list[dict[str, object]]:
    from scipy.interpolate import LSQBivariateSpline

    from rgbd_rs.surface import DEFAULT_TEST_WINDOW, SegmentFits, fit_grid, fit_mask

    rows: list[dict[str, object]] = []
    w, h = 640, 480
    pts = cloud(w, h)
    # 10k-pixel segment, 10x10 knot cells (scipy: 10x10 interior knots over the same box).
    mask = np.zeros((h, w), bool)
    mask[100:200, 200:300] = True
    ours = ours_ms(lambda: fit_mask(pts, mask, spacing=10.0, with_dof=False), 31)
    crop = ours_ms(lambda: fit_mask(pts, mask, spacing=10.0, with_dof=False, crop=True).k1, 31)
    full = ours_ms(lambda: fit_mask(pts, mask, spacing=10.0, with_dof=False).k1, 31)
    v, u = np.nonzero(mask)
    z = pts[mask][:, 2].astype(np.float64)
    tx = np.linspace(200, 300, 12)[1:-1]
    ty = np.linspace(100, 200, 12)[1:-1]
    bbox = [200, 300, 100, 200]
    uf, vf = u.astype(float), v.astype(float)
    scipy_ms = timeit(lambda: LSQBivariateSpline(uf, vf, z, tx, ty, bbox=bbox), REPEATS)
    rows.append({"case": "10k-pixel segment, 10x10 knot spans", **ours, "scipy": scipy_ms})
    rows.append({"case": "10k-pixel segment + box-sized maps (crop=True)", **crop, "scipy": None})
    rows.append({"case": "10k-pixel segment + 640x480 maps", **full, "scipy": None})
    # All segments of a 640x480 frame: 300 tiles of 32x32 pixels, 16-pixel spacing.
    labels = ((np.arange(h)[:, None] // 32) * 20 + np.arange(w)[None, :] // 32).astype(np.int32)
    ours = ours_ms(lambda: SegmentFits(pts, labels, spacing=16.0, criterion="gcv"))
    seam = ours_ms(lambda: SegmentFits(pts, labels, spacing=16.0))
    alone = ours_ms(lambda: SegmentFits(pts, labels, surfaces=False))
    one = labels == 0
    vv, uu = np.nonzero(one)
    zz = pts[one][:, 2].astype(np.float64)
    t1 = np.array([16.0])
    u1, v1 = uu.astype(float), vv.astype(float)
    per = timeit(lambda: LSQBivariateSpline(u1, v1, zz, t1, t1, bbox=[0, 32, 0, 32]), REPEATS)
    rows.append({"case": "300 segments of a 640x480 frame (with dof)", **ours, "scipy": per * 300})
    rows.append(
        {
            "case": "300 segments of a 640x480 frame, seam test (default)",
            **seam,
            "scipy": None,
        }
    )
    rows.append(
        {"case": "300 segments of a 640x480 frame, seam test alone", **alone, "scipy": None}
    )
    # The merge test on every pair of 4-adjacent tiles (565 pairs), per pair.
    tiles = SegmentFits(pts, labels, spacing=16.0)
    adj = [(i, i + 1) for i in range(300) if i % 20 != 19] + [(i, i + 20) for i in range(280)]
    pairs = ours_ms(lambda: [tiles.should_merge(i, j) for i, j in adj], 5)
    per_pair = {k: t / len(adj) for k, t in pairs.items()}
    rows.append({"case": "seam should_merge, per adjacent tile pair", **per_pair, "scipy": None})
    # union_error of two adjacent 5k-pixel segments.
    pair = np.full((h, w), -1, np.int32)
    pair[100:171, 100:171] = 0
    pair[100:171, 171:242] = 1
    fits = SegmentFits(pts, pair, spacing=16.0, criterion="gcv")
    ours = ours_ms(lambda: fits.union_error(0, 1), 201)
    rows.append({"case": "union_error, two 5k-pixel segments", **ours, "scipy": None})
    fits = SegmentFits(pts, pair, spacing=16.0)
    ours = ours_ms(lambda: fits.union_error(0, 1), 201)
    rows.append({"case": "union_error (seam), two 5k-pixel segments", **ours, "scipy": None})
    # The seam test's union with a large segment: exact union fit vs the local one (default).
    big = np.full((h, w), -1, np.int32)
    big[40:440, 100:500] = 0  # 160k pixels
    big[200:240, 500:540] = 1  # 1.6k pixels beside it
    halves = np.full((h, w), -1, np.int32)
    halves[40:440, 100:300] = 0  # 80k pixels
    halves[40:440, 300:500] = 1  # 80k pixels, a 400-pixel seam
    for name, lab in (("160k + 1.6k-pixel segments", big), ("two 80k-pixel halves", halves)):
        for win, how in ((None, "exact"), (DEFAULT_TEST_WINDOW, "local")):
            fits = SegmentFits(pts, lab, surfaces=False, test_window=win)
            ours = ours_ms(lambda fits=fits: fits.union_error(0, 1), 51)  # type: ignore[misc]
            case = f"seam union_error, {name}, {how}"
            rows.append({"case": case, **ours, "scipy": None})
    # A 320x320 depth view with curvature maps (shape pipeline), 16 and 8-pixel spacing.
    view = cloud(320, 320)
    vv, uu = np.mgrid[0:320, 0:320]
    uv, vvf = uu.ravel().astype(float), vv.ravel().astype(float)
    zv = view[..., 2].ravel().astype(np.float64)
    for s in (16.0, 8.0):
        ours = ours_ms(lambda s=s: fit_grid(view, spacing=s).k1)  # type: ignore[misc]
        knots = np.arange(1, int(np.ceil(320 / s))) * s
        sp = timeit(
            lambda knots=knots: LSQBivariateSpline(  # type: ignore[misc]
                uv, vvf, zv, knots, knots, bbox=[0, 320, 0, 320]
            ),
            repeats=3,
        )
        rows.append({"case": f"320x320 view + curvature maps, spacing {s:g}", **ours, "scipy": sp})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--markdown", action="store_true", help="print the README table")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(run_one()))
        return
    results = {}
    for threads in (1, 2):
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
        cmd = [sys.executable, __file__, "--child"]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        results[threads] = json.loads(out.stdout.strip().splitlines()[-1])
    print(
        "| case | scipy ms | rgbd_rs ms, 1 thread: median (min) | vs scipy "
        "| rgbd_rs ms, 2 threads: median (min) | vs scipy |"
    )
    print("|" + "---|" * 6)
    for r1, r2 in zip(results[1], results[2], strict=True):
        sp = r1["scipy"]
        sp_s = f"{sp:.1f}" if sp else "(no equivalent)"
        r_1 = f"{sp / r1['ours']:.0f}x" if sp else "-"
        r_2 = f"{sp / r2['ours']:.0f}x" if sp else "-"
        t_1 = f"{r1['ours']:.2f} ({r1['min']:.2f})"
        t_2 = f"{r2['ours']:.2f} ({r2['min']:.2f})"
        print(f"| {r1['case']} | {sp_s} | {t_1} | {r_1} | {t_2} | {r_2} |")
    if not args.markdown:
        print("\nscipy fits z only (1 channel, 1 thread); rgbd_rs fits X, Y, Z.")
        load = os.getloadavg()
        print(f"load average after: {load[0]:.1f} {load[1]:.1f} (other processes inflate times)")


if __name__ == "__main__":
    main()
