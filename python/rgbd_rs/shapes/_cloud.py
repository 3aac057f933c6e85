"""One check of a point cloud given to the shape functions, naming the caller's argument."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.meshes import Mesh
from rgbd_rs.meshes import _far_centre as far_centre
from rgbd_rs.meshes import _far_from_origin as far_from_origin

__all__ = [
    "centred_cloud",
    "check_extent",
    "check_mesh",
    "cloud",
    "far_centre",
    "far_from_origin",
    "mesh_area",
]

#: The largest bounding-box side the native shape kernels accept (their ``MAX_EXTENT``).
MAX_EXTENT = 1e30


def check_extent(name: str, points: npt.NDArray[np.floating], what: str = "points") -> None:
    """Refuse finite ``points`` whose bounding box is wider than :data:`MAX_EXTENT` (its side in
    float64: float32 coordinates can span more than float32 can hold). ``what``: the message's
    word for them ("points", "a mesh")."""
    if len(points) == 0:
        return
    p = np.asarray(points, np.float64)
    extent = float((p.max(axis=0) - p.min(axis=0)).max())
    if not extent <= MAX_EXTENT:
        raise InvalidArgumentError(
            f"{name}: got {what} spanning {extent:.3g} units, expected a shape at most "
            f"{MAX_EXTENT:.0e} units across (rescale it)"
        )


def mesh_area(vertices: npt.NDArray[np.floating], triangles: npt.NDArray[np.integer]) -> float:
    """Total area of the triangles (float64; 0 when every triangle is degenerate)."""
    v = np.asarray(vertices, np.float64)[np.asarray(triangles, np.int64)]  # M x 3 x 3
    return float(0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum())


def check_mesh(name: str, mesh: Mesh) -> None:
    """Refuse a mesh the shape functions cannot see: no triangles, a bounding box beyond
    :data:`MAX_EXTENT`, or triangles that all have zero area (its views would be empty and the
    network would still name a class; a point cloud on one point is refused alike)."""
    if mesh.triangles.size == 0:
        raise InvalidArgumentError(f"{name}: got a mesh with no triangles, expected at least one")
    check_extent(name, mesh.vertices, "a mesh")
    if not mesh_area(mesh.vertices, mesh.triangles) > 0:
        raise InvalidArgumentError(
            f"{name}: got a mesh whose {len(mesh.triangles)} triangle(s) all have zero area, "
            "expected a 3-D shape (a surface or a solid)"
        )


def cloud(name: str, value: object, *, fix: str = "") -> npt.NDArray[np.float32]:
    """``value`` as ``N x 3`` finite float32 points within :data:`MAX_EXTENT`."""
    pts = _validate.array(name, value, shape=(None, 3), finite=True, fix=fix)
    check_extent(name, pts)
    return pts


def centred_cloud(
    name: str, value: object, *, fix: str = ""
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float64]]:
    """:func:`cloud`, moved to the origin in float64 first when :func:`far_centre` says it lies
    far out; returns the points and the shift subtracted (zeros when none). For functions whose
    result does not depend on where the shape is (its views, its class)."""
    pts = cloud(name, value, fix=fix)  # every check, in float32 as everywhere
    exact = np.asarray(_validate.asarray(name, value), np.float64)
    centre = far_centre(exact)
    if centre is None:
        return pts, np.zeros(3)
    return (exact - centre).astype(np.float32), centre
