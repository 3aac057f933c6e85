"""Over-segmentation speed (and, with --quality, boundary recall against SLIC) on NYUv2 frames.

Speed: rgbd_rs.segmentation.oversegment against a numpy reference written here, in the same
run, each in a fresh process with RAYON_NUM_THREADS (and the BLAS thread count) set to the
same number. The reference is the Fowlkes et al. one-shot Nyström method as in METHOD_NOTES §6
(pinv(A), sqrtm(pinv(A)), Q = A + Asi B Bᵀ Asi, SVD, V = [A; Bᵀ] Asi U L^-1/2, E = V[:, 1:] /
V[:, :1]) with float64 B, followed by the same k-means strategy (k-means++ on a subsample of the
same size, the same number of Lloyd iterations, one assignment of every pixel, blocked matrix
products) and a 4-connected split (scipy.ndimage.label per cluster); same m, n_vectors, k and
k-means input (embedding, features, position). It does not absorb small fragments. Times are
medians after a warm-up. "speed-up" = numpy time / rgbd_rs time.

Quality (--quality): boundary recall (2 px) of our default over-segmentation and of scikit-image
SLIC on RGB at the same segment count (SLIC's n_segments adjusted until its count is within 3 %),
ground truth = connected components of label40 (0 = unlabeled excluded), features =
rgbd_rs.segmentation.features.features. Frames 1, 14, 29, 46, 77 were used to choose the
defaults; the table reports the other frames.

    python benches/bench_oversegment.py                 # speed, 2 threads
    python benches/bench_oversegment.py --threads 1 2
    python benches/bench_oversegment.py --quality 10    # boundary recall on 10 frames
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from _timing import timeit

REPEATS = 3
#: Frames used while choosing the defaults (excluded from the quality table).
TUNING_FRAMES = (1, 14, 29, 46, 77)


def nyu_features(index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(features, rgb, region ground truth) of NYUv2 frame ``index``."""
    from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame, region_ground_truth
    from rgbd_rs.segmentation.features import features

    fr = load_nyuv2_frame(index)
    f = features(fr.rgb, fr.depth, NYUV2_CAMERA).vectors
    return f, fr.rgb, region_ground_truth(fr.label40)


# -- the numpy reference -----------------------------------------------------------------------


def _affinity(x: np.ndarray, y: np.ndarray, sigma: float) -> np.ndarray:
    """exp(-||x_i - y_j||^2 / sigma^2), float64, computed in place."""
    d: np.ndarray = x @ y.T
    d *= -2.0
    d += (x * x).sum(1)[:, None]
    d += (y * y).sum(1)[None, :]
    np.maximum(d, 0.0, out=d)
    d *= -1.0 / sigma**2
    np.exp(d, out=d)
    return d


