"""The fusion part of ``rgbd demo``: a generated SYNTH3-style scene fused end to end."""

from __future__ import annotations

import time
from pathlib import Path

from rgbd_rs.data.synth import generate, synth3_rig
from rgbd_rs.fusion.evaluate import Sample, evaluate_sample, figure
from rgbd_rs.fusion.fuse import shipped_estimator
from rgbd_rs.viz import save_png

#: The demo's scene: test scene 1 of the default-seed synthetic set, at the thesis' 960x540.
DEMO_SCENE = 1


def run_fusion(out: Path | None, seed: int = 0) -> dict[str, float]:
    """Render a scene, fuse its ToF and stereo data, return the RMS disparity error of every
    method (thesis Table 3.2 protocol) and the seconds each part took."""
    rig = synth3_rig(0.5)
    t0 = time.perf_counter()
    s, _ = generate(seed, "test", DEMO_SCENE, rig)
    t1 = time.perf_counter()
    sample = Sample("demo", s.left, s.right, s.tof_depth, s.tof_amplitude, rig, s.gt_disparity)
    r = evaluate_sample(sample, estimator=shipped_estimator())
    t2 = time.perf_counter()
    if out is not None:
        save_png(out / "fusion.png", figure([sample], [r]))
    return {**r.rms, "render_s": t1 - t0, "evaluate_s": t2 - t1, "pixels": float(r.pixels)}


def report(res: dict[str, float]) -> None:
    """Print :func:`run_fusion`'s numbers."""
    print("ToF-stereo fusion on a rendered SYNTH3-style scene (960x540, ToF 512x424)")
    print(
        f"  rendered in {res['render_s']:.1f} s; ToF upsampling + SGM + confidences (heuristic "
        f"and ConvNet) + 4 LC fusions in {res['evaluate_s']:.1f} s"
    )
    methods = [k for k in res if k not in ("render_s", "evaluate_s", "pixels")]
    rows = ", ".join(f"{m} {res[m]:.2f}" for m in methods)
    print(f"  RMS disparity error (px) on {int(res['pixels'])} common pixels: {rows}")
