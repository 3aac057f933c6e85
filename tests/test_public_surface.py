"""The public surface cannot grow by accident (issue 32).

Public is what the public modules export (their ``__all__``: what the docs' API reference
documents and the bad-input suite covers, see test_bad_input_coverage.py). Every other
function or class is either named with a leading underscore, lives in a tooling module (one
that backs a CLI command: evaluation, training, calibration, the synthetic data generators,
the demo; users run those through ``rgbd``), or is a type of a public signature listed below.
A new helper without an underscore fails this test.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import rgbd_rs
from test_bad_input_coverage import public_callables

#: Modules that back a CLI command; their names are implementation, not API.
TOOLING = (
    "rgbd_rs.cli",
    "rgbd_rs.demo",
    "rgbd_rs.demo_fusion",
    "rgbd_rs.demo_page",
    "rgbd_rs.demo_scene",
    "rgbd_rs.data.synth",
    "rgbd_rs.data.synth_indoor_objects",
    "rgbd_rs.data.synth_indoor_scene",
    "rgbd_rs.data.synth_indoor_walls",
    "rgbd_rs.data.synth_preview",
    "rgbd_rs.data.tof_variation",
    "rgbd_rs.fusion.calibrate",
    "rgbd_rs.fusion.evaluate",
    "rgbd_rs.fusion.evaluate_real",
    "rgbd_rs.fusion.evaluate_stereo",
    "rgbd_rs.fusion.real_scenes",
    "rgbd_rs.fusion.score",
    "rgbd_rs.nn.confidence_data",
    "rgbd_rs.nn.confidence_train",
    "rgbd_rs.segmentation.evaluate",
    "rgbd_rs.segmentation.evaluate_semantic",
    "rgbd_rs.segmentation.semantic_train",
    "rgbd_rs.shapes.evaluate",
    "rgbd_rs.shapes.scaling",
    "rgbd_rs.shapes.train",
)

#: Not exported, no underscore, and why.
KNOWN: dict[str, str] = {
    "rgbd_rs.fusion.clues.Clues": "returned by compute_clues",
    "rgbd_rs.fusion.upsample.SparseToF": "returned by the ToF reprojection step",
    "rgbd_rs.segmentation.semantic_data.Frame": "the protocol a frame sequence's items follow",
    "rgbd_rs.segmentation.semantic_data.SemanticFrames": "returned by open_frames",
    "rgbd_rs.shapes.augment.AugmentedShapes": "dataset returned by the training pipeline",
    "rgbd_rs.shapes.augment.RotatedShapes": "dataset returned by the training pipeline",
    "rgbd_rs.shapes.augment.MixedShapes": "dataset returned by the training pipeline (mixup)",
    "rgbd_rs.shapes.dataset.CachedShapes": "dataset returned by ShapeCache.dataset",
    "rgbd_rs.shapes.dataset.ShapeSource": "base class of OffTree / PointCloudSet (open_shapes)",
    "rgbd_rs.shapes.classify.shipped_weights": "which shipped checkpoints exist (rgbd classify)",
    "rgbd_rs.fusion.fuse.shipped_estimator": "the shipped ConvNet fuse() runs on the near or "
    "the far camera (the demo, the benches)",
    "rgbd_rs.nn.shapes.pack": "the packed input layout ShapeNet and its datasets share",
    "rgbd_rs.nn.shapes.unpack": "inverse of pack",
    # Defined natively, named here (their __module__) so that they pickle.
    "rgbd_rs.errors.RgbdError": "the error classes (rgbd_rs.errors.__all__, rgbd_rs.__all__)",
    "rgbd_rs.errors.InvalidArgumentError": "an error class (rgbd_rs.errors.__all__)",
    "rgbd_rs.errors.ShapeMismatchError": "an error class (rgbd_rs.errors.__all__)",
}


def _defined_names() -> dict[str, str]:
    """``{module.name: name}`` of every function and class a non-private module defines."""
    found: dict[str, str] = {}
    for info in pkgutil.walk_packages(rgbd_rs.__path__, "rgbd_rs."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts[1:]) or info.name.startswith(TOOLING):
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if name.startswith("_") or not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if getattr(obj, "__module__", None) == mod.__name__:
                found[f"{mod.__name__}.{name}"] = name
    return found


def test_no_public_looking_name_outside_the_public_api() -> None:
    public = {n.split(".")[0] for n in public_callables()}
    stray = sorted(k for k, n in _defined_names().items() if n not in public and k not in KNOWN)
    assert not stray, (
        "not exported by a public module, yet named without an underscore (make it private, "
        f"export and document it, or list it in KNOWN with why): {stray}"
    )


def test_known_names_exist() -> None:
    defined = _defined_names()
    assert not sorted(set(KNOWN) - set(defined)), "KNOWN lists names that no longer exist"
