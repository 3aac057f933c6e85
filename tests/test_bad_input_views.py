"""Bad input to :mod:`rgbd_rs.shapes.views` (see tests/test_bad_input.py for the contract and
the meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

import rgbd_rs.shapes.views as V
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.meshes import Mesh, box

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
P = np.random.default_rng(0).uniform(size=(16, 3))
NAN = np.array([[0.0, np.nan, 0.0], [1.0, 1.0, 1.0]])
NO_TRIS = Mesh(np.zeros((3, 3), np.float32), np.zeros((0, 3), np.uint32))
HUGE = np.array([[0.0, 0, 0], [3e38, 0, 0]])
HUGE_MESH = Mesh(np.array([[0.0, 0, 0], [3e38, 0, 0], [0, 3e38, 0]]), np.array([[0, 1, 2]]))

CASES: list[Case] = [
    Case("depth_views", lambda: V.depth_views(np.zeros((0, 3))), SHAPE, r"^shape: got an empty"),
    Case("depth_views", lambda: V.depth_views(np.zeros((4, 2))), SHAPE, r"^shape: got shape", "2"),
    Case("depth_views", lambda: V.depth_views(NAN), ARG, r"^shape: got 1 non-finite", "nan"),
    Case("depth_views", lambda: V.depth_views(NO_TRIS), ARG, r"^shape: got a mesh with no", "m"),
    Case("depth_views", lambda: V.depth_views(P, 0), ARG, r"^resolution: got 0", "res0"),
    Case("depth_views", lambda: V.depth_views(P, 10**6), ARG, r"^resolution: got 1000000", "big"),
    Case("depth_views", lambda: V.depth_views(P, 8.0), ARG, r"^resolution: got 8.0", "float"),  # type: ignore[arg-type]
    Case("depth_views", lambda: V.depth_views(P, lcn=1), ARG, r"^lcn: got 1", "lcn"),  # type: ignore[arg-type]
    Case(
        "depth_views",
        lambda: V.depth_views(P, background=np.nan),
        ARG,
        r"^background: got nan, expected .*nan only with lcn=False",
        "nan-bg",
    ),
    Case("depth_views", lambda: V.depth_views(P, background="x"), ARG, r"^background", "bg"),  # type: ignore[arg-type]
    Case("depth_views", lambda: V.depth_views(P, lcn_window=4), ARG, r"^lcn_window: got 4", "w"),
    Case("depth_views", lambda: V.depth_views(P, splat_radius=0), ARG, r"^splat_radius", "r0"),
    Case("depth_views", lambda: V.depth_views(P, splat_radius=1e3), ARG, r"^splat_radius", "r"),
    Case(
        "depth_views",
        lambda: V.depth_views(box((1, 1, 1)), splat_radius=2.0),
        ARG,
        r"^splat_radius: got 2.0 for a mesh",
        "mesh-radius",
    ),
    Case(
        "depth_views",
        lambda: V.depth_views(HUGE),
        ARG,
        r"^shape: got points spanning 3e\+38 units, expected a shape at most 1e\+30 units across",
        "huge",
    ),
    Case(
        "depth_views",
        lambda: V.depth_views(HUGE_MESH),
        ARG,
        r"^shape: got a mesh spanning 3e\+38 units",
        "huge-mesh",
    ),
    Case(
        "depth_views_batch",
        lambda: V.depth_views_batch([P, HUGE]),
        ARG,
        r"^shapes\[1\]: got points spanning",
        "huge",
    ),
    Case("depth_views_batch", lambda: V.depth_views_batch(P), ARG, r"^shapes: got ndarray"),
    Case(
        "depth_views_batch",
        lambda: V.depth_views_batch([P, NAN]),
        ARG,
        r"^shapes\[1\]: got 1 non-finite",
        "nan",
    ),
    Case(
        "depth_views_batch",
        lambda: V.depth_views_batch([P, np.zeros((2, 4))]),
        SHAPE,
        r"^shapes\[1\]: got shape",
        "shape",
    ),
    Case("depth_views_batch", lambda: V.depth_views_batch([P], 0), ARG, r"^resolution", "res"),
    Case(
        "depth_views_batch",
        lambda: V.depth_views_batch([P, NO_TRIS]),
        ARG,
        r"^shapes\[1\]: got a mesh with no triangles",
        "mesh",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.ones((8, 8)), 5, eps=1e300),
        ARG,
        r"^eps: got 1e\+300, expected a magnitude within float32",
        "eps-f32",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.zeros(5)),
        SHAPE,
        r"^image: got shape \(5,\)",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.full((4, 4), np.inf)),
        ARG,
        r"^image: got 16 non-finite",
        "inf",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.zeros((4, 4)), 2),
        ARG,
        r"^window: got 2, expected an odd",
        "even",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.zeros((4, 4)), eps=0.0),
        ARG,
        r"^eps: got 0.0",
        "eps",
    ),
    Case(
        "local_contrast_normalize",
        lambda: V.local_contrast_normalize(np.zeros((0, 4))),
        SHAPE,
        r"^image: got an empty",
        "empty",
    ),
    Case("splat_radii", lambda: V.splat_radii(np.zeros((0, 3))), SHAPE, r"^points: got an empty"),
    Case("splat_radii", lambda: V.splat_radii(NAN), ARG, r"^points: got 1 non-finite", "nan"),
    Case("splat_radii", lambda: V.splat_radii(P, -1), ARG, r"^resolution: got -1", "res"),
    Case("lcn_window", lambda: V.lcn_window(0), ARG, r"^resolution: got 0"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
