"""The whole ToF-stereo pipeline of thesis ch. 3: :func:`fuse`."""

from __future__ import annotations

import dataclasses
import functools
import sys
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, TypeGuard

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.camera import Pose, ToFStereoRig
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import (
    F32,
    U8,
    disagreement_warning,
    far_camera_warning,
    map2d,
    negative_depth_error,
    rgb8,
    rig_arg,
    scale_factor,
    tof_depth_warning,
    unit_map,
    views,
    with_reference,
)
from rgbd_rs.fusion._pose_check import pose_warning, turn_warning
from rgbd_rs.fusion.census import CensusParams
from rgbd_rs.fusion.confidence import stereo_confidence, tof_confidence
from rgbd_rs.fusion.lc import LcParams, lc_fuse
from rgbd_rs.fusion.pose_refine import WIDE_DEGREES, PoseRefinement, _pose_error
from rgbd_rs.fusion.scale_refine import (
    SCALE_GRID,
    ScaleRefinement,
    _clear_turn,
    _rescaled,
    _scale_and_turn,
)
from rgbd_rs.fusion.sources import (
    SOURCE_LC,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_LC_UNMEASURED,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_NONE,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_STEREO,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_TOF,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_TOF_CARRIED,  # noqa: F401 (re-exported: FusionResult.source)
    _carry_tof_to_border,
    _extend_tof_into_band,
    _fill_single_source,
    _unseen_from_tof,
)
from rgbd_rs.fusion.stereo import (
    _predict_search_range,
    _same_search,
    _whole_steps,
    _widest_range,
    search_range,
    sgm,
)
from rgbd_rs.fusion.upsample import ToFOnReference, _densify_tof, _reproject_tof
from rgbd_rs.geometry import depth_to_disparity, disparity_to_depth

if TYPE_CHECKING:  # torch is imported only when the ConvNet runs
    from rgbd_rs.nn.confidence import ConfidenceEstimator

ConfidenceKind = Literal["convnet", "uniform", "heuristic"]
StereoMatcher = Literal["census", "opencv"]
#: Stereo matchers ``fuse`` runs: ours (:func:`~rgbd_rs.fusion.census.census_match`) or OpenCV's.
STEREO_MATCHERS = ("census", "opencv")
#: The matcher of the confidence kinds without a network (a ConvNet uses the one it was trained
#: on: :attr:`~rgbd_rs.nn.confidence.ConfidenceEstimator.matcher`). Chosen on the real
#: validation cases (6 scenes x 2 ToF laws) with the heuristic confidences: census mean fused /
#: better input 0.943, worst fused / good input 1.366; OpenCV's SGBM 1.033 / 1.460.
DEFAULT_STEREO: StereoMatcher = "census"
#: The census matcher's settings in ``fuse``: the matcher's defaults with its left-right check
#: on (tolerance 1 px). Chosen on the real validation cases (6 scenes x 2 ToF laws, the shipped
#: ConvNet): mean fused / better input 0.829 and worst fused / good input 1.005 with the check,
#: 0.867 / 1.068 without (the matcher alone prefers no check, where a hole counts as an error;
#: in the fusion the ToF fills the holes).
FUSION_CENSUS = CensusParams(lr_tolerance=1)
#: The largest yaw / pitch ``fuse()``'s orientation refinement reaches, degrees (its wide probe's
#: :data:`~rgbd_rs.fusion.pose_refine.WIDE_DEGREES`, then a degree around the probe's best): a
#: turn found there is reported as the edge of the search.
POSE_SEARCH_DEGREES = WIDE_DEGREES + 1.0
#: Confidence kinds by name ("convnet" runs the shipped ConvNet, rgbd_rs/nn/weights).
CONFIDENCE_KINDS = ("convnet", "uniform", "heuristic")
#: Unconfirmed ToF pixels: where the colour of a pixel differs by more than this (mean absolute
#: difference, 8-bit levels) from every ToF sample within the upsampling window
#: (:attr:`~rgbd_rs.fusion.upsample.ToFOnReference.color_gap`), its upsampled depth came only
#: from surfaces of other colours, i.e. from across an edge that the coarser ToF cannot place
#: (a background pixel given the foreground's depth). The estimated ToF confidence ("convnet",
#: "heuristic") is 0 there, so LC takes such a pixel from the stereo map and its consistent
#: neighbours; the ToF value still fills it where LC leaves it empty. Chosen on the real train
#: + val cases (20 scenes x 3 ToF laws, docs/experiments.md; P_S^3): mean fused / better input
#: 0.802 without the gate, 0.772 with it, and the worst damage to a good input 1.265 -> 1.035
#: (Barn2: a sparse ToF bleeding across edges beside a good stereo map).
UNCONFIRMED_COLOR_GAP = 20.0


