"""Camera models (thesis §2.2): pinhole intrinsics, Heikkila / Brown-Conrady distortion with the
rational extension, rigid poses, and the stereo and ToF-stereo rigs built from them.

Conventions: x right, y down, z forward (OpenCV); pixel centres at integer coordinates; depth is
z along the optical axis in metres; NaN marks a missing measurement.

Example:
    >>> import numpy as np
    >>> from rgbd_rs.camera import Distortion, PinholeCamera
    >>> cam = PinholeCamera(500.0, 500.0, 319.5, 239.5, 640, 480, Distortion(k1=-0.1))
    >>> px = cam.project(np.array([[0.1, 0.0, 1.0]]))
    >>> bool(np.allclose(cam.undistort_points(px), [[369.5, 239.5]]))
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError

__all__ = ["Distortion", "PinholeCamera", "Pose", "StereoRig", "ToFStereoRig"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
Interpolation = Literal["nearest", "linear"]

#: Newton iterations and residual tolerance (normalised units) used to invert the lens model.
UNDISTORT_MAX_ITER = 20
UNDISTORT_TOL = 1e-12
#: Tolerance on ``|R^T R - I|`` accepted for rotations (factory calibrations store f32).
ROTATION_TOL = 1e-5


def _flat(name: str, value: object) -> np.ndarray:
    """``value`` raveled to 1-D; ragged or non-array input raises naming ``name``."""
    return np.ravel(_validate.asarray(name, value))


def _camera_arg(name: str, value: object) -> PinholeCamera:
    if not isinstance(value, PinholeCamera):
        raise InvalidArgumentError(f"{name}: got {type(value).__name__}, expected a PinholeCamera")
    return value


#: Largest magnitude of a distortion coefficient (a 1e30 k1 projected points to 8e28 px).
MAX_DISTORTION = 1e9


@dataclass(frozen=True)
class Distortion:
    """Lens distortion of eq. 2.8 (Heikkila) plus the rational terms k4..k6.

    ``k1, k2, k3`` radial numerator, ``k4, k5, k6`` radial denominator, ``p1, p2`` tangential
    (the thesis' d1, d2). All zero means an ideal pinhole.
    """

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    k5: float = 0.0
    k6: float = 0.0

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"):
            v = _validate.real(f"distortion.{name}", getattr(self, name))
            if abs(v) > MAX_DISTORTION:
                raise InvalidArgumentError(
                    f"distortion.{name}: got {v:.3g}, expected a coefficient within "
                    f"+-{MAX_DISTORTION:g} (calibrated lenses stay within a few hundred)"
                )

    @classmethod
    def from_opencv(cls, coeffs: npt.ArrayLike) -> Distortion:
        """From OpenCV's order ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])`` (4, 5 or 8 values)."""
        c = _validate.array(
            "coeffs",
            _flat("coeffs", coeffs),
            shape=(None,),
            dtype=np.float64,
            finite=True,
            allow_empty=True,
        )
        if c.size not in (0, 4, 5, 8):
            raise ShapeMismatchError(
                f"coeffs: got {c.size} coefficients, expected 0, 4, 5 or 8 "
                "(k1, k2, p1, p2[, k3[, k4, k5, k6]])"
            )
        if c.size and float(np.abs(c).max()) > MAX_DISTORTION:
            raise InvalidArgumentError(
                f"coeffs: got a coefficient of {float(np.abs(c).max()):.3g}, expected each within "
                f"+-{MAX_DISTORTION:g}"
            )
        full = np.zeros(8)
        full[: c.size] = c
        return cls(*(float(v) for v in full))

    def to_opencv(self) -> F64:
        """The 8 coefficients in OpenCV's rational-model order."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3, self.k4, self.k5, self.k6])

    @property
    def is_identity(self) -> bool:
        """True when there is no distortion at all."""
        return not self.to_opencv().any()


@array_eq
@dataclass(frozen=True)
class Pose:
    """Rigid transform ``X_b = R X_a + t`` taking points of frame *a* into frame *b* (metres)."""

    rotation: F64 = field(default_factory=lambda: np.eye(3))
    translation: F64 = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        r = _validate.array("rotation", self.rotation, shape=(3, 3), dtype=np.float64, finite=True)
        t = _validate.array(
            "translation",
            _flat("translation", self.translation),
            shape=(3,),
            dtype=np.float64,
            finite=True,
        )
        err = float(np.abs(r.T @ r - np.eye(3)).max())
        if err > ROTATION_TOL or np.linalg.det(r) <= 0:
            raise InvalidArgumentError(
                f"rotation: got a matrix with |R^T R - I| = {err:.2e} and det = "
                f"{np.linalg.det(r):.4f}, expected a rotation (orthonormal, det = +1)"
            )
        r.flags.writeable = False
        t.flags.writeable = False
        object.__setattr__(self, "rotation", r)
        object.__setattr__(self, "translation", t)

    @classmethod
    def identity(cls) -> Pose:
        """The identity transform."""
        return cls()

    @classmethod
    def from_matrix(cls, matrix: npt.ArrayLike) -> Pose:
        """From a 4x4 (or 3x4) homogeneous matrix ``[R | t]``."""
        m = _validate.array("matrix", matrix, shape=(None, 4), dtype=np.float64, finite=True)
        if m.shape[0] not in (3, 4):
            raise ShapeMismatchError(f"matrix: got shape {m.shape}, expected (3, 4) or (4, 4)")
        try:
            return cls(m[:3, :3], m[:3, 3])
        except RgbdError as e:  # the rotation block is part of the argument the caller named
            raise type(e)(f"matrix: {e}") from None

    def as_matrix(self) -> F64:
        """The 4x4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation
        return m

    def inverse(self) -> Pose:
        """The transform from *b* back to *a*."""
        return Pose(self.rotation.T, -self.rotation.T @ self.translation)

    def compose(self, first: Pose) -> Pose:
        """``self ∘ first``: apply ``first`` then ``self``."""
        first = _pose_arg("first", first)
        return Pose(
            self.rotation @ first.rotation, self.rotation @ first.translation + self.translation
        )

    def apply(self, points: npt.ArrayLike) -> F64:
        """Transform ``N x 3`` points."""
        p = _validate.array("points", points, shape=(None, 3), dtype=np.float64, allow_empty=True)
        return np.asarray(p @ self.rotation.T + self.translation, dtype=np.float64)

    def _native(self) -> tuple[list[float], list[float]]:
        return [float(v) for v in self.rotation.ravel()], [float(v) for v in self.translation]


def _pose_arg(name: str, value: object, *, default_identity: bool = False) -> Pose:
    """``value`` if it is a :class:`Pose` (None -> identity when ``default_identity``)."""
    if value is None and default_identity:
        return Pose.identity()
    if not isinstance(value, Pose):
        want = "a Pose or None" if default_identity else "a Pose"
        raise InvalidArgumentError(f"{name}: got {type(value).__name__}, expected {want}")
    return value


#: The focal lengths a camera may have, in pixels: far beyond any lens (a 1 m telephoto on 1 um
#: pixels is 1e6 px), and inside them the projection's products and squares stay within float32
#: (at 1e30 px a normal's cross product overflows; at 1e-40 px the inverse does).
FOCAL_RANGE = (1e-3, 1e8)
#: The farthest a principal point may lie from the image origin, in pixels (the focal range's
#: top: beyond it the projection's products leave float32 as a focal length's would).
MAX_PRINCIPAL = FOCAL_RANGE[1]


def _focal(name: str, value: object) -> float:
    return _validate.within(name, value, FOCAL_RANGE, "a focal length", "px")


def _principal(name: str, value: object) -> float:
    c = _validate.real(name, value)
    if abs(c) > MAX_PRINCIPAL:
        raise InvalidArgumentError(
            f"{name}: got {c:.3g} px, expected a principal point within +-{MAX_PRINCIPAL:g} px"
        )
    return c


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole intrinsics (eq. 2.5-2.6) of a ``width x height`` image, with lens distortion.

    Args:
        fx, fy: focal lengths in pixels (within :data:`FOCAL_RANGE`).
        cx, cy: principal point in pixels (pixel centres are integers).
        width, height: image size in pixels.
        distortion: the lens model; default none.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    distortion: Distortion = field(default_factory=Distortion)

    def __post_init__(self) -> None:
        # Stored as Python numbers (a numpy scalar would not survive save_camera's JSON).
        for name, v in (
            ("fx", _focal("fx", self.fx)),
            ("fy", _focal("fy", self.fy)),
            ("cx", _principal("cx", self.cx)),
            ("cy", _principal("cy", self.cy)),
            ("width", _validate.size("width", self.width)),
            ("height", _validate.size("height", self.height)),
        ):
            object.__setattr__(self, name, v)
        if not isinstance(self.distortion, Distortion):
            raise InvalidArgumentError(
                f"distortion: got {type(self.distortion).__name__}, expected a Distortion"
            )

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_matrix(
        cls, K: npt.ArrayLike, width: int, height: int, distortion: Distortion | None = None
    ) -> PinholeCamera:
        """From a 3x3 intrinsic matrix ``K`` (zero skew)."""
        k = _validate.array("K", K, shape=(3, 3), dtype=np.float64, finite=True)
        if k[0, 1] != 0 or k[1, 0] != 0 or not np.allclose(k[2], [0, 0, 1]):
            raise InvalidArgumentError(
                f"K: got {k.tolist()}, expected [[fx,0,cx],[0,fy,cy],[0,0,1]]"
            )
        return cls(
            float(k[0, 0]),
            float(k[1, 1]),
            float(k[0, 2]),
            float(k[1, 2]),
            width,
            height,
            Distortion() if distortion is None else distortion,
        )

    @property
    def K(self) -> F64:
        """The 3x3 intrinsic matrix (eq. 2.6)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)``."""
        return self.width, self.height

    @property
    def hfov(self) -> float:
        """Horizontal field of view of the ideal pinhole, radians."""
        return 2.0 * math.atan(self.width / (2.0 * self.fx))

    def scaled(self, sx: float, sy: float | None = None) -> PinholeCamera:
        """The same camera imaging at a resolution scaled by ``sx`` (and ``sy``, default ``sx``).

        Uses the pixel-centre convention: ``c' = (c + 0.5) s - 0.5``.
        """
        sx = _validate.real("sx", sx, positive=True)
        sy = sx if sy is None else _validate.real("sy", sy, positive=True)
        for name, s, side in (("sx", sx, self.width), ("sy", sy, self.height)):
            if side * s < 0.5:
                raise InvalidArgumentError(
                    f"{name}: got {s}, which makes the {side} px side {side * s:.3g} px; expected "
                    "a factor that leaves at least one pixel"
                )
            if not side * s <= _validate.MAX_SIDE:
                raise InvalidArgumentError(
                    f"{name}: got {s}, which makes the image {side * s:.3g} px; expected at most "
                    f"{_validate.MAX_SIDE} px"
                )
        return replace(
            self,
            fx=self.fx * sx,
            fy=self.fy * sy,
            cx=(self.cx + 0.5) * sx - 0.5,
            cy=(self.cy + 0.5) * sy - 0.5,
            width=max(1, round(self.width * sx)),
            height=max(1, round(self.height * sy)),
        )

    def cropped(self, x0: int, y0: int, width: int, height: int) -> PinholeCamera:
        """The camera of the sub-image ``[y0:y0+height, x0:x0+width]``."""
        x0 = _validate.integer("x0", x0, maximum=self.width - 1)
        y0 = _validate.integer("y0", y0, maximum=self.height - 1)
        width = _validate.integer("width", width, minimum=1, maximum=self.width - x0)
        height = _validate.integer("height", height, minimum=1, maximum=self.height - y0)
        return replace(self, cx=self.cx - x0, cy=self.cy - y0, width=width, height=height)

    def without_distortion(self) -> PinholeCamera:
        """The ideal pinhole with the same intrinsics."""
        return replace(self, distortion=Distortion())

    def _ideal_target(self, target: PinholeCamera | None) -> PinholeCamera:
        """``target``, or this camera without distortion; rejects anything else."""
        if target is None:
            return self.without_distortion()
        return _camera_arg("target", target)

    def _native(self) -> tuple[float, float, float, float, int, int, list[float]]:
        return (
            float(self.fx),
            float(self.fy),
            float(self.cx),
            float(self.cy),
            int(self.width),
            int(self.height),
            [float(v) for v in self.distortion.to_opencv()],
        )

    # -- points -------------------------------------------------------------------------------
    def project(self, points: npt.ArrayLike, pose: Pose | None = None) -> F64:
        """Project ``N x 3`` points (eq. 2.7 with distortion) to ``N x 2`` distorted pixels.

        ``pose`` maps the points' frame into this camera's frame (default: already in it).
        Points with ``z <= 0`` after the transform give NaN.
        """
        p = _validate.array("points", points, shape=(None, 3), dtype=np.float64, allow_empty=True)
        pose = _pose_arg("pose", pose, default_identity=True)
        return _rgbd_rs.project_points(p, self._native(), pose._native())

    def undistort_points(
        self,
        pixels: npt.ArrayLike,
        *,
        normalized: bool = False,
        max_iter: int = UNDISTORT_MAX_ITER,
        tol: float = UNDISTORT_TOL,
    ) -> F64:
        """Remove the lens distortion from ``N x 2`` pixels (Newton's method).

        Returns ideal pixels of the same intrinsics, or normalised image-plane coordinates when
        ``normalized``. Points where the iteration does not reach ``tol`` within ``max_iter``
        steps give NaN.
        """
        normalized = _validate.flag("normalized", normalized)
        px = _validate.array("pixels", pixels, shape=(None, 2), dtype=np.float64, allow_empty=True)
        max_iter = _validate.integer("max_iter", max_iter, minimum=1, maximum=1000)
        tol = _validate.real("tol", tol, positive=True)
        return _rgbd_rs.undistort_pixels(px, self._native(), bool(normalized), max_iter, tol)

    def distort_points(self, pixels: npt.ArrayLike) -> F64:
        """Apply the lens distortion to ``N x 2`` ideal pixels."""
        px = _validate.array("pixels", pixels, shape=(None, 2), dtype=np.float64, allow_empty=True)
        return _rgbd_rs.distort_pixels(px, self._native())

    def backproject(self, pixels: npt.ArrayLike, depth: npt.ArrayLike) -> F64:
        """3-D points (camera frame) of ``N x 2`` distorted pixels at depths ``z`` (``N``)."""
        px = _validate.array("pixels", pixels, shape=(None, 2), dtype=np.float64, allow_empty=True)
        z = _validate.array(
            "depth", depth, shape=(px.shape[0],), dtype=np.float64, allow_empty=True
        )
        xy = self.undistort_points(px, normalized=True)
        z = np.where(z > 0, z, np.nan)
        return np.column_stack([xy * z[:, None], z])

    # -- images -------------------------------------------------------------------------------
    def depth_to_points(self, depth: npt.ArrayLike) -> F32:
        """Back-project an ``H x W`` depth map (z, metres) to an ``H x W x 3`` point cloud.

        Invalid depth (NaN, <= 0) gives NaN points. An integer map (a raw depth image, usually
        millimetres) is refused: divide it into metres first.
        """
        _validate.metric_depth("depth", depth)
        d = _validate.array("depth", depth, shape=(self.height, self.width))
        return _rgbd_rs.depth_to_points(d, self._native(), UNDISTORT_MAX_ITER, UNDISTORT_TOL)

    def undistort_map(
        self, target: PinholeCamera | None = None, rotation: npt.ArrayLike | None = None
    ) -> F32:
        """For each pixel of the ideal ``target`` camera (default: this camera without
        distortion), the ``(x, y)`` pixel of this camera that sees the same ray: ``H x W x 2``.

        ``rotation`` (3x3) rectifies: target rays are rotated by ``R^T`` into this camera, as in
        OpenCV's ``initUndistortRectifyMap``.
        """
        target = self._ideal_target(target)
        rot = None
        if rotation is not None:
            rot = [float(v) for v in Pose(rotation).rotation.ravel()]  # type: ignore[arg-type]
        return _rgbd_rs.undistort_map(self._native(), target._native(), rot)

    def undistort_image(
        self,
        image: npt.ArrayLike,
        *,
        interpolation: Interpolation = "linear",
        target: PinholeCamera | None = None,
    ) -> np.ndarray:
        """Resample an ``H x W`` or ``H x W x C`` image/depth map onto the ideal ``target``.

        Use ``interpolation="nearest"`` for depth (no mixed depths across edges). Float input
        gives float32 with NaN where the source has no sample; integer input keeps its dtype with
        0 there.
        """
        src = _validate.asarray("image", image)
        img, was_2d = _validate.image("image", src)
        if img.shape[:2] != (self.height, self.width):
            raise ShapeMismatchError(
                f"image: got size {img.shape[1]}x{img.shape[0]}, expected the camera's "
                f"{self.width}x{self.height}"
            )
        interpolation = _validate.choice("interpolation", interpolation, ("nearest", "linear"))  # type: ignore[assignment]
        target = self._ideal_target(target)
        out = _rgbd_rs.undistort_image(img, self._native(), target._native(), interpolation)
        if src.dtype.kind in "iu":
            info = np.iinfo(src.dtype)
            # Clipped in float64: float32 cannot hold int32's bounds (2**31 - 1 rounds up to 2**31).
            wide = np.rint(np.asarray(out, np.float64))
            out = np.clip(np.nan_to_num(wide, nan=0.0), info.min, info.max).astype(src.dtype)
        return out[:, :, 0] if was_2d else out


@dataclass(frozen=True)
class StereoRig:
    """A rectified stereo pair: identical ideal intrinsics, the right camera ``baseline`` metres
    along +x of the left one. Disparity ``d = u_left - u_right = baseline * fx / z`` (eq. 2.15).
    """

    left: PinholeCamera
    right: PinholeCamera
    baseline: float

    def __post_init__(self) -> None:
        _camera_arg("left", self.left)
        _camera_arg("right", self.right)
        # Stored as the float it was checked as (an int such as 2**64 reached numpy as an object).
        object.__setattr__(
            self, "baseline", _validate.real("baseline", self.baseline, positive=True)
        )
        if self.left.size != self.right.size or not math.isclose(
            self.left.fx, self.right.fx, rel_tol=1e-6, abs_tol=1e-6
        ):
            raise InvalidArgumentError(
                f"right: got {self.right.size} fx={self.right.fx}, expected a rectified pair with "
                f"the left camera's size {self.left.size} and fx={self.left.fx}"
            )
        if self.baseline * self.left.fx > _validate.F32_MAX:
            raise InvalidArgumentError(
                f"baseline: got {self.baseline:.3g} m with fx={self.left.fx:g}: every disparity "
                f"baseline x fx / z would overflow float32; expected baseline x fx <= "
                f"{_validate.F32_MAX:.3g} (a baseline in metres)"
            )
        # A rectified pair's rows line up (same fy, cy) and d = baseline * fx / z holds only
        # with the same cx: an offset (Middlebury's "doffs") would shift every disparity.
        for name in ("fy", "cx", "cy"):
            a, b = getattr(self.left, name), getattr(self.right, name)
            if not math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-6):
                hint = (
                    "shift one image by the offset first"
                    if name == "cx"
                    else "rectify the pair first: its rows must line up"
                )
                raise InvalidArgumentError(
                    f"right: got {name}={b}, expected the left camera's {name}={a} (a rectified "
                    f"pair shares its intrinsics; {hint})"
                )

    @property
    def focal(self) -> float:
        """The common horizontal focal length in pixels."""
        return self.left.fx

    @property
    def left_to_right(self) -> Pose:
        """Pose taking left-camera points into the right camera's frame."""
        return Pose(np.eye(3), np.array([-self.baseline, 0.0, 0.0]))


@dataclass(frozen=True)
class ToFStereoRig:
    """A ToF camera beside a rectified stereo pair (thesis §3.2).

    ``tof_to_reference`` maps ToF-frame points into the reference camera's frame; the reference
    is the right camera as in the thesis (``reference="right"``) or the left one.
    """

    tof: PinholeCamera
    stereo: StereoRig
    tof_to_reference: Pose
    reference: Literal["left", "right"] = "right"

    def __post_init__(self) -> None:
        _camera_arg("tof", self.tof)
        if not isinstance(self.stereo, StereoRig):
            raise InvalidArgumentError(
                f"stereo: got {type(self.stereo).__name__}, expected a StereoRig"
            )
        _pose_arg("tof_to_reference", self.tof_to_reference)
        _validate.choice("reference", self.reference, ("left", "right"))

    @property
    def reference_camera(self) -> PinholeCamera:
        """The camera the fused disparity is expressed on."""
        return self.stereo.right if self.reference == "right" else self.stereo.left
