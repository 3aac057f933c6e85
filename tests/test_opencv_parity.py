"""Parity with OpenCV: projection, point undistortion, undistortion maps and remapping, for the
Heikkila / Brown-Conrady model (5 coefficients) and its rational extension (8)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rgbd_rs import Distortion, PinholeCamera, Pose

PX_TOL = 1e-4  # the parity tolerance, pixels

MODELS = {
    "brown5": [-0.28, 0.07, 1e-3, -5e-4, -0.008],
    # Azure Kinect colour camera factory coefficients (rational model; k4..k6 in the denominator).
    "rational8": [0.3301, -2.4894, -1.618e-4, -1.294e-4, 1.4537, 0.2089, -2.3029, 1.3751],
}


def camera(model: str) -> PinholeCamera:
    return PinholeCamera(
        611.8, 611.9, 639.3, 365.9, 1280, 720, Distortion.from_opencv(MODELS[model])
    )


def rodrigues_pose(seed: int) -> tuple[Pose, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    rvec = rng.normal(scale=0.1, size=3)
    tvec = rng.normal(scale=0.1, size=3)
    r, _ = cv2.Rodrigues(rvec)
    return Pose(r, tvec), rvec, tvec


def points_in_view(cam: PinholeCamera, n: int, seed: int) -> np.ndarray:
    """Random points whose ideal projections lie inside the image (where calibrations are valid)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0, cam.width - 1, n)
    v = rng.uniform(0, cam.height - 1, n)
    z = rng.uniform(0.3, 8.0, n)
    return np.column_stack([(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z])


@pytest.mark.parametrize("model", MODELS)
def test_project_points_matches_cv2(model: str) -> None:
    cam = camera(model)
    pose, rvec, tvec = rodrigues_pose(3)
    pts = pose.inverse().apply(points_in_view(cam, 20_000, 4))
    ours = cam.project(pts, pose)
    ref, _ = cv2.projectPoints(pts, rvec, tvec, cam.K, cam.distortion.to_opencv())
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=PX_TOL, rtol=0)


@pytest.mark.parametrize("model", MODELS)
def test_undistort_points_matches_cv2_iterative(model: str) -> None:
    cam = camera(model)
    ideal = points_in_view(cam, 20_000, 5)
    distorted = cam.project(ideal)
    ours = cam.undistort_points(distorted)
    # cv2.undistortPoints stops after 5 fixed-point steps by default; with a tight criterion it
    # converges to the same inverse we compute with Newton.
    ref = cv2.undistortPoints(
        distorted.reshape(-1, 1, 2),
        cam.K,
        cam.distortion.to_opencv(),
        R=None,
        P=cam.K,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14),
    ).reshape(-1, 2)
    np.testing.assert_allclose(ours, ref, atol=PX_TOL, rtol=0)
    # ... and both are the true ideal projections.
    np.testing.assert_allclose(ours, cam.without_distortion().project(ideal), atol=1e-6, rtol=0)
    norm = cam.undistort_points(distorted, normalized=True)
    np.testing.assert_allclose(norm, ideal[:, :2] / ideal[:, 2:], atol=1e-9)


def test_undistort_points_matches_default_cv2_on_mild_distortion() -> None:
    cam = PinholeCamera(600.0, 600.0, 320.0, 240.0, 640, 480, Distortion(k1=-0.05, k2=0.01))
    px = np.random.default_rng(6).uniform([0, 0], [639, 479], size=(5000, 2))
    ref = cv2.undistortPoints(px.reshape(-1, 1, 2), cam.K, cam.distortion.to_opencv(), P=cam.K)
    np.testing.assert_allclose(cam.undistort_points(px), ref.reshape(-1, 2), atol=PX_TOL)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("rectify", [False, True])
def test_undistort_map_matches_init_undistort_rectify_map(model: str, rectify: bool) -> None:
    cam = camera(model)
    target = PinholeCamera(500.0, 500.0, 630.0, 360.0, 1280, 720)
    r = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0] if rectify else None
    ours = cam.undistort_map(target, r)
    mx, my = cv2.initUndistortRectifyMap(
        cam.K, cam.distortion.to_opencv(), r, target.K, target.size, cv2.CV_32FC1
    )
    # Both are float32 maps of the same formula; float32 rounding of ~1000 px values is 6e-5.
    np.testing.assert_allclose(ours[..., 0], mx, atol=2e-4, rtol=0)
    np.testing.assert_allclose(ours[..., 1], my, atol=2e-4, rtol=0)


def test_undistort_image_matches_cv2_remap() -> None:
    cam = camera("brown5")
    rng = np.random.default_rng(7)
    img = cv2.GaussianBlur(rng.uniform(0, 255, (720, 1280, 3)).astype(np.float32), (0, 0), 3)
    ours = cam.undistort_image(img)
    mx, my = cv2.initUndistortRectifyMap(
        cam.K, cam.distortion.to_opencv(), None, cam.K, cam.size, cv2.CV_32FC1
    )
    ref = cv2.remap(
        img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan
    )
    inside = np.isfinite(ours).all(axis=2) & np.isfinite(ref).all(axis=2)
    assert inside.mean() > 0.9
    # OpenCV interpolates with 1/32-pixel fixed-point weights; on this smooth image that is
    # well under one grey level.
    assert np.abs(ours[inside] - ref[inside]).max() < 0.5
    nearest = cam.undistort_image(img[:, :, 0], interpolation="nearest")
    ref_n = cv2.remap(img[:, :, 0], mx, my, cv2.INTER_NEAREST, borderValue=np.nan)
    agree = np.isfinite(nearest) & np.isfinite(ref_n)
    assert (nearest[agree] == ref_n[agree]).mean() > 0.99
    u8 = cam.undistort_image(img.astype(np.uint8))
    assert u8.dtype == np.uint8 and u8.shape == img.shape
