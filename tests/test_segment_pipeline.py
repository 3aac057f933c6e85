"""The segmentation pipeline end to end on a real NYUv2 frame, and `rgbd segment`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.cli import main
from rgbd_rs.data import NYUV2_CAMERA, data_root, load_nyuv2_frame
from rgbd_rs.metrics import variation_of_information
from rgbd_rs.segmentation.pipeline import segment

pytestmark = pytest.mark.skipif(data_root() is None, reason="shared data not found")


@pytest.fixture(scope="module")
def frame():  # type: ignore[no-untyped-def]
    return load_nyuv2_frame(1)


@pytest.fixture(scope="module")
def result(frame):  # type: ignore[no-untyped-def]
    return segment(frame.rgb, frame.depth, NYUV2_CAMERA, n_segments=150)


def test_stages_and_shapes(frame, result) -> None:  # type: ignore[no-untyped-def]
    assert result.over.shape == result.labels.shape == frame.depth.shape
    assert list(result.seconds) == ["features", "oversegment", "fits", "merge"]
    n_over = np.unique(result.over[result.over >= 0]).size
    assert n_over >= 100
    assert 2 <= result.merge.n_segments < n_over, "the merging joins segments"
    assert result.merge.mode == "fit" and result.semantic is None
    # Final segments are unions of over-segments.
    pairs = np.unique(np.stack([result.over.ravel(), result.labels.ravel()]), axis=1)
    assert np.unique(pairs[0]).size == pairs.shape[1]
    np.testing.assert_array_equal(result.fits.labels(), result.labels)


def test_merging_moves_toward_the_ground_truth(frame, result) -> None:  # type: ignore[no-untyped-def]
    from rgbd_rs.data import region_ground_truth

    gt = region_ground_truth(frame.label40)
    over = variation_of_information(result.over, gt)
    merged = variation_of_information(result.labels, gt)
    assert merged < over, (over, merged)


def test_deterministic(frame, result) -> None:  # type: ignore[no-untyped-def]
    again = segment(frame.rgb, frame.depth, NYUV2_CAMERA, n_segments=150)
    np.testing.assert_array_equal(again.labels, result.labels)


def test_cli_writes_labels_overlay_and_frames(tmp_path: Path) -> None:
    root = data_root()
    assert root is not None
    f = root / "nyuv2" / "frames"
    calib = Path(__file__).parents[1] / "examples" / "nyu_camera.json"
    out = tmp_path / "seg"
    argv = ["segment", "--rgb", str(f / "0001_rgb.png"), "--depth", str(f / "0001_depth.png")]
    argv += ["--calib", str(calib), "--out", str(out), "--segments", "60", "--frames", "10"]
    assert main([*argv, "--quiet"]) == 0
    labels = np.load(out / "labels.npy")
    assert labels.shape == (480, 640)
    for name in ("labels.png", "overlay.png", "segments.png", "over.npy", "merge/0000.png"):
        assert (out / name).exists(), name
