"""The real Azure Kinect ToF frame reprojected onto its colour camera.

How the registration is checked (there is no ground truth for this frame): the reprojected depth
must cover a plausible part of the colour lattice, keep the source's depth range (the cameras are
3 cm apart, so depths change by millimetres to centimetres, not more), and its occluding contours
must land on colour edges - with the calibrated pose most of them do, with the inverse pose (a
wrong registration of the same magnitude) almost none do.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError
from rgbd_rs.data import (
    load_azure_kinect_calibration,
    load_azure_kinect_frame,
    reproject_to_color,
)
from rgbd_rs.metrics import edge_alignment


@pytest.fixture(scope="module")
def kinect(shared_data: Path):  # type: ignore[no-untyped-def]
    tof = shared_data / "tof"
    return (
        load_azure_kinect_calibration(tof / "azure_kinect_calibration.json"),
        load_azure_kinect_frame(tof / "azure_kinect_frame.npz"),
    )


def test_mode_specific_intrinsics(kinect) -> None:  # type: ignore[no-untyped-def]
    cal, frame = kinect
    assert (cal.depth.width, cal.depth.height) == frame.depth.shape[::-1] == (640, 576)
    assert (cal.color.width, cal.color.height) == (1280, 720)
    assert frame.color.shape == (720, 1280, 3)
    # NFOV unbinned: 1024-px sensor cropped at (192, 180); principal point near the crop centre.
    assert 300 < cal.depth.cx < 340 and 270 < cal.depth.cy < 360
    assert cal.depth.fx == pytest.approx(504.6, abs=0.1)
    # 720p: 4096x3072 binned to 1280x960 and cropped by 120 rows.
    assert cal.color.fx == pytest.approx(611.8, abs=0.1)
    assert cal.color.cy == pytest.approx(0.5066176 * 960 - 120 - 0.5, abs=1e-3)
    assert np.linalg.norm(cal.depth_to_color.translation) == pytest.approx(0.0323, abs=1e-3)


def test_reprojection_onto_colour_is_plausible(kinect) -> None:  # type: ignore[no-untyped-def]
    cal, frame = kinect
    rep = reproject_to_color(frame, cal)
    assert rep.depth.shape == (720, 1280)
    assert 0.45 < rep.coverage < 0.75  # the NFOV cone covers the centre of the wider colour view
    src = np.nanpercentile(frame.depth, [5, 50, 95])
    dst = np.nanpercentile(rep.depth, [5, 50, 95])
    np.testing.assert_allclose(dst, src, atol=0.1)
    assert (
        rep.channels is not None and np.isfinite(rep.channels).sum() == np.isfinite(rep.depth).sum()
    )
    good = edge_alignment(rep.depth, frame.color)
    wrong = edge_alignment(
        reproject_to_color(frame, cal, pose=cal.depth_to_color.inverse()).depth,
        frame.color,
    )
    assert good > 0.5 and good > 4 * wrong, (good, wrong)


def test_loader_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(InvalidArgumentError, match=r"broken.npz"):
        load_azure_kinect_frame(bad)
    calib = tmp_path / "calib.json"
    calib.write_text('{"CalibrationInformation": {"Cameras": []}}')
    with pytest.raises(InvalidArgumentError, match=r"calib.json"):
        load_azure_kinect_calibration(calib)
    with pytest.raises(InvalidArgumentError, match=r"depth_mode"):
        load_azure_kinect_calibration(calib, depth_mode="HFOV")
