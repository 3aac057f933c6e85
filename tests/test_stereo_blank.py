"""A stereo pair with no texture to match (rgbd_rs.fusion._blank): ``sgm`` and ``rgbd stereo``
warn when most of a view is blank, saturated or covered, and stay quiet on real frames; the row
check does not read a slope from a textured band too narrow to show one."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from rgbd_rs.cli import main
from rgbd_rs.data.stereo_scenes import load_stereo_scene
from rgbd_rs.fusion import CensusParams, census_match, measure_row_alignment, sgm
from rgbd_rs.fusion._blank import BLANK_SHARE, blank_note, blank_share
from rgbd_rs.io import write_png


def _banded(rows: int, shape: tuple[int, int] = (120, 200)) -> np.ndarray:
    """A saturated image (grey 250) with a random texture in its top ``rows`` rows."""
    img = np.full((*shape, 3), 250, np.uint8)
    img[:rows] = np.random.default_rng(0).integers(0, 256, (rows, shape[1], 3))
    return img


def test_share_counts_single_level_windows() -> None:
    assert blank_share(np.full((30, 40), 7, np.uint8)) == 1.0
    noise = np.random.default_rng(1).integers(0, 256, (30, 40)).astype(np.uint8)
    assert blank_share(noise) == 0.0
    half = noise.copy()
    half[:, 20:] = 0  # the 2 columns beside the texture see it in their 5x5 window
    assert blank_share(half) == pytest.approx(18 / 40)
    assert blank_note(noise, noise) is None
    note = blank_note(noise, np.full((30, 40), 255, np.uint8))
    assert note is not None and note.startswith("right: 100% of the image has no texture")


def test_real_frames_read_textured(shared_data: Path) -> None:
    # The constant's margin: Middlebury views and NYUv2's bordered Kinect frames stay far below.
    scene = load_stereo_scene("Lampshade1")  # val, the least textured view of the shared data
    grey = cv2.cvtColor(scene.right, cv2.COLOR_RGB2GRAY)
    assert blank_share(grey) < 0.02
    frames = sorted((shared_data / "nyuv2" / "frames").glob("*_rgb.png"))
    assert frames
    worst = max(blank_share(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)) for f in frames)
    assert worst < BLANK_SHARE / 4


@pytest.mark.parametrize("method", ["census", "opencv"])
def test_sgm_warns_on_a_blown_out_pair(method: str) -> None:
    img = _banded(20)
    with pytest.warns(RuntimeWarning, match=r"^left: 8\d% of the image has no texture"):
        sgm(img, img, reference="left", max_disparity=32, method=method)
    textured = _banded(120)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sgm(textured, textured, reference="left", max_disparity=32, method=method)


def test_cli_warns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_png(tmp_path / "l.png", _banded(120))
    write_png(tmp_path / "r.png", np.zeros((120, 200, 3), np.uint8))  # a lens cap
    argv = ["stereo", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png")]
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main([*argv, "--max-disparity", "32", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "--right: 100% of the image has no texture" in err
    assert "check the camera's exposure and lens" in err


def test_a_narrow_textured_band_gives_no_slope() -> None:
    # A pair matched with itself: its rows agree. Texture in the top sixth only: the offsets'
    # sub-pixel noise once gave a slope that read 0.59 px at the bottom and resampled the view.
    img = cv2.cvtColor(_banded(20), cv2.COLOR_RGB2GRAY)
    first = census_match(img, img, reference="left", max_disparity=32,
                         params=CensusParams(align_rows=False))  # fmt: skip
    found = measure_row_alignment(img, img, first.disparity, reference="left")
    assert found is not None and found.slope_y == 0.0
    assert found.max_offset < 0.5  # under ALIGN_THRESHOLD: not resampled
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "rows disagree" warning
        census_match(img, img, reference="left", max_disparity=32)


def test_opencv_reads_colour_texture_of_one_grey_level() -> None:
    # Colours that all convert to one grey level: OpenCV's SGBM matches them (in colour), ours
    # sees a blank image.
    rng = np.random.default_rng(2)
    g = rng.integers(0, 2, (120, 200))
    img = np.zeros((120, 200, 3), np.uint8)
    img[g == 0] = (255, 0, 0)  # RGB: grey 0.299 * 255 = 76
    img[g == 1] = (0, 130, 0)  # grey 0.587 * 130 = 76
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    assert grey.min() == grey.max()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sgm(img, img, reference="left", max_disparity=32, method="opencv")
    with pytest.warns(RuntimeWarning, match=r"^left: 100% of the image has no texture"):
        sgm(img, img, reference="left", max_disparity=32, method="census")
