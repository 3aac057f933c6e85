"""3-D shape classification (thesis ch. 5): six depth views, voxel density profiles and spline
curvature maps of a shape, fed to a 15-branch ConvNet. So far: the voxel representation
(:mod:`.voxels`)."""

from rgbd_rs.shapes.voxels import VoxelGrid, density_profiles, voxelize

__all__ = ["VoxelGrid", "density_profiles", "voxelize"]
