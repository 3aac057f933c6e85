"""ToF pixels as 3-D points, projected into the reference camera and paired with the stereo map:
what the pose checks (:mod:`rgbd_rs.fusion._pose_check`, :mod:`rgbd_rs.fusion.pose_refine`)
compare."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs
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
    tof, st, both = paired_many(points, pose.rotation[None], pose.translation, rig, stereo)
    return tof[0][both[0]], st[0][both[0]]


def turn_rotations(rotation: F64, turns: npt.ArrayLike) -> F64:
    """The rotations of a ToF turned about its own centre by each ``(yaw, pitch)`` of ``turns``
    (``K x 2``, degrees; yaw about the reference camera's y axis, then pitch about its x axis),
    after ``rotation``: ``K x 3 x 3``, re-orthonormalised (SVD) so a rotation at the edge of
    :class:`~rgbd_rs.camera.Pose`'s tolerance stays inside it. A zero turn gives ``rotation``."""
    t = np.deg2rad(np.asarray(turns, dtype=np.float64).reshape(-1, 2))
    ca, sa, cb, sb = np.cos(t[:, 0]), np.sin(t[:, 0]), np.cos(t[:, 1]), np.sin(t[:, 1])
    zero, one = np.zeros_like(ca), np.ones_like(ca)
    ry = np.stack([ca, zero, sa, zero, one, zero, -sa, zero, ca], axis=1).reshape(-1, 3, 3)
    rx = np.stack([one, zero, zero, zero, cb, -sb, zero, sb, cb], axis=1).reshape(-1, 3, 3)
    u, _, vt = np.linalg.svd(ry @ rx @ rotation)
    out = u @ vt
    keep = ~(t == 0).all(axis=1) & (np.linalg.det(out) > 0)
    out[~keep] = rotation
    return np.asarray(out, dtype=np.float64)


def paired_many(
    points: F64,
    rotations: F64,
    translations: F64,
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
) -> tuple[F64, F64, npt.NDArray[np.bool_]]:
    """:func:`paired_disparities` for ``K`` poses at once (one projection of all the points):
    ``points`` ``N x 3`` (or ``K x N x 3``, one set per pose), ``rotations`` ``K x 3 x 3``,
    ``translations`` ``K x 3`` (or ``3``). Returns ``(tof, stereo, both)``, each ``K x N``:
    the two disparities of each point under each pose, and where both are finite (elsewhere
    the values are meaningless)."""
    t = np.broadcast_to(np.reshape(translations, (-1, 3)), (len(rotations), 3))
    # One 2-D product per pose: the same arithmetic as Pose.apply (a batched product of small
    # matrices is slower in numpy and rounds differently).
    moved = np.stack(
        [(points if points.ndim == 2 else points[k]) @ r.T + t[k] for k, r in enumerate(rotations)]
    )
    # Projected, rounded to the nearest pixel and looked up natively: the same arithmetic as
    # the camera's projection, numpy's rint and a lookup (points behind the camera dropped).
    tof, st, both = _rgbd_rs.land_points(
        moved.reshape(-1, 3),
        rig.reference_camera._native(),
        np.ascontiguousarray(stereo, dtype=np.float32),
        rig.stereo.baseline * rig.stereo.focal,
    )
    shape = moved.shape[:-1]
    tof, st, both = tof.reshape(shape), st.reshape(shape), both.reshape(shape)
    return tof, st, both


def shares(
    points: F64,
    rotations: F64,
    translations: F64,
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    tol: float,
) -> list[tuple[int, float]]:
    """(pixels compared, share within ``tol``) of ToF ``points`` (``N x 3``, or ``K x N x 3``:
    one set per pose) moved by each of ``K`` poses (one projection of all of them)."""
    tof, st, both = paired_many(points, rotations, translations, rig, stereo)
    counts = both.sum(axis=1)
    within = (both & (np.abs(tof - st) <= tol)).sum(axis=1)
    return [(int(n), float(k / n) if n else 0.0) for n, k in zip(counts, within, strict=True)]


def turned_shares(
    points: F64,
    pose: Pose,
    turns: list[tuple[float, float]],
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    tol: float,
) -> list[tuple[int, float]]:
    """:func:`shares` of ``pose`` turned by each ``(yaw, pitch)`` of ``turns`` (degrees; see
    :func:`turn_rotations`)."""
    if not turns:
        return []
    rotations = turn_rotations(pose.rotation, turns)
    return shares(points, rotations, pose.translation, rig, stereo, tol)
