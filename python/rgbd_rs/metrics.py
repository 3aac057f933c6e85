"""Evaluation measures shared by the pipelines: RMS error (the fusion tables' RMS disparity
error), depth-edge alignment. Segmentation's VoI and Rand index join them here."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = ["bad_pixel_rate", "depth_edges", "edge_alignment", "edge_band", "rms_error"]

#: Relative depth step that counts as a depth edge in :func:`edge_alignment` (5 %).
DEPTH_EDGE_REL_STEP = 0.05


def rms_error(
    estimate: npt.ArrayLike, truth: npt.ArrayLike, mask: npt.ArrayLike | None = None
) -> float:
    """Root-mean-square of ``estimate - truth`` over the pixels where both are finite (and
    ``mask`` is true): the RMS disparity error of thesis Table 3.2 for disparity maps.

    Computed in the inputs' float32, so equal inputs give equal figures everywhere. No pixel to
    compare raises :class:`~rgbd_rs.InvalidArgumentError`.
    """
    try:
        ndim = max(np.ndim(estimate), 1)
    except ValueError:  # ragged input: let the validator word the error
        ndim = 1
    e = _validate.array("estimate", estimate, shape=(None,) * ndim)
    t = _validate.array("truth", truth, shape=e.shape)
    keep = np.isfinite(e) & np.isfinite(t)
    if mask is not None:
        m = _validate.asarray("mask", mask)
        if m.dtype != np.bool_:
            raise InvalidArgumentError(f"mask: got dtype {m.dtype}, expected a boolean array")
        if m.shape != e.shape:
            raise ShapeMismatchError(f"mask: got shape {m.shape}, expected {e.shape}")
        keep &= m
    if not keep.any():
        raise InvalidArgumentError(
            "mask: got no pixel where estimate and truth are both finite, expected at least one"
        )
    diff = e[keep] - t[keep]
    return float(np.sqrt(np.mean(diff**2)))


def bad_pixel_rate(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    threshold: float,
    mask: npt.ArrayLike | None = None,
) -> float:
    """Fraction of the compared pixels (both finite, and ``mask``) whose absolute error exceeds
    ``threshold`` (the ">1 px" / ">2 px" bad-pixel rates of stereo benchmarks)."""
    t = _validate.real("threshold", threshold, nonnegative=True)
    e = _validate.array("estimate", estimate, shape=(None, None))
    g = _validate.array("truth", truth, shape=e.shape)
    keep = np.isfinite(e) & np.isfinite(g)
    if mask is not None:
        m = _validate.asarray("mask", mask)
        if m.dtype != np.bool_ or m.shape != e.shape:
            raise ShapeMismatchError(
                f"mask: got {m.dtype} of shape {m.shape}, expected bool of shape {e.shape}"
            )
        keep &= m
    if not keep.any():
        raise InvalidArgumentError(
            "mask: got no pixel where estimate and truth are both finite, expected at least one"
        )
    return float(np.mean(np.abs(e[keep] - g[keep]) > t))


def edge_band(
    depth: npt.ArrayLike, width: int = 2, rel_step: float = DEPTH_EDGE_REL_STEP
) -> npt.NDArray[np.bool_]:
    """Pixels within ``width`` pixels (chessboard distance) of a depth edge of ``depth`` (or of a
    disparity map: a relative step is the same in both). :func:`depth_edges` marks the side with
    the smaller value (the nearer one for depth, the farther for disparity); ``width >= 1``
    covers both sides either way."""
    w = _validate.integer("width", width, maximum=1000)
    edges = depth_edges(depth, rel_step)
    if w == 0:
        return edges
    kernel = np.ones((2 * w + 1, 2 * w + 1), np.uint8)
    return np.asarray(cv2.dilate(edges.astype(np.uint8), kernel) > 0)


def depth_edges(
    depth: npt.ArrayLike, rel_step: float = DEPTH_EDGE_REL_STEP
) -> npt.NDArray[np.bool_]:
    """Pixels whose right or lower neighbour differs in depth by more than ``rel_step`` (relative),
    marked on the nearer side (the occluding contour). Needs both samples valid."""
    d = _validate.array("depth", depth, shape=(None, None))
    rel_step = _validate.real("rel_step", rel_step, positive=True)
    edges = np.zeros(d.shape, bool)
    with np.errstate(invalid="ignore"):
        for a, b, ea, eb in (
            (d[:, :-1], d[:, 1:], edges[:, :-1], edges[:, 1:]),
            (d[:-1, :], d[1:, :], edges[:-1, :], edges[1:, :]),
        ):
            step = np.abs(a - b) > rel_step * np.minimum(a, b)
            ea |= step & (a < b)
            eb |= step & (b < a)
    return edges


def edge_alignment(depth: npt.ArrayLike, image: npt.ArrayLike, max_distance: float = 2.0) -> float:
    """Fraction of depth edges that lie within ``max_distance`` pixels of an image (Canny) edge.

    A registration check: a depth map correctly reprojected onto a colour camera has its
    occluding contours on the colour image's edges.
    """
    d = _validate.array("depth", depth, shape=(None, None))
    img = _validate.asarray("image", image)
    if img.dtype != np.uint8:
        raise InvalidArgumentError(f"image: got dtype {img.dtype}, expected uint8")
    if img.shape[:2] != d.shape or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] < 3):
        raise ShapeMismatchError(
            f"image: got shape {img.shape}, expected {d.shape} or {(*d.shape, 3)} (the depth size)"
        )
    max_distance = _validate.real("max_distance", max_distance, nonnegative=True)
    gray = (
        np.ascontiguousarray(img)
        if img.ndim == 2
        else cv2.cvtColor(np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_RGB2GRAY)
    )
    canny = cv2.Canny(gray, 50, 150)
    dist = cv2.distanceTransform((canny == 0).astype(np.uint8), cv2.DIST_L2, 3)
    edges = depth_edges(d)
    if not edges.any():
        raise InvalidArgumentError("depth: got a map without depth edges, expected at least one")
    return float((dist[edges] <= max_distance).mean())