def shipped_estimator(far: bool = False) -> ConfidenceEstimator:
    """The confidence ConvNet shipped in the package, loaded once per process: with ``far``,
    the one for fusing on the camera of the pair farther from the ToF
    (:data:`~rgbd_rs.nn.confidence.WEIGHTS_FAR`)."""
    return _shipped(bool(far))


@functools.cache
def _shipped(far: bool) -> ConfidenceEstimator:
    from rgbd_rs.nn.confidence import WEIGHTS_FAR, ConfidenceEstimator

    return ConfidenceEstimator.load(WEIGHTS_FAR if far else None)


#: Swapped left/right images. A pair's match score is the share of the pixels SGM can search
#: (those at least ``max_disparity`` from the image edge) that SGM matches and, where the ToF has
#: a disparity, matches within ``SWAP_AGREE`` px of it. Below ``SWAP_SUSPECT_SCORE`` the pair is
#: also matched with the images exchanged, and a score there of at least ``SWAP_GAIN`` times
#: (and at least ``SWAP_SUSPECT_SCORE``) means the images were swapped. Chosen on the synthetic
#: test set and Middlebury: correct pairs score 0.36-0.97, swapped ones 0.01-0.16. Without a ToF
#: the score is SGM's coverage alone, both orders are always matched, and the exchanged order
#: must reach ``SWAP_GAIN_STEREO_ONLY`` times the given one (there swapped pairs reach 0.28-0.68
#: of the correct order's 0.78-0.97, a ratio of 1.3 or more).
SWAP_AGREE = 2.0
SWAP_SUSPECT_SCORE = 0.25
SWAP_GAIN = 2.0
SWAP_GAIN_STEREO_ONLY = 1.2


