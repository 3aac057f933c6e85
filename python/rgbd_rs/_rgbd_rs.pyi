# Hand-written stub of the native module; checked against it by mypy.stubtest.
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "HHA_ANGLE_RADIUS",
    "HHA_GRAVITY_RADIUS",
    "HHA_MAX_MEDIAN_DEPTH_M",
    "MAX_ELEMENTS",
    "MAX_PIXELS",
    "MAX_RADIUS",
    "MAX_SIDE",
    "OVERSEG_DEFAULT_FEATURE_WEIGHT",
    "OVERSEG_DEFAULT_FIT_POINTS",
    "OVERSEG_DEFAULT_SAMPLES",
    "OVERSEG_DEFAULT_SEGMENTS",
    "OVERSEG_DEFAULT_SIGMA",
    "OVERSEG_DEFAULT_SPATIAL_WEIGHT",
    "OVERSEG_DEFAULT_VECTORS",
    "OVERSEG_MAX_SAMPLES",
    "SOURCE_LC",
    "SOURCE_LC_UNMEASURED",
    "SOURCE_NONE",
    "SOURCE_STEREO",
    "SOURCE_TOF",
    "SOURCE_TOF_CARRIED",
    "SPLINE_DEFAULT_LAMBDA",
    "SPLINE_MAX_DEGREE",
    "T_C",
    "T_D",
    "T_SIM",
    "T_THETA_DEG",
    "VIEWS_MAX_RESOLUTION",
    "VIEWS_MAX_SPLAT_PX",
    "VIEWS_MIN_SPLAT_PX",
    "VIEWS_SPLAT_KNN_FACTOR",
    "VIEWS_SPLAT_MEDIAN_CAP",
    "VIEWS_SPLAT_NEIGHBOURS",
    "VOXEL_MAX_RESOLUTION",
    "InvalidArgumentError",
    "LcConfig",
    "NativeScene",
    "RgbdError",
    "SegmentFits",
    "SgmConfig",
    "ShapeMismatchError",
    "UpsampleConfig",
    "after_fork_in_child",
    "agreement",
    "bridge_band_across_dropouts",
    "carry_tof_to_border",
    "census_sgm",
    "check_metric_depth",
    "clue_maps",
    "clue_warp_maps",
    "cost_curve_stats",
    "density_profiles",
    "depth_disparity",
    "depth_to_points",
    "depth_view_curvatures",
    "distort_pixels",
    "extend_tof_into_band",
    "fill_single_source",
    "fit_surface",
    "hha_encode",
    "interrupt_running",
    "label_regions",
    "land_points",
    "lc_fuse",
    "local_contrast_normalize",
    "majority_classes",
    "mean_shift_filter",
    "merge_regions",
    "mesh_depth_views",
    "mesh_depth_views_raycast",
    "normalise_clues",
    "normals_from_points",
    "num_threads",
    "oversegment",
    "pdf_stats",
    "pixel_features",
    "point_depth_views",
    "point_depth_views_batch",
    "point_splat_radii",
    "project_points",
    "remap",
    "render_points",
    "reproject_depth",
    "segment_boundaries",
    "sgm_defaults",
    "square_normals",
    "undistort_image",
    "undistort_map",
    "undistort_pixels",
    "unseen_from_tof",
    "upsample_depth",
    "use_side_pool",
    "view_curvatures",
    "voxelize_mesh",
    "voxelize_points",
]

_CameraArgs = tuple[float, float, float, float, int, int, list[float]]
_PoseArgs = tuple[list[float], list[float]]

class RgbdError(ValueError): ...
class InvalidArgumentError(RgbdError): ...
class ShapeMismatchError(RgbdError): ...

MAX_RADIUS: int
MAX_SIDE: int
MAX_PIXELS: int
MAX_ELEMENTS: int
SPLINE_MAX_DEGREE: int
SPLINE_DEFAULT_LAMBDA: float
SOURCE_NONE: int
SOURCE_LC: int
SOURCE_TOF: int
SOURCE_STEREO: int
SOURCE_TOF_CARRIED: int
SOURCE_LC_UNMEASURED: int

def num_threads() -> int: ...
def interrupt_running() -> None: ...
def after_fork_in_child() -> None: ...
def use_side_pool(on: bool) -> None: ...
def project_points(
    points: npt.NDArray[np.float64], cam: _CameraArgs, pose_args: _PoseArgs
) -> npt.NDArray[np.float64]: ...
def land_points(
    points: npt.NDArray[np.float64], cam: _CameraArgs, map: npt.NDArray[np.float32], bf: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_]]: ...
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
def agreement(
    a: npt.NDArray[np.float32], b: npt.NDArray[np.float32], tol: float
) -> tuple[int, int]: ...

