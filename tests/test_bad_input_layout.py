"""Memory layout (unaligned, strided, Fortran-order arrays are copied, never refused or misread)
and hostile fuzzing of the camera and geometry array and scalar arguments: each call either
returns a well-formed result or raises an RgbdError naming the argument."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rgbd_rs import (
    Distortion,
    InvalidArgumentError,
    PinholeCamera,
    Pose,
    Reprojection,
    RgbdError,
    ShapeMismatchError,
    StereoRig,
    _rgbd_rs,
    depth_to_disparity,
    disparity_to_depth,
    normals_from_depth,
    normals_from_points,
    reproject_depth,
)

CAM = PinholeCamera(20.0, 20.0, 3.5, 2.5, 8, 6, Distortion(k1=-0.1, k4=0.05))
DEPTH = np.ones((6, 8), np.float32)

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
@example(
    value=np.full((6, 8), 2147483584, np.int32)
)  # rounds to 2**31 in float32 (was a cast warning)
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
# Found by this fuzz in a fresh-clone run: an int baseline beyond 2**63 was kept as an int.
@example(baseline=2**64, focal=None, radius=None)
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
