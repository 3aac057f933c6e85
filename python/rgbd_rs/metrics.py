"""Evaluation measures shared by the pipelines."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError

#: Relative depth step that counts as a depth edge in :func:`edge_alignment` (5 %).
DEPTH_EDGE_REL_STEP = 0.05


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
    img = np.asarray(image)
    if img.shape[:2] != d.shape:
        raise InvalidArgumentError(f"image: got shape {img.shape}, expected size {d.shape}")
    gray = (
        img
        if img.ndim == 2
        else cv2.cvtColor(np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_RGB2GRAY)
    )
    canny = cv2.Canny(gray.astype(np.uint8), 50, 150)
    dist = cv2.distanceTransform((canny == 0).astype(np.uint8), cv2.DIST_L2, 3)
    edges = depth_edges(d)
    if not edges.any():
        raise InvalidArgumentError("depth: got a map without depth edges, expected at least one")
    return float((dist[edges] <= max_distance).mean())
