"""The segmentation and shape parts of ``rgbd demo``: a real NYUv2 frame segmented and labeled
with the shipped semantic ConvNet, and the shared meshes classified with the shipped shape
weights (both need ../shared/data; skipped without it)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rgbd_rs import metrics
from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame, region_ground_truth
from rgbd_rs.data.paths import data_root
from rgbd_rs.segmentation.pipeline import Segmentation
from rgbd_rs.viz import save_png

#: The NYUv2 frame of the demo (the first of the test split).
DEMO_FRAME = 46
#: The meshes the demo classifies (in ../shared/data/meshes).
#: Meshes of the shared data and their up axes (the networks expect z up; the bunny is y-up).
DEMO_MESHES = (
    ("modelnet10_bathtub_0005.off", "z"),
    ("stanford_bunny.off", "y"),
    ("pyvista_airplane.ply", "z"),
)


def run_segmentation(out: Path | None) -> dict[str, float] | None:
    """Segment and label :data:`DEMO_FRAME`; None without the shared data."""
    from rgbd_rs.segmentation import segment

    if data_root() is None:
        return None
    f = load_nyuv2_frame(DEMO_FRAME)
    t = time.perf_counter()
    r = segment(f.rgb, f.depth, NYUV2_CAMERA)
    seconds = time.perf_counter() - t
    gt = region_ground_truth(f.label40)
    res = {
        "seconds": seconds,
        "over": float(np.unique(r.over[r.over >= 0]).size),
        "segments": float(r.merge.n_segments),
        "voi": metrics.variation_of_information(r.labels, gt),
        "ri": metrics.rand_index(r.labels, gt),
    }
    if r.network_labels is not None and r.refined_labels is not None:
        res["net_acc"] = metrics.pixel_accuracy(r.network_labels, f.label13)
        res["refined_acc"] = metrics.pixel_accuracy(r.refined_labels, f.label13)
    if out is not None:
        save_png(out / "segmentation.png", segmentation_figure(f.rgb, r, f.label13))
    return res


def segmentation_figure(rgb: np.ndarray, r: Segmentation, label13: np.ndarray) -> np.ndarray:
    """Colour, the segments' boundaries, the refined classes and the ground truth, 640 px
    panels, the class images with a legend of NYUv2's 13 classes."""
    from rgbd_rs.data.nyuv2 import LABEL13_NAMES
    from rgbd_rs.data.synth_indoor import LABEL13_COLORS
    from rgbd_rs.viz import class_picture, grid, image_panel, outline_segments

    panels = [
        image_panel(np.ascontiguousarray(rgb[..., ::-1]), "colour", width=640),
        image_panel(outline_segments(rgb, r.labels), f"{r.merge.n_segments} segments", width=640),
    ]
    if r.semantic is not None:
        for labels, title in (
            (r.semantic, "classes (ConvNet + segment refinement)"),
            (label13.astype(np.int64), "ground truth (NYUv2 13 classes)"),
        ):
            panels.append(class_picture(labels, LABEL13_NAMES, LABEL13_COLORS, title, width=640))
    return grid(panels, columns=2)


def run_shapes() -> list[tuple[str, str, float]] | None:
    """Classify :data:`DEMO_MESHES` with the shipped weights: (file, class, probability)."""
    from rgbd_rs.shapes import classify

    root = data_root()
    if root is None:
        return None
    rows = []
    for name, up in DEMO_MESHES:
        best, probs = classify(root / "meshes" / name, up=up)
        rows.append((name if up == "z" else f"{name} ({up} up)", best, probs[best]))
    return rows


def report(seg: dict[str, float] | None, shapes: list[tuple[str, str, float]] | None) -> None:
    """Print :func:`run_segmentation` and :func:`run_shapes`."""
    if seg is None:
        print("NYUv2 frame: shared data not found (set RGBD_DATA) - skipped")
    else:
        print(f"RGB-D segmentation + semantic labeling of NYUv2 frame {DEMO_FRAME:04d} (real data)")
        print(
            f"  {int(seg['over'])} over-segments -> {int(seg['segments'])} segments in "
            f"{seg['seconds']:.1f} s; VoI {seg['voi']:.2f}, RI {seg['ri']:.3f} against the "
            "region ground truth"
        )
        if "net_acc" in seg:
            print(
                f"  pixel accuracy (13 classes): ConvNet {seg['net_acc']:.1%}, after segment "
                f"refinement {seg['refined_acc']:.1%}"
            )
    if shapes is None:
        print("Meshes: shared data not found (set RGBD_DATA) - skipped")
        return
    print("Shape classification of real meshes (shipped ModelNet40 weights)")
    for name, best, p in shapes:
        print(f"  {name}: {best} ({p:.0%})")
