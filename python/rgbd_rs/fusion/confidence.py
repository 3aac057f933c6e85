"""Stage 3 without a network: deterministic ToF and stereo confidences in [0, 1].

These follow the structure of Marin et al. ECCV 2016 ([64]; METHOD_NOTES §2) whose exact
formulas could not be read, so every formula and threshold here is our approximation:

- ToF: ``P_T = P_AI * P_LV``. ``P_AI`` comes from the disparity noise the CW-ToF noise law
  predicts from the amplitude (I/Q noise ``sigma^2 = read^2 + shot * (A + ambient)``, phase and
  depth noise ``~ sigma / A``, disparity noise ``~ d^2 sigma / A``), taken *relative to the
  frame's median prediction* — the per-scene normalisation the thesis applies to its clues
  (eq. 3.2-3.6) — and mapped linearly to [0, 1] between ``NOISE_RATIO_MIN`` and
  ``NOISE_RATIO_MAX``. The ratio carries no unit: scaling the amplitude (with the noise terms,
  which share its unit) by any factor leaves ``P_AI`` unchanged, and the modulation frequency,
  baseline and focal length cancel. The absolute noise level, which the amplitude alone cannot
  tell without a sensor calibration, is what ``P_LV`` measures: it falls linearly with the local
  standard deviation of the ToF disparity in pixels (noise, mixed pixels at edges, multipath
  ramps).
- Stereo: ``P_S = P_peak * P_glob``: the peak ratio ``(c2 - c1) / c2`` of the pointwise cost
  curve (c1 best, c2 second best away from it) times the agreement ``c1 / c(d_SGM)`` of the
  SGM-optimised choice with the pointwise minimum.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import F32
from rgbd_rs.fusion.stereo import cost_curve_stats

#: ToF noise law defaults, in the amplitude's own unit: no read noise and no ambient light, i.e.
#: the pure shot-noise law (phase noise ~ 1 / sqrt(A)), which needs no unit. Give your sensor's
#: terms in its amplitude unit to refine it.
READ_NOISE = 0.0
SHOT_NOISE = 1.0
AMBIENT = 0.0
#: Predicted disparity noise, as a multiple of the frame's median prediction, mapped to
#: confidence 1 (below ``NOISE_RATIO_MIN``) ... 0 (above ``NOISE_RATIO_MAX``). Chosen: a pixel
#: twice as noisy as the frame's typical one is still fully trusted; one twenty times as noisy
#: (a shot-noise-limited pixel with 1/400 of the typical amplitude at the same depth) not at all.
NOISE_RATIO_MIN = 2.0
NOISE_RATIO_MAX = 20.0
#: Local-variation term: window (px) and the disparity std (px) at which it reaches 0. Chosen.
LV_WINDOW = 5
LV_TAU = 1.5
#: Additive guard of the cost ratios (grey levels).
COST_EPS = 1.0


#: The largest noise-law term tof_confidence takes (its squares stay finite in float64).
MAX_NOISE_TERM = 1e100


def tof_confidence(
    disparity: npt.ArrayLike,
    amplitude: npt.ArrayLike,
    *,
    read_noise: float = READ_NOISE,
    shot_noise: float = SHOT_NOISE,
    ambient: float = AMBIENT,
) -> F32:
    """Heuristic ToF confidence ``P_AI * P_LV`` on the reference lattice (0 where no ToF).

    Args:
        disparity: the ToF disparity on the reference camera (pixels, NaN = none).
        amplitude: the ToF amplitude on the same lattice, in any unit (NaN or <= 0 = none).
        read_noise, shot_noise, ambient: the I/Q noise law ``read^2 + shot * (A + ambient)`` in
            the amplitude's unit (default: pure shot noise, unit-free).

    ``P_AI`` depends on the amplitude only through ratios to the frame's own statistics, so any
    unit of the amplitude gives the same map (see the module docstring).
    """
    d = np.asarray(_validate.array("disparity", disparity, shape=(None, None)), np.float32)
    a = np.asarray(_validate.array("amplitude", amplitude, shape=d.shape), np.float32)
    read_noise = _validate.real("read_noise", read_noise, nonnegative=True)
    shot_noise = _validate.real("shot_noise", shot_noise, nonnegative=True)
    ambient = _validate.real("ambient", ambient, nonnegative=True)
    for name, v in (("read_noise", read_noise), ("shot_noise", shot_noise), ("ambient", ambient)):
        if v > MAX_NOISE_TERM:  # squared or multiplied by amplitudes below: keep it finite
            raise InvalidArgumentError(f"{name}: got {v}, expected at most {MAX_NOISE_TERM:g}")
    if read_noise == 0 and shot_noise == 0:
        raise InvalidArgumentError(
            "read_noise/shot_noise: got 0 and 0, expected at least one positive noise term"
        )
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(d) & (d > 0) & np.isfinite(a) & (a > 0)
    p_ai = np.zeros(d.shape, np.float32)
    if ok.any():
        # float64: the amplitude may be in any unit (1e-4 ... 1e8 and beyond).
        amp = a[ok].astype(np.float64)
        disp = d[ok].astype(np.float64)
        # The law's constant factors (c / 4 pi f_mod, 1 / (b f)) cancel in the ratio.
        noise = disp * disp * np.sqrt(read_noise**2 + shot_noise * (amp + ambient)) / amp
        ratio = noise / np.median(noise)
        span = NOISE_RATIO_MAX - NOISE_RATIO_MIN
        p_ai[ok] = np.clip((NOISE_RATIO_MAX - ratio) / span, 0, 1)
    p_lv = np.clip(1 - _local_std(d, LV_WINDOW) / LV_TAU, 0, 1)
    return np.where(ok, p_ai * p_lv, 0).astype(np.float32)


#: Largest magnitude whose square (times a window's count) stays well inside float32.
_SQUARE_SAFE = 1e15


def _local_std(d: F32, window: int) -> F32:
    """Standard deviation over a ``window`` box of the finite values (NaN-aware); in float64
    where the squares would overflow float32 (disparities beyond :data:`_SQUARE_SAFE`)."""
    ok = np.isfinite(d)
    wide = bool(ok.any()) and float(np.max(np.abs(d[ok]))) > _SQUARE_SAFE
    dtype: type[np.floating[Any]] = np.float64 if wide else np.float32
    v: npt.NDArray[np.floating[Any]] = np.where(ok, d, 0).astype(dtype)
    k = (window, window)
    n = cv2.boxFilter(ok.astype(dtype), -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
    s1 = cv2.boxFilter(v, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
    s2 = cv2.boxFilter(v * v, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
    n = np.maximum(n, 1)
    var = np.maximum(s2 / n - (s1 / n) ** 2, 0)
    return np.asarray(np.sqrt(var), np.float32)


def stereo_confidence(
    reference_image: npt.ArrayLike,
    target_image: npt.ArrayLike,
    disparity: npt.ArrayLike,
    *,
    target_sign: int = 1,
    max_disparity: int = 128,
) -> F32:
    """Heuristic stereo confidence ``P_peak * P_glob`` (0 where the stereo map is NaN)."""
    c1, c2, at = cost_curve_stats(
        reference_image,
        target_image,
        disparity,
        target_sign=target_sign,
        max_disparity=max_disparity,
    )
    with np.errstate(invalid="ignore"):
        p_peak = np.where(np.isinf(c2), 1.0, (c2 - c1) / (c2 + COST_EPS))
        p_glob = (c1 + COST_EPS) / (at + COST_EPS)
        p = np.clip(p_peak, 0, 1) * np.clip(p_glob, 0, 1)
    return np.where(np.isfinite(p), p, 0).astype(np.float32)
