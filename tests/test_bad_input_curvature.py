"""Bad input to :mod:`rgbd_rs.shapes.curvature` (see tests/test_bad_input.py for the contract and
the meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

import rgbd_rs.shapes.curvature as C
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.meshes import Mesh

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

P = np.random.default_rng(0).normal(size=(64, 3)).astype(np.float32)
EMPTY = Mesh(np.zeros((3, 3), np.float32), np.zeros((0, 3), np.uint32))

CASES: list[Case] = [
    Case("curvature_maps", lambda: C.curvature_maps("ball.off"), ARG, r"^shape: got str"),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(np.zeros((4, 2))),
        SHAPE,
        r"^shape: got shape \(4, 2\)",
        "2-D",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(np.zeros((0, 3))),
        SHAPE,
        r"^shape: got an empty",
        "empty-cloud",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(np.array([[0.0, np.nan, 0.0]])),
        ARG,
        r"^shape: got 1 non-finite",
        "nan",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(EMPTY),
        ARG,
        r"^shape: got a mesh with no triangles",
        "empty-mesh",
    ),
    Case("curvature_maps", lambda: C.curvature_maps(P, 0), ARG, r"^resolution: got 0", "zero"),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(P, 2.5),  # type: ignore[arg-type]
        ARG,
        r"^resolution: got 2\.5",
        "float",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(P, 10**9),
        ARG,
        r"^resolution: got 1000000000",
        "huge",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(P, 16, views=np.zeros((6, 8, 8), np.float32)),
        SHAPE,
        r"^views: got shape \(6, 8, 8\), expected \(6, 16, 16\)",
        "views-size",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(P, 8, views=np.full((6, 8, 8), np.inf, np.float32)),
        ARG,
        r"^views: got infinite depths",
        "views-inf",
    ),
    Case(
        "curvature_maps",
        lambda: C.curvature_maps(P, 8, views=np.full((6, 8, 8), "x")),
        ARG,
        r"^views: got dtype <U1",
        "views-dtype",
    ),
    Case("knot_spacing", lambda: C.knot_spacing(0), ARG, r"^resolution: got 0"),
    Case("knot_spacing", lambda: C.knot_spacing(64, 0), ARG, r"^spans: got 0", "spans"),
    Case("knot_spacing", lambda: C.knot_spacing(True), ARG, r"^resolution: got True", "bool"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
