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


def run_shapes(out: Path | None = None) -> list[tuple[str, str, float]] | None:
    """Classify :data:`DEMO_MESHES` with the shipped weights: (file, class, probability); with
    ``out``, ``out/shapes.png``: the 15 network inputs of the first mesh (:func:`shape_figure`)."""
    from rgbd_rs.shapes import classify

    root = data_root()
    if root is None:
        return None
    rows = []
    for name, up in DEMO_MESHES:
        best, probs = classify(root / "meshes" / name, up=up)
        rows.append((name if up == "z" else f"{name} ({up} up)", best, probs[best]))
    if out is not None:
        name, up = DEMO_MESHES[0]
        save_png(out / "shapes.png", shape_figure(root / "meshes" / name, up, rows[0][1:]))
    return rows


def shape_figure(path: Path, up: str, result: tuple[str, float]) -> np.ndarray:
    """BGR picture of what the shape network reads for the mesh at ``path`` (its shipped input
    spec, each map normalised as the network gets it): the six depth views, the six curvature
    maps (k1, the larger principal curvature) and the three voxel density profiles, titled
    with ``result`` = (class, probability)."""
    from rgbd_rs.meshes import load_mesh
    from rgbd_rs.shapes import VIEW_NAMES, ShapeClassifier, shape_inputs, to_z_up
    from rgbd_rs.viz import grid, image_panel, map_panel

    spec = ShapeClassifier.load().spec
    x = shape_inputs(to_z_up(load_mesh(path), up), spec)
    width = 240
    panels = []

    def row(maps: np.ndarray, titles: list[str]) -> None:
        # One symmetric whole-number range per row: the maps are normalised (about -2..2).
        q = float(np.ceil(np.nanpercentile(np.abs(maps), 99))) or 1.0
        for m, t in zip(maps, titles, strict=True):
            panels.append(map_panel(m, t, unit="", vmin=-q, vmax=q, width=width))

    if "depth" in x:
        row(x["depth"], [f"depth view {v}" for v in VIEW_NAMES])
    if "curvature" in x:
        row(x["curvature"][:, 0], [f"k1 curvature {v}" for v in VIEW_NAMES])
    if "volume" in x:
        row(x["volume"], [f"density profile along {a}" for a in "xyz"])
    label, p = result
    head = grid(panels, columns=6)
    title = f"{path.name}: the network's inputs (normalised); classified as {label} ({p:.0%})"
    strip = image_panel(np.full((1, head.shape[1], 3), 255, np.uint8), title, width=head.shape[1])
    return np.vstack([strip, head])


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
