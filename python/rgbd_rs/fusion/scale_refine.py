"""Refine the ToF's depth scale against the stereo map.

A ToF whose depths are a few percent off the stereo pair's scale (a ToF scale error, or a
stereo baseline a few percent off) shifts every ToF disparity by that share; on the real val
scenes a 3 % error made the fusion damage a good input by up to 1.6 x. The stereo map can tell:
:func:`refine_tof_scale` fits the factor ``g`` in ``d_stereo ~ g * d_ToF`` (a truncated mean
absolute difference over a 0.5 % grid of 0.94-1.06) on a few thousand ToF pixels. On the 60
train / val cases it finds 0.995-1.005 on exact rigs and 1.025-1.035 for a 3 % error
(docs/experiments.md, "a ToF depth scale a few percent off").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs.camera import ToFStereoRig
from rgbd_rs.fusion._inputs import check_tof_unit, map2d, rig_arg
from rgbd_rs.fusion._tof_points import paired_disparities
from rgbd_rs.fusion.pose_refine import (
    MIN_DROP,
    PoseRefinement,
    _clear_fit,
    _points_or_none,
    _pose_error,
    _refine_if_off,
    _scale,
    _truncate,
)

#: The factors tried (``d_stereo ~ g * d_ToF``).
SCALE_GRID = np.round(np.arange(0.94, 1.0601, 0.005), 3)
#: A fit is *clear* when ``g`` is at least this far from 1 (and lowers the error as
#: :class:`~rgbd_rs.fusion.pose_refine.PoseRefinement` asks: 15 % and 0.08 px).
MIN_SCALE_CHANGE = 0.01


@dataclass(frozen=True)
class ScaleRefinement:
    """What :func:`refine_tof_scale` found.

    Attributes:
        factor: ``g`` in ``d_stereo ~ g * d_ToF``: the ToF's depths divided by it agree best
            with the stereo map over the 0.94-1.06 grid (1 when nothing fits better; a gain
            of a hair picks another factor, so use it only when :attr:`clear`).
        error_before, error_after: the truncated mean absolute disparity difference (pixels)
            at 1 and at ``factor``.
        pixels: ToF pixels compared.
        scale: ``max(1, width / 960)`` of the reference camera (the pixel thresholds' scale).
    """

    factor: float
    error_before: float
    error_after: float
    pixels: int
    scale: float = 1.0

    @property
    def clear(self) -> bool:
        """Whether the fit is large and certain enough to act on."""
        changed = abs(self.factor - 1) >= MIN_SCALE_CHANGE - 1e-9
        return _clear_fit(changed, self.pixels, self.error_before, self.error_after, self.scale)


def _fit(
    tof: npt.NDArray[np.float64], st: npt.NDArray[np.float64], truncate: float
) -> tuple[float, float, float]:
    """(factor, error at 1, error at the factor) over :data:`SCALE_GRID`."""
    errors = [float(np.minimum(np.abs(g * tof - st), truncate).mean()) for g in SCALE_GRID]
    before = float(np.minimum(np.abs(tof - st), truncate).mean())
    k = int(np.argmin(errors))
    if errors[k] >= before:
        return 1.0, before, before
    return float(SCALE_GRID[k]), before, errors[k]


def refine_tof_scale(
    tof_depth: npt.ArrayLike, rig: object, stereo_disparity: npt.ArrayLike
) -> ScaleRefinement:
    """The factor ``g`` (0.94-1.06) by which the ToF's disparities best fit the stereo map.

    Args:
        tof_depth: the ToF frame (metres; NaN/<=0 invalid), ``rig.tof``'s size.
        rig: :class:`~rgbd_rs.ToFStereoRig`; ``stereo_disparity`` lies on its reference camera.
        stereo_disparity: the matcher's disparity on the reference camera (NaN = none).

    ``tof_depth / factor`` is the ToF in the stereo pair's scale. Deterministic; with fewer than
    100 pixels to compare the factor is 1.
    """
    r = rig_arg(rig)
    depth = map2d("tof_depth", tof_depth, (r.tof.height, r.tof.width))
    check_tof_unit(depth, r)
    cam = r.reference_camera
    stereo = map2d("stereo_disparity", stereo_disparity, (cam.height, cam.width))
    found = _refine_scale(depth, r, stereo)
    if found is None:
        return ScaleRefinement(1.0, float("inf"), float("inf"), 0, _scale(r))
    return found


def _refine_scale(
    depth: npt.NDArray[np.float32], rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> ScaleRefinement | None:
    """``fuse()``'s fit (None: fewer than 100 pixels to compare, or a lens the ToF pixels cannot
    be undistorted through)."""
    points = _points_or_none(depth, rig)
    if len(points) == 0:
        return None
    tof, st = paired_disparities(points, rig.tof_to_reference, rig, stereo)
    if tof.size < 100:
        return None
    factor, before, after = _fit(tof, st, _truncate(rig))
    return ScaleRefinement(factor, before, after, int(tof.size), _scale(rig))


def _rescaled(depth: npt.NDArray[np.float32], factor: float) -> npt.NDArray[np.float32]:
    """``depth`` divided by ``factor`` where valid (> 0), as float32."""
    return np.where(depth > 0, depth / factor, depth).astype(np.float32)


def _clear_turn(
    depth: npt.NDArray[np.float32], rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> PoseRefinement | None:
    """``fuse()``'s orientation refinement when it is clear, else None."""
    found = _refine_if_off(depth, rig, stereo)
    return found if found is not None and found.clear else None


def _scale_and_turn(
    depth: npt.NDArray[np.float32], rig: ToFStereoRig, stereo: npt.NDArray[np.float32]
) -> tuple[ScaleRefinement | None, PoseRefinement | None]:
    """``fuse()``'s fits of the ToF against the stereo map: the depth scale first (a scale
    error shifts every ToF disparity, which a turn would partly absorb), then the orientation;
    each only where clear. A pitch can pass for a scale on slanted surfaces, so the rescaling
    stays only where, with its own turn, it fits :data:`MIN_DROP` px better than the turn alone
    (train, ToF pitched 0.5 degrees: 0.851 px fused without that guard, 0.818 with it)."""
    scaled = _refine_scale(depth, rig, stereo)
    turned = _clear_turn(depth, rig, stereo)
    if scaled is None or not scaled.clear:
        return None, turned
    fit_depth = _rescaled(depth, scaled.factor)
    turned_scaled = _clear_turn(fit_depth, rig, stereo)
    with_scale = _pose_error(fit_depth, _with_turn(rig, turned_scaled), stereo)
    without = _pose_error(depth, _with_turn(rig, turned), stereo)
    if with_scale <= without - MIN_DROP * _scale(rig):
        return scaled, turned_scaled
    return None, turned


def _with_turn(rig: ToFStereoRig, turn: PoseRefinement | None) -> ToFStereoRig:
    """``rig`` with ``turn``'s pose (itself without one)."""
    return rig if turn is None else dataclasses.replace(rig, tof_to_reference=turn.pose)