_F32Map = npt.NDArray[np.float32]

def fill_single_source(
    disparity: _F32Map,
    plausibility: _F32Map,
    source: npt.NDArray[np.uint8],
    tof: _F32Map,
    stereo: _F32Map,
    tof_confidence: _F32Map | None,
    stereo_confidence: _F32Map | None,
    keep_out_zero: bool,
    cross_check: bool,
) -> None: ...
def unseen_from_tof(
    disparity: _F32Map,
    plausibility: _F32Map,
    source: npt.NDArray[np.uint8],
    tof: _F32Map,
    stereo: _F32Map,
    tof_confidence: _F32Map | None,
    sign: float,
) -> None: ...
def extend_tof_into_band(
    disparity: _F32Map,
    plausibility: _F32Map,
    source: npt.NDArray[np.uint8],
    tof: _F32Map,
    tof_confidence: _F32Map | None,
    sign: float,
    chain_step: float,
    confirm_gap: float,
) -> None: ...
def carry_tof_to_border(
    disparity: _F32Map,
    plausibility: _F32Map,
    source: npt.NDArray[np.uint8],
    tof: _F32Map,
    tof_confidence: _F32Map | None,
    sign: float,
) -> None: ...
def bridge_band_across_dropouts(
    disparity: _F32Map,
    plausibility: _F32Map,
    source: npt.NDArray[np.uint8],
    tof: _F32Map,
    sign: float,
    chain_step: float,
) -> None: ...
def clue_warp_maps(
    stereo_disparity: npt.NDArray[np.float32], sign: float
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...
def clue_maps(
    grey_reference: npt.NDArray[np.float32],
    warped: npt.NDArray[np.float32],
    columns: npt.NDArray[np.float32],
    tof_disparity: npt.NDArray[np.float32],
    tof_amplitude: npt.NDArray[np.float32],
    stereo_disparity: npt.NDArray[np.float32],
    mu_reference: float,
    mu_target: float,
    amplitude: float,
) -> npt.NDArray[np.float32]: ...
def normalise_clues(
    maps: npt.NDArray[np.float32], sigmas: npt.NDArray[np.float32]
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

_Maps = tuple[
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
]

@final
class _SplineFit:
    """One fitted surface; not in the module namespace (only ``fit_surface`` makes them)."""

    def maps(
        self,
        points: npt.NDArray[np.float32],
        mask: npt.NDArray[np.bool_] | None,
        u0: int,
        v0: int,
    ) -> _Maps: ...

def fit_surface(
    points: npt.NDArray[np.float32],
    mask: npt.NDArray[np.bool_] | None,
    spacing: float,
    degree: int,
    lam: float,
    with_dof: bool,
) -> tuple[_SplineFit, int, float, float | None, bool, tuple[int, int, int, int]]: ...

@final
class SegmentFits:
    def __new__(
        cls,
        points: npt.NDArray[np.float32],
        labels: npt.NDArray[np.int32],
        spacing: float,
        degree: int,
        lam: float,
        criterion: str,
        test_spacing: float,
        noise_scale: float,
        noise_power: float,
        tolerance: float,
        surfaces: bool,
        test_window: int | None = ...,
    ) -> SegmentFits: ...
    @staticmethod
    def seam_defaults() -> tuple[float, float, float, float, int | None]: ...
    @property
    def n_labels(self) -> int: ...
    @property
    def label_ids(self) -> list[int]: ...
    @property
    def merges(self) -> int: ...
    @property
    def criterion(self) -> str: ...
    def size(self, i: int) -> int: ...
    def fit_error(self, i: int) -> float: ...
    def seam(self, i: int, j: int) -> int: ...
    def mse(self, i: int) -> float: ...
    def union_error(self, i: int, j: int) -> float: ...
    def should_merge(self, i: int, j: int) -> bool: ...
    def merge(self, i: int, j: int) -> float: ...
    def find(self, label: int) -> int: ...
    def labels(self) -> npt.NDArray[np.int32]: ...
    def maps(self, points: npt.NDArray[np.float32]) -> _Maps: ...

_ViewArgs = tuple[str, float, float, float, float, int, int, _PoseArgs]
_MaterialArgs = tuple[
    list[float], float, float, str, list[float], int, npt.NDArray[np.float32] | None
]
_F32 = npt.NDArray[np.float32]
_I32 = npt.NDArray[np.int32]

@final
class NativeScene:
    def __new__(
        cls,
        vertices: _F32,
        triangles: npt.NDArray[np.uint32],
        object: npt.NDArray[np.uint32],
        materials: list[_MaterialArgs],
        lights: list[tuple[list[float], list[float]]],
        ambient: list[float],
    ) -> NativeScene: ...
    @property
    def triangle_count(self) -> int: ...
    def depth(self, v: _ViewArgs) -> _F32: ...
    def gbuffer(self, v: _ViewArgs) -> tuple[_F32, _F32, _I32, _I32, _F32]: ...
    def color(self, v: _ViewArgs, supersample: int, shadows: bool) -> _F32: ...
    def tof(
        self,
        v: _ViewArgs,
        frequency_hz: float,
        subsamples: int,
        multipath_rays: int,
        noise: bool,
        power: float,
        read_noise: float,
        shot_noise: float,
        ambient: float,
        amplitude_threshold: float,
        wrap_phase: bool,
        seed: int,
    ) -> tuple[_F32, _F32, _F32]: ...

def render_points(points: _F32, radius: float, v: _ViewArgs) -> tuple[_F32, _I32]: ...

_U8 = npt.NDArray[np.uint8]

def label_regions(image: _U8, tolerance: float) -> tuple[_I32, int]: ...
def mean_shift_filter(
    image: _U8,
    spatial_radius: float,
    color_radius: float,
    max_level: int = 1,
    max_iter: int = 5,
    epsilon: float = 1.0,
) -> _U8: ...
def cost_curve_stats(
    reference: _U8,
    target: _U8,
    disparity: _F32,
    target_sign: int,
    max_disparity: int,
    block: int,
) -> tuple[_F32, _F32, _F32]: ...

@final
class SgmConfig:
    def __new__(
        cls,
        min_disparity: int,
        max_disparity: int,
        census_width: int,
        census_height: int,
        census_reference: str,
        p1: int,
        p2: int,
        p2_contrast: float,
        paths: int,
        subpixel: str,
        lr_tolerance: int | None,
        uniqueness: int,
        median: int,
        speckle_size: int,
        speckle_range: float,
        vertical_tolerance: int,
        stats: bool,
    ) -> SgmConfig: ...

def sgm_defaults() -> dict[str, Any]: ...
def census_sgm(
    left: _U8, right: _U8, reference: str, config: SgmConfig
) -> tuple[_F32, _F32 | None, _F32 | None]: ...

@final
class UpsampleConfig:
    def __new__(
        cls, radius: int, sigma_s: float, sigma_c: float, sigma_r: float
    ) -> UpsampleConfig: ...

def upsample_depth(
    sparse: _F32,
    channel: _F32 | None,
    image: _U8,
    labels: _I32 | None,
    config: UpsampleConfig,
) -> tuple[_F32, _F32 | None, _F32]: ...

@final
class LcConfig:
    def __new__(
        cls,
        radius: int,
        gamma_s: float,
        gamma_c: float,
        gamma_t: float,
        truncation: float,
        bin_width: float,
        stride: int,
        target_sign: int,
    ) -> LcConfig: ...
    @staticmethod
    def for_width(width: int) -> LcConfig: ...
    @staticmethod
    def gamma_s_for_radius(radius: int) -> float: ...
    def with_target_sign(self, target_sign: int) -> LcConfig: ...
    @property
    def radius(self) -> int: ...
    @property
    def gamma_s(self) -> float: ...
    @property
    def gamma_c(self) -> float: ...
    @property
    def gamma_t(self) -> float: ...
    @property
    def truncation(self) -> float: ...
    @property
    def bin_width(self) -> float: ...
    @property
    def stride(self) -> int: ...
    @property
    def target_sign(self) -> int: ...

def lc_fuse(
    reference: _U8,
    target: _U8,
    disparities: list[_F32],
    confidences: list[_F32 | None],
    config: LcConfig,
) -> tuple[_F32, _F32]: ...

# -- region adjacency and merging (crates/rgbd-py/src/segment.rs) --------------------------------

T_SIM: float
T_D: float
T_C: float
T_THETA_DEG: float

def segment_boundaries(
    labels: _I32,
    depth: _F32 | None,
    lab: _F32 | None,
    normals: _F32 | None,
    max_depth_step: float,
    max_color_distance: float,
    max_normal_angle: float,
) -> tuple[_I32, npt.NDArray[np.uint64], npt.NDArray[np.bool_]]: ...
def merge_regions(
    fits: SegmentFits, pairs: _I32, pdfs: _F32 | None, t_sim: float, mean: bool = False
) -> tuple[_I32, _I32, _I32, npt.NDArray[np.float64], npt.NDArray[np.float64], _I32 | None]: ...
def pdf_stats(pdfs: _F32) -> tuple[int, float, float]: ...
def majority_classes(labels: _I32, pdfs: _F32) -> _I32: ...

# -- HHA and square-window normals (crates/rgbd-py/src/hha.rs) ----------------------------------
HHA_ANGLE_RADIUS: int
HHA_GRAVITY_RADIUS: int
HHA_MAX_MEDIAN_DEPTH_M: float

def hha_encode(
    depth: _F32, raw_depth: _F32 | None, camera: tuple[float, float, float, float]
) -> tuple[_U8, npt.NDArray[np.float64], float, _F32]: ...
def check_metric_depth(depth: _F32) -> None: ...
def pixel_features(
    lab: _F32, depth: _F32, normals: _F32, camera: tuple[float, float, float, float]
) -> tuple[_F32, _F32, npt.NDArray[np.bool_], tuple[float, float, float]]: ...
def square_normals(
    depth: _F32,
    raw_depth: _F32 | None,
    camera: tuple[float, float, float, float],
    radius: int,
    toward_camera: bool,
) -> _F32: ...

# -- Nyström normalized-cuts over-segmentation (crates/rgbd-py/src/oversegment.rs) --------------

OVERSEG_DEFAULT_SIGMA: float
OVERSEG_DEFAULT_SAMPLES: int
OVERSEG_DEFAULT_VECTORS: int
OVERSEG_MAX_SAMPLES: int
OVERSEG_DEFAULT_SEGMENTS: int
OVERSEG_DEFAULT_SPATIAL_WEIGHT: float
OVERSEG_DEFAULT_FEATURE_WEIGHT: float
OVERSEG_DEFAULT_FIT_POINTS: int

def oversegment(
    features: _F32,
    n_segments: int,
    sigma: float,
    n_samples: int,
    n_vectors: int,
    seed: int,
    min_size: int,
    spatial_weight: float,
    feature_weight: float,
    fit_points: int,
) -> tuple[_I32, int]: ...

# -- voxelization (crates/rgbd-py/src/voxel.rs) ---------------------------------------------------

VOXEL_MAX_RESOLUTION: int

def voxelize_points(
    points: _F32, resolution: int, dilate: int
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64], float]: ...
def voxelize_mesh(
    vertices: _F32, faces: npt.NDArray[np.uint32], resolution: int, solid: bool
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64], float]: ...
def density_profiles(filled: npt.NDArray[np.uint8]) -> _F32: ...

