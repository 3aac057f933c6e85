"""Every public function, fed random shapes, dtypes, NaN/inf, empty arrays and bad scalars, either
returns a well-formed result or raises an RgbdError naming the argument - never anything else
(no TypeError from numpy, no panic from Rust)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rgbd_rs import (
    Distortion,
    InvalidArgumentError,
    PinholeCamera,
    Pose,
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


CALLS: dict[str, Callable[[np.ndarray], Any]] = {
    "project": lambda a: CAM.project(a),
    "project_pose": lambda a: CAM.project(a, Pose(np.eye(3), [0.0, 0.0, -1.0])),
    "undistort_points": lambda a: CAM.undistort_points(a),
    "distort_points": lambda a: CAM.distort_points(a),
    "backproject": lambda a: CAM.backproject(a, np.ones(len(a)) if a.ndim else a),
    "depth_to_points": lambda a: CAM.depth_to_points(a),
    "undistort_image": lambda a: CAM.undistort_image(a),
    "undistort_image_nearest": lambda a: CAM.undistort_image(a, interpolation="nearest"),
    "depth_to_disparity": lambda a: depth_to_disparity(a, 0.1, 100.0),
    "disparity_to_depth": lambda a: disparity_to_depth(a, 0.1, 100.0),
    "reproject_depth": lambda a: reproject_depth(a, CAM, CAM.scaled(2.0), Pose()),
    "reproject_channels": lambda a: reproject_depth(
        np.ones((6, 8), np.float32), CAM, CAM, Pose(), channels=a
    ),
    "normals_from_points": lambda a: normals_from_points(a),
    "normals_from_depth": lambda a: normals_from_depth(a, CAM),
    "distortion_from_opencv": lambda a: Distortion.from_opencv(a),
    "pose_rotation": lambda a: Pose(a),
    "pose_from_matrix": lambda a: Pose.from_matrix(a),
    "camera_from_matrix": lambda a: PinholeCamera.from_matrix(a, 8, 6),
}


@pytest.mark.parametrize("name", CALLS)
@SETTINGS
@given(value=arrays())
def test_arrays_either_work_or_raise_rgbd_error(name: str, value: np.ndarray) -> None:
    try:
        out = CALLS[name](value)
    except RgbdError as exc:
        msg = str(exc)
        assert ": got " in msg and "expected" in msg, msg
        return
    assert out is not None


SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-3, 3),
    st.none(),
    st.text(max_size=2),
    st.booleans(),
)


@SETTINGS
@given(fx=SCALARS, fy=SCALARS, cx=SCALARS, w=SCALARS, h=SCALARS)
def test_camera_scalars(fx: Any, fy: Any, cx: Any, w: Any, h: Any) -> None:
    try:
        cam = PinholeCamera(fx, fy, cx, 0.0, w, h)
    except RgbdError:
        return
    assert cam.fx > 0 and cam.fy > 0 and cam.width >= 1 and cam.height >= 1


@SETTINGS
@given(baseline=SCALARS, focal=SCALARS, radius=SCALARS)
def test_rig_and_reprojection_scalars(baseline: Any, focal: Any, radius: Any) -> None:
    for call in (
        lambda: StereoRig(CAM, CAM, baseline),
        lambda: depth_to_disparity(np.ones(3, np.float32), baseline, focal),
        lambda: reproject_depth(np.ones((6, 8), np.float32), CAM, CAM, Pose(), splat_radius=radius),
    ):
        with contextlib.suppress(RgbdError):
            call()


def test_specific_messages() -> None:
    with pytest.raises(ShapeMismatchError, match=r"^points: got shape \(4, 2\), expected \(N, 3\)"):
        CAM.project(np.zeros((4, 2)))
    with pytest.raises(InvalidArgumentError, match=r"^points: got dtype complex64"):
        CAM.project(np.zeros((4, 3), np.complex64))
    with pytest.raises(ShapeMismatchError, match=r"empty"):
        normals_from_points(np.zeros((0, 4, 3)))
    with pytest.raises(InvalidArgumentError, match=r"^interpolation: got 'cubic'"):
        CAM.undistort_image(np.zeros((6, 8)), interpolation="cubic")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match=r"^splat_radius: got 9"):
        reproject_depth(np.ones((6, 8)), CAM, CAM, Pose(), splat_radius=9)
    with pytest.raises(InvalidArgumentError, match=r"^max_iter: got 0"):
        CAM.undistort_points(np.zeros((1, 2)), max_iter=0)


def test_non_contiguous_inputs_are_copied_not_misread() -> None:
    pts = np.random.default_rng(0).uniform(0.5, 2, size=(10, 6))[:, ::2]
    assert not pts.flags.c_contiguous
    np.testing.assert_array_equal(CAM.project(pts), CAM.project(np.ascontiguousarray(pts)))
    depth = np.ones((12, 16), np.float32)[::2, ::2]
    assert np.isfinite(CAM.depth_to_points(depth)).all()


def test_native_layer_rejects_non_contiguous_arrays() -> None:
    pts = np.zeros((10, 6))[:, ::2]
    with pytest.raises(InvalidArgumentError, match=r"points: got a non-contiguous array"):
        _rgbd_rs.project_points(pts, CAM._native(), Pose()._native())


def test_native_layer_validates_camera_tuples() -> None:
    bad = (0.0, 1.0, 0.0, 0.0, 4, 4, [0.0] * 8)
    with pytest.raises(InvalidArgumentError, match=r"^fx: got 0"):
        _rgbd_rs.project_points(np.zeros((1, 3)), bad, Pose()._native())
    with pytest.raises(ShapeMismatchError, match=r"^depth: got 5 elements"):
        _rgbd_rs.depth_to_points(np.zeros((1, 5), np.float32), CAM._native(), 20, 1e-12)
