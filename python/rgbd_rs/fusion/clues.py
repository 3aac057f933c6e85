"""The four input clues of the confidence ConvNet (thesis §3.6, eq. 3.2-3.6).

For a rectified pair on the reference camera (right, as the thesis; left works too):

- ``Delta_LR = |I_L'/mu_L - I_R/mu_R|`` (eq. 3.2): the grey target image warped onto the
  reference with the stereo disparity (``I_L'``), each image divided by its own mean, absolute
  difference;
- ``D_T``, ``D_S``: the ToF and stereo disparities (pixels) on the reference camera;
- ``A_T``: the ToF amplitude on the reference camera divided by its per-frame median (our
  choice: the thesis divides by a training-set sigma alone, which ties the network to one sensor's
  amplitude unit; the per-frame median makes the clue unit-free, so amplitudes in DN, in 0-1 or in
  any other unit give the same input).

:func:`compute_clues` returns these raw maps; :func:`normalise` divides each by the sigma of eq.
3.3-3.6 (the average over the training scenes of each clue's per-scene standard deviation, stored
in the checkpoint, never hard-coded). Invalid pixels (NaN in any input) become 0 after
normalisation and are flagged in :attr:`Clues.valid`: NaN never reaches the network.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import F32, disparity_map, map2d, rgb8

#: Clue names, in channel order.
NAMES = ("delta_lr", "tof_disparity", "stereo_disparity", "tof_amplitude")


@array_eq
@dataclass(frozen=True)
class Clues:
    """Raw clues ``4 x H x W`` float32 (NaN where undefined) in :data:`NAMES` order."""

    maps: F32

    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """``4 x H x W``: where each clue is defined."""
        return np.isfinite(self.maps)


def _grey(img: np.ndarray) -> F32:
    return np.asarray(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY), dtype=np.float32)


def compute_clues(
    reference_image: npt.ArrayLike,
    target_image: npt.ArrayLike,
    tof_disparity: npt.ArrayLike,
    tof_amplitude: npt.ArrayLike,
    stereo_disparity: npt.ArrayLike,
    *,
    reference: Literal["left", "right"] = "right",
) -> Clues:
    """The raw clues of eq. 3.2 and 3.4-3.6 on the reference camera.

    Args:
        reference_image, target_image: uint8 RGB of the reference camera and the other one.
        tof_disparity, tof_amplitude: the ToF reprojected on the reference (``H x W``, NaN none).
        stereo_disparity: SGM on the reference (``d = u_left - u_right``, NaN none).
        reference: which camera of the pair the maps lie on ("right" as the thesis).
    """
    ref = rgb8("reference_image", reference_image)
    h, w = ref.shape[:2]
    tgt = rgb8("target_image", target_image, (w, h), of="reference_image's size")
    d_t = disparity_map("tof_disparity", tof_disparity, (h, w))
    a_t = map2d("tof_amplitude", tof_amplitude, (h, w))
    d_s = disparity_map("stereo_disparity", stereo_disparity, (h, w))
    side = _validate.choice("reference", reference, ("left", "right"))
    g_r, g_t = _grey(ref), _grey(tgt)
    # Reference pixel x sees the target at x + d (reference right) or x - d (reference left);
    # the elementwise work is native (rgbd_fusion::clues), the same f32 arithmetic as numpy's.
    sign = 1.0 if side == "right" else -1.0
    xs, ys = _rgbd_rs.clue_warp_maps(d_s, sign)
    warped: F32 = np.asarray(
        cv2.remap(g_t, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0),
        dtype=np.float32,
    )
    mu_r = float(g_r.mean()) or 1.0
    mu_t = float(g_t.mean()) or 1.0
    with np.errstate(invalid="ignore"):
        amp_ok = np.isfinite(a_t) & (a_t > 0)
    scale = float(np.median(a_t[amp_ok])) if amp_ok.any() else 1.0
    maps = _rgbd_rs.clue_maps(g_r, warped, xs, d_t, a_t, d_s, mu_r, mu_t, scale)
    return Clues(maps)


def _scene_sigmas(clues: Clues) -> F32:
    """Per-scene standard deviation of each clue over its valid pixels (NaN if none)."""
    out = np.full(len(NAMES), np.nan, np.float32)
    for k in range(len(NAMES)):
        v = clues.maps[k][np.isfinite(clues.maps[k])]
        if v.size > 1:
            out[k] = np.std(v)
    return out


def _training_sigmas(per_scene: npt.ArrayLike) -> F32:
    """Eq. 3.3-3.6's sigma: the average over training scenes of each clue's per-scene std."""
    s = np.asarray(per_scene, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] != len(NAMES) or s.shape[0] == 0:
        raise InvalidArgumentError(
            f"per_scene: got shape {s.shape}, expected (scenes, {len(NAMES)})"
        )
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN column: caught below
        sig = np.nanmean(np.where(s > 0, s, np.nan), axis=0)
    if not np.all(np.isfinite(sig) & (sig > 0)):
        raise InvalidArgumentError(f"per_scene: got sigma {sig.tolist()}, expected positive values")
    return np.asarray(sig, dtype=np.float32)


def _normalise(clues: Clues, sigmas: npt.ArrayLike) -> F32:
    """``4 x H x W`` network input: each clue divided by its sigma, invalid pixels set to 0."""
    sig = _validate.array("sigmas", sigmas, shape=(len(NAMES),), finite=True)
    if np.any(sig <= 0):
        raise InvalidArgumentError(f"sigmas: got {sig.tolist()}, expected positive values")
    maps = np.ascontiguousarray(clues.maps, dtype=np.float32)
    return _rgbd_rs.normalise_clues(maps, sig)


def _target_confidence(disparity: npt.ArrayLike, gt: npt.ArrayLike, threshold: float) -> F32:
    """Training target (thesis §3.7): ``1 - min(|d - gt|, T)/T``; NaN where either is missing.

    The thesis' sentence gives ``min(|err|, T)/T`` (an error, 1 = bad); its figures show bright =
    reliable, so the confidence is one minus that (METHOD_NOTES §3)."""
    d = _validate.asarray("disparity", disparity)
    d = _validate.array("disparity", d, shape=(None,) * d.ndim, allow_empty=True)
    g = _validate.array("gt", gt, shape=d.shape, allow_empty=True)  # same shape: no broadcast
    t = _validate.real("threshold", threshold, positive=True)
    e = np.abs(d - g)
    return np.where(np.isfinite(e), 1 - np.minimum(e, t) / t, np.nan).astype(np.float32)