# -- depth views (crates/rgbd-py/src/views.rs) ----------------------------------------------------

VIEWS_MAX_RESOLUTION: int
VIEWS_MAX_SPLAT_PX: float
VIEWS_MIN_SPLAT_PX: float
VIEWS_SPLAT_KNN_FACTOR: float
VIEWS_SPLAT_NEIGHBOURS: int
VIEWS_SPLAT_MEDIAN_CAP: float

def mesh_depth_views(vertices: _F32, faces: npt.NDArray[np.uint32], resolution: int) -> _F32: ...
def mesh_depth_views_raycast(
    vertices: _F32, faces: npt.NDArray[np.uint32], resolution: int
) -> _F32: ...
def point_depth_views(
    points: _F32, resolution: int, splat_radius: float | None = None
) -> tuple[_F32, float]: ...
def point_depth_views_batch(
    clouds: list[_F32], resolution: int, splat_radius: float | None = None
) -> tuple[_F32, _F32]: ...
def point_splat_radii(points: _F32, resolution: int) -> _F32: ...
def local_contrast_normalize(maps: _F32, window: int, eps: float) -> None: ...

# -- curvature maps of depth views (crates/rgbd-py/src/spline.rs, rgbd-spline height.rs) ---------

def depth_view_curvatures(
    depth: _F32, scale: float, spacing: float, lam: float, max_slope: float
) -> _F32: ...
def view_curvatures(
    samples: npt.NDArray[np.float64],
    view_of: npt.NDArray[np.uint32],
    eval: npt.NDArray[np.bool_],
    spacing: float,
    lam: float,
    max_slope: float,
) -> _F32: ...
