"""Curvature maps of a shape's six depth views (thesis §5.3.3).

Each depth view of :func:`rgbd_rs.shapes.views.depth_views` is approximated by a cubic B-spline
surface (a NURBS of degree 3 with unit weights, §5.3.3) whose ``(u, v)`` range is the view's
pixel grid, and the two principal curvatures ``k1 >= k2`` of that surface are sampled at every
pixel: :func:`curvature_maps` returns ``(6, 2, R, R)`` float32, ``[:, 0]`` = k1, ``[:, 1]`` = k2.

**Units and sign.** Curvatures are in units of 1 / (the shape's bounding-cube side), the unit the
views are measured in, so a sphere of radius ``r`` in a cube of side ``a`` reads ``a / r``.
Because the views normalise the shape into its bounding cube, the maps do not depend on the
shape's unit or scale (a shape scaled by 1000 gives the same maps up to float rounding, before
any normalisation). Positive where the surface bulges towards the viewer (a ball seen from
outside: ``k1 = k2 > 0``), negative in a bowl or concave corner.

**Fit.** The surface is the graph ``(u, v, z(u, v))`` of the depth: in an orthographic view
``x`` and ``y`` are exactly linear in ``(u, v)``, which a cubic spline reproduces, so fitting
``z`` alone is the thesis' 3-D fit. Knots every :func:`knot_spacing` pixels (``R / 16``: the
same 16 knot spans per view side at every resolution, so the maps describe the same geometry at
64 and at 320 pixels), second-difference smoothing as in :mod:`rgbd_rs.surface`.

**Rim.** Next to a silhouette a smooth closed surface turns away from the viewer: the depth's
slope grows without bound, no spline follows it, and a fit that includes those pixels rings for
2-3 knot spans inwards (a sphere: k1, k2 off by a median 25 % at 0.6-0.7 of its radius). We fit
the object's pixels only (empty pixels are not data) and leave out the *grazing* ones: pixels
whose depth slope (central differences of the view, in depth units per pixel width) exceeds
:data:`MAX_SLOPE` = 2, i.e. where the surface normal is more than ``atan 2`` = 63.4° from the
view direction. That cuts a sphere at 0.89 of its radius, and it also cuts the view at depth
jumps (a step of more than 2 pixels between neighbours), so one smooth piece does not bend to
meet another. Masking beat per-pixel weights ``1 / (1 + slope²)^k`` and larger thresholds on
a sphere (see the tests and out/notes/curvature.md for the numbers).

**Empty and grazing pixels get 0** (no surface, or no reliable curvature): after the per-map
normalisation of :mod:`rgbd_rs.shapes.dataset` they read like a flat surface would.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes import views as _views
from rgbd_rs.surface import DEFAULT_DEGREE, DEFAULT_LAMBDA, fit_mask

__all__ = [
    "KNOT_SPANS",
    "MAX_SLOPE",
    "curvature_maps",
    "knot_spacing",
]

#: Knot spans across a view side: knots every ``R / KNOT_SPANS`` pixels (:func:`knot_spacing`).
#: The thesis gives no knot rule (METHOD_NOTES §5 [NF]); 16 spans keep a sphere's k1, k2 within
#: 5 % over the inner 80 % of its radius at 64 and at 320 pixels, 8 spans do not.
KNOT_SPANS = 16
#: Largest depth slope (depth units per pixel width, ``tan`` of the angle between the surface
#: normal and the view direction) of a pixel that enters the fit; steeper pixels get 0.
MAX_SLOPE = 2.0
#: Distance (cube sides) the fit's points are moved away from the viewer, so that the spline
#: kernel's camera-facing normal (``n · S < 0``) is the viewer-facing one of an orthographic view.
_Z_OFFSET = 8.0


def knot_spacing(resolution: int) -> float:
    """Knot spacing in pixels for ``resolution``-pixel views: ``resolution / KNOT_SPANS``, at
    least 1 pixel (4 at 64, 20 at 320)."""
    r = _validate.integer("resolution", resolution, minimum=1)
    return max(1.0, r / KNOT_SPANS)


def _slope(depth: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """Per-pixel depth slope in depth units per pixel (central differences; one-sided next to an
    empty pixel; inf where both neighbours along an axis are empty)."""
    z = np.pad(depth, 1, constant_values=np.nan)
    mid = z[1:-1, 1:-1]

    def axis(fwd: np.ndarray, back: np.ndarray) -> np.ndarray:
        central = (fwd - back) / 2
        one = np.where(np.isnan(fwd), mid - back, fwd - mid)
        d = np.where(np.isnan(central), one, central)
        return np.nan_to_num(d, nan=np.inf)

    gx = axis(z[1:-1, 2:], z[1:-1, :-2])
    gy = axis(z[2:, 1:-1], z[:-2, 1:-1])
    return np.asarray(np.hypot(gx, gy), np.float32)


def _view_curvature(depth: npt.NDArray[np.float32], spacing: float) -> npt.NDArray[np.float32]:
    """``(2, R, R)`` k1, k2 of one raw view (NaN = empty), in 1 / cube side."""
    h, w = depth.shape
    out = np.zeros((2, h, w), np.float32)
    res = float(max(h, w))
    keep = np.isfinite(depth) & (_slope(depth) * res <= MAX_SLOPE)
    if keep.sum() < (DEFAULT_DEGREE + 1) ** 2:
        return out
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    pts = np.stack([(u + 0.5) / res - 0.5, (v + 0.5) / res - 0.5, depth + _Z_OFFSET], axis=-1)
    pts[~keep] = np.nan
    fit = fit_mask(pts, keep, spacing=spacing, lam=DEFAULT_LAMBDA, with_dof=False)
    out[0] = np.where(keep, fit.k1, 0)
    out[1] = np.where(keep, fit.k2, 0)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def curvature_maps(
    shape: Mesh | npt.ArrayLike, resolution: int = _views.DEFAULT_RESOLUTION
) -> np.ndarray:
    """The principal-curvature maps of a :class:`~rgbd_rs.meshes.Mesh` or an ``N x 3`` point
    cloud: ``(6, 2, R, R)`` float32, view order of :data:`rgbd_rs.shapes.views.VIEW_NAMES`,
    channel 0 = k1, 1 = k2 (``k1 >= k2``), in 1 / bounding-cube side, 0 on empty and grazing
    pixels (see the module docstring)."""
    if isinstance(shape, (str, bytes)):
        raise InvalidArgumentError(
            f"shape: got {type(shape).__name__}, expected a Mesh or an N x 3 point cloud"
        )
    r = _validate.integer("resolution", resolution, minimum=1, maximum=_views.MAX_RESOLUTION)
    raw = _views.depth_views(shape, r, lcn=False, background=float("nan"))
    spacing = knot_spacing(r)
    return np.stack([_view_curvature(view, spacing) for view in raw])
