"""Stage 3 without a network: deterministic ToF and stereo confidences in [0, 1].

These follow the structure of Marin et al. ECCV 2016 ([64]; METHOD_NOTES §2) whose exact
formulas could not be read, so every formula and threshold here is our approximation:

- ToF: ``P_T = P_AI * P_LV``. ``P_AI`` maps the disparity noise predicted from the amplitude by
  the CW-ToF noise law (I/Q noise ``sigma^2 = read^2 + shot * (A + ambient)``, phase noise
  ``sigma / A``, depth noise ``c / (4 pi f) * sigma / A``, disparity noise ``b f sigma_z / z^2``)
  linearly to [0, 1] between ``SIGMA_D_MIN`` and ``SIGMA_D_MAX``; ``P_LV`` falls linearly with the
  local standard deviation of the ToF disparity (mixed pixels at edges, multipath ramps).
- Stereo: ``P_S = P_peak * P_glob``: the peak ratio ``(c2 - c1) / c2`` of the pointwise cost
  curve (c1 best, c2 second best away from it) times the agreement ``c1 / c(d_SGM)`` of the
  SGM-optimised choice with the pointwise minimum.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.fusion._inputs import F32
from rgbd_rs.fusion.stereo import cost_curve_stats

#: ToF noise model defaults: those of :class:`rgbd_rs.render.ToFModel` (set them from your
#: sensor's noise model for real data).
READ_NOISE = 2.0
SHOT_NOISE = 0.4
AMBIENT = 10.0
FREQUENCY_HZ = 120e6
#: Predicted disparity noise mapped to confidence 1 (below) ... 0 (above), pixels. Chosen.
SIGMA_D_MIN = 0.05
SIGMA_D_MAX = 1.0
#: Local-variation term: window (px) and the disparity std (px) at which it reaches 0. Chosen.
LV_WINDOW = 5
LV_TAU = 1.5
#: Additive guard of the cost ratios (grey levels).
COST_EPS = 1.0
_C = 299_792_458.0


def tof_confidence(
    disparity: npt.ArrayLike,
    amplitude: npt.ArrayLike,
    baseline: float,
    focal: float,
    *,
    read_noise: float = READ_NOISE,
    shot_noise: float = SHOT_NOISE,
    ambient: float = AMBIENT,
    frequency_hz: float = FREQUENCY_HZ,
) -> F32:
    """Heuristic ToF confidence ``P_AI * P_LV`` on the reference lattice (0 where no ToF)."""
    d = np.asarray(_validate.array("disparity", disparity, shape=(None, None)), np.float32)
    a = np.asarray(_validate.array("amplitude", amplitude, shape=d.shape), np.float32)
    b = _validate.real("baseline", baseline, positive=True)
    f = _validate.real("focal", focal, positive=True)
    fm = _validate.real("frequency_hz", frequency_hz, positive=True)
    read_noise = _validate.real("read_noise", read_noise, nonnegative=True)
    shot_noise = _validate.real("shot_noise", shot_noise, nonnegative=True)
    ambient = _validate.real("ambient", ambient, nonnegative=True)
    ok = np.isfinite(d) & (d > 0) & np.isfinite(a) & (a > 0)
    z = np.where(ok, b * f / np.where(ok, d, 1), np.nan)
    amp = np.where(ok, a, np.nan)
    sigma = np.sqrt(read_noise**2 + shot_noise * (amp + ambient))
    sigma_z = _C / (4 * math.pi * fm) * sigma / amp
    sigma_d = b * f * sigma_z / (z * z)
    p_ai = np.clip((SIGMA_D_MAX - sigma_d) / (SIGMA_D_MAX - SIGMA_D_MIN), 0, 1)
    p_lv = np.clip(1 - _local_std(d, LV_WINDOW) / LV_TAU, 0, 1)
    return np.where(ok, p_ai * p_lv, 0).astype(np.float32)


def _local_std(d: F32, window: int) -> F32:
    """Standard deviation over a ``window`` box of the finite values (NaN-aware)."""
    ok = np.isfinite(d).astype(np.float32)
    v = np.where(ok > 0, d, 0).astype(np.float32)
    k = (window, window)
    n = cv2.boxFilter(ok, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
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
