"""The pose checks' batched projection (rgbd_rs.fusion._tof_points): many poses in one call give
what one pose at a time gives (Pose.apply, then the camera's projection)."""

from __future__ import annotations

import numpy as np

from rgbd_rs.camera import Pose
from rgbd_rs.data.synth import synth3_rig
from rgbd_rs.fusion._tof_points import paired_disparities, paired_many, turn_rotations


def _one_at_a_time(points, pose, rig, stereo):  # type: ignore[no-untyped-def]
    """The reference: each point moved by Pose.apply, projected, rounded, read from the map."""
    out_tof, out_st = [], []
    moved = pose.apply(points)
    for x, y, z in moved:
        if not z > 0:
            continue
        u, v = np.rint(rig.reference_camera.project(np.array([[x, y, z]]))[0])
        h, w = stereo.shape
        if not (0 <= u < w and 0 <= v < h):
            continue
        st, tof = float(stereo[int(v), int(u)]), rig.stereo.baseline * rig.stereo.focal / z
        if np.isfinite(st) and np.isfinite(tof):
            out_tof.append(tof)
            out_st.append(st)
    return np.array(out_tof), np.array(out_st)


def _case(seed: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    rig = synth3_rig(0.25)
    cam = rig.reference_camera
    stereo = rng.uniform(1, 40, (cam.height, cam.width)).astype(np.float32)
    stereo[rng.random(stereo.shape) < 0.2] = np.nan
    # Points in front, some far off the image, some behind the camera.
    points = np.column_stack(
        [rng.uniform(-3, 3, 300), rng.uniform(-2, 2, 300), rng.uniform(-0.5, 5, 300)]
    )
    return rig, stereo, points


def test_many_poses_at_once_equal_one_pose_at_a_time() -> None:
    for seed in range(3):
        rig, stereo, points = _case(seed)
        turns = [(0.0, 0.0), (2.0, 0.0), (0.0, -3.0), (-4.5, 1.25)]
        rotations = turn_rotations(rig.tof_to_reference.rotation, turns)
        translations = np.array([[0.01, 0, 0], [0, 0.02, 0], [0, 0, -0.03], [0.05, 0.01, 0.2]])
        tof, st, both = paired_many(points, rotations, translations, rig, stereo)
        assert tof.shape == st.shape == both.shape == (len(turns), len(points))
        for k in range(len(turns)):
            ref_tof, ref_st = _one_at_a_time(
                points, Pose(rotations[k], translations[k]), rig, stereo
            )
            assert 0 < ref_tof.size < len(points)  # the case has pixels dropped and kept
            np.testing.assert_array_equal(tof[k][both[k]], ref_tof)
            np.testing.assert_array_equal(st[k][both[k]], ref_st)


def test_one_point_set_per_pose_and_the_single_pose_form() -> None:
    rig, stereo, points = _case(7)
    pose = rig.tof_to_reference
    scaled = np.stack([points * g for g in (0.9, 1.0, 1.1)])
    tof, st, both = paired_many(
        scaled, np.stack([pose.rotation] * 3), pose.translation, rig, stereo
    )
    for k, g in enumerate((0.9, 1.0, 1.1)):
        ref_tof, ref_st = _one_at_a_time(points * g, pose, rig, stereo)
        np.testing.assert_array_equal(tof[k][both[k]], ref_tof)
        np.testing.assert_array_equal(st[k][both[k]], ref_st)
    single = paired_disparities(points, pose, rig, stereo)
    np.testing.assert_array_equal(single[0], tof[1][both[1]])


def test_turn_rotations_are_the_turns_asked() -> None:
    base = Pose(turn_rotations(np.eye(3), [(10.0, -20.0)])[0]).rotation
    out = turn_rotations(base, [(0.0, 0.0), (30.0, 0.0), (0.0, 45.0)])
    np.testing.assert_array_equal(out[0], base)  # no turn: the rotation itself
    a, b = np.deg2rad(30.0), np.deg2rad(45.0)
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    np.testing.assert_allclose(out[1], ry @ base, atol=1e-12)
    np.testing.assert_allclose(out[2], rx @ base, atol=1e-12)
    for r in out:
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) > 0