def numpy_oversegment(
    features: np.ndarray,
    n_segments: int,
    sigma: float,
    n_samples: int,
    n_vectors: int,
    feature_weight: float,
    spatial_weight: float,
    fit_points: int,
    max_iter: int,
    weights: np.ndarray,
    seed: int = 0,
) -> np.ndarray:
    """Fowlkes et al. one-shot Nyström + k-means + connected-component split, in numpy."""
    from scipy import ndimage

    h, w, dim = features.shape
    f = (features * weights).reshape(-1, dim).astype(np.float64)
    valid = ~np.isnan(f).any(1)
    x = f[valid]
    n = len(x)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(n)
    s, rest = perm[:n_samples], perm[n_samples:]
    xs, xr = x[s], x[rest]
    a = _affinity(xs, xs, sigma)
    b = _affinity(xs, xr, sigma)  # m x (n - m), float64
    # Degrees, normalisation, one-shot eigenvectors (METHOD_NOTES §6).
    a_pinv = np.linalg.pinv(a)
    d1 = a.sum(0) + b.sum(1)
    d2 = b.sum(0) + b.sum(1) @ a_pinv @ b
    dhat = 1.0 / np.sqrt(np.concatenate([d1, d2]))
    a = a * np.outer(dhat[:n_samples], dhat[:n_samples])
    b *= dhat[:n_samples, None]
    b *= dhat[None, n_samples:]
    ev, evec = np.linalg.eigh(np.linalg.pinv(a))
    asi = (evec * np.sqrt(np.maximum(ev, 0.0))) @ evec.T
    q = a + asi @ (b @ b.T) @ asi
    u, lam, _ = np.linalg.svd(q)
    proj = asi @ u[:, : n_vectors + 1] / np.sqrt(lam[: n_vectors + 1])
    v = np.concatenate([a @ proj, b.T @ proj])  # [A; Bᵀ] Asi U L^-1/2
    emb = v[:, 1:] / v[:, :1]
    e = np.empty_like(emb)
    e[perm] = emb
    e = (e - e.mean(0)) / e.std()
    pix = np.flatnonzero(valid)
    step = max(1.0, np.sqrt(n / n_segments))
    pos = np.stack([pix % w, pix // w], 1) * (spatial_weight / step)
    z = np.hstack([e, x * feature_weight, pos]).astype(np.float32)
    # k-means++ on a subsample, Lloyd, one assignment pass.
    fit = z[np.sort(rng.permutation(n)[:fit_points])]
    centres = [fit[rng.integers(len(fit))]]
    d2min = ((fit - centres[0]) ** 2).sum(1)
    for _ in range(1, n_segments):
        c = fit[rng.choice(len(fit), p=d2min / d2min.sum())]
        centres.append(c)
        d2min = np.minimum(d2min, ((fit - c) ** 2).sum(1))
    cen = np.array(centres)

    def assign(data: np.ndarray) -> np.ndarray:
        out = np.empty(len(data), np.int64)
        for i in range(0, len(data), 8192):
            blk = data[i : i + 8192]
            out[i : i + 8192] = np.argmin((cen * cen).sum(1)[None] - 2 * blk @ cen.T, 1)
        return out

    lab = assign(fit)
    for _ in range(max_iter):
        for j in range(n_segments):
            mem = lab == j
            if mem.any():
                cen[j] = fit[mem].mean(0)
        new = assign(fit)
        if (new == lab).all():
            break
        lab = new
    full = np.full(h * w, -1, np.int64)
    full[valid] = assign(z)
    full = full.reshape(h, w)
    out = np.full((h, w), -1, np.int32)
    nxt = 0
    for j in range(n_segments):
        comp, nc = ndimage.label(full == j)
        out[comp > 0] = comp[comp > 0] - 1 + nxt
        nxt += nc
    return out


# -- speed -------------------------------------------------------------------------------------


def run_one(which: str, frame: int) -> dict[str, object]:
    import importlib

    from rgbd_rs import _rgbd_rs

    # By name: the package exports a function called ``oversegment`` that shadows the module.
    ov = importlib.import_module("rgbd_rs.segmentation.oversegment")

    f, _, _ = nyu_features(frame)

    def ours() -> np.ndarray:
        return ov.oversegment(f)

    def ref() -> np.ndarray:
        return numpy_oversegment(
            f,
            ov.DEFAULT_N_SEGMENTS,
            ov.DEFAULT_SIGMA,
            ov.DEFAULT_N_SAMPLES,
            ov.DEFAULT_N_VECTORS,
            ov.DEFAULT_FEATURE_WEIGHT,
            ov.DEFAULT_SPATIAL_WEIGHT,
            _rgbd_rs.OVERSEG_DEFAULT_FIT_POINTS,
            20,  # the k-means iteration cap of rgbd-segment (DEFAULT_MAX_ITER)
            ov.default_channel_weights(f.shape[2]),
        )

    run = ours if which == "ours" else ref
    labels = run()
    ms = timeit(run, REPEATS)
    t0 = time.process_time()
    run()
    cpu = (time.process_time() - t0) * 1e3
    return {"which": which, "ms": ms, "cpu_ms": cpu, "segments": int(labels.max()) + 1}


def speed(threads: list[int], frame: int) -> None:
    print(f"NYUv2 frame {frame:04d}, 640x480, defaults (m, n_vectors, k from oversegment)")
    print("wall = median wall time; cpu = CPU time of one call, all threads (robust to load)")
    print(
        f"{'threads':>7} {'numpy wall/cpu (ms)':>20} {'rgbd_rs wall/cpu (ms)':>22} "
        f"{'speed-up':>9} segments"
    )
    for t in threads:
        env = dict(
            os.environ,
            RAYON_NUM_THREADS=str(t),
            OMP_NUM_THREADS=str(t),
            OPENBLAS_NUM_THREADS=str(t),
            MKL_NUM_THREADS=str(t),
        )
        res = {}
        for which in ("numpy", "ours"):
            out = subprocess.run(
                [sys.executable, __file__, "--one", which, "--frame", str(frame)],
                capture_output=True,
                text=True,
                env=env,
                check=True,
            )
            res[which] = json.loads(out.stdout.strip().splitlines()[-1])
        ref, ours = res["numpy"], res["ours"]
        rw, rc = f"{ref['ms']:.0f}", f"{ref['cpu_ms']:.0f}"
        ow, oc = f"{ours['ms']:.0f}", f"{ours['cpu_ms']:.0f}"
        print(
            f"{t:>7} {rw + ' / ' + rc:>20} {ow + ' / ' + oc:>22} "
            f"{float(ref['ms']) / float(ours['ms']):>8.1f}x "
            f"{ours['segments']} (numpy {ref['segments']})"
        )


# -- quality -----------------------------------------------------------------------------------


def quality(n_frames: int) -> None:
    from skimage.segmentation import slic

    from rgbd_rs.data.nyuv2 import nyuv2_frames
    from rgbd_rs.metrics import boundary_recall
    from rgbd_rs.segmentation.oversegment import oversegment

    frames = [i for i in nyuv2_frames() if i not in TUNING_FRAMES][:n_frames]
    print("frame  segments  BR ours  BR SLIC (same count)")
    ours_all, slic_all, counts = [], [], []
    for i in frames:
        f, rgb, gt = nyu_features(i)
        lab = oversegment(f)
        n = int(lab.max()) + 1
        target = n
        for _ in range(5):
            sl = slic(rgb, n_segments=target, start_label=0).astype(np.int32)
            got = len(np.unique(sl))
            if abs(got - n) <= 0.03 * n:
                break
            target = max(2, round(target * n / got))
        sl[lab < 0] = -1  # compare on the same pixels
        r1, r2 = boundary_recall(lab, gt), boundary_recall(sl, gt)
        ours_all.append(r1)
        slic_all.append(r2)
        counts.append(n)
        print(f"{i:04d}  {n:>4}/{got:<4}  {r1:7.3f}  {r2:7.3f}", flush=True)
    wins = sum(a >= b for a, b in zip(ours_all, slic_all, strict=True))
    print(
        f"mean   {np.mean(counts):>4.0f}       {np.mean(ours_all):7.3f}  {np.mean(slic_all):7.3f}"
        f"   (ours >= SLIC on {wins}/{len(frames)})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, nargs="+", default=[2])
    ap.add_argument("--frame", type=int, default=1)
    ap.add_argument("--quality", type=int, default=0, metavar="N", help="frames for the BR table")
    ap.add_argument("--one", choices=["ours", "numpy"], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.frame)))
    elif args.quality:
        quality(args.quality)
    else:
        speed(args.threads, args.frame)


if __name__ == "__main__":
    main()
