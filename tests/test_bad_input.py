"""Bad input to the public API ends in an RgbdError that names the argument (ShapeMismatchError
for shapes, InvalidArgumentError otherwise), never another exception type, a panic or an aborted
interpreter.

This file holds the camera and geometry cases; tests/test_bad_input_*.py hold those of fusion
(``_fusion``), render, surface and meshes (``_render``), data, io, viz and metrics (``_data``);
``_layout`` the memory-layout promises and the hostile fuzzing; ``_coverage`` the meta-test that
every public callable has a case. The shared ``Case`` lives in tests/bad_input.py.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bad_input import Case, check, isolated, params
from rgbd_rs import (
    Distortion,
    InvalidArgumentError,
    PinholeCamera,
    Pose,
    ShapeMismatchError,
    StereoRig,
    ToFStereoRig,
    depth_to_disparity,
    disparity_to_depth,
    normals_from_depth,
    normals_from_points,
    reproject_depth,
)

CAM = PinholeCamera(20.0, 20.0, 3.5, 2.5, 8, 6, Distortion(k1=-0.1, k4=0.05))
RIG = StereoRig(CAM.without_distortion(), CAM.without_distortion(), 0.1)
PTS = np.array([[0.1, 0.2, 1.0], [-0.3, 0.1, 2.0]])
PX = np.array([[1.0, 2.0], [3.0, 4.0]])
DEPTH = np.ones((6, 8), np.float32)
SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

CASES: list[Case] = [
    # -- camera.Distortion ----------------------------------------------------------------------
    Case("Distortion", lambda: Distortion(k1="x"), ARG, r"^distortion\.k1: got 'x'"),
    Case("Distortion", lambda: Distortion(k2=float("nan")), ARG, r"^distortion\.k2", "nan"),
    Case("Distortion", lambda: Distortion(p1=2**1100), ARG, r"^distortion\.p1", "huge"),
    Case(
        "Distortion.from_opencv",
        lambda: Distortion.from_opencv([1.0, 2.0, 3.0]),
        SHAPE,
        r"^coeffs: got 3 coefficients",
    ),
    Case(
        "Distortion.from_opencv",
        lambda: Distortion.from_opencv([[1.0], [2.0, 3.0]]),
        ARG,
        r"^coeffs: got list",
        "ragged",
    ),
    Case("Distortion.from_opencv", lambda: Distortion.from_opencv("abcd"), ARG, r"^coeffs", "str"),
    # -- camera.Pose ----------------------------------------------------------------------------
    Case("Pose", lambda: Pose(np.eye(2)), SHAPE, r"^rotation: got shape \(2, 2\)"),
    Case("Pose", lambda: Pose(2 * np.eye(3)), ARG, r"^rotation: got a matrix", "not a rotation"),
    Case("Pose", lambda: Pose(np.eye(3), [1.0, 2.0]), SHAPE, r"^translation: got shape", "t"),
    Case("Pose", lambda: Pose(np.eye(3), [[1.0], [2.0, 3.0]]), ARG, r"^translation", "ragged"),
    Case("Pose", lambda: Pose("x"), ARG, r"^rotation: got dtype", "str"),
    Case("Pose.from_matrix", lambda: Pose.from_matrix(np.eye(5)), SHAPE, r"^matrix: got shape"),
    Case("Pose.from_matrix", lambda: Pose.from_matrix(np.eye(4)[:2]), SHAPE, r"^matrix", "2 rows"),
    Case("Pose.compose", lambda: Pose().compose(None), ARG, r"^first: got NoneType"),
    Case("Pose.apply", lambda: Pose().apply(np.zeros((2, 2))), SHAPE, r"^points: got shape"),
    Case("Pose.apply", lambda: Pose().apply("abc"), ARG, r"^points: got dtype", "str"),
    # -- camera.PinholeCamera -------------------------------------------------------------------
    Case("PinholeCamera", lambda: PinholeCamera(0.0, 1.0, 0.0, 0.0, 4, 4), ARG, r"^fx: got 0"),
    Case(
        "PinholeCamera",
        lambda: PinholeCamera(2**1100, 1.0, 0.0, 0.0, 4, 4),
        ARG,
        r"^fx: got",
        "huge int",
    ),
    Case(
        "PinholeCamera",
        lambda: PinholeCamera(1.0, 1.0, 0.0, 0.0, "4", 4),
        ARG,
        r"^width: got '4'",
        "str width",
    ),
    Case(
        "PinholeCamera",
        lambda: PinholeCamera(1.0, 1.0, 0.0, 0.0, 4, 4, "k1"),
        ARG,
        r"^distortion: got str",
        "distortion",
    ),
    Case(
        "PinholeCamera",
        isolated("rgbd_rs.PinholeCamera(1.0, 1.0, 0.0, 0.0, 2**20, 2**20).undistort_map()"),
        ARG,
        r"width|height|pixels",
        "2**20 x 2**20 undistort_map",
    ),
    Case(
        "PinholeCamera",
        isolated("rgbd_rs.PinholeCamera(1.0, 1.0, 0.0, 0.0, 2**70, 1).undistort_map()"),
        ARG,
        r"^width",
        "2**70 wide",
    ),
    Case(
        "PinholeCamera.from_matrix",
        lambda: PinholeCamera.from_matrix(np.eye(2), 8, 6),
        SHAPE,
        r"^K: got shape",
    ),
    Case(
        "PinholeCamera.from_matrix",
        lambda: PinholeCamera.from_matrix([[1, 1, 0], [0, 1, 0], [0, 0, 1]], 8, 6),
        ARG,
        r"^K: got",
        "skew",
    ),
    Case("PinholeCamera.scaled", lambda: CAM.scaled(-1.0), ARG, r"^sx: got -1"),
    Case("PinholeCamera.scaled", lambda: CAM.scaled(1.0, "y"), ARG, r"^sy: got 'y'", "sy"),
    Case("PinholeCamera.cropped", lambda: CAM.cropped(0, 0, 100, 1), ARG, r"^width: got 100"),
    Case("PinholeCamera.cropped", lambda: CAM.cropped(-1, 0, 1, 1), ARG, r"^x0: got -1", "x0"),
    Case("PinholeCamera.project", lambda: CAM.project(PTS, pose="x"), ARG, r"^pose: got str"),
    Case(
        "PinholeCamera.project",
        lambda: CAM.project(np.zeros((4, 2))),
        SHAPE,
        r"^points: got shape \(4, 2\), expected \(N, 3\)",
        "shape",
    ),
    Case(
        "PinholeCamera.project",
        lambda: CAM.project(np.zeros((4, 3), np.complex64)),
        ARG,
        r"^points: got dtype complex64",
        "complex",
    ),
    Case(
        "PinholeCamera.undistort_points",
        lambda: CAM.undistort_points(PX, max_iter=0),
        ARG,
        r"^max_iter: got 0",
    ),
    Case(
        "PinholeCamera.undistort_points",
        lambda: CAM.undistort_points(PX, tol=-1.0),
        ARG,
        r"^tol: got -1",
        "tol",
    ),
    Case(
        "PinholeCamera.undistort_points",
        lambda: CAM.undistort_points(np.zeros((2, 3))),
        SHAPE,
        r"^pixels: got shape",
        "shape",
    ),
    Case(
        "PinholeCamera.distort_points",
        lambda: CAM.distort_points(np.zeros(4)),
        SHAPE,
        r"^pixels: got shape \(4,\)",
    ),
    Case(
        "PinholeCamera.backproject",
        lambda: CAM.backproject(PX, np.ones(3)),
        SHAPE,
        r"^depth: got shape \(3,\), expected \(2\)",
    ),
    Case(
        "PinholeCamera.depth_to_points",
        lambda: CAM.depth_to_points(np.ones((6, 7), np.float32)),
        SHAPE,
        r"^depth: got shape \(6, 7\), expected \(6, 8\)",
    ),
    Case("PinholeCamera.undistort_map", lambda: CAM.undistort_map("x"), ARG, r"^target: got str"),
    Case(
        "PinholeCamera.undistort_map",
        lambda: CAM.undistort_map(rotation="x"),
        ARG,
        r"^rotation: got dtype",
        "rotation",
    ),
    Case(
        "PinholeCamera.undistort_map",
        lambda: CAM.undistort_map(rotation=np.eye(2)),
        SHAPE,
        r"^rotation: got shape",
        "rotation shape",
    ),
    Case(
        "PinholeCamera.undistort_image",
        lambda: CAM.undistort_image(np.zeros((5, 8))),
        SHAPE,
        r"^image: got size 8x5",
    ),
    Case(
        "PinholeCamera.undistort_image",
        lambda: CAM.undistort_image(np.zeros((6, 8)), interpolation="cubic"),
        ARG,
        r"^interpolation: got 'cubic'",
        "interpolation",
    ),
    Case(
        "PinholeCamera.undistort_image",
        lambda: CAM.undistort_image([[1, 2], [3]]),
        ARG,
        r"^image: got list",
        "ragged",
    ),
    Case(
        "PinholeCamera.from_matrix",
        lambda: PinholeCamera.from_matrix(np.eye(3), 8, 6, np.zeros(5)),
        ARG,
        r"^distortion: got ndarray",
        "distortion array",
    ),
    Case(
        "PinholeCamera.undistort_image",
        lambda: CAM.undistort_image(np.zeros((6, 8, 2, 2))),
        SHAPE,
        r"^image: got shape",
        "4-D",
    ),
    # -- camera rigs ----------------------------------------------------------------------------
    Case("StereoRig", lambda: StereoRig(CAM, CAM, 0.0), ARG, r"^baseline: got 0"),
    Case(
        "StereoRig",
        lambda: StereoRig(CAM, CAM, 1e308),
        ARG,
        r"^baseline: got 1e\+308 m with fx=\S+: every disparity .* would overflow float32",
        "huge",
    ),
    Case("StereoRig", lambda: StereoRig("x", CAM, 0.1), ARG, r"^left: got str", "left"),
    Case("StereoRig", lambda: StereoRig(CAM, CAM.scaled(2.0), 0.1), ARG, r"^right: got", "size"),
    Case(
        "StereoRig",
        lambda: StereoRig(CAM, dataclasses.replace(CAM, cy=CAM.cy + 1.0), 0.1),
        ARG,
        r"^right: got cy=3\.5, expected the left camera's cy=2\.5",
        "rectify",
    ),
    Case(
        "StereoRig",
        lambda: StereoRig(CAM, dataclasses.replace(CAM, cx=CAM.cx - 2.0), 0.1),
        ARG,
        r"^right: got cx=1\.5, expected the left camera's cx=3\.5",
        "shift",
    ),
    Case(
        "ToFStereoRig",
        lambda: ToFStereoRig(CAM, RIG, Pose(), "middle"),
        ARG,
        r"^reference: got 'middle'",
    ),
    Case("ToFStereoRig", lambda: ToFStereoRig("x", RIG, Pose()), ARG, r"^tof: got str", "tof"),
    Case("ToFStereoRig", lambda: ToFStereoRig(CAM, CAM, Pose()), ARG, r"^stereo: got", "stereo"),
    Case(
        "ToFStereoRig",
        lambda: ToFStereoRig(CAM, RIG, np.eye(4)),
        ARG,
        r"^tof_to_reference: got ndarray",
        "pose",
    ),
    # -- geometry -------------------------------------------------------------------------------
    Case(
        "depth_to_disparity",
        lambda: depth_to_disparity(DEPTH, 1e300, 30.0),
        ARG,
        r"^baseline: got 1e\+300 with focal 30: baseline x focal",
        "huge baseline",
    ),
    Case(
        "depth_to_disparity",
        lambda: depth_to_disparity(np.zeros(3, np.complex64), 0.1, 100.0),
        ARG,
        r"^depth: got dtype complex64",
    ),
    Case(
        "depth_to_disparity",
        lambda: depth_to_disparity(DEPTH, "b", 100.0),
        ARG,
        r"^baseline: got 'b'",
        "baseline",
    ),
    Case(
        "depth_to_disparity",
        lambda: depth_to_disparity(DEPTH, 0.1, 0.0),
        ARG,
        r"^focal: got 0",
        "focal 0",
    ),
    Case(
        "disparity_to_depth",
        lambda: disparity_to_depth(DEPTH, 0.1, None),
        ARG,
        r"^focal: got None",
    ),
    Case(
        "disparity_to_depth",
        lambda: disparity_to_depth([[1.0], [2.0, 3.0]], 0.1, 10.0),
        ARG,
        r"^disparity: got list",
        "ragged",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(np.ones((6, 7)), CAM, CAM, Pose()),
        SHAPE,
        r"^depth: got shape \(6, 7\)",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(np.full((6, 8), 1500, np.uint16), CAM, CAM, Pose()),
        ARG,
        r"^depth: got dtype uint16, expected float depth in metres .*millimetres",
        "raw millimetres",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(DEPTH, CAM, CAM, "x"),
        ARG,
        r"^pose: got str",
        "pose",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(DEPTH, CAM, None, Pose()),
        ARG,
        r"^target: got NoneType",
        "target",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(DEPTH, CAM, CAM, Pose(), splat_radius=9),
        ARG,
        r"^splat_radius: got 9",
        "splat",
    ),
    Case(
        "reproject_depth",
        lambda: reproject_depth(DEPTH, CAM, CAM, Pose(), channels=np.ones((6, 9))),
        SHAPE,
        r"^channels: got shape \(6, 9\)",
        "channels",
    ),
    Case(
        "normals_from_points",
        lambda: normals_from_points(np.zeros((4, 4, 2))),
        SHAPE,
        r"^points: got shape \(4, 4, 2\)",
    ),
    Case(
        "normals_from_points",
        lambda: normals_from_points(np.zeros((0, 4, 3))),
        SHAPE,
        r"^points: got an empty array",
        "empty",
    ),
    Case(
        "normals_from_points",
        lambda: normals_from_points(np.zeros((2, 2, 3)), max_depth_jump="x"),
        ARG,
        r"^max_depth_jump: got 'x'",
        "jump",
    ),
    Case(
        "normals_from_depth",
        lambda: normals_from_depth(DEPTH, "cam"),
        ARG,
        r"^camera: got str",
    ),
    Case(
        "normals_from_depth",
        lambda: normals_from_depth(np.ones((5, 8)), CAM),
        SHAPE,
        r"^depth: got shape \(5, 8\)",
        "shape",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_shape_errors_name_image_axes_h_w() -> None:
    # A 3-channel depth given for a depth map reads as an image (H, W), a point list as (N, 3).
    from rgbd_rs import _validate

    with pytest.raises(
        ShapeMismatchError, match=r"^depth: got shape \(4, 5, 3\), expected \(H, W\)$"
    ):
        _validate.array("depth", np.zeros((4, 5, 3)), shape=(None, None))
    with pytest.raises(ShapeMismatchError, match=r"expected \(H, W, 3\)$"):
        _validate.array("rgb", np.zeros((4, 5)), shape=(None, None, 3))
    with pytest.raises(ShapeMismatchError, match=r"expected \(N, 3\)$"):
        _validate.array("points", np.zeros((4, 2)), shape=(None, 3))
    with pytest.raises(ShapeMismatchError, match=r"expected \(N, N, N\)$"):  # C x H x W: no names
        _validate.array("cues", np.zeros((4, 2)), shape=(None, None, None))
