"""HHA encoding of a depth map (Gupta et al. 2014) and the square-window normals it uses.

HHA turns a metric depth map into three 8-bit channels that a colour ConvNet can take:

- **disparity**: ``31000 / max(z_cm, 100)`` (saturates at 255 below ~1.22 m);
- **height** above the lowest point, in cm; if the lowest point is less than 90 cm below the
  camera the floor is assumed 130 cm below it (so a view without floor still has heights);
- **angle** between the surface normal and gravity, in degrees, plus 38 (the reference's
  ``+ 128 - 90``); pixels without a normal get 180 + 38 = 218, as the reference.

Every step follows Gupta's MATLAB code (``processDepthImage``/``saveHHA``; see
../shared/reference/METHOD_NOTES.md §7): normals from least-squares planes ``n . p = 1`` in
7x7 (angle) and 21x21 (gravity) windows, holes of the raw depth left out of the windows;
gravity by 5 iterations at 45° then 5 at 15° (smallest eigenvector of
``Σ_wall n nᵀ - Σ_floor n nᵀ``); points rotated so gravity is the y axis (Rodrigues); values
rounded half away from zero and saturated to uint8 as MATLAB's ``uint8``.

Pixel coordinates are the camera's (pixel centres at integers from 0, as everywhere in rgbd_rs).
The MATLAB code uses 1-based pixel indices with the same intrinsics, so to reproduce its output
from intrinsics written for it (e.g. the NYU toolbox's ``cx = 325.58``) pass
``PinholeCamera(fx, fy, cx - 1, cy - 1, ...)``.

Robust where the Python port is not:

- missing depth (NaN, 0, negative, infinite) is allowed anywhere, also in ``depth`` itself
  (pass raw, unfilled depth directly): missing pixels take no part in the normals, and get 0
  disparity and 0 height (MATLAB's ``uint8(NaN)``);
- depth in millimetres is refused: if the median valid depth is above 50 (no indoor or
  Kinect-class scene has a median beyond 50 m) ``InvalidArgumentError`` says
  "depth looks like millimetres; divide by 1000" (below a median of 1000 it names centimetres
  too);
- depth with no valid pixel is refused with a clear error;
- a view without floor falls back on the assumed floor 1.3 m below the camera.

Example:
    >>> import numpy as np
    >>> from rgbd_rs import PinholeCamera
    >>> from rgbd_rs.segmentation.hha import hha_details
    >>> cam = PinholeCamera(500.0, 500.0, 31.5, 23.5, 64, 48)
    >>> r = hha_details(np.full((48, 64), 2.0, np.float32), cam)
    >>> r.image.shape, r.image.dtype.name, int(r.image[24, 32, 0])
    ((48, 64, 3), 'uint8', 155)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = [
    "ANGLE_RADIUS",
    "GRAVITY_RADIUS",
    "MAX_MEDIAN_DEPTH_M",
    "HhaResult",
    "hha",
    "hha_details",
    "square_normals",
]

U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

#: Window half-size of the normals of the angle channel (7x7, the reference's ``R = 3``).
ANGLE_RADIUS: int = _rgbd_rs.HHA_ANGLE_RADIUS
#: Window half-size of the normals that estimate gravity (21x21, the reference's ``R = 10``).
GRAVITY_RADIUS: int = _rgbd_rs.HHA_GRAVITY_RADIUS
#: A median valid depth above this (metres) is taken for millimetres and refused.
MAX_MEDIAN_DEPTH_M: float = _rgbd_rs.HHA_MAX_MEDIAN_DEPTH_M


@array_eq
@dataclass(frozen=True)
class HhaResult:
    """An HHA image and the gravity and floor it was computed with."""

    #: ``H x W x 3`` uint8: channel 0 disparity, 1 height, 2 angle (the MATLAB order; a PNG
    #: written with ``cv2.imwrite`` needs ``image[..., ::-1]`` to store the same file).
    image: U8
    #: Unit gravity direction in the camera frame (x right, y down, z forward), pointing down.
    gravity: F64
    #: Height of the floor the height channel is measured from, metres relative to the camera
    #: along gravity (negative = below): the lowest valid point, or -1.3 m when that is above
    #: -0.9 m.
    floor: float
    #: ``H x W x 3`` float32 unit normals behind the angle channel (7x7 windows), oriented
    #: toward the camera, NaN where undefined: :func:`square_normals` of the same depth (pass
    #: them to :func:`~rgbd_rs.segmentation.features.pixel_features` to skip recomputing them).
    normals: F32


def _camera(camera: object, depth: np.ndarray) -> tuple[float, float, float, float]:
    if not isinstance(camera, PinholeCamera):
        raise InvalidArgumentError(f"camera: got {type(camera).__name__}, expected a PinholeCamera")
    h, w = depth.shape
    if (camera.width, camera.height) != (w, h):
        raise ShapeMismatchError(
            f"camera: got a {camera.width}x{camera.height} camera, expected one for the "
            f"{w}x{h} depth map"
        )
    if not camera.distortion.is_identity:
        raise InvalidArgumentError(
            "camera: got a camera with lens distortion, expected an ideal pinhole "
            "(undistort the depth first, e.g. with camera.undistort_image; rgbd reproject "
            "--undistort)"
        )
    return (float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy))


def _depth(name: str, value: object) -> np.ndarray:
    d = _validate.asarray(name, value)
    if d.dtype.kind == "b":
        raise InvalidArgumentError(f"{name}: got dtype bool, expected depth in metres (float)")
    return _validate.array(name, d, shape=(None, None))


def _raw(raw_depth: object, depth: np.ndarray) -> np.ndarray | None:
    if raw_depth is None:
        return None
    r = _depth("raw_depth", raw_depth)
    if r.shape != depth.shape:
        raise ShapeMismatchError(
            f"raw_depth: got shape {r.shape}, expected {depth.shape} (the depth's)"
        )
    with np.errstate(invalid="ignore"):
        # (a depth without a valid pixel is refused as such, by the native check)
        if not (np.isfinite(r) & (r > 0)).any() and (np.isfinite(depth) & (depth > 0)).any():
            raise InvalidArgumentError(
                "raw_depth: got no valid depth (every pixel 0, negative, NaN or inf), expected "
                "the unfilled depth with some measured pixels (or None: depth's own holes)"
            )
    return r


def hha_details(
    depth: npt.ArrayLike, camera: PinholeCamera, *, raw_depth: npt.ArrayLike | None = None
) -> HhaResult:
    """HHA of ``depth`` with the gravity and floor it used (see the module docstring).

    Args:
        depth: ``H x W`` depth in metres (z along the optical axis); NaN, 0 or negative = missing.
            Usually the filled (in-painted) map; raw depth with holes works too.
        camera: the ideal pinhole of ``depth`` (``width x height`` must match it).
        raw_depth: the unfilled depth (``H x W``, same units); its holes (0 or NaN) are left out
            of the normals, as the reference's ``missingMask``. Default: ``depth``'s own holes.

    Raises:
        InvalidArgumentError: no valid depth, depth in millimetres, a camera with distortion.
        ShapeMismatchError: camera or ``raw_depth`` not matching ``depth``.
    """
    d = _depth("depth", depth)
    cam = _camera(camera, d)
    raw = _raw(raw_depth, d)
    image, gravity, floor_cm, normals = _rgbd_rs.hha_encode(d, raw, cam)
    return HhaResult(image=image, gravity=gravity, floor=floor_cm / 100.0, normals=normals)


def hha(
    depth: npt.ArrayLike, camera: PinholeCamera, *, raw_depth: npt.ArrayLike | None = None
) -> U8:
    """HHA image (``H x W x 3`` uint8: disparity, height, angle) of a metric depth map.

    See :func:`hha_details` for the arguments; this returns its ``image``.
    """
    return hha_details(depth, camera, raw_depth=raw_depth).image


def square_normals(
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    radius: int = ANGLE_RADIUS,
    raw_depth: npt.ArrayLike | None = None,
    toward_camera: bool = True,
) -> F32:
    """Unit surface normals (``H x W x 3`` float32, NaN where undefined) of a depth map.

    Each pixel's normal is that of the least-squares plane ``n . p = 1`` through the valid
    back-projected points of its ``(2 radius + 1)^2`` window (clipped at the image border), as
    HHA computes it. A window with fewer than 3 valid points, or only collinear ones, has no
    normal. ``toward_camera`` orients normals toward the camera (``n . p <= 0``); False gives
    the HHA reference's orientation (``n . p >= 0``).

    Raises:
        InvalidArgumentError: ``radius`` out of range, no valid depth, depth in millimetres.
        ShapeMismatchError: camera or ``raw_depth`` not matching ``depth``.
    """
    d = _depth("depth", depth)
    cam = _camera(camera, d)
    raw = _raw(raw_depth, d)
    r = _validate.integer("radius", radius, minimum=1, maximum=max(d.shape))
    if not isinstance(toward_camera, (bool, np.bool_)):
        raise InvalidArgumentError(f"toward_camera: got {toward_camera!r}, expected a bool")
    return _rgbd_rs.square_normals(d, raw, cam, r, bool(toward_camera))
