"""The merging's metric defaults (the depth step T_D in metres, the seam test's Kinect noise law
in 1/m) refuse points in millimetres; given in the points' unit, they give the same merging
(units invariance, on a real NYUv2 frame)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.segmentation import merge_regions
from rgbd_rs.segmentation.merge import T_D
from rgbd_rs.surface import KINECT_V1_NOISE_SCALE, SegmentFits


def _frame(shared_data: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points (metres) and a 12 x 16-block over-segmentation of a crop of NYUv2 frame 0001."""
    from rgbd_rs.data.nyuv2 import load_nyuv2_frame

    frame = load_nyuv2_frame(1)
    pts = frame.camera.depth_to_points(frame.depth)[200:296, 240:368]
    h, w = pts.shape[:2]
    labels = (np.arange(h)[:, None] // 12) * 100 + np.arange(w)[None, :] // 16
    return np.ascontiguousarray(pts, np.float32), labels.astype(np.int32)


def test_millimetres_with_their_constants_merge_alike(shared_data: Path) -> None:
    pts, labels = _frame(shared_data)
    metres = merge_regions(labels, pts)
    assert len(metres.history) > 0
    mm = pts * 1000
    with pytest.raises(InvalidArgumentError, match=r"^points: .*look like millimetres"):
        merge_regions(labels, mm)
    # sigma = a z^2: in millimetres a / 1000
    fits = SegmentFits(
        mm,
        labels,
        noise_scale=KINECT_V1_NOISE_SCALE / 1000,
        surfaces=False,
    )
    same = merge_regions(labels, mm, fits=fits, max_depth_step=T_D * 1000)
    np.testing.assert_array_equal(same.labels, metres.labels)
