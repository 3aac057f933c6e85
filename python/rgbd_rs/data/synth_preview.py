"""The picture of one synthetic scene (``rgbd synth --preview``): left, right, ToF depth,
amplitude, ground truth, and the ToF error caused by each error source alone."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rgbd_rs.data.synth import _rig_poses, generate, synth3_rig, tof_seed
from rgbd_rs.metrics import rms_error
from rgbd_rs.render import ToFModel
from rgbd_rs.viz import as_bgr, colorize, save_png, tile

#: Colour range of the error maps (metres, symmetric).
ERROR_RANGE_M = 0.05


def write_preview(
    path: str | Path, *, seed: int = 0, index: int = 0, scale: float = 0.5
) -> dict[str, float]:
    """Render test scene ``index`` and write the preview PNG; returns per-effect RMS errors (m)."""
    rig = synth3_rig(scale)
    sample, scene = generate(seed, "test", index, rig)
    _, _, to_tof = _rig_poses(rig)
    model = ToFModel()
    noise_seed = tof_seed(seed, "test", index)
    images = [
        as_bgr(sample.left),
        as_bgr(sample.right),
        colorize(sample.gt_depth),
        colorize(sample.tof_gt_depth),
        colorize(sample.tof_depth),
        colorize(sample.tof_amplitude),
    ]
    labels = [
        "left",
        "right (reference)",
        "GT depth (reference)",
        "GT depth (ToF view)",
        "ToF depth (all effects)",
        "ToF amplitude",
    ]
    rms: dict[str, float] = {}
    cases = [
        ("mixed", model.only("mixed")),
        ("multipath", model.only("multipath")),
        ("noise", model.only("noise")),
    ]
    frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name, m in cases:
        f = scene.tof(rig.tof, to_tof, m, seed=noise_seed)
        frames[name] = (f.depth, f.truth)
    # The sample's own ToF frame already has every effect (same default model, same seed).
    frames["all"] = (sample.tof_depth, sample.tof_gt_depth)
    for name, (depth, truth) in frames.items():
        rms[name] = rms_error(depth, truth)
        err = depth - truth
        images.append(colorize(err, -ERROR_RANGE_M, ERROR_RANGE_M, colormap=cv2.COLORMAP_JET))
        labels.append(f"ToF error: {name} (rms {100 * rms[name]:.1f} cm)")
    dropout = np.isnan(sample.tof_depth) & np.isfinite(sample.tof_gt_depth)
    rms["dropout_fraction"] = float(dropout.mean())
    images.append(as_bgr((dropout * 255).astype(np.uint8)))
    labels.append(f"invalid ToF pixels ({100 * dropout.mean():.1f} %)")
    save_png(path, tile(images, labels, columns=4, width=400))
    return rms
