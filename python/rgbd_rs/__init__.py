"""rgbd_rs: classic RGB-D and 3-D scene understanding with a fast Rust core.

The three systems: :mod:`rgbd_rs.fusion` (ToF-stereo fusion: reprojection, census SGM,
confidence, LC fusion), :mod:`rgbd_rs.segmentation` (RGB-D over-segmentation, surface fitting,
semantic labels, merging), :mod:`rgbd_rs.shapes` (views, voxel profiles and curvature maps of a
3-D shape, and the classifier). Beside them: :mod:`rgbd_rs.camera` (camera models),
:mod:`rgbd_rs.geometry` (depth/disparity, reprojection, normals), :mod:`rgbd_rs.surface`,
:mod:`rgbd_rs.render`, :mod:`rgbd_rs.meshes`, :mod:`rgbd_rs.io`, :mod:`rgbd_rs.viz`,
:mod:`rgbd_rs.metrics`, :mod:`rgbd_rs.nn` (the networks) and :mod:`rgbd_rs.data` (dataset
readers). The command line is ``rgbd`` (``rgbd --help``). Errors derive from
:class:`RgbdError` (a ``ValueError``).
"""

from rgbd_rs._fork import install as _install_fork_hook
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

_install_fork_hook()

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
