"""rgbd_rs.data.nyuv2 on the shared NYU Depth v2 frames: listing and splits, shapes, dtypes and
units, the camera, and the region ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.data import (
    LABEL13_NAMES,
    NYUV2_CAMERA,
    data_root,
    load_nyuv2_frame,
    nyuv2_frames,
    region_ground_truth,
)
from rgbd_rs.io import read_png

ROOT = data_root()
FRAMES = None if ROOT is None else ROOT / "nyuv2" / "frames"
needs_data = pytest.mark.skipif(
    FRAMES is None or not FRAMES.is_dir(), reason="shared NYUv2 frames not found"
)


@needs_data
def test_splits() -> None:
    train, test, every = nyuv2_frames("train"), nyuv2_frames("test"), nyuv2_frames()
    assert (len(train), len(test), len(every)) == (25, 25, 50)
    assert max(train) == 43 and min(test) == 46
    assert sorted(train + test) == every
    assert every[0] == 1


@needs_data
def test_frame_shapes_dtypes_units() -> None:
    frame = load_nyuv2_frame(1)
    assert (frame.name, frame.split) == ("0001", "train")
    assert load_nyuv2_frame(46).split == "test"
    assert frame.rgb.shape == (480, 640, 3) and frame.rgb.dtype == np.uint8
    assert frame.depth.shape == (480, 640) and frame.depth.dtype == np.float32
    assert frame.label13.dtype == np.uint8 and frame.label40.dtype == np.uint8
    raw = read_png(FRAMES / "0001_depth.png")  # type: ignore[operator]
    np.testing.assert_allclose(frame.depth, raw / 1000.0, rtol=1e-6)
    assert 0.5 < float(np.nanmedian(frame.depth)) < 10.0  # metres, not millimetres
    assert int(frame.label13.max()) <= 13 and int(frame.label40.max()) <= 40
    # The RGB PNG is stored as RGB: read_png already swaps OpenCV's BGR.
    np.testing.assert_array_equal(frame.rgb, read_png(FRAMES / "0001_rgb.png"))  # type: ignore[operator]


def test_depth_zero_is_nan(tmp_path: object) -> None:
    from pathlib import Path

    from rgbd_rs.io import write_png

    folder = Path(str(tmp_path))
    depth = np.full((4, 5), 2500, np.uint16)
    depth[0, 0] = 0
    write_png(folder / "0007_rgb.png", np.zeros((4, 5, 3), np.uint8))
    write_png(folder / "0007_depth.png", depth)
    for k in ("label13", "label40"):
        write_png(folder / f"0007_{k}.png", np.ones((4, 5), np.uint8))
    assert nyuv2_frames(folder=folder) == [7]
    frame = load_nyuv2_frame(7, folder)
    assert np.isnan(frame.depth[0, 0]) and frame.depth[1, 1] == np.float32(2.5)


def test_camera_and_names() -> None:
    assert isinstance(NYUV2_CAMERA, PinholeCamera)
    assert (NYUV2_CAMERA.width, NYUV2_CAMERA.height) == (640, 480)
    assert NYUV2_CAMERA.fx == pytest.approx(518.857901)
    assert NYUV2_CAMERA.cy == pytest.approx(253.736166 - 1.0)  # 0-based pixel centres
    assert len(LABEL13_NAMES) == 14 and LABEL13_NAMES[0] == "unlabeled"
    assert (LABEL13_NAMES[5], LABEL13_NAMES[12], LABEL13_NAMES[13]) == ("floor", "wall", "window")


def test_region_ground_truth_by_hand() -> None:
    lab = np.array(
        [
            [3, 3, 0, 3],
            [5, 3, 0, 3],
            [5, 5, 3, 3],
        ],
        np.uint8,
    )
    # Diagonal contact does not join (4-connectivity); the right-hand 3s join through row 2.
    want = np.array(
        [
            [0, 0, -1, 1],
            [2, 0, -1, 1],
            [2, 2, 1, 1],
        ]
    )
    np.testing.assert_array_equal(region_ground_truth(lab), want)
    assert region_ground_truth(lab).dtype == np.int32
    # Only diagonal contact: two regions.
    diag = np.array([[1, 2], [2, 1]], np.uint8)
    np.testing.assert_array_equal(region_ground_truth(diag), [[0, 1], [2, 3]])


@needs_data
def test_region_ground_truth_on_a_frame() -> None:
    frame = load_nyuv2_frame(nyuv2_frames("test")[0])
    regions = region_ground_truth(frame.label40)
    assert regions.shape == (480, 640)
    np.testing.assert_array_equal(regions < 0, frame.label40 == 0)
    n = int(regions.max()) + 1
    assert set(np.unique(regions[regions >= 0])) == set(range(n))
    # Each region has one class, and regions of one class are apart (not 4-adjacent).
    for r in range(n):
        assert len(np.unique(frame.label40[regions == r])) == 1
    same_right = (regions[:, :-1] != regions[:, 1:]) & (regions[:, :-1] >= 0)
    assert not np.any(same_right & (frame.label40[:, :-1] == frame.label40[:, 1:]))
    # As many regions as the classes' connected components counted by OpenCV.
    import cv2

    total = 0
    for c in np.unique(frame.label40[frame.label40 > 0]):
        k, _ = cv2.connectedComponents((frame.label40 == c).astype(np.uint8), connectivity=4)
        total += k - 1
    assert n == total
