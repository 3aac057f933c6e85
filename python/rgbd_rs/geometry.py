"""Depth-map geometry on top of :mod:`rgbd_rs.camera`: depth <-> disparity (eq. 2.15),
z-buffered reprojection of a depth map into another camera, and surface normals.

Example (ToF -> colour camera):
    >>> import numpy as np
    >>> from rgbd_rs import PinholeCamera, Pose, reproject_depth
    >>> tof = PinholeCamera(100.0, 100.0, 31.5, 23.5, 64, 48)
    >>> rgb = PinholeCamera(200.0, 200.0, 63.5, 47.5, 128, 96)
    >>> out = reproject_depth(np.full((48, 64), 2.0, np.float32), tof, rgb,
    ...                       Pose(np.eye(3), [0.05, 0.0, 0.0]), splat_radius=1)
    >>> out.depth.shape, float(np.nanmax(out.depth))
    ((96, 128), 2.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import UNDISTORT_MAX_ITER, UNDISTORT_TOL, PinholeCamera, Pose
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = [
    "Reprojection",
    "depth_to_disparity",
    "disparity_to_depth",
    "normals_from_depth",
    "normals_from_points",
    "reproject_depth",
]

F32 = npt.NDArray[np.float32]

#: Largest splat footprint radius accepted by :func:`reproject_depth` (target pixels).
MAX_SPLAT_RADIUS = 8


def depth_to_disparity(depth: npt.ArrayLike, baseline: float, focal: float) -> F32:
    """Disparity ``d = baseline * focal / z`` (eq. 2.15) of a depth map of any shape.

    Args:
        depth: depth in metres; NaN, 0 and negative values are invalid and give NaN.
        baseline: stereo baseline in metres (> 0).
        focal: horizontal focal length in pixels (> 0).
    """
    _validate.metric_depth("depth", depth)
    return _reciprocal("depth", depth, baseline, focal, "disparities")


def disparity_to_depth(disparity: npt.ArrayLike, baseline: float, focal: float) -> F32:
    """Depth ``z = baseline * focal / d`` (eq. 2.15); non-positive or NaN disparity gives NaN."""
    return _reciprocal("disparity", disparity, baseline, focal, "depths")


def _reciprocal(name: str, values: npt.ArrayLike, baseline: float, focal: float, out: str) -> F32:
    """``baseline * focal / values`` (eq. 2.15), refusing input whose result overflows float32
    (a subnormal depth, or a baseline x focal beyond float32) instead of returning inf."""
    d = _as_map(name, values)
    b, f = _validate.real("baseline", baseline), _validate.real("focal", focal)
    if abs(b * f) > _validate.F32_MAX:
        # name the factor out of proportion (a focal of 1e300 px, or a baseline of 1e300 m)
        (big, x), (small, y) = sorted((("focal", f), ("baseline", b)), key=lambda a: -abs(a[1]))
        raise InvalidArgumentError(
            f"{big}: got {x:.3g} with {small} {y:.3g}: baseline x focal = {b * f:.3g} is "
            f"beyond float32's range; expected a product <= {_validate.F32_MAX:.3g}"
        )
    result: F32 = _rgbd_rs.depth_disparity(d, b, f)
    if np.isinf(result).any():  # the kernel gives NaN for invalid input: inf is an overflow
        with np.errstate(invalid="ignore"):
            smallest = float(np.min(d[np.isfinite(d) & (d > 0)]))
        raise InvalidArgumentError(
            f"{name}: got values down to {smallest:.3g} with baseline x focal = {b * f:.3g}, "
            f"which give {out} beyond float32's range; expected values >= "
            f"{b * f / _validate.F32_MAX:.3g}"
        )
    return result


def _as_map(name: str, value: npt.ArrayLike) -> F32:
    arr = _validate.asarray(name, value)
    if arr.ndim == 0:  # a single value: checked as a 1-element map, returned 0-d
        return _validate.array(name, arr.reshape(1), shape=(None,)).reshape(())
    return _validate.array(name, arr, shape=(None,) * arr.ndim, allow_empty=True)


@array_eq
@dataclass(frozen=True)
class Reprojection:
    """Result of :func:`reproject_depth`, all on the target lattice.

    Attributes:
        depth: ``H x W`` float32 z in the target frame, NaN where nothing landed.
        channels: ``H x W x C`` carried values of the winning source pixels (``H x W`` for
            ``H_src x W_src`` channels; None when none were given).
        source_index: ``H x W`` int64 row-major index of the winning source pixel, -1 if none.
    """

    depth: F32
    channels: F32 | None
    source_index: npt.NDArray[np.int64]

    @property
    def coverage(self) -> float:
        """Fraction of target pixels that received a depth."""
        return float(np.isfinite(self.depth).mean())


def reproject_depth(
    depth: npt.ArrayLike,
    source: PinholeCamera,
    target: PinholeCamera,
    pose: Pose,
    *,
    channels: npt.ArrayLike | None = None,
    splat_radius: int = 0,
) -> Reprojection:
    """Reproject a depth map from ``source`` into ``target`` by z-buffered forward splatting.

    Each valid source pixel is back-projected through the source lens, moved by ``pose``
    (source frame -> target frame), projected through the target lens, and written to the target
    pixel it lands on (plus its neighbours within ``splat_radius``) when it is the nearest so
    far, so occluded points are hidden. Target pixels nothing reaches are NaN: with
    ``splat_radius=0`` the output is the sparse sampling the upsampling stage expects.

    Args:
        depth: ``H_s x W_s`` float depth (z, metres, the unit of ``pose``'s translation) on
            the source lattice; NaN/<= 0 invalid. Integer maps (raw millimetres) are refused.
        source, target: the two cameras (with their distortion).
        pose: rigid transform from the source frame to the target frame.
        channels: optional ``H_s x W_s`` or ``H_s x W_s x C`` values (e.g. ToF amplitude)
            carried with the winning samples.
        splat_radius: Chebyshev radius of each splat in target pixels, 0..8.
    """
    for name, cam in (("source", source), ("target", target)):
        if not isinstance(cam, PinholeCamera):
            raise InvalidArgumentError(
                f"{name}: got {type(cam).__name__}, expected a PinholeCamera"
            )
    if not isinstance(pose, Pose):
        raise InvalidArgumentError(f"pose: got {type(pose).__name__}, expected a Pose")
    _validate.metric_depth("depth", depth)
    d = _validate.array("depth", depth, shape=(source.height, source.width))
    ch = None
    squeeze = False
    if channels is not None:
        ch, squeeze = _validate.image("channels", channels)
        if ch.shape[:2] != d.shape:
            raise ShapeMismatchError(
                f"channels: got shape {tuple(np.shape(channels))}, expected the depth map's "
                f"{d.shape} (optionally with a trailing channel axis)"
            )
    r = _validate.integer("splat_radius", splat_radius, maximum=MAX_SPLAT_RADIUS)
    z, carried, idx = _rgbd_rs.reproject_depth(
        d,
        source._native(),
        target._native(),
        pose._native(),
        ch,
        r,
        UNDISTORT_MAX_ITER,
        UNDISTORT_TOL,
    )
    if carried is not None and squeeze:
        carried = carried[:, :, 0]
    return Reprojection(z, carried, idx)


def normals_from_points(points: npt.ArrayLike, *, max_depth_jump: float = float("inf")) -> F32:
    """Unit surface normals (pointing to the camera) of an organised ``H x W x 3`` point cloud.

    Tangents use the neighbour on each axis with the smaller depth step, so normals at depth
    edges come from their own surface and holes (NaN) only remove the normals that have no valid
    neighbour on an axis. A neighbour more than ``max_depth_jump`` metres away in depth is not
    used. Missing normals are NaN.
    """
    p = _validate.array("points", points, shape=(None, None, 3))
    if isinstance(max_depth_jump, bool) or not isinstance(
        max_depth_jump, (int, float, np.integer, np.floating)
    ):
        raise InvalidArgumentError(
            f"max_depth_jump: got {max_depth_jump!r}, expected a number > 0 (inf = none)"
        )
    try:
        jump = float(max_depth_jump)
    except OverflowError:  # an int beyond float range: no limit either way
        jump = float("inf") if max_depth_jump > 0 else float("-inf")
    if not jump > 0:
        raise InvalidArgumentError(f"max_depth_jump: got {jump}, expected a value > 0 (inf = none)")
    # Normals do not depend on the unit: coordinates whose cross products would overflow or
    # underflow float32 are brought near 1 by a power of two (exact), the jump with them.
    with np.errstate(invalid="ignore"):
        finite = np.abs(p[np.isfinite(p)])
    top = float(finite.max()) if finite.size else 0.0
    if top > 0 and not _NORMAL_SCALE_RANGE[0] <= top <= _NORMAL_SCALE_RANGE[1]:
        k = -int(np.floor(np.log2(top)))
        p = np.ldexp(p, k).astype(np.float32)
        jump = math.ldexp(jump, k) if math.isfinite(jump) else jump
    return _rgbd_rs.normals_from_points(p, jump)


#: Coordinate magnitudes whose products stay well inside float32; outside, normals are computed
#: on the points rescaled by a power of two.
_NORMAL_SCALE_RANGE = (2.0**-40, 2.0**40)


def normals_from_depth(
    depth: npt.ArrayLike, camera: PinholeCamera, *, max_depth_jump: float = float("inf")
) -> F32:
    """Normals of a depth map seen by ``camera`` (see :func:`normals_from_points`)."""
    if not isinstance(camera, PinholeCamera):
        raise InvalidArgumentError(f"camera: got {type(camera).__name__}, expected a PinholeCamera")
    return normals_from_points(camera.depth_to_points(depth), max_depth_jump=max_depth_jump)
