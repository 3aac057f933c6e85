"""Where each pixel of :func:`~rgbd_rs.fusion.fuse` comes from, and the pixels LC cannot decide:
those it leaves empty, and those the other camera of the pair cannot see (its photometric terms
need the target pixel, so only the ToF can measure them). The steps run natively
(``rgbd_fusion::sources``, rows in parallel, numpy's f32 comparisons); the in-place ones need
C-contiguous float32 / uint8 maps, as :func:`_fill_single_source` returns them."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs
from rgbd_rs.fusion._inputs import F32

#: :attr:`~rgbd_rs.fusion.fuse.FusionResult.source` values: where each fused pixel comes from.
#: ``SOURCE_TOF_CARRIED``: the strip along the border the other camera cannot see, before the
#: row's first ToF pixel, which takes that pixel's disparity (:func:`_carry_tof_to_border`),
#: and the band's pixels across a ToF dropout, interpolated in their column
#: (:func:`_bridge_band_across_dropouts`).
#: ``SOURCE_LC_UNMEASURED``: LC's answer at a pixel neither input measured, lent by its
#: neighbours. Its ``plausibility`` is as high as anywhere (LC's winner share), but on the real
#: val scenes (18 cases, 3 ToF laws) 23 % of these pixels were more than 2 px off against 1.2 %
#: of LC's measured ones (train: 27 % against 1.2 %): mask them when a hole is better than a guess.
#: The codes are defined once, in ``rgbd_fusion::sources``, where the native steps write them.
SOURCE_NONE, SOURCE_LC, SOURCE_TOF = _rgbd_rs.SOURCE_NONE, _rgbd_rs.SOURCE_LC, _rgbd_rs.SOURCE_TOF
SOURCE_STEREO, SOURCE_TOF_CARRIED = _rgbd_rs.SOURCE_STEREO, _rgbd_rs.SOURCE_TOF_CARRIED
SOURCE_LC_UNMEASURED = _rgbd_rs.SOURCE_LC_UNMEASURED


def _c(m: F32) -> F32:
    """``m`` as the C-contiguous float32 map the native steps read."""
    return np.ascontiguousarray(m, dtype=np.float32)


def _opt(m: F32 | None) -> F32 | None:
    """:func:`_c` of an optional map."""
    return None if m is None else _c(m)


def _fill_single_source(
    lc_disparity: F32,
    lc_plausibility: F32,
    tof: F32,
    stereo: F32,
    tof_confidence: F32 | None,
    stereo_confidence: F32 | None,
    *,
    keep_out_zero: bool = False,
    cross_check: bool = False,
) -> tuple[F32, F32, npt.NDArray[np.uint8]]:
    """The LC map with the pixels it leaves empty but an input measures (outside the stereo
    overlap, stereo holes, ToF dropouts) given that input's value, with that input's confidence
    as plausibility (1 for uniform weights; the ToF's where both measured a pixel LC left
    empty); returns ``(disparity, plausibility, source)``. With ``keep_out_zero`` (confidences
    the caller gave) an input whose confidence there is 0 or NaN stays out; estimated
    confidences never hide the only measurement of a pixel, their value tells how far to trust
    it. After LC's two-view ``cross_check`` nothing is filled: its rejections stand. LC's pixels
    that neither input measured (has a finite value at) are marked :data:`SOURCE_LC_UNMEASURED`
    either way; a value whose confidence is 0 still counts as measured, since the caller sees
    it in ``tof_fused`` / ``stereo_disparity``."""
    disp = np.array(lc_disparity, dtype=np.float32, order="C")
    plaus = np.array(lc_plausibility, dtype=np.float32, order="C")
    source = np.empty(disp.shape, np.uint8)
    _rgbd_rs.fill_single_source(
        disp,
        plaus,
        source,
        _c(tof),
        _c(stereo),
        _opt(tof_confidence),
        _opt(stereo_confidence),
        keep_out_zero,
        cross_check,
    )
    return disp, plaus, source


def _unseen_from_tof(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    tof: F32,
    stereo: F32,
    tof_confidence: F32 | None,
    sign: int,
) -> None:
    """In place: the pixels whose ToF disparity puts their match outside the other image (the
    band of columns the other camera does not see) and that the stereo matcher could not match
    take the ToF's value and confidence. LC cannot check a hypothesis there (its photometric
    terms need the target pixel), so it kept only the few hypotheses that happened to land
    inside the image: wrong ones (a median error of 18-26 px on the real val scenes' bands,
    where the ToF had 0.02-0.13 px; over the 40 train + val cases the band's median error went
    from 25.7 to 11.6 px). Where the stereo map has a match the pixel may be seen after all and
    the ToF's disparity is the suspect one (ToF outliers 36 px too far on Bowling1, which taking
    every such pixel from the ToF made 1.21 x its good stereo map), so LC's answer stays. A ToF
    pixel of confidence 0 (the caller's weights, or an unconfirmed one:
    :data:`UNCONFIRMED_COLOR_GAP`) is not taken either."""
    _rgbd_rs.unseen_from_tof(
        disp, plaus, source, _c(tof), _c(stereo), _opt(tof_confidence), float(sign)
    )


def _carry_tof_to_border(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    tof: F32,
    tof_confidence: F32 | None,
    sign: int,
) -> None:
    """In place: along the border the other camera cannot see (the left one for a left
    reference, target ``x - d``; the right one for a right reference), the pixels before each
    row's first ToF pixel whose target, at that pixel's disparity, lies outside the other image
    take that disparity and confidence: the surface the ToF reaches first, carried to the
    border, is unseen there. The upsampled ToF often stops a few pixels short of the border,
    and whatever else fills the strip is wrong by construction: LC's window lends it hypotheses
    whose targets are inside the image, and the matcher's matches are forced. On the real train
    and val scenes (60 cases under three ToF laws, 20 under the dense protocol) the pixels the
    other camera cannot see went from 46-54 % to 10-16 % off by more than 2 px (RMS 23-27 px to
    9-11 px); the scored, visible pixels are untouched. Where the row's first ToF pixel has
    confidence 0 (an unconfirmed pixel, or the caller's weights), the value carried is the
    row's first pixel of confidence > 0 further in (the strip still ends at the first ToF
    pixel): those rows had kept LC's answers, forced matches near 0 px among them (on the 20
    train / val scenes under law 0, fused disparities under half the scene's smallest true one
    went from 15,475 to 8,950 pixels; the unseen pixels > 2 px off from 11.8 to 10.4 % on val,
    14.1 to 12.7 % on train; the scored pixels unchanged). A row without such a pixel is left
    as it was. The risk,
    not seen in those cases: a ToF dropout along the border in front of a near surface carries
    that surface over a seen background (a limit on the strip's length in pixels, 4-32, lost
    most of the gain: the ToF often starts 16-32 px in)."""
    _rgbd_rs.carry_tof_to_border(disp, plaus, source, _c(tof), _opt(tof_confidence), float(sign))


#: Largest step (px) between neighbouring ToF disparities of the chain
#: :func:`_extend_tof_into_band` follows, and largest gap (px) between the ToF and the fused map
#: that confirms its start.
BAND_CHAIN_STEP = 1.0
BAND_CONFIRM_GAP = 1.0


def _extend_tof_into_band(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    tof: F32,
    tof_confidence: F32 | None,
    sign: int,
) -> None:
    """In place: in each row, the pixels the ToF says the other camera cannot see that continue
    a surface the fusion confirmed take the ToF's value and confidence. From the row's innermost
    pixel whose ToF target is inside the other image, where the fused map (LC, which could still
    weigh both inputs there) agrees with the ToF within :data:`BAND_CONFIRM_GAP` (at its first
    value within that pixel's disparity of it), the chain runs towards the border while the ToF
    has a value within :data:`BAND_CHAIN_STEP` of its neighbour's (and confidence > 0). There
    the stereo map's value is a forced match (the true one lies beyond its search) and LC can
    weigh no other hypothesis (its photometric terms need the target pixel), so it kept the
    forced one with full plausibility."""
    _rgbd_rs.extend_tof_into_band(
        disp,
        plaus,
        source,
        _c(tof),
        _opt(tof_confidence),
        float(sign),
        BAND_CHAIN_STEP,
        BAND_CONFIRM_GAP,
    )


def _bridge_band_across_dropouts(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    tof: F32,
    sign: int,
) -> None:
    """In place: the pixels of the band the other camera cannot see, in rows a ToF dropout left
    without any of the row-wise rules above (no ToF pixel in the row, or none that reaches the
    seen part of it), take the ToF's surface across the dropout, column by column. Between two
    pixels of a column that took the ToF (:data:`SOURCE_TOF`), both unseen, whose values step by
    at most :data:`BAND_CHAIN_STEP` a row, the pixels where the ToF has no value and LC's answer
    stands (or nothing) take the value interpolated between them, where that value keeps their
    target outside the other image, with the smaller of the two ends' plausibility, as
    :data:`SOURCE_TOF_CARRIED`. Those rows had kept LC's answers: the matcher's forced matches
    near 0 px (its only hypotheses there) at plausibility 1 (a 10-row ToF dropout on a rendered
    640 x 360 scene: 34-46 pixels at 0-2 px where the truth is 22-23 px; measured in the
    experiments log, *the band across a ToF dropout*)."""
    _rgbd_rs.bridge_band_across_dropouts(disp, plaus, source, _c(tof), float(sign), BAND_CHAIN_STEP)
