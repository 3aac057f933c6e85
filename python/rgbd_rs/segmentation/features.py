"""Per-pixel 9-D colour/position/normal vectors of eq. 4.1.

Each pixel ``i`` gets ``v_i = [L, a, b, x, y, z, n_x, n_y, n_z]`` with

- ``[L, a, b]``: CIELab colour, as OpenCV converts float sRGB in 0..1 (``cv2.COLOR_RGB2Lab``,
  D65 white: L in 0..100, a and b about -127..127);
- ``[x, y, z]``: the 3-D point from the calibration (``camera.depth_to_points``), metres;
- ``[n_x, n_y, n_z]``: the unit surface normal, oriented toward the camera, from the
  least-squares plane of the valid points in a 7x7 window (:func:`~rgbd_rs.segmentation.hha.
  square_normals`, the same normals as HHA's angle channel).

Each group of three is divided by its average standard deviation over the valid pixels
(eq. 4.1): ``sigma_c = (std L + std a + std b) / 3``, ``sigma_g`` likewise for ``x, y, z``
and ``sigma_n`` for the normal (population standard deviations). So a scene twice as far, or an
image with twice the Lab contrast, gives the same position or colour vectors up to an offset. A
group with no spread at all (sigma = 0, e.g. a uniform image) is left unscaled. A pixel is valid
where its depth is (finite, > 0) and its normal is defined; every channel of an invalid pixel is
NaN.

Example:
    >>> import numpy as np
    >>> from rgbd_rs import PinholeCamera
    >>> from rgbd_rs.segmentation.features import features
    >>> cam = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)
    >>> rgb = np.random.default_rng(0).integers(0, 255, (24, 32, 3), dtype=np.uint8)
    >>> depth = np.linspace(1.0, 3.0, 32 * 24, dtype=np.float32).reshape(24, 32)
    >>> f = features(rgb, depth, cam)
    >>> f.vectors.shape, f.vectors.dtype.name, bool(f.valid.all())
    ((24, 32, 9), 'float32', True)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.segmentation.hha import ANGLE_RADIUS, _camera, square_normals

__all__ = ["FEATURE_DIM", "NORMAL_RADIUS", "Features", "features", "lab_colour"]

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]
Bool = npt.NDArray[np.bool_]

#: Length of a pixel's vector (eq. 4.1): Lab colour, 3-D position, normal.
FEATURE_DIM = 9
#: Default window half-size of the normals (7x7, the HHA angle normals).
NORMAL_RADIUS: int = ANGLE_RADIUS


@array_eq
@dataclass(frozen=True)
class Features:
    """The eq. 4.1 vectors of an image and what they were built from."""

    #: ``H x W x 9`` float32 ``[L, a, b] / sigma_c``, ``[x, y, z] / sigma_g``,
    #: ``[nx, ny, nz] / sigma_n``; NaN on every channel of an invalid pixel.
    vectors: F32
    #: ``H x W`` bool: depth valid and normal defined.
    valid: Bool
    #: ``(sigma_c, sigma_g, sigma_n)``: each group's average standard deviation over the valid
    #: pixels.
    sigmas: tuple[float, float, float]
    #: ``H x W x 3`` float32 CIELab colour (OpenCV float convention), every pixel.
    lab: F32
    #: ``H x W x 3`` float32 points in metres (camera frame), NaN where the depth is invalid.
    points: F32
    #: ``H x W x 3`` float32 unit normals toward the camera, NaN where undefined.
    normals: F32


def _rgb(value: object) -> U8:
    img = _validate.asarray("rgb", value)
    if img.dtype != np.uint8:
        raise InvalidArgumentError(f"rgb: got dtype {img.dtype}, expected uint8")
    if img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
        raise ShapeMismatchError(f"rgb: got shape {img.shape}, expected (H, W, 3)")
    return np.ascontiguousarray(img)


def lab_colour(rgb: npt.ArrayLike) -> F32:
    """CIELab of an ``H x W x 3`` uint8 RGB image as float32 (OpenCV's float conversion)."""
    img = _rgb(rgb)
    return np.asarray(
        cv2.cvtColor(img.astype(np.float32) * np.float32(1.0 / 255.0), cv2.COLOR_RGB2Lab),
        dtype=np.float32,
    )


#: A median valid depth below this (metres) is refused as another unit: no RGB-D camera measures
#: a scene whose median depth is under a millimetre (the 9-D vectors' per-frame scales then
#: overflow float32).
MIN_MEDIAN_DEPTH_M = 1e-3


def _not_too_small(depth: npt.NDArray[np.float32]) -> None:
    with np.errstate(invalid="ignore"):
        valid = depth[np.isfinite(depth) & (depth > 0)]
    if valid.size and float(np.median(valid)) < MIN_MEDIAN_DEPTH_M:
        raise InvalidArgumentError(
            f"depth: got a median valid depth of {float(np.median(valid)):.3g}, expected metres "
            f"(median valid depth >= {MIN_MEDIAN_DEPTH_M:g})"
        )


def features(
    rgb: npt.ArrayLike,
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    normal_radius: int = NORMAL_RADIUS,
    normals: npt.ArrayLike | None = None,
) -> Features:
    """The eq. 4.1 vectors of a colour + depth pair, with their parts (see the module docstring).

    ``features(...).vectors`` is the ``H x W x 9`` float32 array the over-segmentation takes
    (NaN on every channel of an invalid pixel); ``lab``, ``points`` and ``normals`` are the
    unnormalised per-pixel parts the merging uses, ``sigmas`` the three group scales.

    Args:
        rgb: ``H x W x 3`` uint8 colour image (RGB), registered to ``depth``.
        depth: ``H x W`` depth in metres; NaN, 0 or negative = missing.
        camera: the ideal pinhole of both images (``width x height`` must match).
        normal_radius: window half-size of the normals (default 3: 7x7 windows).
        normals: precomputed ``H x W x 3`` unit normals toward the camera (NaN = undefined),
            e.g. ``hha_details(depth, camera).normals`` (the same normals, computed once);
            default: computed here with ``normal_radius``.

    Raises:
        InvalidArgumentError: wrong dtype, depth in millimetres, no valid depth or no pixel
            with a normal, a camera with distortion.
        ShapeMismatchError: ``rgb``, ``depth``, ``normals`` and ``camera`` sizes disagree.
    """
    img = _rgb(rgb)
    d = _validate.asarray("depth", depth)
    if d.dtype.kind == "b":
        raise InvalidArgumentError("depth: got dtype bool, expected depth in metres (float)")
    d = _validate.array("depth", d, shape=(None, None))
    if img.shape[:2] != d.shape:
        raise ShapeMismatchError(
            f"rgb: got {img.shape[1]}x{img.shape[0]}, expected the depth's size "
            f"{d.shape[1]}x{d.shape[0]}"
        )
    _not_too_small(d)
    cam = _camera(camera, d)
    if normals is None:
        r = _validate.integer("normal_radius", normal_radius, minimum=1, maximum=max(d.shape))
        nrm = square_normals(d, camera, radius=r, toward_camera=True)
    else:
        nrm = _validate.array("normals", normals, shape=(*d.shape, 3))
    lab = lab_colour(img)
    vectors, points, valid, sigmas = _rgbd_rs.pixel_features(lab, d, nrm, cam)
    return Features(
        vectors=vectors, valid=valid, sigmas=sigmas, lab=lab, points=points, normals=nrm
    )
