"""Bad input to :mod:`rgbd_rs.segmentation.hha` and :mod:`rgbd_rs.segmentation.features` (see
tests/test_bad_input.py for the contract)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import Distortion, InvalidArgumentError, PinholeCamera, ShapeMismatchError

F = importlib.import_module("rgbd_rs.segmentation.features")  # the module, not the function
H = importlib.import_module("rgbd_rs.segmentation.hha")  # the module, not the function


SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

CAM = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)
_V, _U = np.mgrid[0:24, 0:32]
D = (1.0 + 0.01 * _U + 0.02 * _V).astype(np.float32)
RGB = np.random.default_rng(0).integers(0, 255, (24, 32, 3), dtype=np.uint8)
NAN = np.full((24, 32), np.nan, np.float32)
ONE_PIXEL = np.where((_U == 3) & (_V == 4), 2.0, np.nan).astype(np.float32)

CASES: list[Case] = [
    Case("hha", lambda: H.hha(NAN, CAM), ARG, r"^depth: got no valid depth", "all NaN"),
    Case(
        "hha",
        lambda: H.hha(np.zeros((24, 32), np.float32), CAM),
        ARG,
        r"^depth: got no valid depth",
        "all zero",
    ),
    Case(
        "hha",
        lambda: H.hha(D * 1000, CAM),
        ARG,
        r"^depth: got a median valid depth of .*millimetres; divide by 1000",
        "millimetres",
    ),
    Case("hha", lambda: H.hha(D, "cam"), ARG, r"^camera: got str", "camera type"),  # type: ignore[arg-type]
    Case(
        "hha",
        lambda: H.hha(D[:, :-1], CAM),
        SHAPE,
        r"^camera: got a 32x24 camera, expected one for the 31x24",
        "camera size",
    ),
    Case(
        "hha",
        lambda: H.hha(D, PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24, Distortion(k1=0.1))),
        ARG,
        r"^camera: got a camera with lens distortion",
        "distortion",
    ),
    Case("hha", lambda: H.hha(D[:, :, None], CAM), SHAPE, r"^depth: got shape", "3-D depth"),
    Case("hha", lambda: H.hha(D > 1, CAM), ARG, r"^depth: got dtype bool", "bool depth"),
    Case(
        "hha",
        lambda: H.hha(D.astype(np.complex64), CAM),
        ARG,
        r"^depth: got dtype complex64",
        "complex depth",
    ),
    Case("hha", lambda: H.hha([[1.0, 2.0], [3.0]], CAM), ARG, r"^depth: got list", "ragged"),
    Case(
        "hha",
        lambda: H.hha(D, CAM, raw_depth=D[:-1]),
        SHAPE,
        r"^raw_depth: got shape \(23, 32\)",
        "raw size",
    ),
    Case(
        "hha_details",
        lambda: H.hha_details(np.full((24, 32), np.inf, np.float32), CAM),
        ARG,
        r"^depth: got no valid depth",
        "all inf",
    ),
    Case(
        "hha_details",
        lambda: H.hha_details(D, CAM, raw_depth=D > 1),
        ARG,
        r"^raw_depth: got dtype bool",
        "bool raw",
    ),
    Case(
        "hha_details",
        lambda: H.hha_details(D, CAM, raw_depth=np.zeros_like(D)),
        ARG,
        r"^raw_depth: got no valid depth",
        "raw all holes",
    ),
    Case(
        "square_normals",
        lambda: H.square_normals(D, CAM, raw_depth=np.full_like(D, np.nan)),
        ARG,
        r"^raw_depth: got no valid depth",
        "raw all NaN",
    ),
    Case("square_normals", lambda: H.square_normals(D, CAM, radius=0), ARG, r"^radius: got 0"),
    Case(
        "square_normals",
        lambda: H.square_normals(D, CAM, radius=33),
        ARG,
        r"^radius: got 33",
        "radius too large",
    ),
    Case(
        "square_normals",
        lambda: H.square_normals(D, CAM, toward_camera="yes"),  # type: ignore[arg-type]
        ARG,
        r"^toward_camera: got 'yes'",
        "orientation",
    ),
    Case(
        "square_normals",
        lambda: H.square_normals(NAN, CAM),
        ARG,
        r"^depth: got no valid depth",
        "all NaN",
    ),
    Case(
        "features",
        lambda: F.features(RGB.astype(np.float32), D, CAM),
        ARG,
        r"^rgb: got dtype float32, expected uint8",
    ),
    Case(
        "features",
        lambda: F.features(RGB[:, :, 0], D, CAM),
        SHAPE,
        r"^rgb: got shape \(24, 32\)",
        "grey",
    ),
    Case(
        "features",
        lambda: F.features(RGB[:-1], D, CAM),
        SHAPE,
        r"^rgb: got 32x23, expected the depth's size 32x24",
        "size mismatch",
    ),
    Case(
        "features",
        lambda: F.features(RGB[:, :-1], D[:, :-1], CAM),
        SHAPE,
        r"^camera: got a 32x24 camera",
        "camera size",
    ),
    Case("features", lambda: F.features(RGB, NAN, CAM), ARG, r"^depth: got no valid", "all NaN"),
    Case(
        "features",
        lambda: F.features(RGB, D * 1000, CAM),
        ARG,
        r"^depth: got a median valid depth.*millimetres",
        "millimetres",
    ),
    Case(
        "features",
        lambda: F.features(RGB, ONE_PIXEL, CAM),
        ARG,
        r"^depth: got no pixel with both a valid depth and a surface normal",
        "no normal",
    ),
    Case(
        "features",
        lambda: F.features(RGB, D, CAM, normals=np.zeros((24, 32), np.float32)),
        SHAPE,
        r"^normals: got shape \(24, 32\), expected \(24, 32, 3\)",
        "normals shape",
    ),
    Case(
        "features",
        lambda: F.features(RGB, NAN, CAM, normals=np.zeros((24, 32, 3), np.float32)),
        ARG,
        r"^depth: got no valid depth",
        "normals given, no depth",
    ),
    Case(
        "features",
        lambda: F.features(RGB, D, CAM, normal_radius=-1),
        ARG,
        r"^normal_radius: got -1",
        "radius",
    ),
    Case("lab_colour", lambda: F.lab_colour(RGB > 0), ARG, r"^rgb: got dtype bool"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