@dataclass(frozen=True)
class FusionResult:
    """Everything :func:`fuse` computed, on the reference camera (``H x W`` float32, NaN = none).

    Attributes:
        disparity, depth: the fused map (pixels, metres).
        plausibility: the LC winner's share of the accumulated plausibility (where only one
            input measured the pixel: that input's confidence; see ``source``).
        tof: the reprojected and upsampled ToF (depth, disparity, amplitude, segmentation).
        stereo_disparity: the SGM map.
        tof_confidence, stereo_confidence: the weights used (None = uniform).
        max_disparity: the SGM search range asked for (given, or from :func:`search_range`);
            SGBM and, inside ``fuse``, the census matcher search it in whole 16-px steps
            (:func:`~rgbd_rs.fusion.stereo._whole_steps`).
        reference: the camera the maps lie on (``"left"`` or ``"right"``).
    """

    disparity: F32
    depth: F32
    plausibility: F32
    tof: ToFOnReference
    stereo_disparity: F32
    tof_confidence: F32 | None
    stereo_confidence: F32 | None
    max_disparity: int
    reference: Literal["left", "right"]
    #: The ToF disparities LC fused: ``tof.disparity`` within the SGM search range (the rest
    #: are flying pixels or beyond what the pair can confirm).
    tof_fused: F32
    #: The stereo matcher that made ``stereo_disparity`` (``"census"`` or ``"opencv"``).
    stereo_matcher: str = "census"
    #: Where each pixel of ``disparity`` comes from: :data:`SOURCE_LC` (the fusion),
    #: :data:`SOURCE_LC_UNMEASURED` (the fusion at a pixel neither input measured, lent by its
    #: neighbours: often right, but ~20x as often off by more than 2 px as LC's other pixels at
    #: the same plausibility on real scenes; mask it when a hole is better than a guess),
    #: :data:`SOURCE_TOF` / :data:`SOURCE_STEREO` (LC left it empty and that input measured it:
    #: its value, and its confidence as ``plausibility``; the ToF where both did, and where the
    #: ToF says the other camera cannot see the pixel and the matcher has no value or the ToF
    #: continues a surface the fusion confirmed), :data:`SOURCE_TOF_CARRIED` (along the
    #: border the other camera cannot see, before the row's first ToF pixel: that pixel's value
    #: and confidence), :data:`SOURCE_NONE` (nothing). With ``LcParams(cross_check=True)``
    #: nothing is filled (LC's unmeasured pixels are still marked).
    source: npt.NDArray[np.uint8] | None = None
    #: The ToF pose fused with, ToF frame -> the ``reference`` camera's frame: the rig's,
    #: carried to that camera, or the orientation :func:`refine_tof_pose` found when ``fuse``
    #: refined it (write it into the calibration relative to ``reference``).
    tof_pose: Pose | None = None
    #: The factor the ToF's depths were divided by to fit the stereo pair's scale (1: as given;
    #: see :func:`~rgbd_rs.fusion.scale_refine.refine_tof_scale`).
    tof_scale: float = 1.0


def _is_estimator(value: object) -> TypeGuard[ConfidenceEstimator]:
    """Whether ``value`` is a ConfidenceEstimator (without importing torch when it cannot be:
    an instance exists only once its module was imported)."""
    module = sys.modules.get("rgbd_rs.nn.confidence")
    return module is not None and isinstance(value, module.ConfidenceEstimator)


def _match_score(stereo: F32, tof_disparity: F32, max_disparity: int, sign: int) -> float:
    """The share of searchable pixels SGM matches, consistently with the ToF where it has one."""
    w = stereo.shape[1]
    cols = slice(max_disparity, w) if sign < 0 else slice(0, max(0, w - max_disparity))
    st, tof = stereo[:, cols], tof_disparity[:, cols]
    if st.size == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        good = np.isfinite(st) & ~(np.abs(st - tof) >= SWAP_AGREE)
    return float(good.mean())


def _match(
    left: U8,
    right: U8,
    *,
    reference: str,
    max_disparity: int,
    matcher: str,
    width: int,
    align_rows: bool = True,
) -> F32:
    """SGM as ``fuse`` runs it: ``matcher`` with its settings; the census matcher searches the
    range rounded up to OpenCV's whole steps (:func:`_whole_steps`, within the image), so that,
    as with SGBM, a range :func:`_same_search` calls the same gives the same map.
    ``align_rows=False``: the census matcher matches the pair as given (the swap check's
    exchanged pair, whose poor first match must not be read for rows)."""
    if matcher == "census":
        top = min(_whole_steps(max_disparity), width - 1)
        params = FUSION_CENSUS if align_rows else FUSION_CENSUS.replace(align_rows=False)
        return sgm(
            left,
            right,
            reference=reference,
            max_disparity=top,
            method="census",
            params=params,
        )
    return sgm(left, right, reference=reference, max_disparity=max_disparity)


