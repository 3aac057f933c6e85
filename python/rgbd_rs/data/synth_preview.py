"""The picture of one synthetic scene (``rgbd synth --preview``): left, right, ToF depth,
amplitude, ground truth, and the ToF error caused by each error source alone."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rgbd_rs.data.synth import _rig_poses, generate, synth3_rig, tof_seed
from rgbd_rs.metrics import rms_error
from rgbd_rs.render import ToFModel
from rgbd_rs.viz import (
    NO_DATA_BGR,
    NO_DATA_RGB,
    class_legend,
    grid,
    image_panel,
    map_panel,
    save_png,
)

#: Colour range of the error maps (metres, symmetric).
ERROR_RANGE_M = 0.05
#: Panel width (pixels).
WIDTH = 400


def write_preview(
    path: str | Path, *, seed: int = 0, index: int = 0, scale: float = 0.5
) -> dict[str, float]:
    """Render test scene ``index`` and write the preview PNG; returns per-effect RMS errors (m)."""
    rig = synth3_rig(scale)
    sample, scene = generate(seed, "test", index, rig)
    _, _, to_tof = _rig_poses(rig)
    model = ToFModel()
    noise_seed = tof_seed(seed, "test", index)
    lo = float(np.nanpercentile(sample.gt_depth, 1))
    hi = float(np.nanpercentile(sample.gt_depth, 99))
    panels = [
        image_panel(sample.left[:, :, ::-1], "left camera", width=WIDTH),
        image_panel(sample.right[:, :, ::-1], "right camera (reference)", width=WIDTH),
        map_panel(sample.gt_depth, "true depth (reference)", unit="m", vmin=lo, vmax=hi,
                  width=WIDTH),
        map_panel(sample.tof_gt_depth, "true depth (ToF view)", unit="m", vmin=lo, vmax=hi,
                  width=WIDTH),
        map_panel(sample.tof_depth, "ToF depth (all effects)", unit="m", vmin=lo, vmax=hi,
                  width=WIDTH),
        map_panel(sample.tof_amplitude, "ToF amplitude (sensor units)", unit="", width=WIDTH),
    ]  # fmt: skip
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
        title = f"ToF error: {name}, rms {100 * rms[name]:.1f} cm"
        panels.append(
            map_panel(
                (depth - truth) * 100, title, unit="cm", vmin=-100 * ERROR_RANGE_M,
                vmax=100 * ERROR_RANGE_M, width=WIDTH, colormap=cv2.COLORMAP_JET,
            )
        )  # fmt: skip
    dropout = np.isnan(sample.tof_depth) & np.isfinite(sample.tof_gt_depth)
    rms["dropout_fraction"] = float(dropout.mean())
    pic = np.full((*dropout.shape, 3), 255, np.uint8)
    pic[dropout] = (0, 0, 200)
    pic[~np.isfinite(sample.tof_gt_depth)] = NO_DATA_BGR
    cell = image_panel(pic, f"invalid ToF pixels ({100 * dropout.mean():.1f} %)", width=WIDTH)
    legend = class_legend(
        ["ToF returned nothing", "no surface in view"], [(200, 0, 0), NO_DATA_RGB], WIDTH
    )
    panels.append(np.vstack([cell, legend]))
    save_png(path, grid(panels, columns=4))
    return rms
