"""segment()'s seam test scales its knot spacing with the frame's larger side (16 px at NYUv2's
640), so a frame and its half-resolution copy test seams over the same share of a segment."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.segmentation import segment
from rgbd_rs.surface import DEFAULT_TEST_SPACING

pipeline = sys.modules["rgbd_rs.segmentation.pipeline"]
merge = sys.modules["rgbd_rs.segmentation.merge"]


def test_spacing_in_proportion_to_the_larger_side() -> None:
    assert merge._seam_spacing((480, 640)) == DEFAULT_TEST_SPACING == 16.0
    assert merge._seam_spacing((640, 480)) == 16.0  # portrait: the same frame turned
    assert merge._seam_spacing((240, 320)) == 8.0
    assert merge._seam_spacing((720, 1280)) == 32.0
    assert merge._seam_spacing((6, 8)) == 1.0  # never below a pixel


@pytest.mark.parametrize("width", [64, 96])
def test_segment_passes_it_to_the_fits(monkeypatch: pytest.MonkeyPatch, width: int) -> None:
    seen: list[float] = []
    real = pipeline.SegmentFits

    def spy(*args: Any, **kwargs: Any) -> Any:
        seen.append(kwargs["test_spacing"])
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "SegmentFits", spy)
    h = width * 3 // 4
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (h, width, 3), dtype=np.uint8)
    _, xx = np.mgrid[0:h, 0:width]
    depth = (2.0 + 0.01 * xx + 0.5 * (xx > width // 2)).astype(np.float32)
    cam = PinholeCamera(0.8 * width, 0.8 * width, width / 2, h / 2, width, h)
    segment(rgb, depth, cam, labeler=None, n_segments=12, quiet=True)
    assert seen == [16.0 * width / 640]
