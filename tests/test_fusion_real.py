"""Real scenes as fusion cases (simulated ToF laws on the Middlebury split), the scores the
fusion's knobs are chosen by, and fuse()'s choice of stereo matcher."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError
from rgbd_rs.data import load_stereo_scene
from rgbd_rs.fusion import fuse, sgm
from rgbd_rs.fusion.real_scenes import TOF_SCALE, real_sample, real_samples
from rgbd_rs.fusion.score import score_maps, summarize
from rgbd_rs.nn.confidence import ConfidenceEstimator, ConfidenceNet

FUSE = sys.modules["rgbd_rs.fusion.fuse"]


def test_a_law_is_fixed_per_case_and_redrawn_per_epoch(shared_data: Path) -> None:
    scene = load_stereo_scene("Tsukuba")
    a, b = real_sample(scene, 1), real_sample(scene, 1)
    assert a.name == "Tsukuba_law1"
    np.testing.assert_array_equal(a.tof_depth, b.tof_depth)
    other = real_sample(scene, 1, epoch=3)
    assert not np.array_equal(a.tof_depth, other.tof_depth, equal_nan=True)
    h, w = scene.left.shape[:2]
    for s in (a, other, real_sample(scene, 0)):
        th, tw = s.tof_depth.shape
        # The ToF is coarser than the colour camera: a quarter to a half of its width.
        assert TOF_SCALE[0] * w - 1 <= tw <= TOF_SCALE[1] * w + 1
        assert abs(th / tw - h / w) < 0.05
        assert s.rig.reference == "left"
        np.testing.assert_array_equal(s.gt_disparity, scene.disparity_left)
    names = [s.name for s in real_samples("val", 2)]
    assert len(names) == 12 and names[:2] == ["Baby1_law0", "Baby1_law1"]
    with pytest.raises(InvalidArgumentError, match=r"^split"):
        next(real_samples("dev"))


def test_scores_say_what_the_fusion_did() -> None:
    # Constant disparity 10 on the left view: columns 0-9 are not seen by the right camera.
    gt = np.full((8, 40), 10.0, np.float32)
    tof = gt + 0.2  # good: every pixel within 1 px
    stereo = gt.copy()
    stereo[:, 10:25] += 3.0  # half the visible pixels 3 px off: not good
    stereo[0, 10] = np.nan
    fused = gt + 0.25
    fused[1, 11] = np.nan
    c = score_maps("case", gt, -1, tof, stereo, fused)
    assert c.good == {"tof": True, "stereo": False}
    assert c.pixels == 8 * 30 - 2
    assert c.rms["tof"] == pytest.approx(0.2, abs=1e-5)
    assert c.ratio == pytest.approx(0.25 / 0.2, rel=1e-4)
    assert c.good_ratio == pytest.approx(0.25 / 0.2, rel=1e-4)
    assert c.coverage["union"] == 1.0 and c.coverage["fused"] == pytest.approx(1 - 1 / 240)
    m = summarize([c])
    assert m["worst_good"] == pytest.approx(1.25, rel=1e-4)
    assert m["coverage_gap"] == pytest.approx(1 / 240)
    with pytest.raises(Exception, match="no pixel is valid"):
        score_maps("empty", gt, -1, tof, stereo, np.full_like(gt, np.nan))


def test_fuse_runs_the_matcher_the_network_was_trained_on(shared_data: Path) -> None:
    s = real_sample(load_stereo_scene("Tsukuba"), 0)
    args = (s.left, s.right, s.tof_depth, s.tof_amplitude, s.rig)
    out = fuse(*args, confidence="uniform", stereo="census")
    assert out.stereo_matcher == "census"
    want = sgm(
        s.left,
        s.right,
        reference="left",
        max_disparity=out.max_disparity,
        method="census",
        params=FUSE.FUSION_CENSUS,
    )
    np.testing.assert_array_equal(out.stereo_disparity, want)
    assert fuse(*args, confidence="uniform", stereo="opencv").stereo_matcher == "opencv"
    net = ConfidenceNet(4)
    for matcher in ("census", "opencv"):
        est = ConfidenceEstimator(net, np.ones(4), matcher=matcher)
        assert est.with_stereo_power(2.0).matcher == matcher
        assert fuse(*args, confidence=est).stereo_matcher == matcher
    with pytest.raises(InvalidArgumentError, match=r"^matcher: got 'sgbm'"):
        ConfidenceEstimator(net, np.ones(4), matcher="sgbm")
