"""ToF-stereo fusion speed, measured in one run on a rendered 960x540 scene (test scene 1):

- LC fusion (2 sources: upsampled ToF + SGM, heuristic confidences) in rgbd_rs against a
  straightforward numpy implementation of the same equations (vectorised over pixels, looping
  over window offsets, bincount accumulation). numpy runs on a 16-row strip and is extrapolated
  linearly to the frame (its work per pixel is uniform); both outputs are compared on the strip.
- LC scaling with the window radius, the window stride and the image size.
- Upsampling (extended cross bilateral, segmentation term) against a numpy implementation of the
  same filter; mean-shift segmentation (OpenCV) timed separately.
- The confidence ConvNet's tiled inference (shipped width and the thesis' 128 filters) against
  one whole-image torch forward.
- The stages of ``fuse()`` and its total, wall and CPU (process) time, each native stage beside
  the OpenCV / numpy path it replaced (mean shift, the stereo cost curve) in the same run.

    python benches/bench_fusion.py             # tables on stdout
    python benches/bench_fusion.py --markdown  # README tables
    python benches/bench_fusion.py --stages    # only the fuse() stage table (quicker)
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from _timing import timeit

REPEATS = 3
STRIP_ROWS = 16


def numpy_lc(ref, tgt, sources, radius, gs, gc, gt, trunc, bw, stride, sign, rows):  # type: ignore[no-untyped-def]
    """The LC equations of crates/rgbd-fusion/src/lc.rs, written plainly in numpy."""
    h, w = ref.shape[:2]
    length = 4 * (w - 1) + 1
    k = np.arange(length)
    x0, f = k // 4, (k % 4) / 4.0
    x1 = np.minimum(x0 + 1, w - 1)
    # Rust rounds half away from zero (f32::round); np.rint would round half to even.
    t4 = np.floor((1 - f)[None, :, None] * tgt[:, x0] + f[None, :, None] * tgt[:, x1] + 0.5)
    refi = ref.astype(np.int32)
    t4 = t4.astype(np.int32)
    s_all = np.arange(766) / 3.0
    lut_c = np.exp(-np.minimum(s_all, trunc) / gc)
    lut_t = np.exp(-np.minimum(s_all, trunc) / gt)
    dmin = min(np.nanmin(d) for d, _ in sources)
    dmax = max(np.nanmax(d) for d, _ in sources)
    nb = int((dmax - dmin) / bw) + 3
    ys, xs = np.mgrid[rows, 0:w]
    acc = np.zeros(ys.size * nb)
    accd = np.zeros(ys.size * nb)
    pix = np.arange(ys.size)
    for disp, conf in sources:
        for dy in range(-radius, radius + 1, stride):
            for dx in range(-radius, radius + 1, stride):
                yq, xq = ys + dy, xs + dx
                ok = (yq >= 0) & (yq < h) & (xq >= 0) & (xq < w)
                yq, xq = np.clip(yq, 0, h - 1), np.clip(xq, 0, w - 1)
                d = disp[yq, xq]
                c = np.ones_like(d) if conf is None else conf[yq, xq]
                ok &= np.isfinite(d) & (c > 0)
                sd = sign * 4 * np.nan_to_num(d).astype(np.float32)
                shift = (np.sign(sd) * np.floor(np.abs(sd) + 0.5)).astype(np.int64)
                qpos, ppos = 4 * xq + shift, 4 * xs + shift
                ok &= (qpos >= 0) & (qpos < length) & (ppos >= 0) & (ppos < length)
                qpos, ppos = np.clip(qpos, 0, length - 1), np.clip(ppos, 0, length - 1)
                rp, rq = refi[ys, xs], refi[yq, xq]
                tq, tp = t4[yq, qpos], t4[ys, ppos]
                v = (
                    c
                    * np.exp(-2 * np.hypot(dx, dy) / gs)
                    * lut_c[np.abs(rp - rq).sum(-1)]
                    * lut_c[np.abs(tp - tq).sum(-1)]
                    * lut_t[np.abs(rp - tp).sum(-1)]
                )
                b = ((np.nan_to_num(d) - dmin) / bw).astype(np.int64) + 1
                idx = (pix * nb + b.ravel())[ok.ravel()]
                acc += np.bincount(idx, v.ravel()[ok.ravel()], acc.size)
                accd += np.bincount(idx, (v * d).ravel()[ok.ravel()], acc.size)
    acc, accd = acc.reshape(-1, nb), accd.reshape(-1, nb)
    s = acc.copy()
    s[:, 1:] += acc[:, :-1]
    s[:, :-1] += acc[:, 1:]
    sd = accd.copy()
    sd[:, 1:] += accd[:, :-1]
    sd[:, :-1] += accd[:, 1:]
    s[acc == 0] = -1  # only touched bins compete
    best = s.argmax(1)
    out = sd[pix, best] / s[pix, best]
    out[acc.sum(1) == 0] = np.nan
    return out.reshape(ys.shape).astype(np.float32)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--stages", action="store_true", help="only the fuse() stage table")
    ap.add_argument(
        "--scenes", type=int, default=6, help="fuse() also on this many more test scenes"
    )
    args = ap.parse_args()
    from rgbd_rs import _rgbd_rs
    from rgbd_rs.data.synth import generate, synth3_rig
    from rgbd_rs.fusion import (
        LcParams,
        fuse,
        lc_fuse,
        segment_mean_shift,
        sgm,
        stereo_confidence,
        tof_confidence,
        tof_to_reference,
        upsample_depth,
    )
    from rgbd_rs.geometry import reproject_depth

    rig = synth3_rig(0.5)
    s, _ = generate(0, "test", 1, rig)
    tof = tof_to_reference(s.tof_depth, s.tof_amplitude, rig, s.right)
    st = sgm(s.left, s.right, max_disparity=96)
    ct = tof_confidence(tof.disparity, tof.amplitude)
    cs = stereo_confidence(s.right, s.left, st, max_disparity=96)
    disps, confs = [tof.disparity, st], [ct, cs]
    print(f"threads: {_rgbd_rs.num_threads()}")

    def lc(ref, tgt, ds, cs_, radius, stride):  # type: ignore[no-untyped-def]
        p = LcParams(radius=radius, stride=stride)
        return lambda: lc_fuse(ref, tgt, ds, cs_, params=p)

    rows: list[tuple[str, float, float | None, str]] = []
    scale_rows: list[tuple[str, float]] = []
    if not args.stages:
        # rgbd_rs vs numpy, 39x39-equivalent window at 960x540 (radius 10), stride 1 and 2.
        y0 = 270 - STRIP_ROWS // 2
        strip = slice(y0, y0 + STRIP_ROWS)
        for stride in (1, 2):
            ms = timeit(lc(s.right, s.left, disps, confs, 10, stride), REPEATS)
            fused, _ = lc_fuse(
                s.right, s.left, disps, confs, params=LcParams(radius=10, stride=stride)
            )
            lp = LcParams(radius=10)
            gs = lp.resolved(960)[1]
            t = time.perf_counter()
            # The defaults' constants and bin width (not literals: they follow LcParams).
            ref_out = numpy_lc(
                s.right,
                s.left,
                list(zip(disps, confs, strict=True)),
                10,
                gs,
                lp.gamma_c,
                lp.gamma_t,
                lp.truncation,
                lp.bin_width,
                stride,
                1,
                strip,
            )
            np_strip = time.perf_counter() - t
            np_ms = np_strip * 1e3 * 540 / STRIP_ROWS
            a, b = fused[strip], ref_out
            both = np.isfinite(a) & np.isfinite(b)
            agree = float(np.mean(np.abs(a[both] - b[both]) < 1e-3))
            rows.append(
                (
                    f"LC fusion 960x540, 21x21 window (= 39x39 at full res), stride {stride}",
                    ms,
                    np_ms,
                    f"numpy strip {np_strip:.1f} s x {540 // STRIP_ROWS}; "
                    f"outputs agree on {agree:.1%} of the strip",
                )
            )
        # Scaling with the window.
        for radius, stride in ((5, 1), (10, 1), (19, 1), (10, 2), (19, 2), (19, 3)):
            ms = timeit(lc(s.right, s.left, disps, confs, radius, stride), 1)
            scale_rows.append(
                (f"960x540, radius {radius} ({2 * radius + 1}^2), stride {stride}", ms)
            )
        # Scaling with the image size (the same scene resized; window scaled with it).
        for f in (0.5, 2.0):
            size = (round(960 * f), round(540 * f))
            rr, ll = (
                cv2.resize(im, size, interpolation=cv2.INTER_AREA) for im in (s.right, s.left)
            )
            ds = [cv2.resize(d, size, interpolation=cv2.INTER_NEAREST) * f for d in disps]
            cc = [cv2.resize(c, size, interpolation=cv2.INTER_NEAREST) for c in confs]
            radius = max(1, round(10 * f))
            ms = timeit(lc(rr, ll, ds, cc, radius, 2), 1)
            scale_rows.append((f"{size[0]}x{size[1]}, radius {radius}, stride 2", ms))
        # Upsampling.
        labels = segment_mean_shift(s.right)
        rep = reproject_depth(s.tof_depth, rig.tof, rig.reference_camera, rig.tof_to_reference)
        up_ms = timeit(lambda: upsample_depth(rep.depth, s.right, labels), REPEATS)
        plain_ms = timeit(lambda: upsample_depth(rep.depth, s.right), REPEATS)
        ms_ms = timeit(lambda: segment_mean_shift(s.right), REPEATS)
        t = time.perf_counter()
        np_up = numpy_upsample(rep.depth, s.right, labels)
        np_up_ms = (time.perf_counter() - t) * 1e3
        ours = upsample_depth(rep.depth, s.right, labels)
        both = np.isfinite(ours) & np.isfinite(np_up)
        dev = np.abs(ours[both] - np_up[both]) / np_up[both]
        rows.append(
            (
                "Upsampling 960x540 (radius 5, segmentation term)",
                up_ms,
                np_up_ms,
                f"{np.mean(dev < 1e-4):.2%} of pixels within 1e-4 relative (f32 vs f64)",
            )
        )
        rows.append(("Upsampling 960x540 without labels (joint bilateral)", plain_ms, None, ""))
        rows.append(
            ("Mean-shift segmentation (native pyrMeanShiftFiltering + labels)", ms_ms, None, "")
        )
        # The confidence ConvNet: our tiled inference vs one whole-image torch forward, at the
        # shipped width and at the thesis' 128 filters (random weights: the speed does not depend
        # on them).
        import torch

        from rgbd_rs.fusion.clues import _normalise, compute_clues
        from rgbd_rs.nn.confidence import ConfidenceEstimator, ConfidenceNet, predict

        clues = _normalise(
            compute_clues(s.right, s.left, tof.disparity, tof.amplitude, st), np.ones(4, np.float32)
        )
        shipped = ConfidenceEstimator.load().net.width
        for width in sorted({shipped, 128}):
            net = ConfidenceNet(width)
            ours = timeit(lambda net=net: predict(net, clues), 1)  # type: ignore[misc]

            def whole(net: ConfidenceNet = net) -> None:
                with torch.inference_mode():
                    net(torch.from_numpy(clues)[None])

            rows.append(
                (
                    f"Confidence ConvNet 960x540, width {width}"
                    + (" (shipped)" if width == shipped else " (thesis)"),
                    ours,
                    timeit(whole, 1),
                    "reference column: one whole-image torch forward (no tiling)",
                )
            )
    # The stages of fuse() on this scene: wall and CPU (process) time of each, the native stage
    # beside the OpenCV / numpy path it replaced (same run; the best of REPEATS after a warm-up).
    import rgbd_rs.fusion.confidence as conf_mod
    import rgbd_rs.fusion.upsample as up_mod
    from rgbd_rs.fusion.fuse import FUSION_CENSUS, shipped_estimator
    from rgbd_rs.fusion.stereo import _cost_curve_stats_numpy, _whole_steps
    from rgbd_rs.nn.confidence import _resolve_precision

    def old_segmentation(image, **_: object):  # type: ignore[no-untyped-def]
        filtered = cv2.pyrMeanShiftFiltering(image, 8, 16)
        return _rgbd_rs.label_regions(np.ascontiguousarray(filtered), 2.0)[0]

    def old_cost_curve(ref, tgt, disp, *, target_sign=1, max_disparity=128):  # type: ignore[no-untyped-def]
        g = [cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in (ref, tgt)]
        return _cost_curve_stats_numpy(g[0], g[1], disp, target_sign, max_disparity, 7)

    def old_path(fn):  # type: ignore[no-untyped-def]
        """``fn`` run with OpenCV mean shift and the numpy cost curve patched back in."""

        def run():  # type: ignore[no-untyped-def]
            seg, cc = up_mod.segment_mean_shift, conf_mod.cost_curve_stats
            up_mod.segment_mean_shift, conf_mod.cost_curve_stats = old_segmentation, old_cost_curve
            try:
                return fn()
            finally:
                up_mod.segment_mean_shift, conf_mod.cost_curve_stats = seg, cc

        return run

    grey_r, grey_l = (cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in (s.right, s.left))
    np.testing.assert_array_equal(
        _rgbd_rs.mean_shift_filter(s.right, 8, 16), cv2.pyrMeanShiftFiltering(s.right, 8, 16)
    )
    estimator = shipped_estimator()
    ct_n, cs_n = estimator(s.right, s.left, tof.disparity, tof.amplitude, st, reference="right")
    labels = segment_mean_shift(s.right)
    rep_amp = reproject_depth(
        s.tof_depth, rig.tof, rig.reference_camera, rig.tof_to_reference, channels=s.tof_amplitude
    )
    assert rep_amp.channels is not None
    sparse = rep_amp.depth
    fuse_args = (s.left, s.right, s.tof_depth, s.tof_amplitude, rig)
    # The stages at the search range fuse() derives on this scene (SGBM's time is linear in it).
    dmax = fuse(*fuse_args).max_disparity

    def census_sgm() -> np.ndarray:
        """The stereo map fuse() computes: the census matcher as fuse runs it."""
        return sgm(
            s.left,
            s.right,
            max_disparity=min(_whole_steps(dmax), s.left.shape[1] - 1),
            method="census",
            params=FUSION_CENSUS,
        )

    st_f = census_sgm()
    stages = [
        (
            "mean-shift filter (pyrMeanShiftFiltering, sp 8, sr 16)",
            lambda: _rgbd_rs.mean_shift_filter(s.right, 8, 16),
            lambda: cv2.pyrMeanShiftFiltering(s.right, 8, 16),
        ),
        ("segment_mean_shift (filter + region labels)", lambda: segment_mean_shift(s.right), None),
        (
            "reprojection (ToF -> colour, amplitude carried)",
            lambda: reproject_depth(
                s.tof_depth,
                rig.tof,
                rig.reference_camera,
                rig.tof_to_reference,
                channels=s.tof_amplitude,
            ),
            None,
        ),
        (
            "upsampling (depth + amplitude, segmentation term)",
            lambda: upsample_depth(sparse, s.right, labels, channel=rep_amp.channels),
            None,
        ),
        (
            "tof_to_reference (reprojection + upsampling; old path: with the mean-shift "
            "segmentation, OpenCV's)",
            lambda: tof_to_reference(s.tof_depth, s.tof_amplitude, rig, s.right),
            old_path(
                lambda: tof_to_reference(
                    s.tof_depth, s.tof_amplitude, rig, s.right, segmentation=True
                )
            ),
        ),
        (
            f"census SGM (fuse()'s matcher: 4 paths, LR check; the scene's range {dmax} px)",
            census_sgm,
            lambda: sgm(s.left, s.right, max_disparity=dmax),
        ),
        (
            "OpenCV SGBM-HH 7x7 alone (the peer; fuse() must not take longer, issue 28)",
            lambda: sgm(s.left, s.right, max_disparity=dmax),
            None,
        ),
        (
            "tof_to_reference beside census SGM (fuse()'s first phase, two threads)",
            lambda: overlapped(
                lambda: tof_to_reference(s.tof_depth, s.tof_amplitude, rig, s.right),
                census_sgm,
            ),
            None,
        ),
        (
            f"confidence ConvNet (default: shipped width, {_resolve_precision('auto')}; "
            "old path: float32)",
            lambda: estimator(
                s.right, s.left, tof.disparity, tof.amplitude, st_f, reference="right"
            ),
            lambda: estimator.with_precision("float32")(
                s.right, s.left, tof.disparity, tof.amplitude, st_f, reference="right"
            ),
        ),
        (
            "LC fusion (defaults, ConvNet confidences)",
            lambda: lc_fuse(s.right, s.left, disps, [ct_n, cs_n]),
            None,
        ),
        (
            "fuse() total (default: ConvNet)",
            lambda: fuse(*fuse_args),
            old_path(lambda: fuse(*fuse_args, stereo="opencv")),
        ),
        (
            "stereo cost curve (heuristic confidence only)",
            lambda: _rgbd_rs.cost_curve_stats(grey_r, grey_l, st_f, 1, dmax, 7),
            lambda: _cost_curve_stats_numpy(grey_r, grey_l, st_f, 1, dmax, 7),
        ),
        (
            "stereo confidence (cost curve + ratios)",
            lambda: stereo_confidence(s.right, s.left, st_f, max_disparity=dmax),
            old_path(lambda: conf_mod.stereo_confidence(s.right, s.left, st_f, max_disparity=dmax)),
        ),
        ("ToF confidence", lambda: tof_confidence(tof.disparity, tof.amplitude), None),
        (
            "LC fusion (defaults, heuristic confidences)",
            lambda: lc_fuse(s.right, s.left, disps, confs),
            None,
        ),
        (
            "fuse() total (confidence='heuristic')",
            lambda: fuse(*fuse_args, confidence="heuristic"),
            old_path(lambda: fuse(*fuse_args, confidence="heuristic", stereo="opencv")),
        ),
    ]
    stage_rows = [
        (name, timed(fn, REPEATS), None if old is None else timed(old, REPEATS))
        for name, fn, old in stages
    ]
    # fuse() on more generated test scenes: its time follows the scene's disparity range.
    scene_rows = []
    for seed in range(1, args.scenes + 1):
        sc, _ = generate(seed, "test", 1, rig)
        sargs = (sc.left, sc.right, sc.tof_depth, sc.tof_amplitude, rig)
        scene_rows.append((seed, fuse(*sargs).max_disparity, timed(lambda a=sargs: fuse(*a), 1)))
    if args.markdown:
        print("| stage | rgbd_rs (ms) | reference (ms) | vs reference | note |")
        print("|---|---:|---:|---:|---|")
        for name, ms, ref, note in rows:
            r = f"{ref:.0f}" if ref else "-"
            x = f"{ref / ms:.0f}x" if ref else "-"
            print(f"| {name} | {ms:.0f} | {r} | {x} | {note} |")
        print("\n| LC scaling | ms |\n|---|---:|")
        for name, ms in scale_rows:
            print(f"| {name} | {ms:.0f} |")
        print(
            "\n| fuse() stage, 960x540 | wall ms | CPU ms | OpenCV/numpy path wall ms | CPU ms |"
            "\n|---|---:|---:|---:|---:|"
        )
        for name, (w, c), old in stage_rows:
            o = "- | -" if old is None else f"{old[0]:.0f} | {old[1]:.0f}"
            print(f"| {name} | {w:.0f} | {c:.0f} | {o} |")
        if scene_rows:
            print(
                "\n| fuse() (ConvNet), generated test scene | search range (px) | wall ms"
                " | CPU ms |"
            )
            print("|---|---:|---:|---:|")
            for seed, rng, (w, c) in scene_rows:
                print(f"| seed {seed} | {rng} | {w:.0f} | {c:.0f} |")
    else:
        for name, ms, ref, note in rows:
            x = f"  numpy {ref:.0f} ms ({ref / ms:.0f}x)" if ref else ""
            print(f"{name:70s} {ms:8.0f} ms{x}  {note}")
        for name, ms in scale_rows:
            print(f"  scaling: {name:48s} {ms:8.0f} ms")
        for name, (w, c), old in stage_rows:
            o = (
                ""
                if old is None
                else f"   (OpenCV/numpy path: wall {old[0]:6.0f}, CPU {old[1]:6.0f})"
            )
            print(f"  fuse() stage: {name:58s} wall {w:6.0f} ms, CPU {c:6.0f} ms{o}")
        for seed, rng, (w, c) in scene_rows:
            print(
                f"  fuse() on test scene seed {seed}: range {rng:3d} px, "
                f"wall {w:6.0f}, CPU {c:6.0f} ms"
            )


def overlapped(first, second):  # type: ignore[no-untyped-def]
    """``first()`` here while ``second()`` runs on a worker thread, as fuse() does."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=1) as pool:
        later = pool.submit(second)
        first()
        later.result()


