"""The whole ToF-stereo pipeline of thesis ch. 3: :func:`fuse`."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import F32, map2d, rgb8, rig_arg, views
from rgbd_rs.fusion.confidence import stereo_confidence, tof_confidence
from rgbd_rs.fusion.lc import LcParams, lc_fuse
from rgbd_rs.fusion.stereo import max_search, sgm
from rgbd_rs.fusion.upsample import ToFOnReference, tof_to_reference
from rgbd_rs.geometry import disparity_to_depth

ConfidenceKind = Literal["uniform", "heuristic"]
#: Disparity search range when the ToF data cannot suggest one (px at the given resolution).
DEFAULT_MAX_DISPARITY = 128
#: Margin over the ToF's 99.9th-percentile disparity when deriving the SGM search range.
RANGE_MARGIN = 1.15


@dataclass(frozen=True)
class FusionResult:
    """Everything :func:`fuse` computed, on the reference camera (``H x W`` float32, NaN = none).

    Attributes:
        disparity, depth: the fused map (pixels, metres).
        plausibility: the LC winner's share of the accumulated plausibility.
        tof: the reprojected and upsampled ToF (depth, disparity, amplitude, segmentation).
        stereo_disparity: the SGM map.
        tof_confidence, stereo_confidence: the weights used (None = uniform).
    """

    disparity: F32
    depth: F32
    plausibility: F32
    tof: ToFOnReference
    stereo_disparity: F32
    tof_confidence: F32 | None
    stereo_confidence: F32 | None


def _max_disparity(tof_disp: F32, width: int, requested: int | None) -> int:
    if requested is not None:
        return _validate.integer("max_disparity", requested, minimum=1, maximum=width - 1)
    # A derived range stays within what SGM can search on this width (sgm() words the error
    # when even the smallest range does not fit).
    top = max(1, min(width - 1, max_search(width)))
    finite = tof_disp[np.isfinite(tof_disp)]
    if finite.size == 0:
        return min(DEFAULT_MAX_DISPARITY, top)
    return int(min(top, max(16, np.ceil(np.percentile(finite, 99.9) * RANGE_MARGIN))))


def fuse(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    tof_depth: npt.ArrayLike,
    tof_amplitude: npt.ArrayLike,
    rig: object,
    *,
    confidence: ConfidenceKind | tuple[npt.ArrayLike, npt.ArrayLike] = "heuristic",
    params: LcParams | None = None,
    max_disparity: int | None = None,
) -> FusionResult:
    """Fuse a ToF frame with a rectified stereo pair into one sub-pixel disparity map.

    Args:
        left, right: the rectified colour pair (uint8 RGB, the rig's image size).
        tof_depth, tof_amplitude: the ToF frame (metres, NaN/<=0 invalid; amplitude >= 0).
        rig: :class:`~rgbd_rs.ToFStereoRig`; the output lies on ``rig.reference_camera``.
        confidence: ``"uniform"`` (equal weights, Dal Mutto 2012), ``"heuristic"``
            (:mod:`rgbd_rs.fusion.confidence`), or ``(tof_conf, stereo_conf)`` maps in [0, 1] on
            the reference camera (e.g. from the confidence ConvNet).
        params: LC constants and window (:class:`LcParams`).
        max_disparity: SGM search range; default from the ToF disparities (x1.15).

    A ToF frame without any valid pixel gives the stereo-only LC result with a warning.
    """
    r = rig_arg(rig)
    size = r.stereo.left.size
    lft = rgb8("left", left, size)
    rgt = rgb8("right", right, size)
    ref_img, tgt_img, sign = views(lft, rgt, r.reference)
    h, w = ref_img.shape[:2]
    # The cheap checks come before the stages run.
    if params is not None and not isinstance(params, LcParams):
        raise InvalidArgumentError(f"params: got {type(params).__name__}, expected LcParams")
    given: tuple[F32, F32] | None = None
    if isinstance(confidence, str):
        kind = _validate.choice("confidence", confidence, ("uniform", "heuristic"))
    elif isinstance(confidence, (tuple, list)) and len(confidence) == 2:
        given = (
            map2d("confidence[0]", confidence[0], (h, w)),
            map2d("confidence[1]", confidence[1], (h, w)),
        )
    else:
        raise InvalidArgumentError(
            f"confidence: got {type(confidence).__name__}, expected 'uniform', 'heuristic' "
            "or a (tof_confidence, stereo_confidence) pair of maps"
        )
    if max_disparity is not None:
        _max_disparity(np.empty(0, np.float32), w, max_disparity)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tof = tof_to_reference(tof_depth, tof_amplitude, r, ref_img)
    no_tof = not np.isfinite(tof.disparity).any()
    if no_tof:
        warnings.warn(
            "tof_depth: no valid ToF pixel reaches the reference camera; returning the "
            "stereo-only LC result",
            RuntimeWarning,
            stacklevel=2,
        )
    elif caught:
        for c in caught:
            warnings.warn(c.message, c.category, stacklevel=2)
    dmax = _max_disparity(tof.disparity, w, max_disparity)
    stereo = sgm(lft, rgt, reference=r.reference, max_disparity=dmax)
    tof_disp = np.where(tof.disparity <= dmax, tof.disparity, np.nan).astype(np.float32)
    if not np.isfinite(stereo).any() and no_tof:
        raise InvalidArgumentError(
            "left/right: stereo matching found no valid disparity and the ToF has none either; "
            "expected textured images or valid ToF data"
        )
    ct: F32 | None
    cs: F32 | None
    if given is not None:
        ct, cs = given
    elif kind == "uniform":
        ct = cs = None
    else:
        ct = tof_confidence(tof_disp, tof.amplitude, r.stereo.baseline, r.stereo.focal)
        cs = stereo_confidence(ref_img, tgt_img, stereo, target_sign=sign, max_disparity=dmax)
    disp, plaus = lc_fuse(
        ref_img, tgt_img, [tof_disp, stereo], [ct, cs], target_sign=sign, params=params
    )
    depth = disparity_to_depth(disp, r.stereo.baseline, r.stereo.focal)
    return FusionResult(disp, depth, plaus, tof, stereo, ct, cs)
