"""rgbd_rs: classic RGB-D and 3-D scene understanding with a fast Rust core.

Public modules: :mod:`rgbd_rs.camera` (camera models), :mod:`rgbd_rs.geometry` (depth/disparity,
reprojection, normals), :mod:`rgbd_rs.data` (dataset readers). Errors derive from
:class:`RgbdError` (a ``ValueError``).
"""

from rgbd_rs.camera import Distortion, PinholeCamera, Pose, StereoRig, ToFStereoRig
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.geometry import (
    Reprojection,
    depth_to_disparity,
    disparity_to_depth,
    normals_from_depth,
    normals_from_points,
    reproject_depth,
)

__version__ = "0.1.0"

__all__ = [
    "Distortion",
    "InvalidArgumentError",
    "PinholeCamera",
    "Pose",
    "Reprojection",
    "RgbdError",
    "ShapeMismatchError",
    "StereoRig",
    "ToFStereoRig",
    "__version__",
    "depth_to_disparity",
    "disparity_to_depth",
    "normals_from_depth",
    "normals_from_points",
    "reproject_depth",
]
