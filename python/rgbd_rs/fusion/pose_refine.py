"""Refine the ToF's orientation in the rig against the stereo map.

A ToF calibrated to the colour pair within a fraction of a degree is common; its rays then land
a few pixels off, and the fusion, whose confidences were learned on exact rigs, trusts the
shifted ToF: on the real val scenes a yaw error of 0.25 degrees made the fused map 1.3 x worse
than the better input on average (2.1 x on the worst good input), at 0.5 degrees 2.0 x.
The stereo map can tell: :func:`refine_tof_pose` projects a few thousand ToF pixels into the
reference camera under small rotations of the ToF about its own centre (yaw and pitch: the two
that move its pixels across the image; roll moves them little) and keeps the rotation whose
disparities agree best with the matcher's (a truncated mean absolute difference). On the val
scenes it recovers a 0.4 degree yaw error to within 0.05 degrees; on exact rigs the best
rotation it finds is never :attr:`PoseRefinement.clear`, so ``fuse()`` turns none of them
(docs/experiments.md, "a ToF orientation off by a fraction of a degree"). A wide search
(``max_degrees`` of several degrees) can fit a large spurious turn on a flat or far scene:
act on ``pose`` only when ``clear``. ``fuse()`` searches a degree (continued from its edge
where it stops there), and beside it a coarse probe of turns out to :data:`WIDE_DEGREES` starts
a search around its best, kept where it fits better and the ToF then agrees with the stereo map
(docs/experiments.md, "a ToF turned by one to six degrees").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.camera import Pose, ToFStereoRig
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.fusion._inputs import agree_tol, check_tof_unit, map2d, rig_arg
from rgbd_rs.fusion._tof_points import (
    paired_disparities,
    paired_many,
    sample_points,
    turn_rotations,
    turned_shares,
)

#: ToF pixels projected per candidate rotation (evenly spaced over the valid ones).
REFINE_SAMPLES = 2048
#: Disparity differences are truncated at this many pixels (at 960 px wide; scaled with the
#: width) so occlusions and the matcher's outliers do not pull the fit.
REFINE_TRUNCATE = 3.0
#: The coarse grid's step and the fine grid's step (degrees).
COARSE_STEP = 0.25
FINE_STEP = 0.05
#: A refinement is *clear* when it lowers the truncated error by at least this share and turns
#: the ToF by at least :data:`MIN_DEGREES` (smaller corrections are within the fit's noise:
#: exact rigs of the val scenes gave 0-0.1 degrees and 0-9 % lower errors).
MIN_GAIN = 0.15
MIN_DEGREES = 0.1
#: ... and by at least this many pixels (at 960 px wide; scaled with the width): on a nearly
#: planar, precise scene (Bull: 0.12 px) a turn of the whole ToF trades a few hundredths of a
#: pixel, which the relative gain alone would call clear.
MIN_DROP = 0.08
#: ... and only from at least this many ToF pixels landing on stereo values (a review found 5 of
#: 360 exact rigs turned with 130-400 ToF pixels, none with 400 or more).
MIN_PIXELS = 500
#: After the search, an axis whose turn lowers the error by less than this many pixels (scaled
#: as :data:`MIN_DROP`) is set back to 0: on a flat scene a yaw can trade for a pitch.
AXIS_DROP = 0.02
#: ``fuse()``'s wide probe: turns on a grid of :data:`WIDE_STEP` degrees out to
#: :data:`WIDE_DEGREES` (beyond the 1-degree search), of :data:`WIDE_SAMPLES` of the ToF pixels;
#: the best of them, where it lowers the error by half of :data:`MIN_GAIN`, starts a search of
#: one degree around it.
WIDE_DEGREES = 6.0
WIDE_STEP = 1.0
WIDE_SAMPLES = 512
#: ... and a turn found there must make the ToF agree with the stereo map on this share.
WIDE_FIT = 0.7
#: ``fuse()`` refines the ToF's pose and depth scale only on a reference image at least this
#: many pixels wide. Measured on 420 rendered scenes with exact rigs (seeds 0-9 x 6 scenes at
#: each width): at 96, 144 and 240 px the refinement turned 5, 3 and 1 of them (by 1.3-9.3
#: degrees, the worst RMS +0.72 px) and rescaled one; at 192, 288, 384 and 480 px none; and a
#: true 0.5-degree turn was recovered in 1 of 84 scenes at 96-480 px. Chosen above the widest
#: false turn; the real scenes (384 px and wider) are untouched.
MIN_REFINE_WIDTH = 320
#: The probe's rings (degrees): the eight turns at each distance are tried before a search.
PROBE_RINGS = (0.1, 0.25)


@dataclass(frozen=True)
class PoseRefinement:
    """What :func:`refine_tof_pose` found.

    Attributes:
        pose: the best-fitting ``tof_to_reference`` found (the given one when nothing fits
            better or too few pixels compare); use it only when :attr:`clear`.
        yaw, pitch: the rotation applied to the ToF about its centre, degrees (about the
            reference camera's y and x axes).
        error_before, error_after: the truncated mean absolute disparity difference (pixels)
            between the projected ToF and the stereo map, with the given and the refined pose.
        pixels: ToF pixels compared with the given pose (under 100: too few to judge, and
            the given pose is returned).
    """

    pose: Pose
    yaw: float
    pitch: float
    error_before: float
    error_after: float
    pixels: int
    #: ``max(1, width / 960)`` of the reference camera: the pixel thresholds' scale.
    scale: float = 1.0

    @property
    def clear(self) -> bool:
        """Whether the refinement is large and certain enough to act on (see
        :data:`MIN_GAIN`, :data:`MIN_DEGREES`)."""
        turned = max(abs(self.yaw), abs(self.pitch)) >= MIN_DEGREES - 1e-9
        return _clear_fit(turned, self.pixels, self.error_before, self.error_after, self.scale)


def _clear_fit(changed: bool, pixels: int, before: float, after: float, scale: float) -> bool:
    """Whether a fit that ``changed`` the calibration is certain enough to act on: enough
    pixels, and an error :data:`MIN_GAIN` and :data:`MIN_DROP` px (x ``scale``) lower."""
    return bool(
        changed
        and pixels >= MIN_PIXELS
        and after <= (1 - MIN_GAIN) * before
        and before - after >= MIN_DROP * scale
    )


def _turned(pose: Pose, yaw: float, pitch: float) -> Pose:
    """``pose`` with the ToF turned about its own centre (the reference camera's axes: yaw about
    y, then pitch about x, degrees); re-orthonormalised (:func:`turn_rotations`)."""
    if yaw == 0 and pitch == 0:
        return pose
    return Pose(turn_rotations(pose.rotation, [(yaw, pitch)])[0], pose.translation)


def _error(
    points: npt.NDArray[np.float64],
    pose: Pose,
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    truncate: float,
) -> tuple[float, int]:
    """(truncated mean |d_ToF - d_stereo|, pixels compared) of ToF ``points`` moved by ``pose``."""
    tof, st = paired_disparities(points, pose, rig, stereo)
    if tof.size < 100:
        return float("inf"), int(tof.size)
    return float(np.minimum(np.abs(tof - st), truncate).mean()), int(tof.size)


def _errors(
    points: npt.NDArray[np.float64],
    pose: Pose,
    turns: list[tuple[float, float]],
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    truncate: float,
) -> list[float]:
    """:func:`_error` of ``pose`` turned by each ``(yaw, pitch)`` of ``turns`` (one projection
    of all of them; inf where fewer than 100 pixels compare)."""
    if not turns:
        return []
    rotations = turn_rotations(pose.rotation, turns)
    tof, st, both = paired_many(points, rotations, pose.translation, rig, stereo)
    out = []
    for k in range(len(turns)):
        d = np.abs(tof[k][both[k]] - st[k][both[k]])
        out.append(float(np.minimum(d, truncate).mean()) if d.size >= 100 else float("inf"))
    return out


def _points(depth: npt.NDArray[np.float32], rig: ToFStereoRig) -> npt.NDArray[np.float64]:
    """Up to :data:`REFINE_SAMPLES` evenly spaced valid ToF pixels as 3-D points (ToF frame)."""
    return sample_points(depth, rig, REFINE_SAMPLES)


def _points_or_none(depth: npt.NDArray[np.float32], rig: ToFStereoRig) -> npt.NDArray[np.float64]:
    """:func:`_points` for ``fuse()``'s checks, which must not raise: none where the ToF's lens
    cannot undistort its pixels (no verdict then)."""
    try:
        return _points(depth, rig)
    except RgbdError:
        return np.zeros((0, 3))


def _search(
    points: npt.NDArray[np.float64],
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    truncate: float,
    span: float,
    before: float,
    start: tuple[float, float, float] | None = None,
) -> tuple[float, float, float]:
    """(error, yaw, pitch) of the best rotation: a grid of :data:`COARSE_STEP` over +-span,
    then one of :data:`FINE_STEP` around its best. With ``start`` (error, yaw, pitch of a turn
    found by a coarser probe) the first grid reaches one degree around that turn instead."""
    given = rig.tof_to_reference
    best = (before, 0.0, 0.0) if start is None else start
    centre = (best[1], best[2])
    first = span if start is None else 1.0
    for step, reach in ((COARSE_STEP, first), (FINE_STEP, COARSE_STEP)):
        k = int(np.floor(reach / step + 1e-9))
        offsets = np.arange(-k, k + 1) * step
        turns = [
            (float(centre[0] + dy), float(centre[1] + dx))
            for dy in offsets
            for dx in offsets
            if max(abs(centre[0] + dy), abs(centre[1] + dx)) <= span + 1e-9
            and (centre[0] + dy, centre[1] + dx) != (0.0, 0.0)
        ]
        for (yaw, pitch), e in zip(
            turns, _errors(points, given, turns, rig, stereo, truncate), strict=True
        ):
            if e < best[0] - 1e-12:
                best = (e, yaw, pitch)
        centre = (best[1], best[2])
    err, yaw, pitch = best
    # An axis that buys (almost) nothing goes back to 0 (a yaw traded for a pitch on a flat
    # scene would otherwise be reported as an error of the calibration).
    slack = AXIS_DROP * _scale(rig)
    for axis in ("yaw", "pitch"):
        y0, p0 = (0.0, pitch) if axis == "yaw" else (yaw, 0.0)
        if (y0, p0) == (yaw, pitch):
            continue
        e0 = (
            before
            if (y0, p0) == (0.0, 0.0)
            else _errors(points, given, [(y0, p0)], rig, stereo, truncate)[0]
        )
        if e0 - err < slack:
            err, yaw, pitch = e0, y0, p0
    return err, yaw, pitch


def _scale(rig: ToFStereoRig) -> float:
    """The pixel thresholds' scale: ``max(1, width / 960)`` of the reference camera."""
    return max(1.0, rig.reference_camera.width / 960)


def _truncate(rig: ToFStereoRig) -> float:
    return REFINE_TRUNCATE * _scale(rig)


def refine_tof_pose(
    tof_depth: npt.ArrayLike,
    rig: object,
    stereo_disparity: npt.ArrayLike,
    *,
    max_degrees: float = 1.0,
) -> PoseRefinement:
    """The ToF orientation, turned by at most ``max_degrees`` in yaw and pitch, that best fits
    the stereo map.

    Args:
        tof_depth: the ToF frame (metres; NaN/<=0 invalid), ``rig.tof``'s size.
        rig: :class:`~rgbd_rs.ToFStereoRig`; ``stereo_disparity`` lies on its reference camera.
        stereo_disparity: the matcher's disparity on the reference camera (NaN = none), e.g.
            ``fuse(...).stereo_disparity`` or :func:`~rgbd_rs.fusion.census_match`'s.
        max_degrees: the largest yaw / pitch searched (a grid of 0.25 degrees, then 0.05).

    Deterministic (evenly spaced ToF pixels). With fewer than 100 ToF pixels landing on stereo
    values the given pose is returned (``pixels`` says how many there were).
    """
    r = rig_arg(rig)
    depth = map2d("tof_depth", tof_depth, (r.tof.height, r.tof.width))
    check_tof_unit(depth, r)
    cam = r.reference_camera
    stereo = map2d("stereo_disparity", stereo_disparity, (cam.height, cam.width))
    span = _validate.real("max_degrees", max_degrees, positive=True)
    if span > 10:
        raise InvalidArgumentError(
            f"max_degrees: got {max_degrees!r}, expected at most 10 (a calibration further "
            "off is not refined by a local search: recalibrate)"
        )
    given = r.tof_to_reference
    points = _points(depth, r)
    truncate = _truncate(r)
    before, n = _error(points, given, r, stereo, truncate) if len(points) else (float("inf"), 0)
    if n < 100:
        return PoseRefinement(given, 0.0, 0.0, before, before, n, _scale(r))
    err, yaw, pitch = _search(points, r, stereo, truncate, span, before)
    return PoseRefinement(_turned(given, yaw, pitch), yaw, pitch, before, err, n, _scale(r))


def _wide(
    points: npt.NDArray[np.float64],
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
    truncate: float,
    before: float,
) -> tuple[float, float, float]:
    """(error, yaw, pitch): the wide probe's best turn (one degree or more, up to
    :data:`WIDE_DEGREES`) refined by a search of one degree around it; ``(before, 0, 0)`` where
    no turn of the probe lowers the error by half of :data:`MIN_GAIN`."""
    given = rig.tof_to_reference
    few = points[:: max(1, len(points) // WIDE_SAMPLES)]
    steps = np.arange(-WIDE_DEGREES, WIDE_DEGREES + 1e-9, WIDE_STEP)
    turns = [(0.0, 0.0)] + [
        (float(y), float(p)) for y in steps for p in steps if max(abs(y), abs(p)) >= 1.0 - 1e-9
    ]
    errs = _errors(few, given, turns, rig, stereo, truncate)
    k = 1 + int(np.argmin(errs[1:]))
    if not errs[k] <= (1 - MIN_GAIN / 2) * errs[0]:
        return before, 0.0, 0.0
    start = _errors(points, given, [turns[k]], rig, stereo, truncate)[0]
    if not start < before:
        return before, 0.0, 0.0
    return _search(points, rig, stereo, truncate, WIDE_DEGREES + 1, before, (start, *turns[k]))


def _agreement(
    points: npt.NDArray[np.float64],
    pose: Pose,
    turn: tuple[float, float, float],
    rig: ToFStereoRig,
    stereo: npt.NDArray[np.float32],
) -> float:
    """The share of ``points`` within :func:`~rgbd_rs.fusion._inputs.agree_tol` of the stereo
    map under ``pose`` turned by ``turn``'s (yaw, pitch)."""
    tol = agree_tol(rig.reference_camera.width)
    return turned_shares(points, pose, [turn[1:]], rig, stereo, tol)[0][1]


def _refine_if_off(
    depth: npt.NDArray[np.float32], rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> PoseRefinement | None:
    """``fuse()``'s check: the eight rotations :data:`COARSE_STEP` away first (a few ms); only
    where one of them lowers the error by half of :data:`MIN_GAIN` the whole search of
    :func:`refine_tof_pose` (1 degree), continued from its edge where it stops there; the wide
    probe (:func:`_wide`) in either case, its fit kept where better. None when nothing is worth
    searching."""
    points = _points_or_none(depth, rig)
    if len(points) == 0:
        return None
    truncate = _truncate(rig)
    given = rig.tof_to_reference
    before, n = _error(points, given, rig, stereo, truncate)
    if n < MIN_PIXELS:
        return None
    rings = [
        (a * ring, b * ring)
        for ring in PROBE_RINGS
        for a in (-1, 0, 1)
        for b in (-1, 0, 1)
        if (a, b) != (0, 0)
    ]
    probe = min(_errors(points, given, rings, rig, stereo, truncate))
    within = (before, 0.0, 0.0)  # the 1-degree search's fit
    if probe <= (1 - MIN_GAIN / 2) * before:
        within = _search(points, rig, stereo, truncate, 1.0, before)
    # Further: from the edge of that search, and the wide probe (nothing near fits better when
    # the turn is a few degrees; and the near fit can stop in a trough of its own on a flat
    # scene: Bull, yaw 1.25 degrees, -0.75 yaw and -0.15 pitch).
    further = (before, 0.0, 0.0)
    if within[1:] != (0.0, 0.0) and max(abs(within[1]), abs(within[2])) >= 1.0 - 1e-9:
        further = _search(points, rig, stereo, truncate, WIDE_DEGREES + 1, before, within)
    further = min(further, _wide(points, rig, stereo, truncate, before))
    # A turn from beyond the near search must also make the ToF agree with the stereo map: a
    # depth scale 15-20 % off has no true turn, but a turn of several degrees lowers its error
    # (train / val: such turns agree on 0.21-0.41 of the pixels on average; true turns, once
    # found, on 0.76-1.00).
    if further[0] < within[0] and _agreement(points, given, further, rig, stereo) >= WIDE_FIT:
        within = further
    err, yaw, pitch = within
    if (yaw, pitch) == (0.0, 0.0):
        return None
    return PoseRefinement(_turned(given, yaw, pitch), yaw, pitch, before, err, n, _scale(rig))


def _pose_error(
    depth: npt.NDArray[np.float32], rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> float:
    """The truncated ToF-stereo disparity difference with the rig's pose (inf: too few pixels
    or a lens the ToF pixels cannot be undistorted through)."""
    points = _points_or_none(depth, rig)
    if len(points) == 0:
        return float("inf")
    return _error(points, rig.tof_to_reference, rig, stereo, _truncate(rig))[0]
