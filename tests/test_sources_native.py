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
    BAND_CHAIN_STEP,
    BAND_CONFIRM_GAP,
    SOURCE_LC,
    SOURCE_LC_UNMEASURED,
    SOURCE_NONE,
    SOURCE_STEREO,
    SOURCE_TOF,
    SOURCE_TOF_CARRIED,
    _bridge_band_across_dropouts,
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


def ref_extend_tof_into_band(
    disp: F32,
    plaus: F32,
    source: npt.NDArray[np.uint8],
    tof: F32,
    tof_confidence: F32 | None,
    sign: int,
) -> None:
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


def ref_bridge_band_across_dropouts(
    disp: F32, plaus: F32, source: npt.NDArray[np.uint8], tof: F32, sign: int
) -> None:
    import itertools

    w = disp.shape[1]
    took = source == SOURCE_TOF
    x = np.arange(w, dtype=np.float32)[None, :]
    with np.errstate(invalid="ignore"):
        target = x + np.float32(sign) * disp
        unseen = (target < 0) | (target > w - 1)
    open_ = ~np.isfinite(tof) & np.isin(source, (SOURCE_LC, SOURCE_LC_UNMEASURED, SOURCE_NONE))
    for col in np.flatnonzero((took & unseen).sum(axis=0) >= 2):
        rows = np.flatnonzero(took[:, col])
        for a, b in itertools.pairwise(rows.tolist()):
            if b - a < 2 or not (unseen[a, col] and unseen[b, col]):
                continue
            da, db = disp[a, col], disp[b, col]
            if not abs(db - da) <= np.float32(BAND_CHAIN_STEP * (b - a)):
                continue
            ys = np.arange(a + 1, b)
            v = (da + (db - da) * ((ys - a) / (b - a))).astype(np.float32)
            with np.errstate(invalid="ignore"):
                t = np.float32(col) + np.float32(sign) * v
                keep = open_[ys, col] & ((t < 0) | (t > w - 1))
            ys, v = ys[keep], v[keep]
            disp[ys, col] = v
            plaus[ys, col] = min(plaus[a, col], plaus[b, col])
            source[ys, col] = SOURCE_TOF_CARRIED


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
            (_bridge_band_across_dropouts, ref_bridge_band_across_dropouts, (tof, sign)),
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


def test_the_native_steps_refuse_maps_they_would_misread() -> None:
    from rgbd_rs.errors import RgbdError

    nan = np.nan
    tof = np.array([[nan, 5.0, nan], [nan, nan, nan]], np.float32)
    stereo = np.full((2, 3), nan, np.float32)
    fortran = [np.asfortranarray(np.zeros((2, 3), t)) for t in (np.float32, np.float32, np.uint8)]
    with pytest.raises(RgbdError, match="disparity: got a non-C-contiguous"):
        _unseen_from_tof(*fortran, tof, stereo, None, 1)
    maps = [np.zeros((2, 3), t) for t in (np.float32, np.float32, np.uint8)]
    with pytest.raises(RgbdError, match=r"tof: got shape \[3, 2\]"):
        _carry_tof_to_border(*maps, tof.reshape(3, 2).copy(), None, 1)
    with pytest.raises(RgbdError, match=r"tof: got shape \[3, 2\]"):
        _bridge_band_across_dropouts(*maps, tof.reshape(3, 2).copy(), 1)
    with pytest.raises(RgbdError, match=r"plausibility: got shape \[1, 6\]"):
        _extend_tof_into_band(maps[0], maps[1].reshape(1, 6), maps[2], tof, None, 1)


def test_the_cases_reach_the_bridge_across_dropouts() -> None:
    """The comparison above is not vacuous for the bridge: its cases bridge pixels."""
    bridged = 0
    for sign in (1, -1):
        for seed in range(40):
            lc, lcp, tof, stereo, ct, cs = _case(seed, False)
            got = _fill_single_source(lc, lcp, tof, stereo, ct, cs)
            _unseen_from_tof(*got, tof, stereo, ct, sign)
            _extend_tof_into_band(*got, tof, ct, sign)
            _carry_tof_to_border(*got, tof, ct, sign)
            before = got[2].copy()
            _bridge_band_across_dropouts(*got, tof, sign)
            bridged += int((got[2] != before).sum())
    assert bridged > 100
