"""The steps after LC (rgbd_rs.fusion.sources), now native (rgbd_fusion::sources), against the
numpy code they replaced (kept here as the reference): the same bits in every map, for both
reference views, with and without confidences, the caller's weights and the two-view check, on
maps with holes, bands the other camera cannot see and rows without a ToF pixel."""

# mypy: ignore-errors

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from rgbd_rs.fusion.sources import (
    SOURCE_LC,
    SOURCE_LC_UNMEASURED,
    SOURCE_NONE,
    SOURCE_STEREO,
    SOURCE_TOF,
    SOURCE_TOF_CARRIED,
    _carry_tof_to_border,
    _extend_tof_into_band,
    _fill_single_source,
    _unseen_from_tof,
)

F32 = npt.NDArray[np.float32]


def ref_take(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    take: npt.NDArray[np.bool_],
    value: F32,
    confidence: F32 | None,
    code: int,
) -> None:
    """In place: the ``take`` pixels get ``value``, its ``confidence`` as plausibility (1 for
    uniform weights) and the source ``code``."""
    disp[take] = value[take]
    plaus[take] = 1.0 if confidence is None else confidence[take]
    source[take] = code


def ref_fill_single_source(
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
    disp = lc_disparity.copy()
    plaus = lc_plausibility.copy()
    source = np.where(np.isfinite(disp), SOURCE_LC, SOURCE_NONE).astype(np.uint8)
    source[np.isfinite(disp) & ~np.isfinite(tof) & ~np.isfinite(stereo)] = SOURCE_LC_UNMEASURED
    if cross_check:
        return disp, plaus, source
    empty = ~np.isfinite(disp)
    for value, conf, code in (
        (tof, tof_confidence, SOURCE_TOF),
        (stereo, stereo_confidence, SOURCE_STEREO),
    ):
        take = empty & np.isfinite(value)
        if conf is not None and keep_out_zero:
            take &= conf > 0  # an input the caller's weights rule out stays out
        ref_take(disp, plaus, source, take, value, conf, code)
        empty &= ~take
    return disp, plaus, source


def ref_unseen_from_tof(
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
    w = tof.shape[1]
    with np.errstate(invalid="ignore"):
        target = np.arange(w, dtype=np.float32)[None, :] + np.float32(sign) * tof
        unseen = np.isfinite(tof) & ((target < 0) | (target > w - 1)) & ~np.isfinite(stereo)
        if tof_confidence is not None:
            unseen &= tof_confidence > 0
    ref_take(disp, plaus, source, unseen, tof, tof_confidence, SOURCE_TOF)


def ref_carry_tof_to_border(
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
    h, w = tof.shape
    flip = sign > 0  # scan from the border the other camera cannot see
    t = tof[:, ::-1] if flip else tof
    finite = np.isfinite(t)
    # The strip ends at the row's first ToF pixel; the value carried is the first one the
    # fusion may trust (confidence > 0), which may lie further in.
    first = np.where(finite.any(axis=1), finite.argmax(axis=1), 0)
    if tof_confidence is not None:
        with np.errstate(invalid="ignore"):
            finite &= (tof_confidence[:, ::-1] if flip else tof_confidence) > 0
    has = finite.any(axis=1)
    x0 = np.where(has, finite.argmax(axis=1), 0)
    rows = np.arange(h)
    d0 = t[rows, x0]
    if tof_confidence is None:
        c0 = np.ones(h, np.float32)
    else:
        c0 = (tof_confidence[:, ::-1] if flip else tof_confidence)[rows, x0]
    cols = np.arange(w)[None, :]
    with np.errstate(invalid="ignore"):  # target x - d0 < 0 (mirrored for a right reference)
        strip = (has & (c0 > 0))[:, None] & (cols < first[:, None]) & (cols < d0[:, None])
    if flip:
        strip = strip[:, ::-1]
    r, c = np.nonzero(strip)
    disp[r, c] = d0[r]
    plaus[r, c] = c0[r]
    source[r, c] = SOURCE_TOF_CARRIED


#: Largest step (px) between neighbouring ToF disparities of the chain
#: :func:`_extend_tof_into_band` follows, and largest gap (px) between the ToF and the fused map
#: that confirms its start.
BAND_CHAIN_STEP = 1.0
BAND_CONFIRM_GAP = 1.0


def ref_extend_tof_into_band(
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
    h, w = tof.shape
    flip = sign > 0  # make the border the other camera cannot see column 0 (target x - d)
    t = tof[:, ::-1] if flip else tof
    c = None if tof_confidence is None else (tof_confidence[:, ::-1] if flip else tof_confidence)
    cols = np.arange(w, dtype=np.float32)[None, :]
    with np.errstate(invalid="ignore"):
        seen = np.isfinite(t) & (t <= cols)
    has = seen.any(axis=1)
    x_e = np.where(has, seen.argmax(axis=1), 0)
    rows = np.arange(h)
    # Confirmation: the fused map's first value inside the edge, within the edge pixel's
    # disparity (the band's own width, so the rule does not depend on the image size), took the
    # ToF's value there: LC, which could still weigh both inputs' photometric terms, chose it.
    fused = disp[:, ::-1] if flip else disp
    d_e = np.where(has, t[rows, x_e], 0.0)
    reach = np.ceil(np.nan_to_num(d_e)).astype(np.int64) + 1
    after = (cols >= x_e[:, None]) & (cols < (x_e + reach)[:, None]) & np.isfinite(fused)
    first = np.where(after.any(axis=1), after.argmax(axis=1), 0)
    with np.errstate(invalid="ignore"):
        confirmed = (
            has
            & after.any(axis=1)
            & (np.abs(t[rows, first] - fused[rows, first]) <= BAND_CONFIRM_GAP)
        )
        # step[x]: pixel x continues the chain from x + 1 (within the step, confidence > 0).
        step = np.abs(t[:, :-1] - t[:, 1:]) <= BAND_CHAIN_STEP
        if c is not None:
            step &= c[:, :-1] > 0
    inside = cols[:, :-1] < x_e[:, None]
    broken = inside & ~step
    # The chain starts after the last break below the edge (or at column 0).
    last_break = np.where(broken.any(axis=1), w - 2 - np.argmax(broken[:, ::-1], axis=1), -1)
    start = last_break + 1
    take = confirmed[:, None] & (cols >= start[:, None]) & (cols < x_e[:, None])
    if flip:
        take = take[:, ::-1]
    ref_take(disp, plaus, source, take, tof, tof_confidence, SOURCE_TOF)


def _case(seed: int, with_conf: bool):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 30)), int(rng.integers(2, 60))  # fuse() needs w >= 2
    base = rng.uniform(0, w * 0.6, (h, 1)).astype(np.float32) + rng.normal(0, 0.4, (h, w)).astype(
        np.float32
    )
    tof = base.copy()
    tof[rng.random((h, w)) < 0.15] = np.nan
    tof[rng.random(h) < 0.2, :] = np.nan  # rows without a ToF pixel
    tof[:, : int(rng.integers(0, 6))] = np.nan  # the ToF stops short of a border
    tof[rng.random((h, w)) < 0.05] += np.float32(5)  # breaks in the chain
    if seed % 3 == 0:
        tof = np.round(tof)  # whole disparities: the strip's and the band's edges exactly
    stereo = (base + rng.normal(0, 1.5, (h, w))).astype(np.float32)
    stereo[rng.random((h, w)) < 0.3] = np.nan
    lc = (base + rng.normal(0, 0.8, (h, w))).astype(np.float32)
    lc[rng.random((h, w)) < 0.25] = np.nan
    lcp = rng.uniform(0, 1, (h, w)).astype(np.float32)
    ct = cs = None
    if with_conf:
        ct = rng.uniform(0, 1, (h, w)).astype(np.float32)
        ct[rng.random((h, w)) < 0.2] = 0
        ct[rng.random((h, w)) < 0.05] = np.nan
        cs = rng.uniform(0, 1, (h, w)).astype(np.float32)
        cs[rng.random((h, w)) < 0.2] = 0
    return lc, lcp, tof, stereo, ct, cs


@pytest.mark.parametrize("with_conf", [False, True])
@pytest.mark.parametrize("sign", [1, -1])
def test_native_steps_equal_the_numpy_code(with_conf: bool, sign: int) -> None:
    kinds = set()
    for seed in range(40):
        lc, lcp, tof, stereo, ct, cs = _case(seed, with_conf)
        for keep_out_zero in (False, True):
            for cross_check in (False, True):
                got = _fill_single_source(
                    lc,
                    lcp,
                    tof,
                    stereo,
                    ct,
                    cs,
                    keep_out_zero=keep_out_zero,
                    cross_check=cross_check,
                )
                want = ref_fill_single_source(
                    lc,
                    lcp,
                    tof,
                    stereo,
                    ct,
                    cs,
                    keep_out_zero=keep_out_zero,
                    cross_check=cross_check,
                )
                _same(got, want)
        got = _fill_single_source(lc, lcp, tof, stereo, ct, cs)
        want = ref_fill_single_source(lc, lcp, tof, stereo, ct, cs)
        for step, ref, args in (
            (_unseen_from_tof, ref_unseen_from_tof, (tof, stereo, ct, sign)),
            (_extend_tof_into_band, ref_extend_tof_into_band, (tof, ct, sign)),
            (_carry_tof_to_border, ref_carry_tof_to_border, (tof, ct, sign)),
        ):
            step(*got, *args)
            ref(*want, *args)
            _same(got, want)
        kinds |= set(np.unique(got[2]).tolist())
    # The cases reach every source the steps write.
    assert {SOURCE_NONE, SOURCE_LC, SOURCE_TOF, SOURCE_TOF_CARRIED, SOURCE_LC_UNMEASURED} <= kinds
    assert with_conf or SOURCE_STEREO in kinds


def _same(got, want) -> None:
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape
        np.testing.assert_array_equal(g, w)
        if g.dtype == np.float32:
            np.testing.assert_array_equal(np.isnan(g), np.isnan(w))
            np.testing.assert_array_equal(
                np.nan_to_num(g).view(np.uint32), np.nan_to_num(w).view(np.uint32)
            )