def timed(fn, repeats):  # type: ignore[no-untyped-def]
    """``(wall ms, CPU ms)`` of ``fn``: the run with the least wall time of ``repeats`` after one
    warm-up. CPU is the process time of all threads (rayon, OpenCV, torch) during that run."""
    fn()
    best = (float("inf"), float("inf"))
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        run = ((time.perf_counter() - w0) * 1e3, (time.process_time() - c0) * 1e3)
        best = min(best, run)
    return best


def numpy_upsample(sparse, image, labels, radius=5, ss=3.0, sc=10.0, sr=0.02):  # type: ignore[no-untyped-def]
    """The extended cross bilateral filter of crates/rgbd-fusion/src/upsample.rs in numpy."""
    h, w = sparse.shape
    img = image.astype(np.float32)
    pad = radius
    z = np.pad(sparse, pad, constant_values=np.nan)
    im = np.pad(img, ((pad, pad), (pad, pad), (0, 0)))
    lab = np.pad(labels, pad, constant_values=-1)
    offs = [(dy, dx) for dy in range(-radius, radius + 1) for dx in range(-radius, radius + 1)]

    def window(dy, dx):  # type: ignore[no-untyped-def]
        sl = (slice(pad + dy, pad + dy + h), slice(pad + dx, pad + dx + w))
        zq = z[sl]
        ok = np.isfinite(zq) & (zq > 0)
        gs = np.exp(-(dx * dx + dy * dy) / (2 * ss * ss))
        dc = np.abs(im[sl] - img).sum(-1) / 3
        gc = np.exp(-dc * dc / (2 * sc * sc))
        return zq, ok, gs, gc, lab[sl] == labels

    sw_same = np.zeros((h, w))
    sz_same = np.zeros((h, w))
    sw_all = np.zeros((h, w))
    sz_all = np.zeros((h, w))
    for dy, dx in offs:
        zq, ok, gs, gc, same = window(dy, dx)
        zq0 = np.where(ok, zq, 0)
        wsame = np.where(ok & same, gs * gc, 0)
        sw_same += wsame
        sz_same += wsame * zq0
        wall = np.where(ok, gs, 0)
        sw_all += wall
        sz_all += wall * zq0
    with np.errstate(invalid="ignore", divide="ignore"):
        z0 = np.where(sw_same > 0, sz_same / sw_same, sz_all / sw_all)
    sw = np.zeros((h, w))
    sz = np.zeros((h, w))
    for dy, dx in offs:
        zq, ok, gs, gc, same = window(dy, dx)
        zq0 = np.where(ok, zq, 0)
        with np.errstate(invalid="ignore"):
            dz = (zq0 - z0) / z0
            wgt = np.where(same, gs * gc, gs * np.exp(-dz * dz / (2 * sr * sr)))
        wgt = np.where(ok, wgt, 0)
        sw += wgt
        sz += wgt * zq0
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(sw > 0, sz / sw, z0).astype(np.float32)


if __name__ == "__main__":
    main()
