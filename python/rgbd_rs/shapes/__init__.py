"""3-D shape classification (thesis ch. 5): six depth views (:mod:`.views`), voxel density
profiles (:mod:`.voxels`) and spline curvature maps of a shape, fed to the 15-branch ConvNet
(:class:`rgbd_rs.nn.ShapeNet`). :func:`classify` runs the shipped weights; :mod:`.dataset` reads
ModelNet (packs or the Princeton OFF tree) and caches the inputs; :mod:`.train` and
:mod:`.evaluate` reproduce the thesis' tables."""

from rgbd_rs.shapes.classify import ShapeClassifier, classify, to_z_up
from rgbd_rs.shapes.dataset import (
    InputSpec,
    OffTree,
    PointCloudSet,
    ShapeCache,
    available_representations,
    batch_inputs,
    build_cache,
    load_shape,
    open_shapes,
    sample_surface,
    shape_inputs,
)
from rgbd_rs.shapes.evaluate import ShapeEvaluation
from rgbd_rs.shapes.scaling import ScaledCopies
from rgbd_rs.shapes.train import ShapeRecipe, train_shapes
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
    "InputSpec",
    "OffTree",
    "PointCloudSet",
    "ScaledCopies",
    "ShapeCache",
    "ShapeClassifier",
    "ShapeEvaluation",
    "ShapeRecipe",
    "VoxelGrid",
    "available_representations",
    "batch_inputs",
    "build_cache",
    "classify",
    "density_profiles",
    "depth_views",
    "depth_views_batch",
    "lcn_window",
    "load_shape",
    "local_contrast_normalize",
    "open_shapes",
    "sample_surface",
    "shape_inputs",
    "splat_radii",
    "to_z_up",
    "train_shapes",
    "voxelize",
]
