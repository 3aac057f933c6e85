"""Figures people read (issue 30): readable panels with colour bars and one "no data" colour,
class legends, and the demo's one-page index loaded in a real headless browser."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.demo_page import FIGURES
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.viz import NO_DATA_BGR, class_legend, class_picture, grid, image_panel, map_panel


def test_map_panel_has_the_width_a_bar_and_no_data_grey() -> None:
    v = np.linspace(0, 10, 96 * 54, dtype=np.float32).reshape(54, 96)
    v[:10, :10] = np.nan
    p = map_panel(v, "disparity", unit="px", width=480)
    assert p.shape[1] == 480
    assert p.shape[0] > 28 + 270  # title + map + colour bar below
    title_h = 28
    assert tuple(p[title_h + 5, 5]) == NO_DATA_BGR  # the NaN corner
    assert tuple(p[title_h + 200, 400]) != NO_DATA_BGR
    bar = p[title_h + 270 :]
    assert (np.abs(bar.astype(int) - NO_DATA_BGR).sum(-1) == 0).any()  # the "no data" swatch
    assert len({tuple(c) for c in bar.reshape(-1, 3)}) > 50  # the colour ramp


def test_class_picture_legend_and_no_data() -> None:
    labels = np.array([[0, 1, 2], [-1, 2, 1]])
    names, colors = ["a", "b", "c"], [(255, 0, 0), (0, 255, 0), (0, 0, 255)]
    p = class_picture(labels, names, colors, "classes", width=320)
    assert p.shape[1] == 320
    body = p[28 : 28 + 213]
    assert tuple(body[150, 5]) == NO_DATA_BGR  # label -1, lower left
    assert tuple(body[5, 5]) == (0, 0, 255)  # label 0 in red, as BGR
    legend = class_legend(names, colors, 320)
    assert legend.shape[1] == 320 and legend.shape[0] >= 22
    with pytest.raises(InvalidArgumentError, match=r"^labels: got label 3"):
        class_picture(labels + 1, names, colors, "x")
    with pytest.raises(InvalidArgumentError, match=r"^names/colors: got 3 names and 2"):
        class_legend(names, colors[:2], 320)


def test_segment_colours_are_never_grey_and_class_colours_apart() -> None:
    """A helper read a (70, 70, 70) segment as no data and the window class as ceiling."""
    import cv2

    from rgbd_rs.data.synth_indoor import LABEL13_COLORS
    from rgbd_rs.viz import paint_segments

    labels = np.arange(-1, 5000, dtype=np.int32).reshape(1, -1)
    img = paint_segments(labels, boundaries=False)
    assert (img[0, 0] == NO_DATA_BGR).all()
    hsv = cv2.cvtColor(img[:, 1:], cv2.COLOR_BGR2HSV).reshape(-1, 3).astype(int)
    assert hsv[:, 1].min() >= 150 and hsv[:, 2].min() >= 175  # saturated and bright
    assert (np.abs(img[0, 1:].astype(int) - NO_DATA_BGR).max(axis=1) > 40).all()
    # Same label, same colour (merge animations); consecutive labels' colours differ.
    np.testing.assert_array_equal(paint_segments(labels[:, 10:20], False), img[:, 10:20])
    steps = np.abs(np.diff(img[0, 1:].astype(int), axis=0)).max(axis=1)
    assert (steps > 0).all() and np.median(steps) > 60
    colours = np.array(LABEL13_COLORS[1:], float)
    gaps = np.linalg.norm(colours[:, None] - colours[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() > 40, gaps.min()


def test_a_long_title_wraps_instead_of_running_off_a_narrow_panel() -> None:
    img = np.zeros((40, 80, 3), np.uint8)
    one = image_panel(img, "109 segments", width=320)
    long = image_panel(img, "109 segments (labels.png in colour; white: boundaries)", width=320)
    assert long.shape[1] == one.shape[1] == 320
    assert long.shape[0] == one.shape[0] + 22  # one more line of title
    strip = long[: long.shape[0] - one.shape[0] + 28]
    assert (strip[:, -6:] == 255).all(), "no text in the right margin"
    v = np.linspace(0, 1, 40 * 80, dtype=np.float32).reshape(40, 80)
    one = map_panel(v, "error", unit="px", width=320)
    long = map_panel(
        v, "the fused map's error against the ground truth, 0-3 px", unit="px", width=320
    )
    assert long.shape[0] == one.shape[0] + 22 and (long[:50, -6:] == 255).all()


def test_grid_pads_panels_with_white() -> None:
    a = image_panel(np.zeros((10, 20, 3), np.uint8), "a", width=100)
    b = image_panel(np.zeros((20, 20, 3), np.uint8), "b", width=100)
    g = grid([a, b, a], columns=2)
    assert g.shape[1] == 2 * (100 + 8)
    assert g.shape[0] == 2 * (max(a.shape[0], b.shape[0]) + 8)
    assert (g[-10:, -10:] == 255).all()  # the empty cell


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    out = tmp_path_factory.mktemp("demo")
    res = subprocess.run(
        [sys.executable, "-m", "rgbd_rs.cli", "demo", "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    return out


def test_demo_figures_are_readable_grids(demo_out: Path) -> None:
    from rgbd_rs.io import read_png

    for name, columns in (("fusion.png", 4), ("kinect_depth_to_color.png", 3)):
        img = read_png(demo_out / name)
        assert img.shape[1] >= columns * 320, (name, img.shape)
    page = (demo_out / "index.html").read_text()
    for name in ("synthetic_reprojection", "kinect_depth_to_color", "fusion", "segmentation"):
        assert f'src="{name}.png"' in page
    assert "RMS disparity error (px)" in page and "VoI" in page  # the printed measurements


def _browser() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_browser() is None, reason="Chromium not installed (.ci/run installs it)")
def test_demo_page_loads_every_image_in_a_browser(demo_out: Path) -> None:
    """The page as a browser shows it: a copy of index.html beside it with a script that
    records each image's decoded width once the page has loaded."""
    probe = demo_out / "probe.html"
    script = (
        "<script>window.addEventListener('load', () => {document.body.setAttribute("
        "'data-widths', [...document.images].map(i => i.complete ? i.naturalWidth : -1)"
        ".join(','));});</script>"
    )
    probe.write_text((demo_out / "index.html").read_text().replace("</body>", script + "</body>"))
    browser = _browser()
    assert browser is not None
    res = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=10000",
         "--dump-dom", probe.as_uri()],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    found = re.search(r'data-widths="([^"]*)"', res.stdout)
    assert found, res.stdout[-2000:]
    widths = [int(w) for w in found.group(1).split(",")]
    assert len(widths) == len(FIGURES) and all(w >= 960 for w in widths), widths