def _scale_check(
    left: U8,
    right: U8,
    reference: str,
    stereo: F32,
    tof_disparity: F32,
    widest: int | None,
    match: Callable[..., F32],
) -> tuple[str, float, F32] | None:
    """:func:`~rgbd_rs.fusion._inputs.scale_factor` of the ToF against the stereo map (with the
    map it was read on); where they disagree on most pixels and no factor explains it, once
    more against a map searched over ``widest`` (None: the caller's range stands): depths too
    far make the range derived from them too short for the pair's disparities."""
    said = scale_factor(tof_disparity, stereo)
    if said is not None:
        return (*said, stereo)
    if widest is None or disagreement_warning(tof_disparity, stereo) is None:
        return None
    wide = match(left, right, reference=reference, max_disparity=widest)
    said = scale_factor(tof_disparity, wide)
    return None if said is None else (*said, wide)


def _a_turn_explains(
    depth: F32, rig: ToFStereoRig, stereo: F32, factor: float, refine: bool
) -> bool:
    """Whether a clear turn of the ToF fits ``stereo`` better than its depths divided by
    ``factor`` do: on a slanted flat scene a pitch reads like a scale (Bull, 3 degrees of
    pitch: a factor of 0.74), and the refinement corrects it."""
    if not refine:
        return False
    turn = _clear_turn(depth, rig, stereo)
    return turn is not None and turn.error_after < _pose_error(
        _rescaled(depth, factor), rig, stereo
    )


def _swap_warning(
    left: U8,
    right: U8,
    reference: str,
    stereo: F32,
    tof_disparity: F32,
    dmax: int,
    match: Callable[..., F32],
) -> str | None:
    """A message when the pair looks swapped: SGM matches few pixels (its left-right check fails,
    or its disparities disagree with the ToF) as given and far more with the images exchanged,
    i.e. the pair's disparities as given are negative."""
    sign = 1 if reference == "right" else -1
    has_tof = bool(np.isfinite(tof_disparity).any())
    given = _match_score(stereo, tof_disparity, dmax, sign)
    if has_tof and given >= SWAP_SUSPECT_SCORE:
        return None
    exchanged = match(right, left, reference=reference, max_disparity=dmax, align_rows=False)
    swapped = _match_score(exchanged, tof_disparity, dmax, sign)
    gain = SWAP_GAIN if has_tof else SWAP_GAIN_STEREO_ONLY
    if swapped < max(SWAP_SUSPECT_SCORE, gain * given):
        return None
    return (
        f"left/right: the images look swapped: SGM matches {given:.0%} of the pixels as given "
        f"and {swapped:.0%} with left and right exchanged; check that the left image is the "
        "left camera's (the right camera sits baseline metres along +x of the left one)"
    )


