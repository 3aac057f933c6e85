"""The cross-check of eq. 2.18, in its left-right-consistency form (optional, off by default).

Eq. 2.18 multiplies the reference-view accumulation by the target view's, ``Ω^T(p_T, -d)``.
Keeping ``Ω^T`` for every bin of every target pixel would cost O(pixels x bins), so we check the
two views' *decisions* instead: every source is forward-warped to the target view (z-buffered:
the nearest surface wins), the same LC accumulation runs there with the roles of the images
swapped, and a reference pixel keeps its fused disparity only if the target view's fused
disparity at ``p + s d`` agrees within ``CROSS_CHECK_TOL`` pixels. Twice the LC time; the
rejected pixels become NaN (lower density).
"""

from __future__ import annotations

import numpy as np

from rgbd_rs import _validate
from rgbd_rs.fusion._inputs import F32

#: Agreement (px) between the two views' fused disparities. Chosen.
CROSS_CHECK_TOL = 1.0


def _warp_to_target(disparity: F32, confidence: F32 | None, sign: int) -> tuple[F32, F32 | None]:
    """Forward-warp a reference-view map (and its confidence) to the target view, nearest wins."""
    h, w = disparity.shape
    ys, xs = np.nonzero(np.isfinite(disparity))
    d = disparity[ys, xs]
    tx = np.rint(xs + sign * d).astype(np.int64)
    keep = (tx >= 0) & (tx < w)
    ys, xs, d, tx = ys[keep], xs[keep], d[keep], tx[keep]
    zbuf = np.full((h, w), -np.inf, np.float32)
    np.maximum.at(zbuf, (ys, tx), d)
    win = d >= zbuf[ys, tx]
    out = np.full((h, w), np.nan, np.float32)
    out[ys[win], tx[win]] = d[win]
    conf = None
    if confidence is not None:
        conf = np.zeros((h, w), np.float32)
        conf[ys[win], tx[win]] = confidence[ys[win], xs[win]]
    return out, conf


def _consistent(reference: F32, target: F32, sign: int, tol: float = CROSS_CHECK_TOL) -> F32:
    """``reference`` with NaN where the target view's disparity at ``x + s d`` disagrees."""
    reference = _validate.array("reference", reference, shape=(None, None))
    target = _validate.array("target", target, shape=reference.shape)
    sign = _validate.sign("sign", sign)
    tol = _validate.real("tol", tol, nonnegative=True)
    h, w = reference.shape
    ys, xs = np.nonzero(np.isfinite(reference))
    tx = np.rint(xs + sign * reference[ys, xs]).astype(np.int64)
    ok = (tx >= 0) & (tx < w)
    agree = np.zeros(ys.shape, bool)
    agree[ok] = np.abs(target[ys[ok], tx[ok]] - reference[ys[ok], xs[ok]]) <= tol
    out = np.full((h, w), np.nan, np.float32)
    out[ys[agree], xs[agree]] = reference[ys[agree], xs[agree]]
    return out
