"""Curvature maps of a shape's six depth views (thesis §5.3.3).

Each depth view of :func:`rgbd_rs.shapes.views.depth_views` is approximated by a cubic B-spline
surface (a NURBS of degree 3 with unit weights, §5.3.3) whose ``(u, v)`` range is the view's
pixel grid, and the two principal curvatures ``k1 >= k2`` of that surface are sampled at every
pixel: :func:`curvature_maps` returns ``(6, 2, R, R)`` float32, ``[:, 0]`` = k1, ``[:, 1]`` = k2.

**Units and sign.** Curvatures are in 1 / (the shape's bounding-cube side), the unit the views
are measured in: a sphere of radius ``r`` in a cube of side ``a`` reads ``a / r``. Because the
views normalise the shape into its bounding cube, the maps do not depend on the shape's unit,
scale or position (a shape scaled by 1000 gives the same maps, before any normalisation, up to
float rounding). Positive where the surface bulges towards the viewer (a ball seen from outside:
``k1 = k2 > 0``), negative in a bowl or a concave corner.

**Fit** (Rust, ``rgbd-spline``'s ``height`` module, parallel over the views). The surface is the
graph ``(u, v, z(u, v))`` of the depth: in an orthographic view ``x`` and ``y`` are exactly
linear in ``(u, v)``, which a cubic spline reproduces, so fitting ``z`` alone is the thesis' 3-D
fit at a third of the cost. Knots every ``R / KNOT_SPANS`` pixels (:func:`knot_spacing`; 24 spans
whatever the resolution, so 64 and 320 pixel maps describe the same geometry), a
second-difference penalty :data:`LAMBDA`, and only the control points of knot cells that hold
data are solved for (the others leave their pixels unreported).

**Rim** (meshes). Next to a silhouette a smooth closed surface turns away from the viewer: the
depth's slope grows without bound, no spline follows it, and a fit of every object pixel rings
for 2-3 knot spans inwards (a sphere: k1, k2 off by a median 6-19 % between 0.5 and 0.8 of its
radius, 90th percentile up to 34 %; 1 % with the cut). We fit the object's pixels only (empty
pixels are not data) and leave out the *grazing* ones: pixels whose depth slope (central
differences, one-sided next to an empty pixel, in depth units per pixel width) exceeds
:data:`MAX_SLOPE` = 2, i.e. whose surface normal is more than ``atan 2`` = 63.4° from the view
direction. That cuts a sphere at 0.89 of its radius, and it also cuts a view along depth steps
of more than about 4 pixels (a step of d pixels gives its two border pixels a central-difference
slope of about d / 2); each 4-connected piece of the remaining pixels is fitted with its own
spline (pieces under 16 pixels get 0), so a surface does not bend to meet another one behind it
(a seat in front of a backrest). On a sphere this masking beat per-pixel weights
``1 / (1 + slope²)^k`` (k = 1, 2) and thresholds of 3 and 4; 24 spans beat 16 and 20.

**Point clouds** are not fitted through their splatted views: splats are flat disks, and a fit
of that staircase is off by more than 50 % on a sphere. The data are the points themselves,
projected into each view: a point counts for a view when it is not behind the nearest surface
within one splat radius (``depth <= nearest + 2 · MAX_SLOPE · radius + 1`` px, which also
keeps out back-surface points that show through holes between the front splats) and its
normal (principal component of its :data:`NORMAL_NEIGHBOURS` nearest neighbours) is within
``atan MAX_SLOPE`` of the view direction. ModelNet's 1024 points give a few hundred per view,
so the grid has :data:`POINT_KNOT_SPANS` = 16 spans; curvatures are reported on the splatted
silhouette where the fitted slope is at most :data:`MAX_SLOPE`.

**Empty, grazing and unsupported pixels get 0** (no surface, or no reliable curvature): after
the per-map normalisation of :mod:`rgbd_rs.shapes.dataset` they read like a flat surface would.
Values are clipped to ``±CLIP_PER_SPAN · spans`` (radius of curvature at least half a knot
spacing): sharper bends at creases, depth steps and gaps between sparse points are beyond what
the spline resolves and would otherwise dominate the normalisation.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes import views as _views
from rgbd_rs.shapes._cloud import centred_cloud
from rgbd_rs.surface import DEFAULT_LAMBDA

__all__ = [
    "CLIP_PER_SPAN",
    "KNOT_SPANS",
    "LAMBDA",
    "MAX_SLOPE",
    "POINT_KNOT_SPANS",
    "curvature_maps",
    "knot_spacing",
]

#: Knot spans across a view side for meshes: knots every ``R / KNOT_SPANS`` pixels
#: (:func:`knot_spacing`). The thesis gives no knot rule (METHOD_NOTES §5 [NF]).
KNOT_SPANS = 24
#: Knot spans for point clouds: their visible points are the data, a few hundred per view for
#: ModelNet's 1024, so the grid is coarser.
POINT_KNOT_SPANS = 16
#: Largest depth slope (depth units per pixel width, ``tan`` of the angle between the surface
#: normal and the view direction) of a pixel that enters the fit; steeper pixels get 0.
MAX_SLOPE = 2.0
#: Second-difference smoothness relative to one sample (a pixel of a mesh view, a point of a
#: cloud): :data:`rgbd_rs.surface.DEFAULT_LAMBDA`, small enough that a sphere's curvature is not
#: flattened (1e-3 biases a 1024-point sphere by 10-18 % at 0.5-0.8 of its radius).
LAMBDA = DEFAULT_LAMBDA
#: Curvatures are clipped to ``±CLIP_PER_SPAN · spans`` (1 / cube side): a radius of curvature
#: below half a knot spacing is beyond what the spline resolves (creases, depth steps, gaps
#: between sparse points), and a few such values would dominate the per-map normalisation.
CLIP_PER_SPAN = 2.0
#: Neighbours of the principal-component normal of a point (point clouds).
NORMAL_NEIGHBOURS = 10
#: The view axes ``(right, up, forward)`` of :data:`rgbd_rs.shapes.views.VIEW_NAMES`.
_AXES = np.array(
    [
        [(0, 1, 0), (0, 0, 1), (-1, 0, 0)],
        [(-1, 0, 0), (0, 0, 1), (0, -1, 0)],
        [(0, -1, 0), (0, 0, 1), (1, 0, 0)],
        [(1, 0, 0), (0, 0, 1), (0, 1, 0)],
        [(1, 0, 0), (0, 1, 0), (0, 0, -1)],
        [(-1, 0, 0), (0, 1, 0), (0, 0, 1)],
    ],
    np.float64,
)


def knot_spacing(resolution: int, spans: int = KNOT_SPANS) -> float:
    """Knot spacing in pixels for ``resolution``-pixel views: ``resolution / spans``, at least
    1 pixel (meshes: 2.67 at 64, 13.3 at 320)."""
    r = _validate.integer("resolution", resolution, minimum=1)
    n = _validate.integer("spans", spans, minimum=1)
    return max(1.0, r / n)


def _finish(k: np.ndarray, res: int, spans: int) -> npt.NDArray[np.float32]:
    """1 / pixel -> 1 / cube side; unreported pixels (NaN) -> 0; clipped to the resolvable."""
    limit = CLIP_PER_SPAN * spans
    scaled = np.nan_to_num(np.asarray(k, np.float32) * np.float32(res), nan=0.0)
    return np.asarray(np.clip(scaled, -limit, limit), np.float32)


def _mesh_maps(mesh: Mesh, res: int, depth: np.ndarray | None) -> npt.NDArray[np.float32]:
    if depth is None:
        depth = _views.depth_views(mesh, res, lcn=False, background=float("nan"))
    spacing = knot_spacing(res, KNOT_SPANS)
    k = _rgbd_rs.depth_view_curvatures(depth, float(res), spacing, LAMBDA, MAX_SLOPE)
    return _finish(k, res, KNOT_SPANS)


def _normals(points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Unit normals (unoriented) by principal components of each point's neighbourhood: the
    eigenvector of the smallest eigenvalue of the 3 x 3 scatter matrix, in closed form (the
    trigonometric solution of the characteristic cubic, then the largest cross product of two
    rows of ``C - l I``), 4x faster than ``numpy.linalg.eigh`` on 1024 points."""
    from scipy.spatial import cKDTree

    k = min(NORMAL_NEIGHBOURS, len(points))
    _, idx = cKDTree(points).query(points, k)
    nb = points[np.asarray(idx).reshape(len(points), k)]
    nb = nb - nb.mean(axis=1, keepdims=True)
    x, y, z = nb[..., 0], nb[..., 1], nb[..., 2]
    a, b, c = (x * x).sum(1), (y * y).sum(1), (z * z).sum(1)
    d, e, f = (x * y).sum(1), (x * z).sum(1), (y * z).sum(1)
    q = (a + b + c) / 3
    p = np.sqrt(((a - q) ** 2 + (b - q) ** 2 + (c - q) ** 2 + 2 * (d * d + e * e + f * f)) / 6)
    ps = np.where(p > 0, p, 1.0)
    ba, bb, bc = (a - q) / ps, (b - q) / ps, (c - q) / ps
    bd, be, bf = d / ps, e / ps, f / ps
    det = ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be)
    phi = np.arccos(np.clip(det / 2, -1.0, 1.0)) / 3
    smallest = q + 2 * p * np.cos(phi + 2 * np.pi / 3)
    rows = np.stack([a - smallest, d, e, d, b - smallest, f, e, f, c - smallest], 1).reshape(
        -1, 3, 3
    )
    crosses = np.stack(
        [
            np.cross(rows[:, 0], rows[:, 1]),
            np.cross(rows[:, 0], rows[:, 2]),
            np.cross(rows[:, 1], rows[:, 2]),
        ],
        1,
    )
    norms = np.linalg.norm(crosses, axis=2)
    best = norms.argmax(axis=1)
    n = crosses[np.arange(len(points)), best]
    length = norms[np.arange(len(points)), best]
    n = n / np.where(length > 0, length, 1.0)[:, None]
    n[length == 0] = (0.0, 0.0, 1.0)  # isotropic or degenerate neighbourhood: any direction
    return np.asarray(n)


