"""ToF pixels as 3-D points, projected into the reference camera and paired with the stereo map:
what the pose checks (:mod:`rgbd_rs.fusion._pose_check`, :mod:`rgbd_rs.fusion.pose_refine`)
compare."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs.camera import Pose, ToFStereoRig

F64 = npt.NDArray[np.float64]


def sample_points(depth: npt.NDArray[np.float32], rig: ToFStereoRig, count: int) -> F64:
    """Up to ``count`` evenly spaced valid ToF pixels (finite depth > 0) as ``N x 3`` points in
    the ToF frame (deterministic: no random draw)."""
    with np.errstate(invalid="ignore"):
        valid = np.flatnonzero(np.isfinite(depth) & (depth > 0))
    if valid.size == 0:
        return np.zeros((0, 3))
    pick = valid[np.linspace(0, valid.size - 1, min(count, valid.size)).astype(np.intp)]
    v, u = np.divmod(pick, depth.shape[1])
    return rig.tof.backproject(np.column_stack([u, v]).astype(np.float64), depth.flat[pick])


def paired_disparities(
    points: F64, pose: Pose, rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> tuple[F64, F64]:
    """``(tof, stereo)``: the disparities of ``points`` moved by ``pose`` (ToF frame -> the
    reference camera's) and the stereo map's at the pixels they land on (nearest pixel), where
    both are finite."""
    moved = pose.apply(points)
    z = moved[:, 2]
    with np.errstate(invalid="ignore"):
        front = np.isfinite(z) & (z > 0)
    if not front.any():
        return np.zeros(0), np.zeros(0)
    uv = np.rint(rig.reference_camera.project(moved[front]))
    h, w = stereo.shape
    with np.errstate(invalid="ignore"):
        inside = (
            np.isfinite(uv).all(axis=1)
            & (uv[:, 0] >= 0)
            & (uv[:, 0] < w)
            & (uv[:, 1] >= 0)
            & (uv[:, 1] < h)
        )
    st = stereo[uv[inside, 1].astype(np.intp), uv[inside, 0].astype(np.intp)].astype(np.float64)
    tof = rig.stereo.baseline * rig.stereo.focal / z[front][inside]
    both = np.isfinite(st) & np.isfinite(tof)
    return tof[both], st[both]