def fuse(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    tof_depth: npt.ArrayLike,
    tof_amplitude: npt.ArrayLike,
    rig: object,
    *,
    confidence: ConfidenceKind
    | ConfidenceEstimator
    | tuple[npt.ArrayLike, npt.ArrayLike] = "convnet",
    params: LcParams | None = None,
    max_disparity: int | None = None,
    reference: Literal["left", "right"] | None = None,
    stereo: StereoMatcher | None = None,
    refine_pose: bool = True,
) -> FusionResult:
    """Fuse a ToF frame with a rectified stereo pair into one sub-pixel disparity map.

    Args:
        left, right: the rectified colour pair (uint8 RGB, the rig's image size).
        tof_depth, tof_amplitude: the ToF frame (metres, NaN/<=0 invalid; amplitude >= 0).
        rig: :class:`~rgbd_rs.ToFStereoRig`; the output lies on ``rig.reference_camera``
            unless ``reference`` says otherwise.
        confidence: ``"convnet"`` (default: the confidence ConvNet of thesis §3.6 with the
            weights shipped in the package; on the camera farther from the ToF, those trained
            for it), a :class:`~rgbd_rs.nn.confidence.ConfidenceEstimator`
            (your own checkpoint), ``"uniform"`` (equal weights, Dal Mutto 2012), ``"heuristic"``
            (:mod:`rgbd_rs.fusion.confidence`), or ``(tof_conf, stereo_conf)`` maps in [0, 1] on
            the reference camera.
        params: LC constants and window (:class:`LcParams`).
        max_disparity: SGM search range; default :func:`~rgbd_rs.fusion.stereo.search_range`
            of the ToF disparities (robust to flying pixels, at most a third of the width).
        reference: the camera to fuse on, ``"left"`` or ``"right"``; default the rig's.
        stereo: the stereo matcher, ``"census"`` (ours) or ``"opencv"`` (SGBM); default the
            one the ConvNet was trained on (its clues come from the matcher), else
            :data:`DEFAULT_STEREO`.
        refine_pose: when the ToF fits the stereo map clearly better turned (yaw and pitch,
            0.1 to :data:`POSE_SEARCH_DEGREES` degrees: the search of
            :func:`~rgbd_rs.fusion.pose_refine.refine_tof_pose` within a degree, a coarse
            probe of larger turns where nothing near fits), fuse with that orientation and
            warn; likewise when its depths fit it clearly better scaled by 1-6 %
            (:func:`~rgbd_rs.fusion.scale_refine.refine_tof_scale`).
            ``False`` fuses the pose and the depths as given.

    A ToF frame without any valid pixel gives the stereo-only LC result with a warning.
    ToF depths that look like millimetres (or kilometres) for the rig are refused
    (:class:`~rgbd_rs.InvalidArgumentError`, before any work). Other implausible input warns
    once each (:class:`RuntimeWarning`), saying what to check: depths beyond the stereo range
    of the rig, a left/right pair that looks swapped, an output camera farther from the ToF
    than the other one (fuse on the camera beside the ToF: the stereo pair's occlusions are then
    what the ToF sees), a ToF pose that fits the stereo map better inverted or read from the
    other camera, and a ToF that agrees with the stereo map almost nowhere.
    """
    asked = rig_arg(rig)
    refine_pose = _validate.flag("refine_pose", refine_pose)
    r = asked if reference is None else with_reference(asked, reference)
    far = far_camera_warning(r)
    if far is not None:
        warnings.warn(far, RuntimeWarning, stacklevel=2)
    size = r.stereo.left.size
    lft = rgb8("left", left, size)
    rgt = rgb8("right", right, size)
    ref_img, tgt_img, sign = views(lft, rgt, r.reference)
    h, w = ref_img.shape[:2]
    if w < 2:
        raise InvalidArgumentError(
            f"left/right: got images {w} pixel wide, expected at least 2 columns to match"
        )
    # The cheap checks come before the stages run.
    if params is not None and not isinstance(params, LcParams):
        raise InvalidArgumentError(f"params: got {type(params).__name__}, expected LcParams")
    given: tuple[F32, F32] | None = None
    estimator = None
    kind = "given"
    if isinstance(confidence, str):
        kind = _validate.choice("confidence", confidence, CONFIDENCE_KINDS)
        if kind == "convnet":
            # On the camera far from the ToF, the network trained for it (docs/training.md).
            estimator = shipped_estimator(far=far is not None)
    elif _is_estimator(confidence):
        estimator = confidence
        kind = "convnet"
    elif isinstance(confidence, (tuple, list)) and len(confidence) == 2:
        given = (
            unit_map("confidence[0]", confidence[0], (h, w)),
            unit_map("confidence[1]", confidence[1], (h, w)),
        )
        if not ((given[0] > 0) | (given[1] > 0)).any():  # NaN compares False, as 0 does
            warnings.warn(
                "confidence: neither map gives any pixel a weight > 0 (all NaN or 0): the "
                "fused map will be empty",
                RuntimeWarning,
                stacklevel=2,
            )
    else:
        raise InvalidArgumentError(
            f"confidence: got {type(confidence).__name__}, expected 'convnet', 'uniform', "
            "'heuristic', a ConfidenceEstimator or a (tof_confidence, stereo_confidence) pair"
        )
    matcher: str
    if stereo is None:
        matcher = estimator.matcher if estimator is not None else DEFAULT_STEREO
    else:
        matcher = _validate.choice("stereo", stereo, STEREO_MATCHERS)
    match = functools.partial(_match, matcher=matcher, width=w)
    if max_disparity is not None:
        max_disparity = _validate.integer("max_disparity", max_disparity, minimum=1, maximum=w - 1)
    # Depths in the wrong unit are refused before any work (as segment() does); other
    # implausible depths warn once the result is known (below).
    depth_map = map2d("tof_depth", tof_depth, (r.tof.height, r.tof.width))
    negative = negative_depth_error(depth_map)
    if negative is not None:
        raise InvalidArgumentError(negative)
    implausible = tof_depth_warning(depth_map, r)
    if implausible is not None and implausible[1]:
        raise InvalidArgumentError(implausible[0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sparse = _reproject_tof(depth_map, tof_amplitude, r)
    # SGM runs on a worker thread (OpenCV releases the GIL) while the ToF is upsampled here (the
    # native filter releases it too): with the range predicted from the sparse ToF, re-run in
    # the rare scene where the upsampled ToF's range asks for another SGBM step.
    if max_disparity is None:
        sparse_disp = depth_to_disparity(sparse.depth, r.stereo.baseline, r.stereo.focal)
        guess = _predict_search_range(sparse_disp, w)
    else:
        guess = max_disparity
    with ThreadPoolExecutor(max_workers=1) as pool:
        early = pool.submit(match, lft, rgt, reference=r.reference, max_disparity=guess)
        tof = _densify_tof(sparse, r, ref_img)
        dmax = search_range(tof.disparity, w) if max_disparity is None else max_disparity
        st_map = early.result()
    if not _same_search(guess, dmax):
        st_map = match(lft, rgt, reference=r.reference, max_disparity=dmax)
    no_tof = not np.isfinite(tof.disparity).any()
    if no_tof:
        pose = ""
        with np.errstate(invalid="ignore"):
            measured = bool((np.isfinite(depth_map) & (depth_map > 0)).any())
        if measured:  # depths that land nowhere: the pose may be off (a translation in mm)
            shift = float(np.linalg.norm(r.tof_to_reference.translation))
            pose = f" (check the ToF's pose in the rig: it sits {shift:.3g} m from the camera)"
        warnings.warn(
            "tof_depth: no valid ToF pixel reaches the reference camera; returning the "
            f"stereo-only LC result{pose}",
            RuntimeWarning,
            stacklevel=2,
        )
    else:
        for c in caught:
            warnings.warn(c.message, c.category, stacklevel=2)
        if implausible is not None:
            warnings.warn(implausible[0], RuntimeWarning, stacklevel=2)
    # Depths in another unit or scale first: the checks below read the ToF's disparities as true.
    off_scale = None
    if not no_tof:
        wide = None if max_disparity is not None else _widest_range(w)
        scaled_by = _scale_check(lft, rgt, r.reference, st_map, tof.disparity, wide, match)
        if scaled_by is not None and not _a_turn_explains(
            depth_map, r, scaled_by[2], scaled_by[1], refine_pose
        ):
            off_scale = scaled_by[0]
    if off_scale is not None:
        warnings.warn(off_scale, RuntimeWarning, stacklevel=2)
    swapped = (
        None
        if off_scale is not None
        else _swap_warning(lft, rgt, r.reference, st_map, tof.disparity, dmax, match)
    )
    if swapped is not None:
        warnings.warn(swapped, RuntimeWarning, stacklevel=2)
    tof_disp = np.where(tof.disparity <= dmax, tof.disparity, np.nan).astype(np.float32)
    # The ToF's depth scale against the stereo pair's first (a scale error shifts every ToF
    # disparity, which a turn would partly absorb), then a ToF turned by a fraction of a degree
    # is refined; a pose read the wrong way round is named (only when another reading beats
    # even the refined pose: a turn can make the inverted reading fit a flat scene better than
    # the turned pose as given); other disagreement only in general terms.
    refine = refine_pose and swapped is None and off_scale is None and not no_tof
    rescale, found = _scale_and_turn(depth_map, r, st_map) if refine else (None, None)
    fitted = None if found is None else found.pose
    # The readings are compared on the depths the fits chose (a depth scale a few percent off
    # otherwise makes the inverted reading fit better than the pose as given).
    checked = depth_map if rescale is None else _rescaled(depth_map, rescale.factor)
    wrong_way = (
        None
        if swapped is not None or off_scale is not None
        else pose_warning(checked, asked, r, st_map, fitted)
    )
    if wrong_way is not None:
        warnings.warn(wrong_way, RuntimeWarning, stacklevel=2)
        found = rescale = None  # fits made with a pose read the wrong way round
    if rescale is not None:
        warnings.warn(_rescaled_message(rescale), RuntimeWarning, stacklevel=2)
        depth_map = checked  # the rescaled depths the pose check read
    if found is not None:
        warnings.warn(_refined_message(found), RuntimeWarning, stacklevel=2)
        r = dataclasses.replace(r, tof_to_reference=found.pose)
    if found is not None or rescale is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said once already, for the given pose and depths
            tof = _densify_tof(_reproject_tof(depth_map, tof_amplitude, r), r, ref_img)
        if max_disparity is None:  # the corrected ToF's range, as a corrected rig would give
            refit = search_range(tof.disparity, w)
            if not _same_search(dmax, refit):
                st_map = match(lft, rgt, reference=r.reference, max_disparity=refit)
            dmax = refit
        tof_disp = np.where(tof.disparity <= dmax, tof.disparity, np.nan).astype(np.float32)
    # Several degrees off: only where the refinement did not act (its warning says when it
    # stopped at the edge of its search).
    quiet = swapped or off_scale or wrong_way or no_tof or found is not None or rescale is not None
    turned = None if quiet else turn_warning(depth_map, r, st_map)
    if turned is not None:
        warnings.warn(turned, RuntimeWarning, stacklevel=2)
    apart = (
        None
        if swapped or off_scale or wrong_way or turned
        else disagreement_warning(tof_disp, st_map)
    )
    if apart is not None:
        warnings.warn(apart, RuntimeWarning, stacklevel=2)
    if not np.isfinite(st_map).any() and no_tof:
        raise InvalidArgumentError(
            "left/right: stereo matching found no valid disparity and the ToF has none either; "
            "expected textured images or valid ToF data"
        )
    if given is None and kind != "uniform" and not no_tof:
        _warn_without_amplitude(tof_disp, tof.amplitude, network=estimator is not None)
    ct: F32 | None
    cs: F32 | None
    if given is not None:
        ct, cs = given
    elif kind == "uniform":
        ct = cs = None
    elif estimator is not None:
        ct, cs = estimator(ref_img, tgt_img, tof_disp, tof.amplitude, st_map, reference=r.reference)
        ct = _unconfirmed_to_zero(ct, tof.color_gap)
    else:
        ct = _unconfirmed_to_zero(tof_confidence(tof_disp, tof.amplitude), tof.color_gap)
        cs = stereo_confidence(ref_img, tgt_img, st_map, target_sign=sign, max_disparity=dmax)
    lc_disp, lc_plaus = lc_fuse(
        ref_img, tgt_img, [tof_disp, st_map], [ct, cs], target_sign=sign, params=params
    )
    # After LC's two-view check nothing is filled back: its rejections stand.
    cross_check = params is not None and params.cross_check
    disp, plaus, source = _fill_single_source(
        lc_disp,
        lc_plaus,
        tof_disp,
        st_map,
        ct,
        cs,
        keep_out_zero=given is not None,
        cross_check=cross_check,
    )
    if not cross_check:
        _unseen_from_tof(disp, plaus, source, tof_disp, st_map, ct, sign)
        _extend_tof_into_band(disp, plaus, source, tof_disp, ct, sign)
        _carry_tof_to_border(disp, plaus, source, tof_disp, ct, sign)
    depth = disparity_to_depth(disp, r.stereo.baseline, r.stereo.focal)
    return FusionResult(
        disp,
        depth,
        plaus,
        tof,
        st_map,
        ct,
        cs,
        dmax,
        r.reference,
        tof_disp,
        matcher,
        source,
        r.tof_to_reference,
        1.0 if rescale is None else rescale.factor,
    )


def _refined_message(found: PoseRefinement) -> str:
    """The warning of a ToF orientation that ``fuse()`` refined against the stereo map."""
    return (
        f"rig: the ToF fits the stereo map better turned by {found.yaw:+.2f} degrees of yaw and "
        f"{found.pitch:+.2f} of pitch (disparity difference {found.error_before:.2f} -> "
        f"{found.error_after:.2f} px, truncated mean): fused with that orientation"
        f"{_edge_note(max(abs(found.yaw), abs(found.pitch)) >= POSE_SEARCH_DEGREES - 1e-6)}. "
        "Correct the calibration (the result's tof_pose is the pose fused with, relative to "
        "its reference camera; rgbd fuse writes it to fused.npz), or pass refine_pose=False "
        "(rgbd fuse --keep-pose) to fuse the pose as given"
    )


def _edge_note(at_edge: bool) -> str:
    """A clause for a fit that stopped at the edge of its search."""
    if not at_edge:
        return ""
    return (
        " (the edge of the search: the calibration may be further off than that, and the "
        "fused map worse than with a corrected one)"
    )


def _rescaled_message(found: ScaleRefinement) -> str:
    """The warning of a ToF depth scale that ``fuse()`` refined against the stereo map."""
    return (
        f"tof_depth/rig: the ToF's depths fit the stereo map better divided by {found.factor:.3f} "
        f"(disparity difference {found.error_before:.2f} -> {found.error_after:.2f} px, "
        f"truncated mean): fused with them rescaled"
        f"{_edge_note(found.factor in (float(SCALE_GRID[0]), float(SCALE_GRID[-1])))}. A ToF "
        "depth scale error, or a stereo baseline that far off, reads so; the result's "
        "tof_scale is the factor (rgbd fuse writes it to fused.npz). Pass refine_pose=False "
        "(rgbd fuse --keep-pose) to fuse the depths as given"
    )


def _warn_without_amplitude(tof_disparity: F32, amplitude: F32, *, network: bool) -> None:
    """Warn when no ToF pixel has a finite amplitude > 0: the heuristic confidences then give
    the ToF no weight anywhere; a ConvNet reads it as one of its clues, and never saw a frame
    without it."""
    have = np.isfinite(tof_disparity)
    with np.errstate(invalid="ignore"):
        usable = have & np.isfinite(amplitude) & (amplitude > 0)
    if have.any() and not usable.any():
        effect = (
            "the ConvNet reads it as one of its clues and was never trained without it"
            if network
            else "the heuristic confidences give the ToF no weight"
        )
        warnings.warn(
            "tof_amplitude: no ToF pixel has a finite amplitude > 0 (all zero, NaN or "
            f"infinite): {effect}; pass the camera's amplitude (any unit), or "
            "confidence='uniform' (rgbd fuse --confidence uniform)",
            RuntimeWarning,
            stacklevel=3,
        )


def _unconfirmed_to_zero(confidence: F32, color_gap: F32 | None) -> F32:
    """``confidence`` with 0 where the ToF pixel is unconfirmed (:data:`UNCONFIRMED_COLOR_GAP`)."""
    if color_gap is None:
        return confidence
    with np.errstate(invalid="ignore"):
        unconfirmed = color_gap > UNCONFIRMED_COLOR_GAP
    return np.where(unconfirmed, np.float32(0), confidence).astype(np.float32)
