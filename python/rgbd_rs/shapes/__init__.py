"""3-D shape classification (thesis ch. 5): six depth views (:mod:`.views`), voxel density
profiles (:mod:`.voxels`) and spline curvature maps of a shape, fed to a 15-branch ConvNet."""

from rgbd_rs.shapes.views import (
    DEFAULT_RESOLUTION,
    THESIS_RESOLUTION,
    VIEW_NAMES,
    depth_views,
    depth_views_batch,
    lcn_window,
    local_contrast_normalize,
    splat_radii,
)
from rgbd_rs.shapes.voxels import VoxelGrid, density_profiles, voxelize

__all__ = [
    "DEFAULT_RESOLUTION",
    "THESIS_RESOLUTION",
    "VIEW_NAMES",
    "VoxelGrid",
    "density_profiles",
    "depth_views",
    "depth_views_batch",
    "lcn_window",
    "local_contrast_normalize",
    "splat_radii",
    "voxelize",
]
