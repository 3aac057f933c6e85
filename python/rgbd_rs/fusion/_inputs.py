"""Validation helpers shared by the fusion stages (private)."""

from __future__ import annotations

from typing import Literal, cast

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.camera import ToFStereoRig
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]


def image8(name: str, value: object) -> U8:
    """``value`` as an array after the checks that need no copy (so a huge input is not copied
    before it is refused): uint8, ``H x W x 3`` or grey ``H x W``, not empty."""
    arr = _validate.asarray(name, value)
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3):
        raise ShapeMismatchError(f"{name}: got shape {arr.shape}, expected (H, W, 3) or (H, W)")
    if arr.dtype != np.uint8:
        raise InvalidArgumentError(f"{name}: got dtype {arr.dtype}, expected uint8 (0-255)")
    if arr.size == 0:
        raise ShapeMismatchError(f"{name}: got an empty image, expected at least 1x2 pixels")
    return arr


def grey8(name: str, value: object) -> U8:
    """A C-contiguous uint8 grey image of an RGB (or already grey) uint8 image (``image8``'s
    checks first)."""
    arr = image8(name, value)
    if arr.ndim == 2:
        return np.ascontiguousarray(arr)
    grey = cv2.cvtColor(np.ascontiguousarray(arr), cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(grey, dtype=np.uint8)


def pair8(left: object, right: object) -> tuple[U8, U8]:
    """A stereo pair after :func:`image8`'s checks, the right image of the left one's size."""
    lft, rgt = image8("left", left), image8("right", right)
    if rgt.shape[:2] != lft.shape[:2]:
        raise ShapeMismatchError(
            f"right: got {rgt.shape[1]}x{rgt.shape[0]} pixels, expected {lft.shape[1]}x"
            f"{lft.shape[0]} (the left image's size)"
        )
    return lft, rgt


def rgb8(
    name: str,
    value: object,
    size: tuple[int, int] | None = None,
    of: str = "the calibration's image size",
) -> U8:
    """An ``H x W x 3`` uint8 image (grey ``H x W`` is replicated); ``size`` = ``(W, H)``,
    ``of`` says whose size it is (the message's words)."""
    arr = image8(name, value)
    if arr.ndim == 2:
        arr = np.repeat(arr[:, :, None], 3, axis=2)
    if size is not None and (arr.shape[1], arr.shape[0]) != size:
        raise ShapeMismatchError(
            f"{name}: got {arr.shape[1]}x{arr.shape[0]} pixels, expected {size[0]}x{size[1]} ({of})"
        )
    return np.ascontiguousarray(arr)


def map2d(name: str, value: object, shape: tuple[int, int]) -> F32:
    """An ``H x W`` float32 map of ``shape``."""
    return np.asarray(_validate.array(name, value, shape=shape), dtype=np.float32)


def disparity_map(name: str, value: object, shape: tuple[int, int]) -> F32:
    """:func:`map2d` of disparities: NaN = none, others within +-``MAX_SIDE`` px (no image is
    wider; an inf or a 1e30 would reach the ConvNet's clues or overflow the fusion's bins)."""
    d = map2d(name, value, shape)
    with np.errstate(invalid="ignore"):
        far = np.abs(d) > _validate.MAX_SIDE
    if far.any():
        worst = float(np.abs(d[far]).max())
        raise InvalidArgumentError(
            f"{name}: got {int(far.sum())} value(s) as large as {worst:.3g} px, expected "
            f"disparities within +-{_validate.MAX_SIDE} px (no image is wider), or NaN for none"
        )
    return d


def unit_map(name: str, value: object, shape: tuple[int, int]) -> F32:
    """An ``H x W`` float32 map of ``shape`` with values in [0, 1] (NaN allowed: no weight)."""
    m = map2d(name, value, shape)
    with np.errstate(invalid="ignore"):
        bad = (m < 0) | (m > 1)
    if bad.any():
        raise InvalidArgumentError(
            f"{name}: got values in [{np.nanmin(m):.3g}, {np.nanmax(m):.3g}], expected values in "
            "[0, 1] (NaN = no weight)"
        )
    return m


def rig_arg(rig: object) -> ToFStereoRig:
    if not isinstance(rig, ToFStereoRig):
        raise InvalidArgumentError(f"rig: got {type(rig).__name__}, expected a ToFStereoRig")
    return rig


def views(left: U8, right: U8, reference: str) -> tuple[U8, U8, int]:
    """``(reference image, target image, target_sign)``: the target pixel of reference pixel x
    is ``x + sign * d`` with ``d = u_left - u_right``."""
    return (right, left, 1) if reference == "right" else (left, right, -1)


def with_reference(rig: ToFStereoRig, reference: str) -> ToFStereoRig:
    """``rig`` with its output on the ``reference`` camera: ``tof_to_reference`` is carried
    across the rectified pair (the right camera sits ``baseline`` metres along +x of the left)."""
    ref = _validate.choice("reference", reference, ("left", "right"))
    if ref == rig.reference:
        return rig
    left_to_right = rig.stereo.left_to_right
    across = left_to_right.inverse() if ref == "left" else left_to_right
    side = cast(Literal["left", "right"], ref)
    return ToFStereoRig(rig.tof, rig.stereo, across.compose(rig.tof_to_reference), side)


def negative_depth_error(depth: F32) -> str | None:
    """The refusal of a depth map with negative depths of several values and none > 0 (a sign
    flipped: one repeated value, such as -1, is an invalid-pixel mark), else None."""
    with np.errstate(invalid="ignore"):
        if (depth > 0).any():
            return None
        neg = depth[depth < 0]
    if np.unique(neg[:100_000]).size < 2:
        return None
    return (
        f"tof_depth: got only negative depths ({float(neg.min()):.3g} to {float(neg.max()):.3g}), "
        "expected metres > 0 in front of the camera (NaN, 0 or a negative value mark invalid "
        "pixels): is the sign flipped?"
    )


#: How :func:`far_camera_warning`'s message starts (a filter for callers that fuse on the far
#: camera on purpose: ``warnings.filterwarnings("ignore", FAR_CAMERA_WARNING)``).
FAR_CAMERA_WARNING = "reference: the ToF sits"
#: The other camera must be nearer the ToF than the reference camera by this share of the
#: baseline before :func:`far_camera_warning` speaks (a ToF midway between them is fine).
FAR_CAMERA_MARGIN = 0.1


def far_camera_warning(rig: ToFStereoRig) -> str | None:
    """A warning when the rig fuses on the camera of the pair farther from the ToF, else None.

    The pixels the stereo pair cannot match are those the other camera does not see; a ToF
    beside the reference camera sees them, one beside the other camera does not, so there
    neither input measures the surface. On the 15 real val cases with right-view ground truth
    (ToF 4 cm below the left camera, 160 mm baseline, 3 laws) the shipped network fuses to a
    mean RMS of 1.02 px on the right camera against 0.77 px on the left one (the network
    trained on near-camera cases only: 1.90 px, worse than stereo alone)."""
    baseline = rig.stereo.baseline
    tof_centre = np.asarray(rig.tof_to_reference.translation, float)
    # The other camera's centre in the reference camera's frame.
    other_x = -baseline if rig.reference == "right" else baseline
    to_ref = float(np.linalg.norm(tof_centre))
    to_other = float(np.linalg.norm(tof_centre - np.array([other_x, 0.0, 0.0])))
    if to_ref - to_other <= FAR_CAMERA_MARGIN * baseline:
        return None
    other = "left" if rig.reference == "right" else "right"
    return (
        f"{FAR_CAMERA_WARNING} {to_other:.3g} m from the {other} camera and {to_ref:.3g} m "
        f"from the {rig.reference} camera, where the map is fused; the surfaces the {other} "
        "camera cannot see (where the stereo pair cannot match) are hidden from the ToF too, so "
        "nothing measures them (on real scenes the fused error grew by a third). Fuse on the "
        f"{other} camera: reference='{other}' (rgbd fuse --reference {other})"
    )


#: A stereo pair resolves depth only where the disparity is at least this many pixels; ToF depths
#: whose disparity on the rig lies below it everywhere are "beyond the stereo range".
MIN_STEREO_DISPARITY = 1.0
#: Share of the valid ToF pixels that may lie outside the rig's disparity range [1 px, width)
#: before the depths count as implausible "everywhere" (flying pixels, noise). Chosen.
IMPLAUSIBLE_SHARE = 0.99
#: Share of the pixels that must become plausible in another unit for the warning to name it.
UNIT_MAJORITY = 0.5


def check_tof_unit(depth: F32, rig: ToFStereoRig) -> None:
    """Refuse ToF depths that look like millimetres (or kilometres) for ``rig``
    (:func:`tof_depth_warning`'s unit case): every stage that takes ``tof_depth`` calls it."""
    implausible = tof_depth_warning(depth, rig)
    if implausible is not None and implausible[1]:
        raise InvalidArgumentError(implausible[0])


def tof_depth_warning(depth: F32, rig: ToFStereoRig) -> tuple[str, bool] | None:
    """What is implausible about the ToF depths (metres) for ``rig`` and whether it is their
    unit (then ``fuse`` refuses them), or None.

    Checked on the disparities ``b f / z`` the depths would have on the stereo pair: if almost
    all (``IMPLAUSIBLE_SHARE``) lie below ``MIN_STEREO_DISPARITY`` (beyond the stereo range) or
    at or above the image width (nearer than any match), the message says so, and names
    millimetres (or kilometres) when most (``UNIT_MAJORITY``) of the depths divided
    (multiplied) by 1000 would be plausible; if most (but not almost all) do, a warning asks
    whether the map is the depth at all (an amplitude passed as depth reads so).
    """
    with np.errstate(invalid="ignore"):
        z = depth[np.isfinite(depth) & (depth > 0)].astype(np.float64)
    if z.size == 0:
        return None
    bf = rig.stereo.baseline * rig.stereo.focal
    width = rig.stereo.left.width

    def plausible(scale: float) -> float:
        d = bf / (z * scale)
        return float(np.mean((d >= MIN_STEREO_DISPARITY) & (d < width)))

    share = plausible(1.0)
    if share >= UNIT_MAJORITY:
        return None
    med = float(np.median(z))
    d_med = bf / med
    rig_text = (
        f"baseline {rig.stereo.baseline:g} m x focal {rig.stereo.focal:.1f} px, "
        f"{width} px wide: disparities {MIN_STEREO_DISPARITY:g}-{width} px are depths "
        f"{bf / width:.3g}-{bf / MIN_STEREO_DISPARITY:.3g} m"
    )
    if share > 1 - IMPLAUSIBLE_SHARE:
        # Most, not almost all: a map of another kind (the amplitude), or a unit with outliers.
        return (
            f"tof_depth: {100 * (1 - share):.0f} % of the ToF depths lie outside the stereo "
            f"rig's range (median {med:.4g} m; {rig_text}); check that it is the depth map in "
            "metres (not the amplitude) and the calibration's baseline and focal length",
            False,
        )
    for scale, unit in ((1e-3, "millimetres"), (1e3, "kilometres")):
        if plausible(scale) >= UNIT_MAJORITY:
            # depths in metres with a baseline in millimetres read the same way
            baseline = (
                f"; or the calibration's baseline ({rig.stereo.baseline:g}) is in millimetres"
                if scale > 1
                else ""
            )
            return (
                f"tof_depth: the ToF depths look like {unit}, not metres (median {med:.4g}, "
                f"outside the stereo rig's range: {rig_text}); check the depth unit (rgbd fuse "
                "reads .npy/.npz in metres, a 16-bit PNG in millimetres unless --depth-scale "
                f"says otherwise){baseline}",
                True,
            )
    where = "beyond" if d_med < MIN_STEREO_DISPARITY else "nearer than"
    return (
        f"tof_depth: the ToF depths lie {where} the stereo rig's range (median {med:.4g} m; "
        f"{rig_text}); check the depth unit and the calibration's baseline and focal length",
        False,
    )


#: The agreement check of :func:`disagreement_warning`: the ToF and the matcher agree at a pixel
#: within this many pixels of disparity (at a 960-px wide image; scaled with wider images).
AGREE_PX = 2.0
#: ... and fewer than this share of the pixels both measure agreeing warns. Measured with the
#: shipped defaults (a script, not kept; docs/experiments.md): 111 correct train/val
#: cases (Middlebury under three ToF laws and the dense one, both cameras; 12 rendered val
#: scenes) agree on 0.435-1.000 of those pixels (Middlebury 0.730-1.000); the amplitude passed
#: as depth on 0.000-0.108 (16 cases the unit check let through), a pose translation 10x too
#: long on 0.082-0.938 (6 of 20 below the limit). A pose given inverted (0.557-0.992) or
#: measured from the other camera (0.373-0.993) overlaps the correct cases: those are left to
#: :func:`rgbd_rs.fusion._pose_check.pose_warning`.
AGREE_SHARE = 0.25


def agree_tol(width: int) -> float:
    """:data:`AGREE_PX` for a map ``width`` pixels wide (scaled up past 960 px)."""
    return AGREE_PX * max(1.0, width / 960)


#: :func:`scale_factor` speaks where the stereo map's disparities are a factor outside this
#: range of the ToF's (the depth-scale refinement fits 0.94-1.06) ...
SCALE_OFF = (0.8, 1.25)
#: ... and the ToF's disparities times that factor agree with the stereo map on at least this
#: share of the pixels both measure, and by this much more than as given.
SCALE_FIT = 0.5
SCALE_GAIN = 0.25
SCALE_REL = 0.1
#: Pixels it compares, at most (evenly spaced over those both maps measure).
SCALE_SAMPLES = 65536


def scale_factor(tof_disparity: F32, stereo_disparity: F32) -> tuple[str, float] | None:
    """A warning and the factor ``k`` when the ToF's disparities agree with the stereo map only
    once multiplied by one ``k`` far from 1 (depths in another unit than metres, a wrong PNG
    depth scale, or a rig baseline that far off; the ToF's depths divided by ``k`` fit it), or
    None. ``k`` is the median ratio of the two maps."""
    with np.errstate(invalid="ignore"):
        both = np.flatnonzero(
            np.isfinite(tof_disparity) & np.isfinite(stereo_disparity) & (tof_disparity > 0)
        )
    if both.size < 100:
        return None
    # Evenly spaced pixels are plenty for one factor (a 960 x 540 map: ~4 ms, not ~10).
    pick = both[:: max(1, both.size // SCALE_SAMPLES)]
    tof = tof_disparity.ravel()[pick].astype(np.float64)
    st = stereo_disparity.ravel()[pick].astype(np.float64)
    k = float(np.median(st / tof))
    if SCALE_OFF[0] <= k <= SCALE_OFF[1] or not np.isfinite(k) or k <= 0:
        return None
    tol = agree_tol(tof_disparity.shape[1])
    given = float((np.abs(tof - st) <= tol).mean())
    # Within the tolerance, or 10 % of the scaled disparity (depths ten times too near also
    # move the ToF's pixels in the image: the scaled map agrees less closely).
    scaled = float((np.abs(k * tof - st) <= np.maximum(tol, SCALE_REL * st)).mean())
    if scaled < SCALE_FIT or scaled - given < SCALE_GAIN:
        return None
    return (
        f"tof_depth/rig: the ToF's depths look {k:.3g} x the stereo pair's: its disparities "
        f"times {k:.3g} agree with the stereo map within {tol:g} px on {scaled:.0%} of the pixels "
        f"both measure, as given on {given:.0%}; check tof_depth's unit (metres; a 16-bit PNG's "
        "depth scale) and the rig's baseline. Fused as given, the ToF's wrong depths win where "
        "the network trusts them"
    ), k


def disagreement_warning(tof_disparity: F32, stereo_disparity: F32) -> str | None:
    """A warning when the ToF and the stereo matcher, both on the reference camera, agree on
    almost none of the pixels they both measure (a misregistered or wrong ToF input), or None."""
    tol = agree_tol(tof_disparity.shape[1])
    both, within = _rgbd_rs.agreement(
        np.ascontiguousarray(tof_disparity, dtype=np.float32),
        np.ascontiguousarray(stereo_disparity, dtype=np.float32),
        tol,
    )
    if both < 100:
        return None  # too few to judge
    share = within / both
    if share >= AGREE_SHARE:
        return None
    return (
        f"tof_depth/rig: the ToF and the stereo map agree within {tol:g} px on only {share:.0%} "
        "of the pixels both measure (correct inputs agree on 44-100 % of them on the real and "
        "rendered validation scenes): "
        "check that tof_depth is the depth in metres (not the amplitude) and the ToF's pose in "
        "the rig (tof_to_reference: its translation's unit, its direction, the reference camera "
        "it is relative to)"
    )


def check_cost_volume(max_disparity: int, width: int, height: int, disparities: int) -> None:
    """Refuses a search of ``disparities`` disparities on ``width x height`` pixels whose cost
    volume holds more than ``MAX_ELEMENTS`` elements (both matchers: census_match stores 2 bytes
    each, OpenCV's SGBM-HH about 4), naming ``max_disparity``."""
    if width * height * disparities > _rgbd_rs.MAX_ELEMENTS:
        raise InvalidArgumentError(
            f"max_disparity: got {max_disparity}, expected a search whose cost volume ({width} x "
            f"{height} x {disparities}) holds at most {_rgbd_rs.MAX_ELEMENTS} elements"
        )
