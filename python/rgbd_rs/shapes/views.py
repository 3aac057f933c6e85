"""The six orthographic depth views of a shape (thesis §5.3.1) and local contrast normalisation.

**Frame.** The views are taken from the faces of the shape's bounding *cube* (the convention of
:mod:`rgbd_rs.shapes.voxels`): the largest bounding-box extent spans the cube and the shape is
centred along the other axes, so proportions survive; a single point gets a cube of side 1.
z is up (ModelNet): turn a y-up or x-up shape with :func:`rgbd_rs.shapes.to_z_up` first (what
``classify(..., up=)`` does), or its side views show it lying on its back.

**Views** (:data:`VIEW_NAMES`), each ``R x R``, row 0 at the top, column 0 on the left:

=====  ==============  =======  =====  ===========
index  seen from       right    up     looks along
=====  ==============  =======  =====  ===========
0      +x side         +y       +z     -x
1      +y side         -x       +z     -y
2      -x side         -y       +z     +x
3      -y side         +x       +z     +y
4      top (+z)        +x       +y     -z
5      bottom (-z)     -x       +y     +z
=====  ==============  =======  =====  ===========

The side views go round the vertical axis counter-clockwise (seen from above), so turning the
shape by +90° about z moves side view ``k``'s image unchanged to view ``(k + 1) % 4`` and turns
the top and bottom images by 90° (a cheap rotation augmentation). No view is mirrored. View 0
and the top view are oriented like the X and Z maps of
:func:`~rgbd_rs.shapes.voxels.density_profiles`, view 3 like its Y map.

**Depth** is the distance from the cube face into the shape in units of the cube side: 0 on the
face, 1 on the opposite face (the normalised z-buffer of an orthographic camera whose near and
far planes are the two faces). Pixels that see nothing get ``background`` (default 1.0, the far
plane, as a cleared z-buffer reads; ``nan`` marks them for a mask). Multiply by ``R`` for depth
in pixels.

**Meshes** are z-buffer rasterized (every triangle sampled at the pixel centres it covers, the
first-surface depth a ray through each pixel centre sees; ``_rgbd_rs.mesh_depth_views_raycast``
is the BVH ray-cast reference). Triangles seen exactly edge-on are invisible, so a flat mesh has
empty side views.

**Point clouds** are drawn as z-buffered camera-facing disks ("splats"), one radius per point
(:func:`splat_radii`): ``SPLAT_KNN_FACTOR`` (0.8) times the point's distance to its 8th nearest
neighbour, between ``1/sqrt(2)`` px (a disk always covers its own pixel) and 3 times the median
radius (an outlier stays a small blob). The disks follow the local density: for points scattered
uniformly at random over a surface (ModelNet's clouds are) the 8th-neighbour distance is about
``sqrt(8 / (pi l))`` at density ``l``, and disks of 0.8 of it leave about 0.6 % of the surface
uncovered; the projected spacing is never larger than the 3-D one, so 1024 ModelNet points give
closed views (median radius about 3.6 px at 64 x 64, 18 px at 320 x 320). The price is a
silhouette grown by about one radius (thin legs look thicker than in a mesh view).
SimpleView (Goyal et al. 2021) instead draws each point into one pixel of a 128 x 128
perspective view and averages the depths landing there weighted by inverse depth: sparse, not
closed images its ResNet learns to read. We keep the nearest surface like the mesh z-buffer, so
point and mesh views of one object agree (depth within 0.01 of the cube side on ModelNet
meshes).

**Local contrast normalisation** (:func:`local_contrast_normalize`, thesis: applied to each input
independently) follows Jarrett et al. 2009 as used by Farabet/Couprie (METHOD_NOTES §8):
subtractive then divisive step, ``y = v / max(sigma, mean(sigma), eps)``, with Torch's border
correction, over a uniform (box) window, Torch7's default kernel; integral images (Rust) make its
cost independent of its size (a 45-tap Gaussian in scipy took 100+ ms for six 320 x 320 views).
The thesis does not give the window; we use 9 px at 64 x 64 (Jarrett's 9 x 9) and keep its size
relative to the image (:func:`lcn_window`: 5 at 32, 9 at 64, 45 at 320), so a network sees the
same kind of input at every resolution.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes._cloud import centred_cloud, check_mesh

__all__ = [
    "BACKGROUND",
    "DEFAULT_RESOLUTION",
    "THESIS_RESOLUTION",
    "VIEW_NAMES",
    "depth_views",
    "depth_views_batch",
    "lcn_window",
    "local_contrast_normalize",
    "splat_radii",
]

#: The view order of :func:`depth_views` (see the module docstring for each orientation).
VIEW_NAMES = ("+x", "+y", "-x", "-y", "top", "bottom")
#: Default view side: the resolution the shape network trains at on a CPU (Table 5.1's pooling
#: adapted to it); the thesis uses :data:`THESIS_RESOLUTION`.
DEFAULT_RESOLUTION = 64
#: The thesis' view side (§5.3.1).
THESIS_RESOLUTION = 320
#: Largest view side, from the Rust core.
MAX_RESOLUTION: int = _rgbd_rs.VIEWS_MAX_RESOLUTION
#: Depth of pixels that see nothing: the far face (a cleared z-buffer).
BACKGROUND = 1.0
#: Automatic splat radii (Rust core): each point's disk is ``SPLAT_KNN_FACTOR`` times the
#: distance to its ``SPLAT_NEIGHBOURS``-th nearest neighbour, capped at ``SPLAT_MEDIAN_CAP``
#: times the median radius.
SPLAT_KNN_FACTOR: float = _rgbd_rs.VIEWS_SPLAT_KNN_FACTOR
SPLAT_NEIGHBOURS: int = _rgbd_rs.VIEWS_SPLAT_NEIGHBOURS
SPLAT_MEDIAN_CAP: float = _rgbd_rs.VIEWS_SPLAT_MEDIAN_CAP
#: Smallest automatic splat radius (pixels) and largest accepted one.
MIN_SPLAT_PX: float = _rgbd_rs.VIEWS_MIN_SPLAT_PX
MAX_SPLAT_PX: float = _rgbd_rs.VIEWS_MAX_SPLAT_PX
#: LCN window (pixels) at :data:`DEFAULT_RESOLUTION` (Jarrett et al. 2009 and Torch7's default:
#: 9 x 9); the window scales with the resolution, see :func:`lcn_window`.
LCN_WINDOW_AT_64 = 9
#: Torch's divisive-normalisation threshold (METHOD_NOTES §8): standard deviations below it are
#: not amplified.
LCN_EPS = 1e-4


def lcn_window(resolution: int) -> int:
    """The LCN window for ``resolution``-pixel images: ``9 * resolution / 64`` rounded to an odd
    integer, at least 3 (32 -> 5, 64 -> 9, 128 -> 19, 320 -> 45)."""
    r = _validate.integer("resolution", resolution, minimum=1)
    w = round(LCN_WINDOW_AT_64 * r / DEFAULT_RESOLUTION)
    return max(3, w if w % 2 else w + 1)


def local_contrast_normalize(
    image: npt.ArrayLike, window: int = LCN_WINDOW_AT_64, *, eps: float = LCN_EPS
) -> np.ndarray:
    """Local contrast normalisation of an ``H x W`` image, or of each ``H x W`` map of a stack
    ``(..., H, W)`` independently (Jarrett et al. 2009; Farabet/Couprie; METHOD_NOTES §8).

    With ``B`` the sum over a ``window x window`` box (Torch7's default kernel, ``ones(9, 9)``;
    zeros outside the image) and ``N = B(1)`` the number of pixels it holds (Torch's border
    correction)::

        v = x - B(x) / N                       # subtractive step
        sigma = sqrt(B(v^2) / N)               # local standard deviation
        y = v / max(sigma, mean(sigma), eps)   # divisive step (Jarrett), mean over the map

    A constant map gives zeros. Returns float32 of the input's shape; the input must be finite.
    """
    x = _validate.asarray("image", image)
    if x.ndim < 2:
        raise ShapeMismatchError(f"image: got shape {x.shape}, expected (H, W) or (..., H, W)")
    x = _validate.array("image", x, shape=(None,) * x.ndim, finite=True)
    w = _validate.integer("window", window, minimum=1)
    if w % 2 == 0:
        raise InvalidArgumentError(f"window: got {window}, expected an odd number of pixels")
    e = _validate.real("eps", eps, positive=True, f32=True)
    out = np.array(x, dtype=np.float32, order="C", copy=True)
    _rgbd_rs.local_contrast_normalize(out.reshape(-1, *x.shape[-2:]), w, e)
    return out


def _points(name: str, shape: object) -> np.ndarray:
    return centred_cloud(name, shape)[0]  # the views do not depend on where the shape is


def _resolution(resolution: object) -> int:
    return _validate.integer("resolution", resolution, minimum=1, maximum=MAX_RESOLUTION)


def _radius(value: float | None) -> float | None:
    if value is None:
        return None
    r = _validate.real("splat_radius", value, positive=True)
    if r > MAX_SPLAT_PX:
        raise InvalidArgumentError(f"splat_radius: got {r}, expected at most {MAX_SPLAT_PX} pixels")
    return r


def splat_radii(points: npt.ArrayLike, resolution: int = DEFAULT_RESOLUTION) -> np.ndarray:
    """The automatic splat radius of each point of an ``N x 3`` cloud viewed at ``resolution``,
    in pixels (float32, ``(N,)``): ``SPLAT_KNN_FACTOR`` times the point's distance to its
    ``SPLAT_NEIGHBOURS``-th nearest neighbour (in cube sides) times ``resolution``, clamped to
    ``[MIN_SPLAT_PX, min(MAX_SPLAT_PX, SPLAT_MEDIAN_CAP * median)]``."""
    pts = _points("points", points)
    return np.asarray(_rgbd_rs.point_splat_radii(pts, _resolution(resolution)))


def _mesh(name: str, shape: Mesh) -> tuple[np.ndarray, np.ndarray]:
    check_mesh(name, shape)
    return shape.vertices, shape.triangles


def _finish(
    raw: np.ndarray, lcn: bool, background: float, window: int | None, resolution: int
) -> np.ndarray:
    if not lcn:
        if not math.isnan(background):
            raw = np.where(np.isnan(raw), np.float32(background), raw)
        return raw.astype(np.float32, copy=False)
    filled = np.where(np.isnan(raw), np.float32(background), raw)
    return local_contrast_normalize(filled, lcn_window(resolution) if window is None else window)


def _options(
    resolution: object, lcn: object, background: object, window: object
) -> tuple[int, bool, float, int | None]:
    r = _resolution(resolution)
    if not isinstance(lcn, (bool, np.bool_)):
        raise InvalidArgumentError(f"lcn: got {lcn!r}, expected True or False")
    if isinstance(background, bool) or not isinstance(
        background, (int, float, np.integer, np.floating)
    ):
        raise InvalidArgumentError(f"background: got {background!r}, expected a number or nan")
    try:
        bg = float(background)
    except OverflowError:  # an int beyond the float range, e.g. 2**1100
        bg = math.inf
    if math.isinf(bg) or (math.isnan(bg) and lcn):
        raise InvalidArgumentError(
            f"background: got {bg}, expected a finite number (nan only with lcn=False)"
        )
    if abs(bg) > _validate.F32_MAX:  # the views are float32
        raise InvalidArgumentError(
            f"background: got {bg:.3g}, expected a number float32 can hold (|x| <= "
            f"{_validate.F32_MAX:.3g})"
        )
    w = None
    if window is not None:
        w = _validate.integer("lcn_window", window, minimum=1)
        if w % 2 == 0:
            raise InvalidArgumentError(f"lcn_window: got {w}, expected an odd number of pixels")
    return r, bool(lcn), bg, w


def depth_views(
    shape: Mesh | npt.ArrayLike,
    resolution: int = DEFAULT_RESOLUTION,
    *,
    lcn: bool = True,
    splat_radius: float | None = None,
    background: float = BACKGROUND,
    lcn_window: int | None = None,
) -> np.ndarray:
    """The six depth views of a :class:`~rgbd_rs.meshes.Mesh` or an ``N x 3`` point cloud:
    ``(6, R, R)`` float32 in the order of :data:`VIEW_NAMES` (see the module docstring for the
    frame, orientations and depth scale).

    ``lcn`` applies :func:`local_contrast_normalize` to each view (window :func:`lcn_window`
    of the resolution unless ``lcn_window`` is given) after empty pixels get ``background``;
    with ``lcn=False`` the raw depths in ``[0, 1]`` come back (``background=nan`` marks empty
    pixels). ``splat_radius`` (pixels, point clouds only) gives every point one disk radius
    instead of :func:`splat_radii`.
    """
    r, do_lcn, bg, window = _options(resolution, lcn, background, lcn_window)
    rad = _radius(splat_radius)
    if isinstance(shape, Mesh):
        if rad is not None:
            raise InvalidArgumentError(
                f"splat_radius: got {splat_radius} for a mesh, expected None (points only)"
            )
        v, f = _mesh("shape", shape)
        raw = _rgbd_rs.mesh_depth_views(v, f, r)
    else:
        raw, _ = _rgbd_rs.point_depth_views(_points("shape", shape), r, rad)
    return _finish(raw, do_lcn, bg, window, r)


def depth_views_batch(
    shapes: Sequence[Mesh | npt.ArrayLike],
    resolution: int = DEFAULT_RESOLUTION,
    *,
    lcn: bool = True,
    splat_radius: float | None = None,
    background: float = BACKGROUND,
    lcn_window: int | None = None,
) -> np.ndarray:
    """:func:`depth_views` of many shapes: ``(B, 6, R, R)`` float32. Point clouds go to one
    native call parallel over the clouds; meshes go one call each (each call is parallel over
    its views already)."""
    if isinstance(shapes, (Mesh, np.ndarray, str, bytes)) or not isinstance(shapes, Sequence):
        raise InvalidArgumentError(
            f"shapes: got {type(shapes).__name__}, expected a sequence of meshes / point clouds"
        )
    r, do_lcn, bg, window = _options(resolution, lcn, background, lcn_window)
    rad = _radius(splat_radius)
    out = np.empty((len(shapes), 6, r, r), np.float32)
    if not shapes:
        return out
    clouds: list[np.ndarray] = []
    where: list[int] = []
    for i, s in enumerate(shapes):
        if isinstance(s, Mesh):
            if rad is not None:
                raise InvalidArgumentError(
                    f"splat_radius: got {splat_radius} with a mesh in shapes[{i}], expected None"
                )
            out[i] = _rgbd_rs.mesh_depth_views(*_mesh(f"shapes[{i}]", s), r)
        else:
            clouds.append(_points(f"shapes[{i}]", s))
            where.append(i)
    if clouds:
        out[where] = _rgbd_rs.point_depth_views_batch(clouds, r, rad)[0]
    return _finish(out, do_lcn, bg, window, r)
