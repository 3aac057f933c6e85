"""The whole ToF-stereo pipeline of thesis ch. 3: :func:`fuse`."""

from __future__ import annotations

import functools
import sys
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, TypeGuard

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import Pose
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._ahead import Ahead, stopped_on_interrupt
from rgbd_rs.fusion._fuse_checks import (
    POSE_SEARCH_DEGREES,  # noqa: F401 (re-exported: fuse()'s docstring)
    check_maps,
)
from rgbd_rs.fusion._inputs import (
    F32,
    U8,
    far_camera_warning,
    map2d,
    negative_depth_error,
    rgb8,
    rig_arg,
    tof_depth_warning,
    unit_map,
    views,
    with_reference,
)
from rgbd_rs.fusion.census import CensusParams
from rgbd_rs.fusion.confidence import stereo_confidence, tof_confidence
from rgbd_rs.fusion.lc import LcParams, lc_fuse
from rgbd_rs.fusion.sources import (
    SOURCE_LC,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_LC_UNMEASURED,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_NONE,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_STEREO,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_TOF,  # noqa: F401 (re-exported: FusionResult.source)
    SOURCE_TOF_CARRIED,  # noqa: F401 (re-exported: FusionResult.source)
    _bridge_band_across_dropouts,
    _carry_tof_to_border,
    _extend_tof_into_band,
    _fill_single_source,
    _unseen_from_tof,
)
from rgbd_rs.fusion.stereo import (
    MIN_RANGE_COVERAGE,
    _predict_search_range,
    _range_and_coverage,
    _same_search,
    _sgm,
    _whole_steps,
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


@array_eq
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
    #: and confidence; in that band across a ToF dropout: the ToF's value above and below,
    #: interpolated, and their smaller confidence), :data:`SOURCE_NONE` (nothing). With
    #: ``LcParams(cross_check=True)`` nothing is filled (LC's unmeasured pixels are still marked).
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
        top = _fuse_top(matcher, max_disparity, width)
        params = FUSION_CENSUS if align_rows else FUSION_CENSUS.replace(align_rows=False)
        return _sgm(
            left,
            right,
            reference=reference,
            max_disparity=top,
            method="census",
            params=params,
        )
    return _sgm(left, right, reference=reference, max_disparity=max_disparity)


def _fuse_top(matcher: str, max_disparity: int, width: int) -> int:
    """The largest disparity :func:`_match` searches for ``max_disparity``: whole 16-px steps
    (:func:`_whole_steps`), within the image for the census matcher."""
    top = _whole_steps(max_disparity)
    return min(top, width - 1) if matcher == "census" else top


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
            of the ToF disparities (robust to flying pixels, at most a third of the width; the
            widest when the ToF is valid on under 1 % of the image). The range reaches only
            as near as the ToF saw: where it misses the nearest surfaces (saturated, outside
            its view), give this.
        reference: the camera to fuse on, ``"left"`` or ``"right"``; default the rig's.
        stereo: the stereo matcher, ``"census"`` (ours) or ``"opencv"`` (SGBM); default the
            one the ConvNet was trained on (its clues come from the matcher), else
            :data:`DEFAULT_STEREO`.
        refine_pose: when the ToF fits the stereo map clearly better turned (yaw and pitch,
            0.1 to :data:`POSE_SEARCH_DEGREES` degrees: the search of
            :func:`~rgbd_rs.fusion.pose_refine.refine_tof_pose` within a degree, a coarse
            probe of larger turns where nothing near fits), fuse with that orientation and
            warn; likewise when its depths fit it clearly better scaled by 1-6 %
            (:func:`~rgbd_rs.fusion.scale_refine.refine_tof_scale`). Only on a reference
            image at least :data:`~rgbd_rs.fusion.pose_refine.MIN_REFINE_WIDTH` (320) px wide:
            below it the fit turned exact rigs. ``False`` fuses the pose and the depths as
            given.

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

    # SGM runs on a worker thread (fusion._ahead; the matchers release the GIL) while the ToF is
    # upsampled here (the native filter releases it too): with the range predicted there from
    # the sparse ToF, re-run in the rare scene where the upsampled ToF's range asks for another
    # SGBM step.
    def early_match() -> tuple[int, F32]:
        guess = max_disparity
        if guess is None:
            sparse_disp = depth_to_disparity(sparse.depth, r.stereo.baseline, r.stereo.focal)
            guess = _predict_search_range(sparse_disp, w)
        return guess, match(lft, rgt, reference=r.reference, max_disparity=guess)

    early = Ahead(early_match)
    with stopped_on_interrupt(early):
        tof = _densify_tof(sparse, r, ref_img)
        dmax, share = (
            _range_and_coverage(tof.disparity, w) if max_disparity is None else (max_disparity, 1.0)
        )
        guess, st_map = early.result()
    if not _same_search(guess, dmax):
        st_map = match(lft, rgt, reference=r.reference, max_disparity=dmax)
    no_tof = not np.isfinite(tof.disparity).any()
    if max_disparity is None and not no_tof and share < MIN_RANGE_COVERAGE:
        warnings.warn(
            f"tof_depth: valid ToF pixels cover {100 * share:.2g} % of the reference "
            f"image, too few to bound the stereo search: searched the widest range, {dmax} "
            "px, as without a ToF (pass max_disparity, rgbd fuse --max-disparity, to "
            "choose it)",
            RuntimeWarning,
            stacklevel=2,
        )
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
    tof_disp = np.where(tof.disparity <= dmax, tof.disparity, np.nan).astype(np.float32)

    def confidences(
        tof_disp: F32, tof: ToFOnReference, st_map: F32, dmax: int
    ) -> tuple[F32 | None, F32 | None]:
        if given is not None:
            return given
        if kind == "uniform":
            return None, None
        if estimator is not None:
            ct, cs = estimator(
                ref_img, tgt_img, tof_disp, tof.amplitude, st_map, reference=r.reference
            )
            return _unconfirmed_to_zero(ct, tof.color_gap), cs
        ct = _unconfirmed_to_zero(tof_confidence(tof_disp, tof.amplitude), tof.color_gap)
        cs = stereo_confidence(ref_img, tgt_img, st_map, target_sign=sign, max_disparity=dmax)
        return ct, cs

    def fused(tof_disp: F32, st_map: F32, ct: F32 | None, cs: F32 | None) -> tuple[F32, F32]:
        return lc_fuse(
            ref_img, tgt_img, [tof_disp, st_map], [ct, cs], target_sign=sign, params=params
        )

    # The confidences and LC on the maps as they stand, LC on a worker thread beside the
    # checks (it releases the GIL; they are mostly single-threaded): kept unless the checks
    # correct the ToF's pose or depth scale (then both run again on the corrected maps). Their
    # warnings are said where they were before, after the checks'.
    ahead: Ahead[tuple[F32, F32]] | None = None
    conf_ahead: tuple[F32 | None, F32 | None] | None = None
    if not no_tof:
        with warnings.catch_warnings(record=True) as said_ahead:
            warnings.simplefilter("always")
            try:
                conf_ahead = confidences(tof_disp, tof, st_map, dmax)
            except Exception:  # raised again in its place, after the checks have spoken
                conf_ahead = None
        if conf_ahead is not None:
            ahead = Ahead(fused, tof_disp, st_map, *conf_ahead)
    with stopped_on_interrupt(ahead):
        checked = check_maps(
            lft,
            rgt,
            asked,
            r,
            depth_map,
            tof_amplitude,
            ref_img,
            tof,
            st_map,
            dmax,
            tof_disp,
            max_disparity=max_disparity,
            match=match,
            refine_pose=refine_pose,
            no_tof=no_tof,
        )
        r, tof, st_map, dmax = checked.rig, checked.tof, checked.stereo, checked.max_disparity
        tof_disp = checked.tof_disparity
        if not np.isfinite(st_map).any() and no_tof:
            raise InvalidArgumentError(
                "left/right: stereo matching found no valid disparity and the ToF has none "
                "either; expected textured images or valid ToF data"
            )
        if given is None and kind != "uniform" and not no_tof:
            _warn_without_amplitude(tof_disp, tof.amplitude, network=estimator is not None)
        if ahead is not None and conf_ahead is not None and not checked.corrected:
            ct, cs = conf_ahead
            for c in said_ahead:
                warnings.warn(c.message, c.category, stacklevel=2)
            lc_disp, lc_plaus = ahead.result()
        else:
            if ahead is not None:
                ahead.wait()  # LC of the maps before the correction: not used
            ct, cs = confidences(tof_disp, tof, st_map, dmax)
            lc_disp, lc_plaus = fused(tof_disp, st_map, ct, cs)
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
        _bridge_band_across_dropouts(disp, plaus, source, tof_disp, sign)
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
        1.0 if checked.rescale is None else checked.rescale.factor,
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
