"""Smoke test of an installed rgbd_rs (``make wheel`` runs it in the wheel's own venv).

Checks the installed files (typing marker, shipped weights), imports every module of the
package (a module-level import of something the venv lacks fails here), then runs one small
call of each system on synthetic input: fusion (``fuse`` with the shipped confidence ConvNet),
segmentation (``segment`` with the shipped semantic ConvNet) and shapes (``classify`` a box).
Run it from outside the source tree (``python -I``) so the installed package is the one tested.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time
from pathlib import Path


def _step(name: str, t0: float) -> float:
    t = time.perf_counter()
    print(f"  {name}: {t - t0:.1f} s", flush=True)
    return t


def main() -> int:
    import numpy as np

    import rgbd_rs

    t = time.perf_counter()
    pkg = Path(rgbd_rs.__file__).parent
    if "--expect-in" in sys.argv:
        where = sys.argv[sys.argv.index("--expect-in") + 1]
        assert where in str(pkg), f"rgbd_rs imported from {pkg}, expected under {where}"
    assert (pkg / "py.typed").exists(), "py.typed missing from the wheel"
    for name in ("confidence", "shapes_modelnet10", "shapes_modelnet40", "semantic_nyuv2"):
        weights = pkg / "nn" / "weights" / f"{name}.pt"
        assert weights.is_file() and weights.stat().st_size > 1000, f"{weights}: missing"
    print(f"rgbd_rs {rgbd_rs.__version__} from {pkg}")

    walk = pkgutil.walk_packages([str(pkg)], "rgbd_rs.")
    modules = [m.name for m in walk if not m.name.endswith(".__main__")]  # __main__ runs the CLI
    for name in modules:
        importlib.import_module(name)
    t = _step(f"imported all {len(modules)} modules", t)

    cam = rgbd_rs.PinholeCamera(100.0, 100.0, 10.0, 10.0, 20, 20)
    assert cam.project(np.array([[0.0, 0.0, 1.0]])).shape == (1, 2)

    from rgbd_rs.data.synth import generate, synth3_rig
    from rgbd_rs.fusion import fuse

    rig = synth3_rig(0.125)  # 240 x 135
    s = generate(0, "test", 0, rig)[0]
    out = fuse(s.left, s.right, s.tof_depth, s.tof_amplitude, rig)
    ok = np.isfinite(out.disparity) & np.isfinite(s.gt_disparity)
    err = float(np.median(np.abs(out.disparity - s.gt_disparity)[ok]))
    assert ok.mean() > 0.5 and err < 2.0, (ok.mean(), err)
    t = _step(f"fusion: fuse() 240x135, median error {err:.2f} px on {ok.mean():.0%}", t)

    from rgbd_rs.data.synth_indoor import render_indoor_frame
    from rgbd_rs.segmentation import segment

    f = render_indoor_frame(0, 0, width=160, height=120)
    seg = segment(f.rgb, f.depth, f.camera, n_segments=30)
    n = int(np.unique(seg.labels[seg.labels >= 0]).size)
    assert seg.labels.shape == f.depth.shape and n >= 1 and seg.semantic is not None
    t = _step(f"segmentation: segment() 160x120, {n} segments, semantic labels", t)

    from rgbd_rs.meshes import box
    from rgbd_rs.shapes import classify

    label, probs = classify(box((1.0, 0.6, 0.4)))
    assert label in probs and abs(sum(probs.values()) - 1.0) < 1e-3
    _step(f"shapes: classify(box) -> {label!r}", t)
    print("wheel smoke test OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
