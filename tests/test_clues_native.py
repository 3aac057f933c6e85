"""The confidence ConvNet's clues, computed natively (rgbd_fusion::clues), against the numpy
arithmetic they replaced: the same bits, NaN included, for both reference views, maps with
holes, warps leaving the image, and amplitudes that are zero, NaN or missing."""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
import pytest

from rgbd_rs.fusion.clues import Clues, _normalise, compute_clues


def _numpy_clues(  # type: ignore[no-untyped-def]
    ref, tgt, d_t, a_t, d_s, reference
) -> np.ndarray:
    """compute_clues as it was written in numpy (the reference)."""
    g_r = np.asarray(cv2.cvtColor(ref, cv2.COLOR_RGB2GRAY), dtype=np.float32)
    g_t = np.asarray(cv2.cvtColor(tgt, cv2.COLOR_RGB2GRAY), dtype=np.float32)
    h, w = g_r.shape
    sign = 1.0 if reference == "right" else -1.0
    xs = np.arange(w, dtype=np.float32)[None, :] + sign * d_s
    ys = np.broadcast_to(np.arange(h, dtype=np.float32)[:, None], (h, w))
    ok = np.isfinite(xs) & (xs >= 0) & (xs <= w - 1)
    warped = cv2.remap(
        g_t,
        np.where(ok, xs, -1).astype(np.float32),
        np.ascontiguousarray(ys),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    mu_r = float(g_r.mean()) or 1.0
    mu_t = float(g_t.mean()) or 1.0
    delta = np.where(ok, np.abs(warped / mu_t - g_r / mu_r), np.nan)
    with np.errstate(invalid="ignore"):
        amp_ok = np.isfinite(a_t) & (a_t > 0)
    scale = float(np.median(a_t[amp_ok])) if amp_ok.any() else 1.0
    amp = np.where(amp_ok & np.isfinite(d_t), a_t / scale, np.nan)
    return np.stack([delta, d_t, d_s, amp]).astype(np.float32)


def _case(seed: int, amplitude: str):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(3, 40)), int(rng.integers(3, 70))
    ref = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    tgt = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    d_s = rng.uniform(-2, w / 2, (h, w)).astype(np.float32)
    d_s[rng.random((h, w)) < 0.2] = np.nan
    d_t = rng.uniform(0, w / 2, (h, w)).astype(np.float32)
    d_t[rng.random((h, w)) < 0.3] = np.nan
    a_t = rng.uniform(0, 3000, (h, w)).astype(np.float32)
    a_t[rng.random((h, w)) < 0.2] = np.nan
    a_t[rng.random((h, w)) < 0.1] = 0
    if amplitude == "none":
        a_t[:] = np.nan
    return ref, tgt, d_t, a_t, d_s


@pytest.mark.parametrize("amplitude", ["some", "none"])
@pytest.mark.parametrize("reference", ["right", "left"])
def test_native_clues_equal_the_numpy_arithmetic(
    amplitude: str, reference: Literal["left", "right"]
) -> None:
    for seed in range(6):
        ref, tgt, d_t, a_t, d_s = _case(seed, amplitude)
        got = compute_clues(ref, tgt, d_t, a_t, d_s, reference=reference).maps
        want = _numpy_clues(ref, tgt, d_t, a_t, d_s, reference)
        assert got.dtype == np.float32 and got.shape == want.shape
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
        assert np.isfinite(got[0]).any() and np.isnan(got[0]).any()


def test_native_normalisation_equals_the_numpy_arithmetic() -> None:
    ref, tgt, d_t, a_t, d_s = _case(3, "some")
    clues = compute_clues(ref, tgt, d_t, a_t, d_s)
    sigmas = np.array([0.3, 7.5, 11.0, 0.9], np.float32)
    x = clues.maps / sigmas[:, None, None]
    want = np.where(np.isfinite(x), x, 0).astype(np.float32)
    got = _normalise(clues, sigmas)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    # A strided (non-contiguous) stack of clues is read the same way.
    wide = np.concatenate([clues.maps, clues.maps], axis=2)[:, :, ::2]
    np.testing.assert_array_equal(
        _normalise(Clues(wide), sigmas),
        np.where(np.isfinite(wide / sigmas[:, None, None]), wide / sigmas[:, None, None], 0),
    )


def test_normalisation_wants_one_map_per_sigma() -> None:
    from rgbd_rs.errors import RgbdError

    with pytest.raises(RgbdError, match=r"expected \(4, H, W\): one map per sigma"):
        _normalise(Clues(np.ones((2, 4, 4), np.float32)), np.ones(4, np.float32))
