"""The meta-test of the bad-input suite: every public callable of every public module (its
``__all__``, else the functions and classes it defines) has at least one case in
tests/test_bad_input*.py, or is listed in ``EXEMPT`` with the reason it takes no input to check.
"""

from __future__ import annotations

import importlib
import inspect
import types
from collections.abc import Iterator
from pathlib import Path

import rgbd_rs
import rgbd_rs.data
import rgbd_rs.data.nyuv2
import rgbd_rs.data.nyuv2_mat
import rgbd_rs.data.synth_indoor
import rgbd_rs.fusion
import rgbd_rs.io
import rgbd_rs.meshes
import rgbd_rs.metrics
import rgbd_rs.nn
import rgbd_rs.render
import rgbd_rs.segmentation
import rgbd_rs.shapes
import rgbd_rs.shapes.curvature
import rgbd_rs.surface
import rgbd_rs.viz
from bad_input import Case

# -- the meta-test: every public callable has a case -------------------------------------------

PUBLIC_MODULES = (
    rgbd_rs,
    rgbd_rs.camera,
    rgbd_rs.geometry,
    rgbd_rs.fusion,
    rgbd_rs.surface,
    rgbd_rs.render,
    rgbd_rs.meshes,
    rgbd_rs.data,
    rgbd_rs.data.nyuv2,
    rgbd_rs.data.nyuv2_mat,
    rgbd_rs.io,
    rgbd_rs.viz,
    rgbd_rs.metrics,
    rgbd_rs.nn,
    rgbd_rs.segmentation,
    rgbd_rs.shapes,
    rgbd_rs.shapes.curvature,
    rgbd_rs.data.synth_indoor,
)

#: Public callables with no caller input to check, and why.
EXEMPT: dict[str, str] = {
    "Distortion.to_opencv": "no arguments",
    "SemanticNet.arch_config": "no arguments",
    "LabeledFrame": "plain record of validated frame arrays, built by the frame readers",
    "SemanticCache.cues": "no arguments",
    "SemanticCache.indices": "no arguments",
    "SemanticCache.labels": "no arguments",
    "SemanticCache.require_complete": "no arguments",
    "SemanticCues": "result container built by cue_maps",
    "SemanticCues.stack": "no arguments",
    "SemanticScores": "result container built by score",
    "SemanticScores.summary": "no arguments",
    "Pose.identity": "no arguments",
    "Pose.as_matrix": "no arguments",
    "Pose.inverse": "no arguments (a validated Pose is invertible)",
    "PinholeCamera.without_distortion": "no arguments",
    "Reprojection": "result container built by reproject_depth",
    "FusionResult": "result container built by fuse",
    "CensusMatch": "result container built by census_match",
    "StereoScene": "plain record of validated scene arrays, built by load_stereo_scene",
    "ToFOnReference": "result container built by tof_to_reference",
    "PoseRefinement": "result container built by refine_tof_pose",
    "ScaleRefinement": "result container built by refine_tof_scale",
    "RowAlignment": "result container built by measure_row_alignment",
    "RowAlignment.field": "no arguments",
    "RowAlignment.plus": "adds two RowAlignment records measure_row_alignment built",
    "RowAlignment.describe": "no arguments",
    "SurfaceMaps": "result container built by the surface fits",
    "SurfaceFit": "result container built by fit_mask / fit_grid",
    "SegmentFits.labels": "no arguments",
    "ToFFrame": "result container built by RenderScene.tof",
    "GBuffer": "result container built by RenderScene.gbuffer",
    "RenderScene": "built by Scene.build from a native scene, not by callers",
    "Texture.uniform": "no arguments",
    "ToFModel.ideal": "no arguments",
    "Mesh.bounds": "no arguments",
    "SynthSample": "result container built by SynthDataset",
    "VoxelGrid": "result container built by voxelize",
    "Features": "result container built by features",
    "HhaResult": "result container built by hha_details",
    "MergeStep": "result container built by merge_regions",
    "MergeResult": "result container built by merge_regions",
    "Segmentation": "result container built by segment",
    "ShapeEvaluation.confusion_markdown": "no arguments",
    "ShapeEvaluation.heatmap": "no arguments",
    "ShapeEvaluation.markdown": "no arguments",
    "ShapeEvaluation.per_class_markdown": "no arguments",
    "ShapeEvaluation.summary": "no arguments",
    "InputSpec.to_dict": "no arguments",
    "ShapeNet.arch_config": "no arguments",
    "ShapeEnsemble.arch_config": "no arguments",
    "available_representations": "no arguments",
    "Synth3Sample": "result container built by Synth3Dataset",
    "MiddleburyPair": "result container built by load_middlebury",
    "NyuFrame": "result container built by load_nyuv2_frame",
    "IndoorFrame": "result container built by render_indoor_frame / IndoorFrames",
    "NyuMatDataset.close": "no arguments",
    "AzureKinectCalibration": "result container built by load_azure_kinect_calibration",
    "EpochStats": "result container built by train",
    "TrainResult": "result container built by train",
    "Checkpoint": "result container built by load_checkpoint",
    "Checkpoint.stripped": "no arguments",
    "TrainConfig.to_dict": "no arguments",
    "is_main_process": "no arguments",
}


def _members(cls: type) -> Iterator[str]:
    for key, value in vars(cls).items():
        if key.startswith("_"):
            continue
        if isinstance(value, (staticmethod, classmethod)) or inspect.isfunction(value):
            yield f"{cls.__qualname__}.{key}"


def public_callables() -> dict[str, str]:
    """``{name: module}`` of every public function, class and method; ``__all__`` where a module
    has one, else the functions and classes it defines without a leading underscore."""
    found: dict[str, str] = {}
    for mod in PUBLIC_MODULES:
        names = getattr(mod, "__all__", None)
        if names is None:
            names = [
                n
                for n, o in vars(mod).items()
                if not n.startswith("_") and getattr(o, "__module__", None) == mod.__name__
            ]
        for n in names:
            obj = getattr(mod, n)
            if isinstance(obj, types.ModuleType) or not (
                inspect.isfunction(obj) or inspect.isclass(obj)
            ):
                continue
            if inspect.isclass(obj) and issubclass(obj, BaseException):
                continue  # the error classes themselves
            found.setdefault(obj.__qualname__, mod.__name__)
            if inspect.isclass(obj):
                for m in _members(obj):
                    found.setdefault(m, mod.__name__)
    return found


def all_cases() -> list[Case]:
    """The ``CASES`` of every tests/test_bad_input*.py module (found by name, so a new area's
    file counts as soon as it exists)."""
    cases: list[Case] = []
    for path in sorted(Path(__file__).parent.glob("test_bad_input*.py")):
        cases += getattr(importlib.import_module(path.stem), "CASES", [])
    return cases


def test_every_public_callable_has_a_bad_input_case() -> None:
    covered = {c.name for c in all_cases()}
    public = public_callables()
    missing = sorted(f"{public[n]}: {n}" for n in public if n not in covered and n not in EXEMPT)
    assert not missing, "public callables without a bad-input case:\n" + "\n".join(missing)
    stale = sorted((covered | set(EXEMPT)) - set(public))
    assert not stale, f"cases or exemptions for names that are not public: {stale}"
    assert not covered & set(EXEMPT), "a name is both covered and exempt"
