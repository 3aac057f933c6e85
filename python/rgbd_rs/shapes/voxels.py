"""Voxelization of meshes and point clouds and the voxel density profiles of thesis §5.3.2.

The grid is a cube over the shape's bounding box: the largest extent spans all voxels and the
shape is centred along the other axes, so proportions survive (a flat shape or a single point
is centred too: a degenerate axis never divides by zero). Meshes mark the voxels their surface
touches (exact triangle-box overlap), or with ``fill="solid"`` also every voxel lying between
surface voxels along at least two axes, which closes non-watertight meshes (and fills cavities
open along one axis). Point clouds mark the voxels holding a point, optionally dilated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes._cloud import centred_cloud, check_mesh

__all__ = ["DEFAULT_RESOLUTION", "VoxelGrid", "density_profiles", "voxelize"]

#: The thesis' profile resolution (32 x 32 maps, §5.3.2).
DEFAULT_RESOLUTION = 32
#: Largest grid side, from the Rust core.
MAX_RESOLUTION: int = _rgbd_rs.VOXEL_MAX_RESOLUTION


@array_eq
@dataclass(frozen=True)
class VoxelGrid:
    """An occupancy grid: ``filled[z, y, x]`` (bool, ``R x R x R``), voxel ``(x, y, z)`` covering
    ``origin + (x, y, z) * size`` to ``+ size``."""

    filled: np.ndarray
    origin: np.ndarray
    size: float

    @property
    def resolution(self) -> int:
        """Voxels per side."""
        return int(self.filled.shape[0])


def voxelize(
    shape: Mesh | npt.ArrayLike,
    resolution: int = DEFAULT_RESOLUTION,
    *,
    fill: str = "surface",
    dilate: int = 0,
) -> VoxelGrid:
    """Voxelizes a :class:`~rgbd_rs.meshes.Mesh` (``fill`` = ``"surface"`` or ``"solid"``) or an
    ``N x 3`` point cloud (occupancy, each point's voxel dilated by ``dilate`` voxels)."""
    r = _validate.integer("resolution", resolution, minimum=1, maximum=MAX_RESOLUTION)
    mode = _validate.choice("fill", fill, ("surface", "solid"))
    d = _validate.integer("dilate", dilate, maximum=r)
    if isinstance(shape, Mesh):
        if d:
            raise InvalidArgumentError(f"dilate: got {dilate}, expected 0 for a mesh")
        check_mesh("shape", shape)
        filled, origin, size = _rgbd_rs.voxelize_mesh(
            shape.vertices, shape.triangles, r, mode == "solid"
        )
    else:
        if mode != "surface":
            raise InvalidArgumentError(
                f"fill: got {fill!r} for a point cloud, expected 'surface' (points have no inside)"
            )
        pts, shift = centred_cloud("shape", shape)
        filled, origin, size = _rgbd_rs.voxelize_points(pts, r, d)
        origin = (np.asarray(origin, np.float64) + shift).astype(np.asarray(origin).dtype)
    return VoxelGrid(filled=filled.astype(bool), origin=origin, size=float(size))


def density_profiles(voxels: VoxelGrid | npt.ArrayLike) -> np.ndarray:
    """The three ``R x R`` maps of §5.3.2: filled voxels counted along X (rows = z from the top,
    columns = y), along Y (rows = z from the top, columns = x) and along Z (top view: rows = y
    from the far side, columns = x). Returns ``(3, R, R)`` float32 raw counts."""
    raw = voxels.filled if isinstance(voxels, VoxelGrid) else _validate.asarray("voxels", voxels)
    if raw.ndim != 3 or len(set(raw.shape)) != 1 or raw.size == 0:
        raise ShapeMismatchError(f"voxels: got shape {raw.shape}, expected (R, R, R)")
    if raw.dtype != np.bool_ and raw.dtype.kind not in "iu":
        raise InvalidArgumentError(f"voxels: got dtype {raw.dtype}, expected bool occupancy")
    occ = np.ascontiguousarray(raw != 0, dtype=np.uint8)
    return _rgbd_rs.density_profiles(occ)
