"""Bad input to :mod:`rgbd_rs.shapes` (see tests/test_bad_input.py for the contract and the
meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

import rgbd_rs.shapes as S
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.meshes import Mesh, box

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
P = np.zeros((4, 3))
#: A tetrahedron 2e30 across, just over the shape kernels' largest extent.
HUGE = 2e30 * np.eye(4, 3)
FLAT = Mesh(np.eye(4, 3, dtype=np.float32), np.array([[0, 0, 0], [1, 1, 1]], np.uint32))


def test_a_shape_up_to_the_largest_extent_is_accepted() -> None:
    views = S.depth_views(5e29 * np.eye(4, 3), 8)
    assert views.shape == (6, 8, 8) and np.isfinite(views).all()


CASES: list[Case] = [
    Case("voxelize", lambda: S.voxelize(np.zeros((0, 3))), SHAPE, r"^shape: got an empty"),
    Case("voxelize", lambda: S.voxelize(np.zeros((4, 2))), SHAPE, r"^shape: got shape", "2-D"),
    Case("voxelize", lambda: S.voxelize(np.array([[0.0, np.nan, 0]])), ARG, r"^shape", "nan"),
    Case("voxelize", lambda: S.voxelize(P, 0), ARG, r"^resolution: got 0", "res"),
    Case("voxelize", lambda: S.voxelize(HUGE), ARG, r"^shape: got points spanning 2e\+30", "huge"),
    Case("shape_inputs", lambda: S.shape_inputs(HUGE), ARG, r"^shape: got points spanning", "huge"),
    # One shape is named as the caller named it, not as the batch it is run in.
    Case("classify", lambda: S.classify(HUGE), ARG, r"^shape: got points spanning 2e\+30", "huge"),
    Case("voxelize", lambda: S.voxelize(P, 4096), ARG, r"^resolution: got 4096", "huge-res"),
    Case("voxelize", lambda: S.voxelize(P, fill="solid"), ARG, r"^fill: got 'solid'", "fill"),
    Case("voxelize", lambda: S.voxelize(P, fill="hollow"), ARG, r"^fill", "fill-name"),
    Case("voxelize", lambda: S.voxelize(P, dilate=-1), ARG, r"^dilate", "dilate"),
    Case("voxelize", lambda: S.voxelize(box((1, 1, 1)), dilate=1), ARG, r"^dilate", "mesh"),
    Case(
        "voxelize",
        lambda: S.voxelize(Mesh(np.zeros((3, 3), np.float32), np.zeros((0, 3), np.uint32))),
        ARG,
        r"^shape: got a mesh with no triangles",
        "empty-mesh",
    ),
    # Triangles that all have zero area: empty views, and yet a class (issue of a fuzz round).
    Case(
        "voxelize", lambda: S.voxelize(FLAT), ARG, r"^shape: got a mesh whose 2 .*zero area", "0a"
    ),
    Case("depth_views", lambda: S.depth_views(FLAT), ARG, r"^shape: .*zero area", "zero-area"),
    Case("classify", lambda: S.classify(FLAT), ARG, r"^shape: .*zero area", "zero-area"),
    Case("classify", lambda: S.classify("no_such.off"), ARG, r"^shape: got no_such\.off", "path"),
    Case("sample_surface", lambda: S.sample_surface(FLAT), ARG, r"^mesh: .*zero area", "zero-area"),
    Case(
        "voxelize",
        lambda: S.voxelize(np.array([[0.0, 0, 0], [3e38, 0, 0]])),
        ARG,
        r"^shape: got points spanning 3e\+38",
        "huge-f64",
    ),
    Case("density_profiles", lambda: S.density_profiles(np.zeros((4, 4, 5))), SHAPE, r"^voxels"),
    Case(
        "density_profiles",
        lambda: S.density_profiles(np.zeros((4, 4, 4), np.float32)),
        ARG,
        r"^voxels: got dtype float32",
        "dtype",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
