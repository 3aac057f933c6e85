"""Depth <-> disparity, z-buffered reprojection and normals."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import (
    InvalidArgumentError,
    PinholeCamera,
    Pose,
    depth_to_disparity,
    disparity_to_depth,
    normals_from_depth,
    normals_from_points,
    reproject_depth,
)
from rgbd_rs.demo import run_synthetic


def test_depth_disparity_eq_2_15() -> None:
    depth = np.array([[2.0, 0.0], [-1.0, np.nan]], np.float32)
    d = depth_to_disparity(depth, baseline=0.12, focal=1000.0)
    assert d.shape == (2, 2) and d.dtype == np.float32
    assert d[0, 0] == pytest.approx(60.0)
    assert np.isnan(d.ravel()[1:]).all()
    np.testing.assert_allclose(disparity_to_depth(d, 0.12, 1000.0)[0, 0], 2.0, rtol=1e-6)
    with pytest.raises(InvalidArgumentError, match=r"^baseline: got 0"):
        depth_to_disparity(depth, 0.0, 1000.0)
    with pytest.raises(InvalidArgumentError, match=r"^focal: got -5"):
        disparity_to_depth(depth, 0.1, -5.0)


def test_reprojection_on_analytic_scene() -> None:
    # Two distorted cameras, analytic depth in both: the reprojected map must agree with the
    # target's own depth (nearest-pixel splatting: sub-millimetre median at 2-3 m).
    res = run_synthetic(None, seed=0)
    assert res.point_round_trip_m < 1e-9
    assert res.reprojection_coverage > 0.95
    assert res.reprojection_median_abs_m < 2e-3


def test_reprojection_hides_occluded_points_and_carries_channels() -> None:
    cam = PinholeCamera(40.0, 40.0, 19.5, 19.5, 40, 40)
    depth = np.full((40, 40), 4.0, np.float32)
    depth[15:25, 15:25] = 1.0
    label = np.zeros((40, 40), np.float32)
    label[15:25, 15:25] = 1.0
    out = reproject_depth(
        depth, cam, cam, Pose(np.eye(3), np.array([0.2, 0.0, 0.0])), channels=label, splat_radius=1
    )
    # The near square moves 8 px, the wall 2 px: where both land the square must win.
    assert out.depth[20, 27] == pytest.approx(1.0)
    assert out.channels is not None and out.channels.shape == (40, 40)
    assert out.channels[20, 27] == 1.0 and out.channels[5, 5] == 0.0
    assert depth.ravel()[out.source_index[20, 27]] == 1.0
    # Without splatting, target columns 17..22 of the square's rows see the wall behind the
    # square, which the source never observed (disocclusion): they stay NaN, the rest is filled.
    sparse = reproject_depth(depth, cam, cam, Pose(np.eye(3), np.array([0.2, 0.0, 0.0])))
    assert np.isnan(sparse.depth[15:25, 17:23]).all()
    assert np.isfinite(sparse.depth[15:25, 23:33]).all()
    assert (sparse.source_index[15:25, 17:23] == -1).all()


def test_sparse_reprojection_to_finer_lattice() -> None:
    tof = PinholeCamera(100.0, 100.0, 31.5, 23.5, 64, 48)
    rgb = tof.scaled(3.0)
    out = reproject_depth(np.full((48, 64), 2.0, np.float32), tof, rgb, Pose())
    # Radius 0: every source pixel lands on exactly one target pixel (no holes filled).
    assert np.isfinite(out.depth).sum() == 64 * 48
    dense = reproject_depth(np.full((48, 64), 2.0, np.float32), tof, rgb, Pose(), splat_radius=1)
    assert dense.coverage > 0.99


def test_normals_plane_and_sphere() -> None:
    cam = PinholeCamera(200.0, 200.0, 63.5, 47.5, 128, 96)
    u, v = np.meshgrid(np.arange(128.0), np.arange(96.0))
    x, y = (u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy
    # Plane n·X = -2 with n = (0.3, -0.2, -1)/|.|: z = -2 / (n · (x, y, 1)).
    n = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    depth = (-2.0 / (n[0] * x + n[1] * y + n[2])).astype(np.float32)
    depth[40:44, 60:64] = np.nan
    normals = normals_from_depth(depth, cam)
    ok = np.isfinite(normals).all(axis=2)
    assert ok.sum() == 128 * 96 - 16
    np.testing.assert_allclose(normals[ok], np.broadcast_to(n, (ok.sum(), 3)), atol=1e-4)
    # Sphere of radius 1 at z = 3: normals equal (P - C) / r and face the camera.
    c = np.array([0.0, 0.0, 3.0])
    d = np.stack([x, y, np.ones_like(x)], axis=2)
    b = d @ c
    a = (d**2).sum(axis=2)
    disc = b**2 - a * (c @ c - 1.0)
    with np.errstate(invalid="ignore"):
        s = (b - np.sqrt(disc)) / a
    pts = (d * s[..., None]).astype(np.float32)
    nrm = normals_from_points(pts, max_depth_jump=0.05)
    inner = np.isfinite(nrm).all(axis=2) & (disc > 0.05 * a)
    ref = (pts[inner] - c) / np.linalg.norm(pts[inner] - c, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip((nrm[inner] * ref).sum(axis=1), -1, 1))).max() < 2.0
    assert (nrm[inner] @ np.array([0, 0, 1.0]) < 0).all()


def test_raw_integer_depth_is_refused_everywhere_depth_means_metres() -> None:
    """reproject_depth and segment refused a uint16 millimetre map; these read it as metres."""
    from rgbd_rs import InvalidArgumentError, PinholeCamera, depth_to_disparity
    from rgbd_rs.geometry import normals_from_depth

    cam = PinholeCamera(fx=100, fy=100, cx=3.5, cy=3.5, width=8, height=8)
    raw = np.full((8, 8), 1500, np.uint16)
    for call in (
        lambda: cam.depth_to_points(raw),
        lambda: depth_to_disparity(raw, 0.1, 100.0),
        lambda: normals_from_depth(raw, cam),
    ):
        with pytest.raises(InvalidArgumentError, match=r"^depth: got dtype uint16, expected float"):
            call()
    with pytest.raises(InvalidArgumentError, match=r"^depth: got dtype uint16"):
        depth_to_disparity(raw[1, 1], 0.1, 100.0)  # a numpy scalar read from the raw map
    metres = raw / 1000
    assert np.allclose(cam.depth_to_points(metres)[..., 2], 1.5)
    assert np.allclose(depth_to_disparity(metres, 0.1, 100.0), 0.1 * 100 / 1.5)


def test_depth_and_disparity_of_a_single_value() -> None:
    """'any shape' includes a scalar (it was refused as 'got shape (), expected (N)')."""
    from rgbd_rs import depth_to_disparity, disparity_to_depth

    d = depth_to_disparity(2.0, 0.1, 500.0)
    assert d.shape == () and d.dtype == np.float32 and float(d) == 25.0
    assert float(disparity_to_depth(d, 0.1, 500.0)) == 2.0
    assert np.isnan(depth_to_disparity(0.0, 0.1, 500.0))
