"""Bad input to the public API ends in an RgbdError that names the argument (ShapeMismatchError
for shapes, InvalidArgumentError otherwise), never another exception type, a panic or an aborted
interpreter.

This file holds the camera and geometry cases, the hostile fuzzing of their array arguments, the
memory-layout promises and the meta-test: every public callable of every public module has at
least one case here or in tests/test_bad_input_*.py (fusion; render, surface and meshes; data,
io, viz and metrics), or is listed in ``EXEMPT`` with the reason it takes no input to check.
"""

from __future__ import annotations

import inspect
import re
import types
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import rgbd_rs
import rgbd_rs.data
import rgbd_rs.fusion
import rgbd_rs.io
import rgbd_rs.meshes
import rgbd_rs.metrics
import rgbd_rs.render
import rgbd_rs.surface
import rgbd_rs.viz
from bad_input import Case, check, isolated, params
from rgbd_rs import (
    Distortion,
    InvalidArgumentError,
    PinholeCamera,
    Pose,
    Reprojection,
    RgbdError,
    ShapeMismatchError,
    StereoRig,
    ToFStereoRig,
    _rgbd_rs,
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
    Case("StereoRig", lambda: StereoRig("x", CAM, 0.1), ARG, r"^left: got str", "left"),
    Case("StereoRig", lambda: StereoRig(CAM, CAM.scaled(2.0), 0.1), ARG, r"^right: got", "size"),
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


# -- memory layout: unaligned, strided and Fortran-order arrays ----------------------------------


def _unaligned(shape: tuple[int, ...], dtype: type = np.float32) -> np.ndarray:
    n = int(np.prod(shape))
    size = np.dtype(dtype).itemsize
    buf = bytearray(n * size + 1)
    arr = np.frombuffer(buf, dtype, n, 1).reshape(shape)
    assert not arr.flags.aligned
    return arr


def test_unaligned_arrays_are_copied_and_work() -> None:
    """The issue's reproducer: an unaligned float32 buffer is copied, not refused."""
    a = _unaligned((2, 3))
    a[...] = [[0.1, 0.2, 1.0], [0.3, -0.1, 2.0]]
    np.testing.assert_array_equal(CAM.project(a), CAM.project(np.array(a)))
    d = _unaligned((6, 8))
    d[...] = 2.0
    np.testing.assert_array_equal(CAM.depth_to_points(d), CAM.depth_to_points(np.array(d)))
    np.testing.assert_array_equal(
        depth_to_disparity(d, 0.1, 100.0), depth_to_disparity(np.array(d), 0.1, 100.0)
    )
    u8 = _unaligned((6, 8), np.float64)
    u8[...] = 1.5
    np.testing.assert_array_equal(
        reproject_depth(u8, CAM, CAM, Pose()).depth,
        reproject_depth(np.array(u8), CAM, CAM, Pose()).depth,
    )


def test_fortran_order_gives_the_c_order_result() -> None:
    rng = np.random.default_rng(0)
    pts = rng.uniform(0.5, 2.0, (7, 3))
    np.testing.assert_array_equal(CAM.project(np.asfortranarray(pts)), CAM.project(pts))
    depth = rng.uniform(1.0, 2.0, (6, 8)).astype(np.float32)
    f = np.asfortranarray(depth)
    assert not f.flags.c_contiguous
    np.testing.assert_array_equal(CAM.depth_to_points(f), CAM.depth_to_points(depth))
    np.testing.assert_array_equal(
        normals_from_points(np.asfortranarray(CAM.depth_to_points(depth))),
        normals_from_points(CAM.depth_to_points(depth)),
    )
    np.testing.assert_array_equal(
        reproject_depth(f, CAM, CAM.scaled(2.0), Pose()).depth,
        reproject_depth(depth, CAM, CAM.scaled(2.0), Pose()).depth,
    )


def test_native_layer_never_reads_fortran_order_transposed() -> None:
    """The private module borrows through one layout-enforcing helper: a Fortran-order array
    either gives the C-order result or is refused naming the argument - never misread."""
    pts = np.random.default_rng(1).uniform(0.5, 2.0, (5, 3))
    want = _rgbd_rs.project_points(pts, CAM._native(), Pose()._native())
    try:
        got = _rgbd_rs.project_points(np.asfortranarray(pts), CAM._native(), Pose()._native())
    except RgbdError as exc:
        assert str(exc).startswith("points"), exc
    else:
        np.testing.assert_array_equal(got, want)


def test_non_contiguous_inputs_are_copied_not_misread() -> None:
    pts = np.random.default_rng(0).uniform(0.5, 2, size=(10, 6))[:, ::2]
    assert not pts.flags.c_contiguous
    np.testing.assert_array_equal(CAM.project(pts), CAM.project(np.ascontiguousarray(pts)))
    depth = np.ones((12, 16), np.float32)[::2, ::2]
    assert np.isfinite(CAM.depth_to_points(depth)).all()


def test_native_layer_validates_camera_tuples() -> None:
    bad = (0.0, 1.0, 0.0, 0.0, 4, 4, [0.0] * 8)
    with pytest.raises(InvalidArgumentError, match=r"^fx: got 0"):
        _rgbd_rs.project_points(np.zeros((1, 3)), bad, Pose()._native())
    with pytest.raises(ShapeMismatchError, match=r"^depth: got"):
        _rgbd_rs.depth_to_points(np.zeros((1, 5), np.float32), CAM._native(), 20, 1e-12)


# -- hostile fuzzing of the array arguments -----------------------------------------------------

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
DTYPES = st.sampled_from([np.float32, np.float64, np.int32, np.uint8, np.bool_, np.complex64])
ELEMENTS = st.floats(allow_nan=True, allow_infinity=True, width=32)


@st.composite
def arrays(draw: st.DrawFn) -> np.ndarray:
    shape = draw(hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=9))
    dtype = draw(DTYPES)
    if np.dtype(dtype).kind == "f":
        return draw(hnp.arrays(dtype, shape, elements=ELEMENTS))
    return draw(hnp.arrays(dtype, shape))


