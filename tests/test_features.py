"""The eq. 4.1 per-pixel vectors (rgbd_rs.segmentation.features) on a real NYUv2 frame."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.segmentation.features import FEATURE_DIM, features, lab_colour
from rgbd_rs.segmentation.hha import hha_details


def camera() -> PinholeCamera:
    # NYU colour intrinsics (1-based in the toolbox) in rgbd_rs' 0-based convention.
    return PinholeCamera(518.857901, 519.469611, 324.582449, 252.736166, 640, 480)


@pytest.fixture(scope="module")
def frame(shared_data: Path) -> tuple[np.ndarray, np.ndarray]:
    root = shared_data / "nyuv2" / "frames"
    rgb = cv2.imread(str(root / "0001_rgb.png"))[:, :, ::-1].copy()
    depth = cv2.imread(str(root / "0001_depth.png"), cv2.IMREAD_UNCHANGED)
    depth = depth.astype(np.float32) / 1000
    # Punch holes (a missing-depth region and scattered pixels) to exercise invalid pixels.
    depth[100:140, 200:260] = np.nan
    depth[::37, ::41] = 0
    return rgb, depth


def test_contract_and_parts(frame: tuple[np.ndarray, np.ndarray]) -> None:
    rgb, depth = frame
    f = features(rgb, depth, camera())
    assert f.vectors.shape == (480, 640, FEATURE_DIM) and f.vectors.dtype == np.float32
    holes = ~(np.isfinite(depth) & (depth > 0))
    assert not f.valid[holes].any()
    assert np.isnan(f.vectors[~f.valid]).all(), "every channel NaN where invalid"
    assert np.isfinite(f.vectors[f.valid]).all()
    assert f.valid.mean() > 0.95
    # Unnormalised parts: Lab as OpenCV's float conversion, points from the calibration,
    # unit normals toward the camera.
    ref_lab = cv2.cvtColor(rgb.astype(np.float32) / 255, cv2.COLOR_RGB2Lab)
    assert np.allclose(f.lab, ref_lab, atol=1e-4)
    assert f.lab[:, :, 0].min() >= 0 and f.lab[:, :, 0].max() <= 100
    pts = camera().depth_to_points(depth)
    v = f.valid
    assert np.allclose(f.points[v], pts[v], rtol=1e-5, atol=1e-6)
    assert np.isnan(f.points[holes]).all()
    assert np.allclose(np.linalg.norm(f.normals[v], axis=1), 1.0, atol=1e-5)
    assert ((f.normals[v] * f.points[v]).sum(axis=1) <= 1e-6).all()
    # Each group divided by its average standard deviation: the normalised groups' average
    # standard deviation is 1, and sigma is the unnormalised one.
    for k, (part, sigma) in enumerate(zip((f.lab, f.points, f.normals), f.sigmas, strict=True)):
        group = f.vectors[v][:, 3 * k : 3 * k + 3].astype(np.float64)
        assert np.std(group, axis=0).mean() == pytest.approx(1.0, rel=1e-5)
        assert np.std(part[v].astype(np.float64), axis=0).mean() == pytest.approx(sigma, rel=1e-6)
        assert np.allclose(group, part[v] / sigma, rtol=1e-5, atol=1e-5)


def test_farther_scene_gives_the_same_vectors(frame: tuple[np.ndarray, np.ndarray]) -> None:
    """The same scene twice as far (depth x 2, units unchanged): the points double, sigma_g
    doubles, and every normalised vector stays the same."""
    rgb, depth = frame
    a = features(rgb, depth, camera())
    b = features(rgb, depth * 2, camera())
    assert np.array_equal(a.valid, b.valid)
    assert b.sigmas[1] == pytest.approx(2 * a.sigmas[1], rel=1e-6)
    assert b.sigmas[0] == a.sigmas[0] and b.sigmas[2] == pytest.approx(a.sigmas[2], rel=1e-5)
    assert np.allclose(a.vectors, b.vectors, atol=1e-4, equal_nan=True)


def test_brightness_moves_only_the_colour_group(frame: tuple[np.ndarray, np.ndarray]) -> None:
    """Halving the brightness changes Lab (L drops), but not position or normals; dividing by
    sigma_c keeps the colour group's spread at 1. A uniform Lab contrast change (L, a, b scaled
    by k about a fixed L) leaves the normalised colour differences between pixels unchanged."""
    rgb, depth = frame
    a = features(rgb, depth, camera())
    dark = (rgb.astype(np.float32) * 0.5).round().astype(np.uint8)
    b = features(dark, depth, camera())
    v = a.valid
    assert np.array_equal(a.vectors[:, :, 3:], b.vectors[:, :, 3:], equal_nan=True)
    assert b.lab[:, :, 0].mean() < a.lab[:, :, 0].mean() - 10
    assert np.std(b.vectors[v][:, :3].astype(np.float64), axis=0).mean() == pytest.approx(1.0)
    # Contrast: Lab' = k Lab about L = 50, back to uint8 RGB.
    k = 0.7
    lab = a.lab.copy()
    lab[:, :, 0] = 50 + k * (lab[:, :, 0] - 50)
    lab[:, :, 1:] *= k
    rgb2 = cv2.cvtColor(lab, cv2.COLOR_Lab2RGB)
    rgb2 = np.clip(np.round(rgb2 * 255), 0, 255).astype(np.uint8)
    c = features(rgb2, depth, camera())
    assert c.sigmas[0] == pytest.approx(k * a.sigmas[0], rel=0.05)
    da = a.vectors[v][:, :3] - a.vectors[v][:, :3].mean(axis=0)
    dc = c.vectors[v][:, :3] - c.vectors[v][:, :3].mean(axis=0)
    # uint8 rounding of the contrast-reduced image is the only difference.
    assert np.median(np.abs(da - dc)) < 0.05


def test_precomputed_normals_and_determinism(frame: tuple[np.ndarray, np.ndarray]) -> None:
    rgb, depth = frame
    a = features(rgb, depth, camera())
    b = features(rgb, depth, camera(), normals=hha_details(depth, camera()).normals)
    assert np.array_equal(a.vectors, b.vectors, equal_nan=True)
    assert a.sigmas == b.sigmas
    wide = features(rgb, depth, camera(), normal_radius=6)
    assert not np.array_equal(wide.normals, a.normals, equal_nan=True)


def test_lab_of_grey_has_no_chroma() -> None:
    grey = np.full((4, 5, 3), 128, np.uint8)
    lab = lab_colour(grey)
    assert np.allclose(lab[:, :, 1:], 0, atol=1e-3)
    assert lab[0, 0, 0] == pytest.approx(53.585, abs=0.01)


def test_uniform_image_keeps_colour_unscaled() -> None:
    """sigma_c = 0 (one colour): the colour group is left as Lab, not divided by zero."""
    cam = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)
    v, u = np.mgrid[0:24, 0:32]
    depth = (1.0 + 0.01 * u + 0.02 * v).astype(np.float32)
    f = features(np.full((24, 32, 3), 200, np.uint8), depth, cam)
    assert f.sigmas[0] == 0.0
    assert np.allclose(f.vectors[:, :, :3], f.lab)
