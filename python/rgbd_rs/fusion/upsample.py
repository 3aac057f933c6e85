"""Stage 1: ToF depth -> the reference colour camera, upsampled to its lattice (thesis §3.3 step 1).

The ToF depth is reprojected by z-buffered forward splatting (one colour pixel per ToF sample,
:func:`rgbd_rs.reproject_depth`) and the sparse samples are interpolated by a cross bilateral
filter (spatial and colour terms). With ``segmentation=True`` the colour image is first segmented
by mean shift (OpenCV's ``pyrMeanShiftFiltering``, reimplemented bit-exactly in Rust, + connected
regions of equal filtered colour) and the filter is Dal Mutto et al.'s extended one (a
segmentation and a depth-range term; see ``crates/rgbd-fusion/src/upsample.rs``); the default
leaves it out (:data:`UPSAMPLE_SEGMENTATION`). Depth becomes disparity with d = b f / z.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import overload

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import F32, check_tof_unit, map2d, rgb8, rig_arg
from rgbd_rs.geometry import depth_to_disparity, reproject_depth

#: Mean-shift bandwidths (spatial px, colour levels) at 960 px width, and the colour tolerance
#: joining filtered pixels into one region. Chosen (METHOD_NOTES §4: the paper's are unknown).
MEANSHIFT_SPATIAL = 8
MEANSHIFT_COLOR = 16
REGION_TOLERANCE = 2.0
#: Largest window half-size (defined once, in crates/rgbd-fusion).
MAX_RADIUS: int = _rgbd_rs.MAX_RADIUS
#: Whether :func:`tof_to_reference` (and :func:`~rgbd_rs.fusion.fuse`) segments the colour image
#: for the upsampling (read at each call). Off: on the real train + val cases the fusion gave
#: about the same without it (60 cases, 20 scenes x 3 ToF laws: mean fused / better input
#: 0.7715 vs 0.7708, worst fused / good input 1.013 vs 1.016, mean fused RMS 0.764 vs 0.770 px;
#: a dense 512 x 424 ToF: 0.903 / 1.352 vs 0.903 / 1.439), and the mean shift took ~70 ms of
#: fuse() at 960 x 540 (docs/experiments.md).
UPSAMPLE_SEGMENTATION = False
#: Extended cross bilateral filter defaults at 960 px width (ToF samples ~2 px apart there).
UPSAMPLE_RADIUS = 5
SIGMA_SPATIAL = 3.0
SIGMA_COLOR = 10.0
SIGMA_RANGE = 0.02


def segment_mean_shift(
    image: npt.ArrayLike,
    *,
    spatial_radius: int = MEANSHIFT_SPATIAL,
    color_radius: int = MEANSHIFT_COLOR,
    tolerance: float = REGION_TOLERANCE,
) -> npt.NDArray[np.int32]:
    """Mean-shift segmentation of an RGB uint8 image: ``H x W`` int32 labels ``0..n-1``.

    The filter is OpenCV's ``pyrMeanShiftFiltering(image, spatial_radius, color_radius)`` (one
    pyramid level, 5 iterations, epsilon 1), computed natively in parallel rows and equal to
    OpenCV's output bit for bit (``crates/rgbd-fusion/src/meanshift.rs``); regions are the
    4-connected pixels whose neighbours' filtered colours differ by at most ``tolerance`` (mean
    absolute, 0-255).
    """
    img = rgb8("image", image)
    sp = _validate.integer("spatial_radius", spatial_radius, minimum=1, maximum=MAX_RADIUS)
    sr = _validate.integer("color_radius", color_radius, minimum=1, maximum=255)
    tol = _validate.real("tolerance", tolerance, nonnegative=True)
    filtered = _rgbd_rs.mean_shift_filter(img, sp, sr)
    labels, _ = _rgbd_rs.label_regions(filtered, tol)
    return labels


def _summable(name: str, values: F32, radius: int) -> None:
    """Refuses values whose weighted sums over a window overflow float32 (the kernel's type)."""
    with np.errstate(invalid="ignore"):
        finite = np.abs(values[np.isfinite(values)])
    limit = _validate.F32_MAX / (2 * radius + 1) ** 2
    if finite.size and float(finite.max()) > limit:
        raise InvalidArgumentError(
            f"{name}: got values up to {float(finite.max()):.3g}, expected at most {limit:.3g} "
            f"(the filter sums a {2 * radius + 1}x{2 * radius + 1} window in float32)"
        )


def _upsample(
    sparse: npt.ArrayLike,
    channel: npt.ArrayLike | None,
    image: npt.ArrayLike,
    labels: npt.ArrayLike | None,
    radius: int,
    sigma_spatial: float,
    sigma_color: float,
    sigma_range: float,
    names: tuple[str, str] = ("sparse", "channel"),
) -> tuple[F32, F32 | None, F32]:
    """The native filter: ``(depth, channel or None, color_gap)`` (see
    :attr:`ToFOnReference.color_gap`)."""
    img = rgb8("image", image)
    h, w = img.shape[:2]
    s = map2d("sparse", sparse, (h, w))
    ch = None if channel is None else map2d("channel", channel, (h, w))
    lab = None
    if labels is not None:
        lab = _validate.array("labels", labels, shape=(h, w), dtype=np.int32)
    r = _validate.integer("radius", radius, minimum=1, maximum=MAX_RADIUS)
    for name, values in zip(names, (s, ch), strict=True):
        if values is not None:
            _summable(name, values, r)
    config = _rgbd_rs.UpsampleConfig(
        r,
        _validate.real("sigma_spatial", sigma_spatial, positive=True, f32=True),
        _validate.real("sigma_color", sigma_color, positive=True, f32=True),
        _validate.real("sigma_range", sigma_range, positive=True, f32=True),
    )
    return _rgbd_rs.upsample_depth(s, ch, img, lab, config)


@overload
def upsample_depth(
    sparse: npt.ArrayLike,
    image: npt.ArrayLike,
    labels: npt.ArrayLike | None = None,
    *,
    channel: None = None,
    radius: int = ...,
    sigma_spatial: float = ...,
    sigma_color: float = ...,
    sigma_range: float = ...,
) -> F32: ...


@overload
def upsample_depth(
    sparse: npt.ArrayLike,
    image: npt.ArrayLike,
    labels: npt.ArrayLike | None = None,
    *,
    channel: npt.ArrayLike,
    radius: int = ...,
    sigma_spatial: float = ...,
    sigma_color: float = ...,
    sigma_range: float = ...,
) -> tuple[F32, F32]: ...


def upsample_depth(
    sparse: npt.ArrayLike,
    image: npt.ArrayLike,
    labels: npt.ArrayLike | None = None,
    *,
    channel: npt.ArrayLike | None = None,
    radius: int = UPSAMPLE_RADIUS,
    sigma_spatial: float = SIGMA_SPATIAL,
    sigma_color: float = SIGMA_COLOR,
    sigma_range: float = SIGMA_RANGE,
) -> F32 | tuple[F32, F32]:
    """Dense depth from sparse samples (NaN elsewhere) guided by ``image`` and ``labels``.

    Without ``labels`` it is a plain joint bilateral filter (spatial x colour). ``sigma_range``
    is relative to depth (0.02 = 2 %). Pixels with no sample within ``radius`` stay NaN.

    ``channel`` (``H x W`` values on the same samples, e.g. the ToF amplitude; NaN = none) is
    interpolated with the very weights the depth gets, so its unit never enters the filter; the
    result is then ``(depth, channel)``.
    """
    depth, carried, _ = _upsample(
        sparse, channel, image, labels, radius, sigma_spatial, sigma_color, sigma_range
    )
    if carried is None:
        return depth
    return depth, carried


@array_eq
@dataclass(frozen=True)
class ToFOnReference:
    """ToF data on the reference camera's lattice (all ``H x W`` float32, NaN = none)."""

    sparse_depth: F32
    depth: F32
    disparity: F32
    amplitude: F32
    #: The segmentation the upsampling followed (None: none, the default).
    labels: npt.NDArray[np.int32] | None
    #: The smallest mean absolute colour difference (8-bit levels) between each pixel and a ToF
    #: sample within the upsampling window (NaN where none): where it is large, the pixel's
    #: depth came only from samples of other-coloured surfaces, i.e. from across an edge that the
    #: low-resolution ToF cannot place (:data:`~rgbd_rs.fusion.fuse.UNCONFIRMED_COLOR_GAP`).
    color_gap: F32 | None = None


def tof_to_reference(
    tof_depth: npt.ArrayLike,
    tof_amplitude: npt.ArrayLike,
    rig: object,
    image: npt.ArrayLike,
    *,
    labels: npt.ArrayLike | None = None,
    radius: int | None = None,
    segmentation: bool | None = None,
) -> ToFOnReference:
    """Reproject ToF depth and amplitude onto the reference camera and upsample both.

    Args:
        tof_depth, tof_amplitude: ``H_t x W_t`` ToF maps (metres; NaN/<=0 invalid).
        rig: the :class:`~rgbd_rs.ToFStereoRig`.
        image: the reference colour image (uint8 RGB) on the reference camera.
        labels: a segmentation of ``image`` for the filter's segmentation term.
        radius: filter window half-size; default scales 5 px at 960 px width.
        segmentation: without ``labels``, segment ``image`` by :func:`segment_mean_shift`
            first (None: :data:`UPSAMPLE_SEGMENTATION`, read at the call: no, a plain cross
            bilateral filter).
    """
    r = rig_arg(rig)
    img = rgb8("image", image, r.reference_camera.size)
    seg = None if segmentation is None else _validate.flag("segmentation", segmentation)
    return _densify_tof(_reproject_tof(tof_depth, tof_amplitude, r), r, img, labels, radius, seg)


@array_eq
@dataclass(frozen=True)
class SparseToF:
    """The ToF samples splatted onto the reference lattice (``H x W`` float32, NaN = none):
    the first half of :func:`tof_to_reference`, for callers that start work on it early."""

    depth: F32
    amplitude: F32


def _reproject_tof(
    tof_depth: npt.ArrayLike, tof_amplitude: npt.ArrayLike, rig: object
) -> SparseToF:
    """The reprojection step of :func:`tof_to_reference` (warns when no ToF pixel is valid)."""
    r = rig_arg(rig)
    tof_shape = (r.tof.height, r.tof.width)
    z = map2d("tof_depth", tof_depth, tof_shape)
    amp = map2d("tof_amplitude", tof_amplitude, tof_shape)
    valid = np.isfinite(z) & (z > 0)
    with np.errstate(invalid="ignore"):
        negative = valid & (amp < 0)
    if negative.any():
        raise InvalidArgumentError(
            f"tof_amplitude: got {int(negative.sum())} negative values (down to "
            f"{float(amp[negative].min()):.3g}), expected amplitudes >= 0 in any unit"
        )
    # The disparity b f / z of a subnormal depth overflows float32 (checked here to name the
    # argument; depth_to_disparity would call it "depth").
    floor = r.stereo.baseline * r.stereo.focal / _validate.F32_MAX
    if valid.any() and float(z[valid].min()) < floor:
        raise InvalidArgumentError(
            f"tof_depth: got depths down to {float(z[valid].min()):.3g} m, expected depths >= "
            f"{floor:.3g} m (smaller ones give disparities beyond float32's range)"
        )
    check_tof_unit(z, r)
    if not valid.any():
        warnings.warn(
            "tof_depth: no valid pixel; the ToF maps on the reference camera are all NaN",
            RuntimeWarning,
            stacklevel=3,
        )
    rep = reproject_depth(
        np.where(valid, z, np.nan), r.tof, r.reference_camera, r.tof_to_reference, channels=amp
    )
    assert rep.channels is not None
    with np.errstate(invalid="ignore"):
        landed = np.isfinite(rep.depth) & (rep.channels > 0)
    sparse_amp = np.where(landed, rep.channels, np.nan).astype(np.float32)
    return SparseToF(rep.depth, sparse_amp)


def _densify_tof(
    sparse: SparseToF,
    rig: object,
    image: npt.ArrayLike,
    labels: npt.ArrayLike | None = None,
    radius: int | None = None,
    segmentation: bool | None = None,
) -> ToFOnReference:
    """The upsampling step of :func:`tof_to_reference` (same arguments)."""
    r = rig_arg(rig)
    img = rgb8("image", image, r.reference_camera.size)
    lab = labels
    if segmentation is None:
        segmentation = UPSAMPLE_SEGMENTATION
    if lab is None and segmentation:
        lab = segment_mean_shift(img)
    if radius is None:
        radius = max(2, round(UPSAMPLE_RADIUS * r.reference_camera.width / 960))
    # One pass: the amplitude rides on the depth's weights (a second filter run on the amplitude
    # would apply the depth-relative range term to amplitude differences).
    dense, dense_amp, gap = _upsample(
        sparse.depth,
        sparse.amplitude,
        img,
        lab,
        radius,
        SIGMA_SPATIAL,
        SIGMA_COLOR,
        SIGMA_RANGE,
        names=("tof_depth", "tof_amplitude"),
    )
    assert dense_amp is not None
    disp = depth_to_disparity(dense, r.stereo.baseline, r.stereo.focal)
    labels_out = None if lab is None else np.asarray(lab, dtype=np.int32)
    return ToFOnReference(sparse.depth, dense, disp, dense_amp, labels_out, gap)