# name -> (call, the argument its errors must name, postcondition on a result)
FUZZ: dict[str, tuple[Callable[[np.ndarray], Any], str, Callable[[np.ndarray, Any], bool]]] = {
    "project": (CAM.project, "points", lambda a, r: r.shape == (len(a), 2)),
    "project_pose": (
        lambda a: CAM.project(a, Pose(np.eye(3), [0.0, 0.0, -1.0])),
        "points",
        lambda a, r: r.shape == (len(a), 2),
    ),
    "undistort_points": (CAM.undistort_points, "pixels", lambda a, r: r.shape == (len(a), 2)),
    "distort_points": (CAM.distort_points, "pixels", lambda a, r: r.shape == (len(a), 2)),
    "backproject": (
        lambda a: CAM.backproject(a, np.ones(len(a)) if a.ndim else a),
        "pixels|depth",
        lambda a, r: r.shape == (len(a), 3),
    ),
    "depth_to_points": (
        CAM.depth_to_points,
        "depth",
        lambda a, r: r.shape == (6, 8, 3) and r.dtype == np.float32,
    ),
    "undistort_image": (
        CAM.undistort_image,
        "image",
        lambda a, r: r.shape == a.shape,
    ),
    "undistort_image_nearest": (
        lambda a: CAM.undistort_image(a, interpolation="nearest"),
        "image",
        lambda a, r: r.shape == a.shape,
    ),
    "depth_to_disparity": (
        lambda a: depth_to_disparity(a, 0.1, 100.0),
        "depth",
        lambda a, r: r.shape == a.shape and r.dtype == np.float32,
    ),
    "disparity_to_depth": (
        lambda a: disparity_to_depth(a, 0.1, 100.0),
        "disparity",
        lambda a, r: r.shape == a.shape and r.dtype == np.float32,
    ),
    "reproject_depth": (
        lambda a: reproject_depth(a, CAM, CAM.scaled(2.0), Pose()),
        "depth",
        lambda a, r: isinstance(r, Reprojection) and r.depth.shape == (12, 16),
    ),
    "reproject_channels": (
        lambda a: reproject_depth(DEPTH, CAM, CAM, Pose(), channels=a),
        "channels",
        lambda a, r: r.channels is not None and r.channels.shape == a.shape,
    ),
    "normals_from_points": (
        normals_from_points,
        "points",
        lambda a, r: r.shape == a.shape and r.dtype == np.float32,
    ),
    "normals_from_depth": (
        lambda a: normals_from_depth(a, CAM),
        "depth",
        lambda a, r: r.shape == (6, 8, 3),
    ),
    "distortion_from_opencv": (
        Distortion.from_opencv,
        "coeffs",
        lambda a, r: isinstance(r, Distortion),
    ),
    "pose_rotation": (Pose, "rotation", lambda a, r: isinstance(r, Pose)),
    "pose_from_matrix": (Pose.from_matrix, "matrix", lambda a, r: isinstance(r, Pose)),
    "camera_from_matrix": (
        lambda a: PinholeCamera.from_matrix(a, 8, 6),
        "K",
        lambda a, r: isinstance(r, PinholeCamera),
    ),
}


