"""``==`` and ``hash`` on the package's dataclasses that hold arrays (a new user's report: they
raised numpy's "truth value of an array is ambiguous" / "unhashable type")."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
from pathlib import Path

import numpy as np
import pytest
import torch

import rgbd_rs
from rgbd_rs import Pose
from rgbd_rs._array_eq import key, same
from rgbd_rs.data import load_rig
from rgbd_rs.meshes import box
from rgbd_rs.segmentation.evaluate_semantic import LabelingScores

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
ARRAY_TYPES = ("NDArray", "F32", "F64", "U32", "I32", "U8", "ndarray", "Tensor", "B8", "U16")


def _turn(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_pose_compares_and_hashes_by_value() -> None:
    a = Pose(np.eye(3), np.zeros(3))
    b = Pose(np.eye(3), np.zeros(3))
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    assert a == Pose.identity()
    moved = Pose(np.eye(3), np.array([0.0, 0.0, 1e-9]))
    turned = Pose(_turn(1.0), np.zeros(3))
    assert a != moved and a != turned and len({a, moved, turned}) == 3
    text: object = "pose"
    assert a != text and (a == text) is False
    assert Pose(np.eye(3), np.array([0.0, -0.0, 0.0])) == a  # -0.0 == 0.0, and hashes alike
    assert hash(Pose(np.eye(3), np.array([0.0, -0.0, 0.0]))) == hash(a)


def test_rigs_and_meshes_compare_by_value() -> None:
    rig = load_rig(EXAMPLES / "calibration.json")
    again = load_rig(EXAMPLES / "calibration.json")
    assert rig == again and hash(rig) == hash(again)
    other = dataclasses.replace(rig, tof_to_reference=Pose(_turn(0.5), np.zeros(3)))
    assert rig != other
    assert box((1, 1, 1)) == box((1, 1, 1)) and box((1, 1, 1)) != box((1, 2, 1))
    assert len({box((1, 1, 1)), box((1, 1, 1))}) == 1


def test_values_compare_by_shape_dtype_and_values_nan_included() -> None:
    hole = np.array([1.0, np.nan], np.float32)
    assert same(hole, hole.copy()) and key(hole) == key(hole.copy())
    assert not same(hole, hole.astype(np.float64))  # dtype
    assert not same(np.zeros((2, 3)), np.zeros((3, 2)))  # shape
    assert not same(np.zeros(2), [0.0, 0.0])  # an array is not a list
    assert same({"w": torch.ones(3)}, {"w": torch.ones(3)})
    assert not same({"w": torch.ones(3)}, {"w": torch.zeros(3)})
    assert not same({"w": torch.ones(3)}, {"v": torch.ones(3)})
    assert key({"w": torch.ones(3)}) == key({"w": torch.ones(3)})
    assert same([np.ones(2), 1], [np.ones(2), 1]) and not same([np.ones(2)], (np.ones(2),))


def test_a_mutable_dataclass_compares_but_stays_unhashable() -> None:
    a, b = LabelingScores(), LabelingScores()
    assert a == b
    b.network[0, 0] = 1
    assert a != b
    with pytest.raises(TypeError, match="unhashable"):
        hash(a)


def test_every_dataclass_with_array_fields_compares_arrays() -> None:
    """A new dataclass with an array field must take ``@array_eq`` (or ``eq=False``)."""
    missing = []
    for info in pkgutil.walk_packages(rgbd_rs.__path__, "rgbd_rs."):
        if info.name.endswith("__main__"):
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if not (inspect.isclass(obj) and dataclasses.is_dataclass(obj)):
                continue
            if obj.__module__ != mod.__name__ or not obj.__dataclass_params__.eq:  # type: ignore[attr-defined]
                continue
            types = " ".join(str(f.type) for f in dataclasses.fields(obj))
            arrays = any(t in types for t in ARRAY_TYPES) and "__eq__" not in vars(obj)
            if arrays and not obj.__eq__.__qualname__.startswith("array_eq."):
                missing.append(f"{mod.__name__}.{name}")
    assert not missing, f"dataclasses with array fields but a tuple __eq__: {missing}"


def test_nan_scores_equal_themselves_and_nans_hash_alike() -> None:
    """A review: a NaN float field made a result unequal to itself, and numpy's 0/0 NaN (sign
    bit set) hashed apart from np.nan while comparing equal."""
    import copy

    from rgbd_rs.render import ToFFrame
    from rgbd_rs.segmentation.semantic_train import SemanticScores

    s = SemanticScores(("a", "b"), np.zeros((2, 2), np.int64), np.nan, np.nan, (np.nan, np.nan))
    assert s == s and s == copy.deepcopy(s)
    with np.errstate(invalid="ignore"):
        zero_by_zero = np.array([1.0, 0.0], np.float32) / np.array([1.0, 0.0], np.float32)
    plain = np.array([1.0, np.nan], np.float32)
    z = np.zeros(2, np.float32)
    a, b = ToFFrame(plain, z, z), ToFFrame(zero_by_zero, z, z)
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1


def test_a_surface_fit_is_itself_and_a_segmentation_ignores_its_timing() -> None:
    from rgbd_rs.segmentation.pipeline import Segmentation
    from rgbd_rs.surface import fit_mask

    pts = np.dstack([*np.meshgrid(np.arange(8.0), np.arange(8.0)), np.full((8, 8), 2.0)])
    pts = pts.astype(np.float32)
    mask = np.ones((8, 8), bool)
    a, b = fit_mask(pts, mask, with_dof=True), fit_mask(pts, mask, with_dof=False)
    assert a != b and a == a and len({a, b}) == 2
    names = [f.name for f in dataclasses.fields(Segmentation) if f.compare]
    assert "seconds" not in names and "fits" not in names and "labels" in names
