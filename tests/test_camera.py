"""PinholeCamera / Distortion / Pose / rigs: construction, validation and basic algebra."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import (
    Distortion,
    InvalidArgumentError,
    PinholeCamera,
    Pose,
    RgbdError,
    ShapeMismatchError,
    StereoRig,
    ToFStereoRig,
)


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_error_hierarchy_is_value_error() -> None:
    assert issubclass(RgbdError, ValueError)
    assert issubclass(InvalidArgumentError, RgbdError)
    assert issubclass(ShapeMismatchError, RgbdError)


@pytest.mark.parametrize(
    ("kwargs", "arg"),
    [
        ({"fx": 0.0}, "fx"),
        ({"fy": -1.0}, "fy"),
        ({"cx": float("nan")}, "cx"),
        ({"width": 0}, "width"),
        ({"height": 2.5}, "height"),
    ],
)
def test_camera_rejects_bad_intrinsics(kwargs: dict[str, float], arg: str) -> None:
    base = {"fx": 500.0, "fy": 500.0, "cx": 320.0, "cy": 240.0, "width": 640, "height": 480}
    base.update(kwargs)
    with pytest.raises(InvalidArgumentError, match=f"^{arg}: got"):
        PinholeCamera(**base)  # type: ignore[arg-type]


def test_pinhole_projection_eq_2_3() -> None:
    cam = PinholeCamera(500.0, 510.0, 320.0, 240.0, 640, 480)
    px = cam.project(np.array([[0.2, -0.1, 2.0], [0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(px[0], [500 * 0.1 + 320, 510 * -0.05 + 240], atol=1e-12)
    assert np.isnan(px[1]).all()
    np.testing.assert_array_equal(cam.K, [[500, 0, 320], [0, 510, 240], [0, 0, 1]])
    assert PinholeCamera.from_matrix(cam.K, 640, 480) == cam


def test_scaled_and_cropped_keep_rays() -> None:
    cam = PinholeCamera(500.0, 500.0, 319.5, 239.5, 640, 480)
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (320, 240)
    # The centre of the image stays the centre; pixel (0,0)'s top-left corner stays a corner.
    assert half.cx == pytest.approx(159.5) and half.fx == pytest.approx(250.0)
    crop = cam.cropped(100, 50, 200, 100)
    p = np.array([[0.1, 0.05, 1.0]])
    np.testing.assert_allclose(crop.project(p), cam.project(p) - [100, 50])
    with pytest.raises(InvalidArgumentError, match=r"width"):
        cam.cropped(600, 0, 100, 10)


def test_distortion_opencv_order_and_validation() -> None:
    d = Distortion.from_opencv([0.1, -0.2, 0.001, 0.002, 0.03, 0.4, 0.5, 0.6])
    assert (d.k1, d.k2, d.p1, d.p2, d.k3, d.k4, d.k5, d.k6) == (
        0.1,
        -0.2,
        0.001,
        0.002,
        0.03,
        0.4,
        0.5,
        0.6,
    )
    assert Distortion.from_opencv([0.1, 0.2, 0.0, 0.0]).k3 == 0.0
    assert Distortion().is_identity
    with pytest.raises(ShapeMismatchError, match=r"coeffs: got 3 coefficients"):
        Distortion.from_opencv([1.0, 2.0, 3.0])
    with pytest.raises(InvalidArgumentError, match=r"distortion.k1"):
        Distortion(k1=float("inf"))


def test_pose_algebra() -> None:
    a = Pose(rot_z(0.3), np.array([0.1, 0.2, 0.3]))
    b = Pose(rot_z(-1.1), np.array([-1.0, 0.0, 2.0]))
    p = np.random.default_rng(0).normal(size=(10, 3))
    np.testing.assert_allclose(a.inverse().apply(a.apply(p)), p, atol=1e-12)
    np.testing.assert_allclose(b.compose(a).apply(p), b.apply(a.apply(p)), atol=1e-12)
    np.testing.assert_allclose(Pose.from_matrix(a.as_matrix()).rotation, a.rotation)
    with pytest.raises(InvalidArgumentError, match=r"rotation: got a matrix"):
        Pose(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ShapeMismatchError, match=r"translation: got shape \(2,\)"):
        Pose(np.eye(3), np.zeros(2))


def test_backproject_inverts_project() -> None:
    cam = PinholeCamera(500.0, 500.0, 320.0, 240.0, 640, 480, Distortion(k1=-0.2, k2=0.05, p1=1e-3))
    pts = np.random.default_rng(1).uniform([-1, -1, 1], [1, 1, 5], size=(1000, 3))
    np.testing.assert_allclose(cam.backproject(cam.project(pts), pts[:, 2]), pts, atol=1e-9)


def test_depth_to_points_matches_backproject() -> None:
    cam = PinholeCamera(300.0, 310.0, 31.5, 23.5, 64, 48, Distortion(k1=0.1, p2=1e-3))
    depth = np.random.default_rng(2).uniform(0.5, 3, size=(48, 64)).astype(np.float32)
    depth[5, 7] = np.nan
    depth[6, 7] = 0.0
    pts = cam.depth_to_points(depth)
    u, v = np.meshgrid(np.arange(64.0), np.arange(48.0))
    ref = cam.backproject(np.column_stack([u.ravel(), v.ravel()]), depth.ravel()).reshape(48, 64, 3)
    np.testing.assert_allclose(pts, ref, rtol=1e-6, atol=1e-6)
    assert np.isnan(pts[5, 7]).all() and np.isnan(pts[6, 7]).all()
    with pytest.raises(
        ShapeMismatchError, match=r"depth: got shape \(48, 63\), expected \(48, 64\)"
    ):
        cam.depth_to_points(depth[:, :63])


def test_rigs() -> None:
    left = PinholeCamera(700.0, 700.0, 479.5, 269.5, 960, 540)
    rig = StereoRig(left, left, 0.12)
    np.testing.assert_allclose(rig.left_to_right.translation, [-0.12, 0, 0])
    p = np.array([[0.3, 0.1, 2.0]])
    disparity = left.project(p)[0, 0] - left.project(rig.left_to_right.apply(p))[0, 0]
    assert disparity == pytest.approx(0.12 * 700 / 2.0)
    with pytest.raises(InvalidArgumentError, match=r"baseline"):
        StereoRig(left, left, 0.0)
    with pytest.raises(InvalidArgumentError, match=r"right: got"):
        StereoRig(left, left.scaled(0.5), 0.1)
    tof = PinholeCamera(360.0, 360.0, 255.5, 211.5, 512, 424)
    trig = ToFStereoRig(tof, rig, Pose(np.eye(3), np.array([0.0, -0.04, 0.0])))
    assert trig.reference_camera is rig.right
    with pytest.raises(InvalidArgumentError, match=r"reference"):
        ToFStereoRig(tof, rig, Pose(), reference="middle")  # type: ignore[arg-type]