@pytest.mark.parametrize("name", FUZZ)
@SETTINGS
@given(value=arrays())
def test_arrays_either_work_or_raise_a_named_error(name: str, value: np.ndarray) -> None:
    call, arg, ok = FUZZ[name]
    try:
        out = call(value)
    except RgbdError as exc:
        msg = str(exc)
        assert re.match(rf"^({arg})\b", msg), msg
        assert ": got " in msg and "expected" in msg, msg
        assert type(exc) in (InvalidArgumentError, ShapeMismatchError), type(exc)
        return
    assert ok(value, out), (name, value.shape, value.dtype)


SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-3, 3),
    st.integers(2**60, 2**1100),
    st.none(),
    st.text(max_size=2),
    st.booleans(),
)


@SETTINGS
@given(fx=SCALARS, fy=SCALARS, cx=SCALARS, w=SCALARS, h=SCALARS)
def test_camera_scalars(fx: Any, fy: Any, cx: Any, w: Any, h: Any) -> None:
    try:
        cam = PinholeCamera(fx, fy, cx, 0.0, w, h)
    except RgbdError as exc:
        assert type(exc) is InvalidArgumentError
        assert re.match(r"^(fx|fy|cx|width|height): got ", str(exc)), exc
        return
    assert cam.fx > 0 and cam.fy > 0 and cam.width >= 1 and cam.height >= 1
    assert np.isfinite([cam.fx, cam.fy, cam.cx]).all()


@SETTINGS
@given(baseline=SCALARS, focal=SCALARS, radius=SCALARS)
def test_rig_and_reprojection_scalars(baseline: Any, focal: Any, radius: Any) -> None:
    def named(pattern: str, call: Callable[[], Any]) -> Any:
        try:
            return call()
        except RgbdError as exc:
            assert type(exc) is InvalidArgumentError
            assert re.match(rf"^({pattern}): got ", str(exc)), exc
            return None

    rig = named("baseline", lambda: StereoRig(CAM, CAM, baseline))
    if rig is not None:
        assert rig.baseline > 0 and np.isfinite(rig.baseline)
    disp = named("baseline|focal", lambda: depth_to_disparity(np.ones(3), baseline, focal))
    if disp is not None and 1e-30 < float(baseline) * float(focal) < 1e30:  # float32 range
        np.testing.assert_allclose(disp, float(baseline) * float(focal), rtol=1e-5)
    rep = named(
        "splat_radius",
        lambda: reproject_depth(DEPTH, CAM, CAM, Pose(), splat_radius=radius),
    )
    if rep is not None:
        assert 0 <= radius <= 8 and rep.depth.shape == (6, 8)


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
    rgbd_rs.io,
    rgbd_rs.viz,
    rgbd_rs.metrics,
)

#: Public callables with no caller input to check, and why.
EXEMPT: dict[str, str] = {
    "Distortion.to_opencv": "no arguments",
    "Pose.identity": "no arguments",
    "Pose.as_matrix": "no arguments",
    "Pose.inverse": "no arguments (a validated Pose is invertible)",
    "PinholeCamera.without_distortion": "no arguments",
    "Reprojection": "result container built by reproject_depth",
    "FusionResult": "result container built by fuse",
    "ToFOnReference": "result container built by tof_to_reference",
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
    "Synth3Sample": "result container built by Synth3Dataset",
    "MiddleburyPair": "result container built by load_middlebury",
    "AzureKinectCalibration": "result container built by load_azure_kinect_calibration",
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
    from test_bad_input_data import CASES as DATA
    from test_bad_input_fusion import CASES as FUSION
    from test_bad_input_render import CASES as RENDER

    return [*CASES, *FUSION, *RENDER, *DATA]


def test_every_public_callable_has_a_bad_input_case() -> None:
    covered = {c.name for c in all_cases()}
    public = public_callables()
    missing = sorted(f"{public[n]}: {n}" for n in public if n not in covered and n not in EXEMPT)
    assert not missing, "public callables without a bad-input case:\n" + "\n".join(missing)
    stale = sorted((covered | set(EXEMPT)) - set(public))
    assert not stale, f"cases or exemptions for names that are not public: {stale}"
    assert not covered & set(EXEMPT), "a name is both covered and exempt"
