# Hand-written stub of the native module; checked against it by mypy.stubtest.
import numpy as np
import numpy.typing as npt

__all__ = [
    "InvalidArgumentError",
    "RgbdError",
    "ShapeMismatchError",
    "depth_disparity",
    "depth_to_points",
    "distort_pixels",
    "normals_from_points",
    "num_threads",
    "project_points",
    "remap",
    "reproject_depth",
    "undistort_image",
    "undistort_map",
    "undistort_pixels",
]

_CameraArgs = tuple[float, float, float, float, int, int, list[float]]
_PoseArgs = tuple[list[float], list[float]]

class RgbdError(ValueError): ...
class InvalidArgumentError(RgbdError): ...
class ShapeMismatchError(RgbdError): ...

def num_threads() -> int: ...
def project_points(
    points: npt.NDArray[np.float64], cam: _CameraArgs, pose_args: _PoseArgs
) -> npt.NDArray[np.float64]: ...
def undistort_pixels(
    pixels: npt.NDArray[np.float64], cam: _CameraArgs, normalized: bool, max_iter: int, tol: float
) -> npt.NDArray[np.float64]: ...
def distort_pixels(
    pixels: npt.NDArray[np.float64], cam: _CameraArgs
) -> npt.NDArray[np.float64]: ...
def depth_to_points(
    depth: npt.NDArray[np.float32], cam: _CameraArgs, max_iter: int, tol: float
) -> npt.NDArray[np.float32]: ...
def undistort_map(
    src: _CameraArgs, dst: _CameraArgs, rotation: list[float] | None = None
) -> npt.NDArray[np.float32]: ...
def remap(
    image: npt.NDArray[np.float32], map: npt.NDArray[np.float32], interpolation: str
) -> npt.NDArray[np.float32]: ...
def undistort_image(
    image: npt.NDArray[np.float32],
    src: _CameraArgs,
    dst: _CameraArgs,
    interpolation: str,
    rotation: list[float] | None = None,
) -> npt.NDArray[np.float32]: ...
def depth_disparity(
    values: npt.NDArray[np.float32], baseline: float, focal: float
) -> npt.NDArray[np.float32]: ...
def reproject_depth(
    depth: npt.NDArray[np.float32],
    src: _CameraArgs,
    dst: _CameraArgs,
    pose_args: _PoseArgs,
    channels: npt.NDArray[np.float32] | None = None,
    splat_radius: int = 0,
    max_iter: int = 20,
    tol: float = 1e-12,
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32] | None, npt.NDArray[np.int64]]: ...
def normals_from_points(
    points: npt.NDArray[np.float32], max_depth_jump: float
) -> npt.NDArray[np.float32]: ...
