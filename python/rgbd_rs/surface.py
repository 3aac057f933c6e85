"""B-spline (NURBS with unit weights) surface fitting and curvature maps (thesis §4.5, §5.3.3).

Surfaces ``S(u, v) = (X, Y, Z)`` are fitted to organised ``H x W x 3`` point clouds (NaN = no
measurement) with ``(u, v)`` the pixel lattice. The knot grid is anchored to the image: knots every
``spacing`` pixels, so any pixel set gets a number of control points proportional to its area
(thesis §4.5), and the normal equations of disjoint sets add up, which makes
:meth:`SegmentFits.union_error` one small solve.

Example::

    import numpy as np
    from rgbd_rs import PinholeCamera
    from rgbd_rs.surface import fit_grid

    cam = PinholeCamera(fx=525, fy=525, cx=319.5, cy=239.5, width=640, height=480)
    points = cam.depth_to_points(depth)            # H x W x 3, metres
    fit = fit_grid(points, spacing=16)
    fit.k1, fit.k2                                 # principal curvatures, 1/m, k1 >= k2
    fit.error                                      # per-pixel distance to the surface, m
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import FrozenInstanceError, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError

__all__ = [
    "DEFAULT_DEGREE",
    "DEFAULT_LAMBDA",
    "DEFAULT_SPACING",
    "DEFAULT_TEST_SPACING",
    "DEFAULT_TEST_WINDOW",
    "DEFAULT_TOLERANCE",
    "KINECT_V1_NOISE_POWER",
    "KINECT_V1_NOISE_SCALE",
    "MAX_DEGREE",
    "MAX_LAMBDA",
    "SegmentFits",
    "SurfaceFit",
    "SurfaceMaps",
    "fit_grid",
    "fit_mask",
    "ortho_points",
]

F32 = npt.NDArray[np.float32]
I32 = npt.NDArray[np.int32]

#: Knot spacing in pixels. Not given by the thesis or its sources (METHOD_NOTES §5 [NF]); 16 px
#: gives a 640x480 view 43x33 control points and a 1000-pixel segment about 30, enough for the
#: curved furniture of NYUv2 at Kinect noise levels; see the README for its measured effect.
DEFAULT_SPACING = 16.0
#: Degree in u and v (thesis §5.3.3: 3).
DEFAULT_DEGREE = 3
#: Second-difference smoothness weight relative to one data point (keeps knot spans without data
#: well-posed; a noise-free quadric is reproduced to < 1e-6 relative error).
DEFAULT_LAMBDA: float = _rgbd_rs.SPLINE_DEFAULT_LAMBDA
#: Highest supported degree.
MAX_DEGREE: int = _rgbd_rs.SPLINE_MAX_DEGREE

_SEAM = _rgbd_rs.SegmentFits.seam_defaults()
#: Knot spacing (pixels) of the grid the seam test fits on (see :class:`SegmentFits`).
DEFAULT_TEST_SPACING: float = _SEAM[0]
#: Kinect v1 axial depth noise ``sigma_z = a·z²`` (a in 1/m): Khoshelham & Elberink 2012, "Accuracy
#: and resolution of Kinect depth data for indoor mapping applications", Sensors 12(2).
KINECT_V1_NOISE_SCALE: float = _SEAM[1]
#: Exponent of the depth noise of triangulating sensors (``sigma_z ∝ z²``).
KINECT_V1_NOISE_POWER: float = _SEAM[2]
#: Allowed extra squared misfit per seam pixel, in noise variances.
DEFAULT_TOLERANCE: float = _SEAM[3]
#: Window of the seam test's local union fit (control points around the ones both parts hold
#: that move; the others stay at the parts' fits). ``None`` would solve the whole union.
DEFAULT_TEST_WINDOW: int | None = _SEAM[4]


def _label(name: str, value: object) -> int:
    """A segment label: an integer in ``0..2**31-1``."""
    return _validate.integer(name, value, minimum=0, maximum=2**31 - 1)


@array_eq
@dataclass(frozen=True)
class SurfaceMaps:
    """Per-pixel results; NaN where a pixel has no surface (or no measurement, for ``error``)."""

    #: ``H x W x 3`` surface point at each pixel's ``(u, v)``.
    fitted: F32
    #: ``H x W`` distance between the measured point and ``fitted`` (metres).
    error: F32
    #: ``H x W`` larger principal curvature (1/m; positive where the surface bulges to the camera).
    k1: F32
    #: ``H x W`` smaller principal curvature.
    k2: F32
    #: ``H x W`` mean curvature ``(k1 + k2) / 2``.
    mean: F32
    #: ``H x W`` Gaussian curvature ``k1 * k2``.
    gaussian: F32


_MAP_NAMES = ("fitted", "error", "k1", "k2", "mean", "gaussian")


class SurfaceFit(SurfaceMaps):
    """One fitted surface: its per-pixel maps and fit statistics.

    The maps (:attr:`fitted`, :attr:`error`, :attr:`k1`, :attr:`k2`, :attr:`mean`,
    :attr:`gaussian`) are evaluated on first access, all six at once, and only inside
    :attr:`box` (the fitted pixels' bounding box), from a copy of the points taken at fit time;
    a fit whose maps are never read costs only the fit. They are ``H x W`` like the points (NaN
    outside the mask), or box-sized with ``crop=True``. Immutable, like the dataclass it extends.
    """

    #: Valid pixels fitted.
    n: int
    #: Sum of squared 3-D distances to the surface.
    sse: float
    #: Effective degrees of freedom (trace of the hat matrix); None unless ``with_dof``.
    dof: float | None
    #: True when fewer than ``(degree+1)²`` pixels forced the linear fallback ``a + b·u + c·v``.
    linear: bool
    #: ``(row0, row1, col0, col1)``: the pixels ``[row0:row1, col0:col1]`` the fitted pixels lie in
    #: (the mask's bounding box; the whole image without a mask).
    box: tuple[int, int, int, int]
    #: Whether the maps are box-sized (``crop=True``) rather than image-sized.
    cropped: bool
    _image_shape: tuple[int, int]
    _native: _rgbd_rs._SplineFit | None
    # A fit is compared as itself (its maps are computed lazily, its native fit is opaque), not
    # by the maps of the dataclass it extends.
    __eq__ = object.__eq__
    __hash__ = object.__hash__
    _points: F32 | None
    _mask: npt.NDArray[np.bool_] | None
    _cache: dict[str, F32] | None

    def __init__(
        self,
        native: _rgbd_rs._SplineFit | None,
        points: F32 | None,
        mask: npt.NDArray[np.bool_] | None,
        *,
        n: int,
        sse: float,
        dof: float | None,
        linear: bool,
        box: tuple[int, int, int, int],
        image_shape: tuple[int, int],
        cropped: bool,
        maps: dict[str, F32] | None = None,
    ) -> None:
        # Frozen: attributes are set once, here (SurfaceMaps' __setattr__ refuses the maps).
        for name, value in (
            ("n", n),
            ("sse", sse),
            ("dof", dof),
            ("linear", linear),
            ("box", box),
            ("cropped", cropped),
            ("_image_shape", image_shape),
            ("_native", native),
            ("_points", points),
            ("_mask", mask),
            ("_cache", maps),
        ):
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: object) -> None:
        raise FrozenInstanceError(f"cannot assign to field {name!r}")

    def __delattr__(self, name: str) -> None:
        raise FrozenInstanceError(f"cannot delete field {name!r}")

    def __repr__(self) -> str:
        return (
            f"SurfaceFit(n={self.n}, sse={self.sse!r}, dof={self.dof!r}, linear={self.linear}, "
            f"box={self.box}, cropped={self.cropped})"
        )

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        # The native fit does not pickle; the maps do.
        state = (self.n, self.sse, self.dof, self.linear, self.box, self._image_shape)
        return (_restore_fit, (*state, self.cropped, self._all_maps()))

    def _all_maps(self) -> dict[str, F32]:
        maps: dict[str, F32] | None = self._cache
        if maps is not None:
            return maps
        r0, r1, c0, c1 = self.box
        native, points = self._native, self._points
        assert native is not None and points is not None
        raw = dict(zip(_MAP_NAMES, native.maps(points, self._mask, c0, r0), strict=True))
        h, w = self._image_shape
        if self.cropped or self.box == (0, h, 0, w):
            maps = raw
        else:
            maps = {}
            for name, box_map in raw.items():
                full = np.full((h, w, *box_map.shape[2:]), np.nan, np.float32)
                full[r0:r1, c0:c1] = box_map
                maps[name] = full
        object.__setattr__(self, "_cache", maps)
        # The points' copy is not needed any more.
        object.__setattr__(self, "_points", None)
        object.__setattr__(self, "_mask", None)
        return maps

    @property
    def fitted(self) -> F32:
        """Surface point at each pixel's ``(u, v)`` (``... x 3``)."""
        return self._all_maps()["fitted"]

    @property
    def error(self) -> F32:
        """Distance between the measured point and :attr:`fitted` (metres)."""
        return self._all_maps()["error"]

    @property
    def k1(self) -> F32:
        """Larger principal curvature (1/m; positive where the surface bulges to the camera)."""
        return self._all_maps()["k1"]

    @property
    def k2(self) -> F32:
        """Smaller principal curvature."""
        return self._all_maps()["k2"]

    @property
    def mean(self) -> F32:
        """Mean curvature ``(k1 + k2) / 2``."""
        return self._all_maps()["mean"]

    @property
    def gaussian(self) -> F32:
        """Gaussian curvature ``k1 * k2``."""
        return self._all_maps()["gaussian"]

    @property
    def mse(self) -> float:
        """Mean squared error ``sse / n`` (the thesis' segment fitting error ``e``)."""
        return self.sse / self.n

    @property
    def gcv(self) -> float:
        """Generalised cross-validation score ``n·sse / (n - dof)²`` (needs ``with_dof``)."""
        if self.dof is None:
            raise InvalidArgumentError("gcv: got a fit without dof, expected with_dof=True")
        rest = self.n - self.dof
        return float("inf") if rest <= 1e-9 * self.n else self.n * self.sse / rest**2


def _restore_fit(
    n: int,
    sse: float,
    dof: float | None,
    linear: bool,
    box: tuple[int, int, int, int],
    image_shape: tuple[int, int],
    cropped: bool,
    maps: dict[str, F32],
) -> SurfaceFit:
    """Unpickles a :class:`SurfaceFit` (with its maps computed)."""
    return SurfaceFit(
        None,
        None,
        None,
        n=n,
        sse=sse,
        dof=dof,
        linear=linear,
        box=box,
        image_shape=image_shape,
        cropped=cropped,
        maps=maps,
    )


def _rebuild_segment_fits(
    cls: type[SegmentFits],
    points: F32,
    labels: I32,
    options: dict[str, Any],
    merges: tuple[tuple[int, int], ...],
) -> SegmentFits:
    """Unpickles a :class:`SegmentFits`: the same fits built again, the same merges made."""
    fits = cls(points, labels, **options)
    for i, j in merges:
        fits.merge(i, j)
    return fits


#: Largest smoothing weight: past ~1e12 the fit is already the regulariser's limit (the same
#: surface to 1e-4 at 1e8 and 1e12), and past ~1e18 the normal equations lose their pivots.
MAX_LAMBDA = 1e12


#: The largest knot spacing, as a multiple of the grid's larger side (or :data:`DEFAULT_SPACING`
#: on smaller grids): one span then covers the whole grid, and wider ones only lose precision
#: (a quadratic surface 48 px wide: curvature 0.2 % off at 2x, 6 % at 4x, 27 % at 20x).
MAX_SPACING_SIDES = 2.0


def _spacing(name: str, spacing: float, shape: tuple[int, ...]) -> float:
    """A knot spacing of at least 1 px and at most :data:`MAX_SPACING_SIDES` times the larger
    side of a grid of ``shape`` (or :data:`DEFAULT_SPACING`)."""
    s = _validate.real(name, spacing, positive=True)
    if s < 1.0:
        raise InvalidArgumentError(f"{name}: got {s}, expected a knot spacing >= 1 pixel")
    side = max(shape[:2], default=0)
    cap = max(MAX_SPACING_SIDES * side, DEFAULT_SPACING)
    if s > cap:
        why = (
            f"{MAX_SPACING_SIDES:g} times the grid's larger side, {side} px: one knot span "
            "already covers it"
            if cap > DEFAULT_SPACING
            else f"the default spacing; the grid's larger side is {side} px"
        )
        raise InvalidArgumentError(f"{name}: got {s:g}, expected at most {cap:g} px ({why})")
    return s


def _params(
    spacing: float, degree: int, lam: float, shape: tuple[int, ...]
) -> tuple[float, int, float]:
    s = _spacing("spacing", spacing, shape)
    d = _validate.integer("degree", degree, minimum=1, maximum=MAX_DEGREE)
    return s, d, _validate.within("lam", lam, (0.0, MAX_LAMBDA), "a smoothing weight")


def _maps(raw: tuple[F32, F32, F32, F32, F32, F32]) -> dict[str, F32]:
    return dict(zip(("fitted", "error", "k1", "k2", "mean", "gaussian"), raw, strict=True))


def fit_mask(
    points: npt.ArrayLike,
    mask: npt.ArrayLike | None,
    *,
    spacing: float = DEFAULT_SPACING,
    degree: int = DEFAULT_DEGREE,
    lam: float = DEFAULT_LAMBDA,
    with_dof: bool = True,
    crop: bool = False,
) -> SurfaceFit:
    """Fit one surface to the valid points where ``mask`` is true (any shape, holes allowed).

    Maps are NaN outside the mask. Fewer than ``(degree+1)²`` valid pixels fall back to a linear
    fit (``linear=True``); no valid pixel raises :class:`~rgbd_rs.InvalidArgumentError`.
    ``with_dof`` also computes the effective degrees of freedom for :attr:`SurfaceFit.gcv`.
    The maps are computed when first read, inside the mask's bounding box only
    (:attr:`SurfaceFit.box`); ``crop=True`` returns them box-sized instead of ``H x W`` (a small
    segment of a large image then never allocates image-sized maps).
    """
    with_dof = _validate.flag("with_dof", with_dof)
    p = _validate.array("points", points, shape=(None, None, 3))
    m = None
    if mask is not None:
        raw_mask = _validate.asarray("mask", mask)
        if raw_mask.dtype != np.bool_:
            raise InvalidArgumentError(
                f"mask: got dtype {raw_mask.dtype}, expected a boolean array"
            )
        m = _validate.array(
            "mask", raw_mask.view(np.uint8), shape=(p.shape[0], p.shape[1]), dtype=np.uint8
        ).view(np.bool_)
    s, d, lam_ = _params(spacing, degree, lam, p.shape)
    if not isinstance(crop, (bool, np.bool_)):
        raise InvalidArgumentError(f"crop: got {crop!r}, expected True or False")
    if m is not None and not m.any():
        raise InvalidArgumentError("mask: got no pixel set, expected at least one pixel to fit")
    usable = np.isfinite(p).all(axis=2)
    if not (usable if m is None else usable & m).any():
        where = "" if m is None else " inside the mask"
        raise InvalidArgumentError(
            f"points: got no valid pixel (none with three finite coordinates{where}), expected "
            "at least one"
        )
    native, n, sse, dof, linear, box = _rgbd_rs.fit_surface(p, m, s, d, lam_, bool(with_dof))
    r0, r1, c0, c1 = box
    # Copies of the box: the maps are computed later, from the points as they are now.
    pts = np.array(p[r0:r1, c0:c1], dtype=np.float32, order="C")
    sub = None if m is None else np.array(m[r0:r1, c0:c1], order="C")
    return SurfaceFit(
        native,
        pts,
        sub,
        n=n,
        sse=sse,
        dof=dof,
        linear=linear,
        box=box,
        image_shape=(p.shape[0], p.shape[1]),
        cropped=bool(crop),
    )


def fit_grid(
    points: npt.ArrayLike,
    *,
    spacing: float = DEFAULT_SPACING,
    degree: int = DEFAULT_DEGREE,
    lam: float = DEFAULT_LAMBDA,
    with_dof: bool = False,
) -> SurfaceFit:
    """Fit one surface to a whole view (NaN holes skipped) and return it with curvature maps.

    The shape pipeline (thesis §5.3.3) calls this on each rendered depth view. The maps are
    computed when first read (see :class:`SurfaceFit`).
    """
    with_dof = _validate.flag("with_dof", with_dof)
    return fit_mask(points, None, spacing=spacing, degree=degree, lam=lam, with_dof=with_dof)


def ortho_points(depth: npt.ArrayLike, pixel_size: float) -> F32:
    """``H x W x 3`` points of an orthographic depth view: ``(u·s, v·s, depth)``.

    Use with :func:`fit_grid` for the curvature maps of rendered shape views.
    """
    z = _validate.array("depth", depth, shape=(None, None))
    s = _validate.real("pixel_size", pixel_size, positive=True)
    v, u = np.mgrid[0 : z.shape[0], 0 : z.shape[1]].astype(np.float32)
    return np.ascontiguousarray(np.stack([u * s, v * s, z], axis=-1), dtype=np.float32)


class SegmentFits:
    """Spline fits of every segment of a label image, for region merging (thesis §4.7).

    ``labels`` is ``H x W`` integer, ``-1`` (any negative) for unlabelled pixels; any labels
    ``>= 0`` and ``< 2**31`` (compacted internally, so sparse ids cost nothing) name the
    segments, and the methods take those labels. One object may be shared between threads, and
    pickled (as its inputs, which it keeps, 16 bytes a pixel, and its merges: unpickling fits the
    segments again and replays them). Each segment keeps its normal equations; :meth:`union_error`
    sums two systems and solves once (no pass over pixels), :meth:`merge` makes that union
    permanent.

    ``criterion`` picks what :meth:`fit_error` reports:

    * ``"seam"`` (default): the seam test. Each segment's *variance-stabilised depth*
      ``g(z) = ∫dz/sigma(z)`` (for ``sigma = a·z²``: disparity in noise units, ``-1/(a·z)``) is
      fitted on a knot grid of ``test_spacing`` pixels; the error is χ² per pixel (noise
      variances). The union of two segments changes the fit mostly on their *seam*, the pixels
      in cells that hold or touch a cell of the other segment, and eq. 4.8 merges when
      ``χ²(i+j) - χ²(i) - χ²(j) < tolerance · seam``: the two parts agree where they meet to
      within the sensor noise. :meth:`union_error` is ``(χ²(i+j) - tolerance·seam)/(n_i+n_j)`` so
      ``e_i·n_i + e_j·n_j - e_ij·(n_i+n_j)`` is the merge gain. Segments without a seam never
      merge (their union error is inf). The depth is the ``Z`` channel, in the unit of
      ``noise_scale`` (``sigma_z = noise_scale · z**noise_power``; default Kinect v1, metres).
      Scaling a scene's depth by ``k`` and ``noise_scale`` by ``k**(1 - noise_power)`` gives the
      same decisions.
      ``test_window`` (default :data:`DEFAULT_TEST_WINDOW`) makes the union fit local: only the
      control points within ``test_window`` points of those both parts' supports hold move, the
      others stay at the parts' fits, so a union test costs the same whatever the segments'
      sizes (the union's χ² is then an upper bound of the exact one: slightly conservative);
      ``test_window=None`` solves the whole union (exact, cost grows with the larger segment).
      :meth:`merge` always stores the exact fit of the merged segment.
      ``surfaces=False`` builds the seam test alone, without the surface fits of the points
      (about a third of the cost): :meth:`mse` and :meth:`maps` then raise, and :meth:`size`
      counts the pixels with a valid depth.
    * ``"gcv"``: generalised cross-validation ``n·SSE/(n - dof)²``, the MSE corrected for
      the degrees of freedom the fit used. Eq. 4.8 then merges two noisy patches of one surface
      and refuses a union across a depth step.
    * ``"mse"``: the thesis' plain MSE. With a knot grid anchored to the image, the union's fit is
      a restriction of the parts', so its MSE is never below their weighted mean and eq. 4.8 never
      merges; kept for comparison.

    Example::

        fits = SegmentFits(points, labels)
        if fits.should_merge(3, 7):       # eq. 4.8
            fits.merge(3, 7)              # segment 7 joins 3
        fits.labels()                     # the current label image
    """

    def __init__(
        self,
        points: npt.ArrayLike,
        labels: npt.ArrayLike,
        *,
        spacing: float = DEFAULT_SPACING,
        degree: int = DEFAULT_DEGREE,
        lam: float = DEFAULT_LAMBDA,
        criterion: str = "seam",
        test_spacing: float = DEFAULT_TEST_SPACING,
        noise_scale: float = KINECT_V1_NOISE_SCALE,
        noise_power: float = KINECT_V1_NOISE_POWER,
        tolerance: float = DEFAULT_TOLERANCE,
        surfaces: bool = True,
        test_window: int | None = DEFAULT_TEST_WINDOW,
    ) -> None:
        p = _validate.array("points", points, shape=(None, None, 3))
        raw = _validate.asarray("labels", labels)
        if raw.dtype.kind not in "iu":
            raise InvalidArgumentError(f"labels: got dtype {raw.dtype}, expected an integer array")
        lab = _validate.array("labels", raw, shape=(p.shape[0], p.shape[1]), dtype=np.int64)
        if lab.size and lab.max() > np.iinfo(np.int32).max:
            raise InvalidArgumentError(f"labels: got a label {lab.max()}, expected < 2**31")
        crit = _validate.choice("criterion", criterion, ("seam", "gcv", "mse"))
        s, d, lam_ = _params(spacing, degree, lam, p.shape)
        ts = _spacing("test_spacing", test_spacing, p.shape)
        ns = _validate.real("noise_scale", noise_scale, positive=True)
        if ns == KINECT_V1_NOISE_SCALE:  # the default law is in metres; a caller's in its unit
            _validate.metric_points(
                "points", p, "noise_scale's default (Kinect v1) is", "give noise_scale"
            )
        npow = _validate.real("noise_power", noise_power)
        tol = _validate.real("tolerance", tolerance, nonnegative=True)
        lab32 = np.ascontiguousarray(np.maximum(lab, -1), dtype=np.int32)
        if not isinstance(surfaces, bool):
            raise InvalidArgumentError(f"surfaces: got {surfaces!r}, expected True or False")
        if not surfaces and crit != "seam":
            raise InvalidArgumentError(
                f"surfaces: got False with criterion {crit!r}, expected criterion 'seam'"
            )
        win = (
            None
            if test_window is None
            else _validate.integer("test_window", test_window, maximum=2**31 - 1)
        )
        self._native = _rgbd_rs.SegmentFits(
            p, lab32, s, d, lam_, crit, ts, ns, npow, tol, surfaces, win
        )
        self.shape: tuple[int, int] = (p.shape[0], p.shape[1])
        self._surfaces = surfaces
        # What a pickle rebuilds the fits from (the native fits do not pickle): the inputs,
        # copied where they are still the caller's array, and the merges in order.
        if np.may_share_memory(p, np.asarray(points)):  # the caller's buffer (any array type)
            p = p.copy()
        options = {
            "spacing": s,
            "degree": d,
            "lam": lam_,
            "criterion": crit,
            "test_spacing": ts,
            "noise_scale": ns,
            "noise_power": npow,
            "tolerance": tol,
            "surfaces": surfaces,
            "test_window": win,
        }
        self._recipe: tuple[F32, I32, dict[str, object]] = (p, lab32, options)
        self._merges: list[tuple[int, int]] = []
        self._merge_lock = threading.Lock()

    def __reduce__(self) -> tuple[object, ...]:
        """Pickles as the inputs and the merges so far: unpickling fits the segments again
        (as long as building them took) and replays the merges, to the same fits."""
        points, labels, options = self._recipe
        with self._merge_lock:
            merges = tuple(self._merges)
            if len(merges) != self._native.merges:
                raise RgbdError(
                    f"fits: got fits merged {self._native.merges} times, {len(merges)} of them "
                    "recorded (a merge_regions() stopped part way, e.g. by Ctrl-C), expected "
                    "fits whose merges all finished: build SegmentFits again to pickle them"
                )
        return (_rebuild_segment_fits, (type(self), points, labels, options, merges))

    def _merge_natively(self, merge: Callable[[Any], tuple[Any, ...]]) -> tuple[Any, ...]:
        """Runs ``merge(native fits)`` (the native loop of
        :func:`rgbd_rs.segmentation.merge_regions`, which returns ``(labels, kept, absorbed,
        ...)``: ``absorbed[k]`` joined ``kept[k]``) and records its merges, for pickling; no
        other merge or pickle runs in between."""
        with self._merge_lock:
            out = merge(self._native)
            kept, absorbed = np.asarray(out[1]), np.asarray(out[2])
            self._merges.extend((int(a), int(b)) for a, b in zip(kept, absorbed, strict=True))
        return out

    @property
    def n_labels(self) -> int:
        """Number of distinct labels the fits were built with (merged ones included)."""
        return self._native.n_labels

    @property
    def label_ids(self) -> list[int]:
        """The distinct labels (>= 0) the fits were built with, sorted."""
        return self._native.label_ids

    @property
    def criterion(self) -> str:
        """``"seam"``, ``"gcv"`` or ``"mse"``."""
        return self._native.criterion

    def size(self, i: int) -> int:
        """Valid pixels of live segment ``i``."""
        return self._native.size(_label("i", i))

    def fit_error(self, i: int) -> float:
        """Fitting error of live segment ``i`` under :attr:`criterion` (inf: it interpolates).

        ``"seam"``: χ² per pixel of its variance-stabilised depth (noise variances).
        """
        return self._native.fit_error(_label("i", i))

    def mse(self, i: int) -> float:
        """Plain mean squared 3-D distance of segment ``i`` to its surface (fits built with
        ``surfaces=True`` only)."""
        self._need_surfaces("mse")
        return self._native.mse(_label("i", i))

    def _need_surfaces(self, what: str) -> None:
        if not self._surfaces:
            raise RgbdError(
                f"{what}: these fits were built with surfaces=False (the seam test alone), "
                "expected SegmentFits(..., surfaces=True) for surface fits"
            )

    def union_error(self, i: int, j: int) -> float:
        """Fitting error of the union of live segments ``i`` and ``j`` (nothing changes).

        ``"seam"``: ``(χ²(i+j) - tolerance·seam) / (n_i + n_j)``; inf when there is no seam.
        """
        return self._native.union_error(_label("i", i), _label("j", j))

    def seam(self, i: int, j: int) -> int:
        """Seam pixels of live segments ``i`` and ``j`` (``"seam"`` criterion; else 0)."""
        return self._native.seam(_label("i", i), _label("j", j))

    def should_merge(self, i: int, j: int) -> bool:
        """Eq. 4.8: ``e_i|S_i| + e_j|S_j| > e_ij (|S_i| + |S_j|)``."""
        return self._native.should_merge(_label("i", i), _label("j", j))

    def merge(self, i: int, j: int) -> float:
        """Merge live segment ``j`` into ``i``; returns the merged segment's error."""
        a, b = _label("i", i), _label("j", j)
        with self._merge_lock:  # the merges recorded in the order they were made
            error = self._native.merge(a, b)
            self._merges.append((a, b))
        return error

    def find(self, label: int) -> int:
        """The live segment (its label) an original label belongs to now."""
        return self._native.find(_label("label", label))

    def labels(self) -> I32:
        """``H x W`` label image with merged labels replaced by their live segment."""
        return self._native.labels()

    def maps(self, points: npt.ArrayLike) -> SurfaceMaps:
        """Per-pixel maps of ``points`` against the surface of each pixel's current segment
        (fits built with ``surfaces=True`` only)."""
        self._need_surfaces("maps")
        p = _validate.array("points", points, shape=(self.shape[0], self.shape[1], 3))
        return SurfaceMaps(**_maps(self._native.maps(p)))
