"""Is the ToF's pose in the rig given the wrong way round? A check against the stereo map.

The two mistakes a calibration file invites most are a pose in the opposite direction (the
reference camera's frame to the ToF's instead of the ToF's to the reference camera's) and a pose
measured from the other camera of the pair. Neither makes the ToF disagree with the stereo map
everywhere (the ToF sits a few centimetres from the camera, so most surfaces still land near
their stereo match), which is why :func:`~rgbd_rs.fusion._inputs.disagreement_warning` cannot
see them. But the pose the user *meant* then agrees with the stereo map better than the pose
given, and that is what this check measures: it projects a few thousand ToF pixels into the
reference camera under the pose as given and under the three readings of it (inverted, measured
from the other camera, both) and compares their disparities with the matcher's.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable
from typing import Literal

import numpy as np

from rgbd_rs.camera import Pose, ToFStereoRig
from rgbd_rs.errors import RgbdError
from rgbd_rs.fusion._inputs import F32, agree_tol, with_reference
from rgbd_rs.fusion._tof_points import sample_points, shares, turned_shares

#: ToF pixels projected per reading of the pose (evenly spaced over the valid ones).
POSE_SAMPLES = 4096
#: The check speaks when another reading of the pose agrees with the stereo map on at least this
#: much larger a share of the projected pixels than the pose as given. Measured
#: (docs/experiments.md, "a warning for a pose given the wrong way round"): on 111 correct
#: train/val cases (Middlebury under three ToF laws, the dense law and the far camera; 12
#: rendered val scenes) no other reading gains more than 0.008; of the 40 wrong Middlebury rigs
#: (pose inverted, pose from the other camera) 36 gain more than 0.03, of the 24 rendered 18
#: (34 of the 40 named once the orientation refinement runs first: see ``fitted``).
POSE_GAIN = 0.03
#: ... and agrees on at least this share itself (correct rigs: 0.44 and more; a reading that
#: fits worse than that is no diagnosis).
POSE_FLOOR = 0.4

#: A reading is not named where the pose as given, turned about one axis by up to this many
#: degrees (in steps of ``TURN_STEP``) or with its depths scaled by one of ``SCALES``, fits as
#: well: a ToF turned by 1.5-3 degrees (beyond ``refine_tof_pose``'s search) or with depths 5 %
#: off (with ``refine_pose=False``) made the inverted reading fit better than the pose as given.
TURN_DEGREES = 3.0
TURN_STEP = 0.25
SCALES = tuple(float(g) for g in np.round(np.arange(0.90, 1.1001, 0.01), 2) if g != 1.0)

_READINGS = {
    "inverse": "inverted (the reference camera's frame to the ToF's)",
    "other": "measured from the {other} camera",
    "inverse_other": "inverted and measured from the {other} camera",
}


def _readings(asked: ToFStereoRig, fused_on: str) -> dict[str, Pose]:
    """The pose as the caller gave it (relative to ``asked.reference``) and its three other
    readings, each as ToF -> the camera fused on. A reading whose pose cannot be built (a
    rotation at the edge of :class:`~rgbd_rs.camera.Pose`'s tolerance, whose inverse it
    refuses) is left out: a check must not raise."""
    other: Literal["left", "right"] = "right" if asked.reference == "left" else "left"
    out: dict[str, Pose] = {}

    def add(key: str, make: Callable[[], ToFStereoRig]) -> None:
        with contextlib.suppress(RgbdError):
            out[key] = with_reference(make(), fused_on).tof_to_reference

    def inverted() -> ToFStereoRig:
        return dataclasses.replace(asked, tof_to_reference=asked.tof_to_reference.inverse())

    add("given", lambda: asked)
    add("inverse", inverted)
    add("other", lambda: dataclasses.replace(asked, reference=other))
    add("inverse_other", lambda: dataclasses.replace(inverted(), reference=other))
    return out


def _agreements(
    points: np.ndarray, poses: list[Pose], rig: ToFStereoRig, stereo: F32, tol: float
) -> list[tuple[int, float]]:
    """:func:`_shares` of each of ``poses``."""
    if not poses:
        return []
    rotations = np.stack([p.rotation for p in poses])
    translations = np.stack([p.translation for p in poses])
    return shares(points, rotations, translations, rig, stereo, tol)


def _agreement(
    points: np.ndarray, pose: Pose, rig: ToFStereoRig, stereo: F32, tol: float
) -> tuple[int, float]:
    """(pixels compared, share within ``tol``) of ToF ``points`` moved by ``pose``."""
    return _agreements(points, [pose], rig, stereo, tol)[0]


def _plain_error(
    points: np.ndarray, pose: Pose, rig: ToFStereoRig, stereo: F32, tol: float
) -> float:
    """The best share within ``tol`` of ``pose`` turned about one axis (yaw or pitch, up to
    :data:`TURN_DEGREES` in steps of :data:`TURN_STEP`) or with the depths scaled
    (:data:`SCALES`): what a plain orientation or scale error, not a pose read the wrong way
    round, would explain."""
    steps = np.arange(-TURN_DEGREES, TURN_DEGREES + 1e-9, TURN_STEP)
    turns = [t for a in steps[steps != 0] for t in ((float(a), 0.0), (0.0, float(a)))]
    turned = turned_shares(points, pose, turns, rig, stereo, tol)
    scaled = turned_shares(
        np.stack([points * g for g in SCALES]), pose, [(0.0, 0.0)] * len(SCALES), rig, stereo, tol
    )
    return max((share for _, share in turned + scaled), default=0.0)


def pose_warning(
    depth: F32,
    asked: ToFStereoRig,
    rig: ToFStereoRig,
    stereo_disparity: F32,
    fitted: Pose | None = None,
) -> str | None:
    """A warning when another reading of ``asked.tof_to_reference`` (inverted, measured from the
    other camera, or both) makes the ToF agree clearly better with the stereo map, else None.

    ``depth`` is the ToF frame (metres; NaN/<=0 invalid); ``asked`` the rig as the caller gave
    it, ``rig`` the same fused on its output camera (``fuse(reference=...)``), on which
    ``stereo_disparity`` lies; ``fitted``, the given pose turned by a fraction of a degree where
    :func:`~rgbd_rs.fusion.pose_refine.refine_tof_pose` found that clearly better: another reading
    must then fit at least as well as it (a turn can make the inverted reading beat the turned
    pose as given on a flat scene; a translation's flip can look like a turn on a far one).
    Deterministic (evenly spaced ToF pixels, no random draw).
    """
    points = sample_points(depth, rig, POSE_SAMPLES)
    if len(points) < 100:
        return None
    tol = agree_tol(stereo_disparity.shape[1])
    readings = _readings(asked, rig.reference)
    if "given" not in readings:
        return None
    shares = dict(
        zip(
            readings,
            _agreements(points, list(readings.values()), rig, stereo_disparity, tol),
            strict=True,
        )
    )
    n_given, given = shares.pop("given")
    if n_given < 100:
        return None
    # The given pose turned by refine_tof_pose: another reading must fit at least as well.
    turned = 0.0 if fitted is None else _agreement(points, fitted, rig, stereo_disparity, tol)[1]
    best = max(
        (k for k, (n, _) in shares.items() if n >= 100),
        key=lambda k: shares[k][1],
        default=None,
    )
    if best is None:
        return None
    alt = shares[best][1]
    # A reading that fits no better than a wrong input is no diagnosis: the generic check's
    # advice (the translation's unit, the amplitude) is the one that fits then.
    if alt - given < POSE_GAIN or alt < POSE_FLOOR or alt < turned:
        return None
    # A pose turned by a degree or two, or depths a few percent off, also make another reading
    # fit better than the pose as given: the reading is named only where neither does as well.
    if _plain_error(points, readings["given"], rig, stereo_disparity, tol) >= alt:
        return None
    other = "right" if asked.reference == "left" else "left"
    reading = _READINGS[best].format(other=other)
    return (
        f"rig: the ToF agrees with the stereo map within {tol:g} px on {given:.1%} of the "
        f"pixels it reaches with tof_to_reference as given, but on {alt:.1%} if that pose were "
        f"{reading}: check the pose's direction (ToF frame to the {asked.reference} camera's "
        "frame) and the camera it is relative to (the rig's reference)"
    )


#: :func:`turn_warning` looks only where the ToF agrees with the stereo map on less than this
#: share of its pixels (the exact Middlebury rigs: 0.73-1.00; a ToF turned by 3 degrees 0.31-0.60).
TURN_QUIET = 0.8
#: Its probe: turns of the ToF about one or both axes on a grid of this step, up to this far.
TURN_PROBE_STEP = 1.0
TURN_PROBE_DEGREES = 6.0
#: Turns smaller than this (degrees, on the larger axis) are the refinement's business.
TURN_MIN_DEGREES = 2.0
#: It speaks when a turn raises the share by this much, to at least ``TURN_FIT``.
TURN_GAIN = 0.15
TURN_FIT = 0.7


def turn_warning(depth: F32, rig: ToFStereoRig, stereo_disparity: F32) -> str | None:
    """A warning when the ToF, under ``rig``'s pose (the one fused with), agrees with the stereo
    map on few pixels but on many once turned by a few degrees: an orientation error beyond
    what ``fuse()``'s refinement could fit clearly (it then fuses with the pose as given), which
    the fusion cannot absorb (on the val scenes a 3-degree yaw made the fused map 3-8 x worse than
    the stereo map alone), or None. Deterministic; its probe (160 turns, one batched projection)
    costs ~20 ms at 960x540, only where agreement is low."""
    points = sample_points(depth, rig, POSE_SAMPLES // 2)
    if len(points) < 100:
        return None
    tol = agree_tol(stereo_disparity.shape[1])
    pose = rig.tof_to_reference
    n, given = _agreement(points, pose, rig, stereo_disparity, tol)
    if n < 500 or given >= TURN_QUIET:
        return None
    steps = np.arange(-TURN_PROBE_DEGREES, TURN_PROBE_DEGREES + 1e-9, TURN_PROBE_STEP)
    turns = [
        (float(yaw), float(pitch))
        for yaw in steps
        for pitch in steps
        if max(abs(yaw), abs(pitch)) >= TURN_MIN_DEGREES  # below: the refinement's range
    ]
    best, turn = given, (0.0, 0.0)
    probed = turned_shares(points, pose, turns, rig, stereo_disparity, tol)
    for t, (count, share) in zip(turns, probed, strict=True):
        # A turn that moves most ToF pixels off the image compares too few to judge.
        if count >= max(500, n // 2) and share > best:
            best, turn = share, t
    if best - given < TURN_GAIN or best < TURN_FIT:
        return None
    return (
        f"rig: the ToF agrees with the stereo map within {tol:g} px on {given:.0%} of the pixels "
        f"it reaches, but on {best:.0%} turned by about {turn[0]:+.0f} degrees of yaw and "
        f"{turn[1]:+.0f} of pitch: its orientation in the calibration (tof_to_reference) looks "
        "several degrees off, and no turn fitted clearly enough for fuse() to correct it, so "
        "the fused map may be worse than the stereo map alone; fused as given: check the "
        "ToF's calibration (rgbd_rs.fusion.refine_tof_pose with max_degrees=6 gives a finer "
        "estimate)"
    )
