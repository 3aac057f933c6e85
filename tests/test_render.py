"""Rendering: exact geometry through the Python API, the SYNTH3 rig, ToF error sources."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import PinholeCamera, Pose, RgbdError, reproject_depth
from rgbd_rs.data.synth import _rig_poses, synth3_rig
from rgbd_rs.meshes import box, quad, sphere
from rgbd_rs.render import Material, OrthographicCamera, Scene, Texture, ToFModel, render_points


def wall(z: float, half: float = 20.0) -> Scene:
    return Scene().add(
        quad([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    )


def test_plane_gives_analytic_disparity_on_the_synth3_rig() -> None:
    rig = synth3_rig(0.25)  # 480x270
    scene = wall(3.7).build()
    _, to_right, _ = _rig_poses(rig)
    z = scene.depth(rig.reference_camera, to_right)
    np.testing.assert_allclose(z, 3.7, rtol=1e-6)
    from rgbd_rs import depth_to_disparity

    d = depth_to_disparity(z, rig.stereo.baseline, rig.stereo.focal)
    np.testing.assert_allclose(d, 0.12 * rig.stereo.focal / 3.7, rtol=1e-5)


def test_stereo_gt_matches_the_left_view() -> None:
    """Right pixel u_r = u_l - d with d = b f / z sees the depth the left pixel sees."""
    rig = synth3_rig(0.25)
    pts = np.array([[-9, -9], [9, -9], [9, 9], [-9, 9]], float)
    slanted = quad(np.column_stack([pts, 3.0 + 0.2 * pts[:, 0]]))  # z = 3 + 0.2 x
    built = Scene().add(slanted).build()
    to_left, to_right, _ = _rig_poses(rig)
    zl = built.depth(rig.stereo.left, to_left)
    zr = built.depth(rig.stereo.right, to_right)
    cols = np.arange(zl.shape[1], dtype=float)
    d = rig.stereo.baseline * rig.stereo.focal / zl
    for r in range(0, zl.shape[0], 17):
        ur = cols - d[r]
        ok = (ur >= 0) & (ur <= cols[-1])
        np.testing.assert_allclose(np.interp(ur[ok], cols, zr[r]), zl[r][ok], rtol=1e-4)


def test_tof_truth_reprojected_lands_on_the_reference_gt() -> None:
    rig = synth3_rig(0.5)
    s = (
        Scene()
        .add(sphere(0.5, center=(0.0, 0.1, 2.5), rings=48, segments=96))
        .add(wall(4.0).objects[0][0])
    )
    built = s.build()
    _, to_right, to_tof = _rig_poses(rig)
    frame = built.tof(rig.tof, to_tof, ToFModel.ideal())
    gt = built.depth(rig.reference_camera, to_right)
    rep = reproject_depth(
        frame.truth, rig.tof, rig.reference_camera, rig.tof_to_reference, splat_radius=1
    )
    both = np.isfinite(rep.depth) & np.isfinite(gt)
    assert both.mean() > 0.8
    err = np.abs(rep.depth - gt)[both]
    # Exact away from the sphere's silhouette (where splats of one view see the other surface).
    assert np.median(err) < 1e-4 and np.mean(err < 0.01) > 0.97
    # The ideal sensor measures the truth.
    np.testing.assert_allclose(frame.depth, frame.truth, atol=2e-5)


def test_tof_effects_move_the_error_as_physics_says() -> None:
    rig = synth3_rig(0.25)
    scene = Scene()
    scene.add(
        quad([[-3, -3, 3.0], [0, -3, 3.0], [0, 3, 3.0], [-3, 3, 3.0]]), Material(albedo_ir=0.8)
    )
    scene.add(
        quad([[0, -3, 3.0], [3, -3, 3.0], [3, 3, 3.0], [0, 3, 3.0]]), Material(albedo_ir=0.05)
    )
    scene.add(box((0.4, 0.4, 0.4), center=(-0.8, 0.0, 2.0)), Material(albedo_ir=0.8))
    built = scene.build()
    _, _, to_tof = _rig_poses(rig)
    model = ToFModel()

    def err(m: ToFModel) -> tuple[np.ndarray, np.ndarray]:
        f = built.tof(rig.tof, to_tof, m, seed=3)
        return f.depth - f.truth, f.amplitude

    mixed, _ = err(model.only("mixed"))
    gt = built.gbuffer(rig.tof, to_tof)
    edges = np.zeros_like(gt.depth, bool)
    z = gt.depth
    for axis in (0, 1):
        a, b = np.moveaxis(z, axis, 0)[1:], np.moveaxis(z, axis, 0)[:-1]
        jump = (np.abs(a - b) > 0.1) | (np.isnan(a) != np.isnan(b))
        e = np.moveaxis(edges, axis, 0)
        e[1:] |= jump
        e[:-1] |= jump
    near_edge = np.zeros_like(edges)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_edge |= np.roll(np.roll(edges, dy, 0), dx, 1)
    big = np.abs(mixed) > 0.01
    assert big.any() and big[~near_edge].sum() == 0  # mixed pixels only near depth edges

    noise, _ = err(model.only("noise"))
    cols = noise.shape[1]
    bright = noise[:, 30 : cols // 2 - 30][np.abs(gt.depth[:, 30 : cols // 2 - 30] - 3) < 1e-3]
    dark = noise[:, cols // 2 + 30 :]
    assert np.nanstd(dark) > 2 * np.nanstd(bright) > 0  # noise rises as albedo falls

    dropout = ToFModel(amplitude_threshold=500.0).only("dropout")  # bright ~850+, dark ~110
    e, _ = err(dropout)
    assert np.isnan(e[:, cols // 2 + 30 :]).all() and np.isfinite(e[:, 40:60]).all()

    corner = Scene()
    corner.add(quad([[-3, -3, 3.0], [3, -3, 3.0], [3, 3, 3.0], [-3, 3, 3.0]]))
    corner.add(quad([[1, -3, 1.0], [1, 3, 1.0], [1, 3, 3.0], [1, -3, 3.0]]))
    c = corner.build().tof(
        rig.tof, to_tof, ToFModel(frequency_hz=20e6, multipath_rays=32).only("multipath")
    )
    bias = (c.depth - c.truth)[:, 200:300]
    assert np.nanmean(bias) > 0.003 and np.nanmin(bias) > -1e-4  # multipath lengthens paths


def test_orthographic_views_and_point_splats() -> None:
    built = Scene().add(box((1.0, 1.0, 1.0))).build()
    cam = OrthographicCamera(scale=50.0, width=80, height=80)
    pose = Pose(np.eye(3), np.array([0.0, 0.0, 2.0]))  # box centre 2 m in front
    g = built.gbuffer(cam, pose)
    inside = np.isfinite(g.depth)
    assert abs(inside.sum() - 50 * 50) <= 2 * 50 * 2  # a 1 m square at 50 px/m
    np.testing.assert_allclose(g.depth[inside], 1.5, atol=1e-6)
    np.testing.assert_allclose(g.normal[inside], [[0, 0, -1]] * int(inside.sum()), atol=1e-6)
    pts = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.5]], np.float32)
    d, idx = render_points(pts, cam, pose, radius=0.1)
    assert idx[40, 40] == 1 and d[40, 40] == pytest.approx(2.5)  # the nearer point wins
    assert np.isnan(d[0, 0]) and idx[0, 0] == -1


def test_color_is_deterministic_and_textured() -> None:
    cam = PinholeCamera(60.0, 60.0, 31.5, 23.5, 64, 48)
    s = Scene(ambient=0.5).add(
        box((4, 4, 0.1), center=(0, 0, 2.0)), Material(texture=Texture.checker(0.2))
    )
    built = s.build()
    a = built.color(cam, supersample=2)
    assert a.shape == (48, 64, 3) and a.dtype == np.float32
    np.testing.assert_array_equal(a, built.color(cam, supersample=2))
    assert a[..., 0].std() > 0.05  # the checker shows


def test_bad_input_is_named() -> None:
    cam = PinholeCamera(60.0, 60.0, 31.5, 23.5, 64, 48)
    built = wall(2.0).build()
    with pytest.raises(RgbdError, match="supersample"):
        built.color(cam, supersample=0)
    with pytest.raises(RgbdError, match="distortion"):
        built.depth(PinholeCamera(60.0, 60.0, 31.5, 23.5, 64, 48, distortion=_dist()))
    with pytest.raises(RgbdError, match="albedo"):
        Scene().add(box((1, 1, 1)), Material(albedo_ir=2.0)).build()
    with pytest.raises(RgbdError, match="subsamples"):
        built.tof(cam, model=ToFModel(subsamples=0))
    with pytest.raises(RgbdError, match="points"):
        render_points(np.zeros((3, 2)), cam, radius=0.1)


def _dist():  # type: ignore[no-untyped-def]
    from rgbd_rs import Distortion

    return Distortion.from_opencv([0.1, 0, 0, 0, 0])
