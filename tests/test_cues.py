"""The nine cues of the semantic ConvNet (eq. 4.2) on a real NYUv2 frame."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs.data import NYUV2_CAMERA, data_root, load_nyuv2_frame
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.segmentation.cues import CHANNELS, SemanticCues, cue_maps, semantic_cues
from rgbd_rs.segmentation.features import features
from rgbd_rs.segmentation.oversegment import oversegment
from rgbd_rs.surface import SegmentFits

pytestmark = pytest.mark.skipif(data_root() is None, reason="shared data not found")

CAM = NYUV2_CAMERA.scaled(0.5)


@pytest.fixture(scope="module")
def frame():  # type: ignore[no-untyped-def]
    f = load_nyuv2_frame(1)
    rgb = np.ascontiguousarray(f.rgb[::2, ::2])
    depth = np.ascontiguousarray(f.depth[::2, ::2])
    depth[100:140, 40:90] = np.nan  # a hole
    return rgb, depth


@pytest.fixture(scope="module")
def cues(frame) -> SemanticCues:  # type: ignore[no-untyped-def]
    return cue_maps(*frame, CAM, n_segments=80)


def test_stack_layout_and_ranges(frame, cues) -> None:  # type: ignore[no-untyped-def]
    s = cues.stack()
    assert s.shape == (len(CHANNELS), 240, 320) and s.dtype == np.float32
    np.testing.assert_allclose(s[0:3], np.moveaxis(frame[0], -1, 0) / 255, atol=1e-6)
    assert s[:6].min() >= 0 and s[:6].max() <= 1
    assert np.isfinite(s).all()
    hole = np.isnan(frame[1])
    assert (s[6:, hole] == 0).all(), "no depth, no fitting cue"
    assert (s[6][~hole] >= 0).all() and np.count_nonzero(s[6][~hole]) > 0.9 * (~hole).sum()
    assert (s[7] >= s[8]).all(), "c1 >= c2"


def test_clipped_at_the_frame_percentile(cues) -> None:  # type: ignore[no-untyped-def]
    for group in ((cues.error,), (cues.k1, cues.k2)):
        a = np.concatenate([np.abs(v[v != 0]) for v in group])
        top = a.max()
        assert (a >= top * (1 - 1e-6)).mean() >= 0.005, "about 1 % of the values sit at the clip"


def test_walls_are_flat(cues) -> None:  # type: ignore[no-untyped-def]
    # The large wall of frame 1 (upper left) is a plane: curvature far below the frame's tail.
    wall = (slice(20, 80), slice(20, 120))
    assert np.median(np.abs(cues.k1[wall])) < 0.1 * np.abs(cues.k1).max()


def test_precomputed_parts_give_the_same_cues(frame, cues) -> None:  # type: ignore[no-untyped-def]
    f = features(*frame, CAM)
    over = oversegment(f.vectors, 80, seed=0, quiet=True)
    np.testing.assert_array_equal(over, cues.over)
    fits = SegmentFits(f.points, over)
    again = cue_maps(*frame, CAM, feats=f, over=over, fits=fits, hha_image=cues.hha)
    np.testing.assert_array_equal(again.stack(), cues.stack())


def test_semantic_cues_is_the_stack(frame, cues) -> None:  # type: ignore[no-untyped-def]
    np.testing.assert_array_equal(semantic_cues(*frame, CAM, n_segments=80), cues.stack())


def test_bad_parts(frame, cues) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ShapeMismatchError, match="over"):
        cue_maps(*frame, CAM, over=cues.over[:10])
    with pytest.raises(InvalidArgumentError, match="fits"):
        cue_maps(*frame, CAM, over=cues.over, fits="x")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match="feats"):
        cue_maps(*frame, CAM, feats=3)  # type: ignore[arg-type]