def _point_maps(
    points: npt.NDArray[np.float32], res: int, depth: np.ndarray | None
) -> npt.NDArray[np.float32]:
    from scipy.ndimage import minimum_filter

    if depth is None:
        depth, median_radius = _rgbd_rs.point_depth_views(points, res, None)
    else:
        median_radius = float(np.median(_rgbd_rs.point_splat_radii(points, res)))
    # The nearest surface around each pixel: where the splats of the front surface leave a hole,
    # a point of the back surface shows through the z-buffer but not through this.
    reach = max(1, round(float(median_radius)))
    near = minimum_filter(np.nan_to_num(depth, nan=np.inf), size=(1, 2 * reach + 1, 2 * reach + 1))
    p = points.astype(np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    side = float((hi - lo).max()) or 1.0
    q = (p - (lo + hi) / 2) / side
    normals = _normals(p) if len(p) >= 3 else np.zeros_like(p)
    grazing = 1 / np.sqrt(1 + MAX_SLOPE**2)
    samples, view_of = [], []
    for view, (right, up, fwd) in enumerate(_AXES):
        u = (q @ right + 0.5) * res - 0.5
        v = (0.5 - q @ up) * res - 0.5
        z = (q @ fwd + 0.5) * res
        iu = np.clip(np.rint(u), 0, res - 1).astype(np.int64)
        iv = np.clip(np.rint(v), 0, res - 1).astype(np.int64)
        front = near[view, iv, iu] * res
        seen = z <= front + 2 * MAX_SLOPE * reach + 1  # not hidden behind a surface
        seen &= np.abs(normals @ fwd) >= grazing  # not grazing
        samples.append(np.stack([u[seen], v[seen], z[seen]], axis=1))
        view_of.append(np.full(int(seen.sum()), view))
    k = _rgbd_rs.view_curvatures(
        np.concatenate(samples),
        np.concatenate(view_of).astype(np.uint32),
        np.isfinite(depth),
        knot_spacing(res, POINT_KNOT_SPANS),
        LAMBDA,
        MAX_SLOPE,
    )
    return _finish(k, res, POINT_KNOT_SPANS)


def curvature_maps(
    shape: Mesh | npt.ArrayLike,
    resolution: int = _views.DEFAULT_RESOLUTION,
    *,
    views: npt.ArrayLike | None = None,
) -> np.ndarray:
    """The principal-curvature maps of a :class:`~rgbd_rs.meshes.Mesh` or an ``N x 3`` point
    cloud: ``(6, 2, R, R)`` float32, view order of :data:`rgbd_rs.shapes.views.VIEW_NAMES`,
    channel 0 = k1, 1 = k2 (``k1 >= k2``), in 1 / bounding-cube side, 0 on empty and grazing
    pixels (see the module docstring).

    ``views``: the shape's raw views if the caller has them already,
    ``depth_views(shape, resolution, lcn=False, background=nan)`` (``(6, R, R)`` float32, NaN
    where empty); saves rendering them again."""
    if isinstance(shape, (str, bytes)):
        raise InvalidArgumentError(
            f"shape: got {type(shape).__name__}, expected a Mesh or an N x 3 point cloud"
        )
    r = _validate.integer("resolution", resolution, minimum=1, maximum=_views.MAX_RESOLUTION)
    depth = None
    if views is not None:
        depth = _validate.array("views", views, shape=(6, r, r), dtype=np.float32)
        if np.isinf(depth).any():
            raise InvalidArgumentError(
                "views: got infinite depths, expected raw views (NaN where empty)"
            )
    if isinstance(shape, Mesh):
        if shape.triangles.size == 0:
            raise InvalidArgumentError("shape: got a mesh with no triangles, expected at least one")
        return _mesh_maps(shape, r, depth)
    points, _ = centred_cloud("shape", shape)  # the maps do not depend on where the shape is
    return _point_maps(points, r, depth)
