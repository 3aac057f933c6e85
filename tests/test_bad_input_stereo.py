"""Bad input of our census stereo matcher, the stereo scene reader and the colour-bar figure:
each a clear RgbdError naming the argument."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, isolated, params
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError, io, viz
from rgbd_rs import data as D
from rgbd_rs import fusion as F

ARG, SHAPE = InvalidArgumentError, ShapeMismatchError
IMG = np.zeros((20, 40, 3), np.uint8)
GREY = np.zeros((20, 40), np.uint8)


def _bad_manifest(tmp: Path) -> Path:
    (tmp / "scenes.csv").write_text("scene,left\nA,a.png\n")
    return tmp


CASES = [
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, max_disparity=40),
        ARG,
        r"^max_disparity: got 40, expected less than the image width 40",
        "width",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, max_disparity=0),
        ARG,
        r"^max_disparity: got 0",
        "zero",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG[:, :30]),
        SHAPE,
        r"^right: got 30x20",
        "size",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, reference="up"),
        ARG,
        r"^reference: got 'up'",
        "ref",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG.astype(np.float32), IMG),
        ARG,
        r"^left: got dtype float32",
        "dtype",
    ),
    Case(
        "census_match",
        lambda: F.census_match(np.zeros((4, 4, 2), np.uint8), IMG),
        SHAPE,
        r"^left: got shape \(4, 4, 2\)",
        "channels",
    ),
    Case(
        "census_match",
        lambda: F.census_match(np.zeros((0, 5), np.uint8), GREY),
        SHAPE,
        r"^left: got an empty image",
        "empty",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, max_disparity=8, params="x"),
        ARG,
        r"^params: got str",
        "params",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, max_disparity=8, stats=1),
        ARG,
        r"^stats: got 1",
        "stats",
    ),
    Case(
        "census_match",
        lambda: F.census_match(IMG, IMG, max_disparity=2**70),
        ARG,
        r"^max_disparity",
        "huge",
    ),
    Case(
        "census_match",
        lambda: F.census_match(*[np.broadcast_to(np.zeros(1, np.uint8), (20000, 20000))] * 2),
        SHAPE,
        r"^left: got 20000 x 20000 pixels",
        "pixels",
    ),
    Case(
        "census_match",
        isolated(
            "import numpy as np; from rgbd_rs.fusion import census_match; "
            "a = np.broadcast_to(np.zeros(1, np.uint8), (16000, 16000)); "
            "census_match(a, a, max_disparity=9000)"
        ),
        ARG,
        r"^max_disparity: got 9000, expected a search whose cost volume \(16000 x 16000 x 9001\)",
        "absurd",
    ),
    Case("CensusParams", lambda: F.CensusParams(p2=5), ARG, r"^p2: got 5", "p2"),
    Case("CensusParams", lambda: F.CensusParams(p2=10**6), ARG, r"^p2: got 1000000", "p2big"),
    Case(
        "CensusParams",
        lambda: F.CensusParams(census_width=9, census_height=9),
        ARG,
        r"^census_width: got a 9x9 window",
        "bits",
    ),
    Case(
        "CensusParams",
        lambda: F.CensusParams(census_width=4),
        ARG,
        r"^census_width: got a 4x5 window",
        "even",
    ),
    Case("CensusParams", lambda: F.CensusParams(paths=6), ARG, r"^paths: got 6", "paths"),
    Case(
        "CensusParams",
        lambda: F.CensusParams(speckle_range=1e39),
        ARG,
        r"^speckle_range: got 1e\+39, expected a magnitude within float32",
        "f32",
    ),
    Case("CensusParams", lambda: F.CensusParams(median=4), ARG, r"^median: got 4", "median"),
    Case(
        "CensusParams",
        lambda: F.CensusParams(p2_contrast=float("nan")),
        ARG,
        r"^p2_contrast: got nan",
        "nan",
    ),
    Case(
        "CensusParams",
        lambda: F.CensusParams(subpixel="cubic"),
        ARG,
        r"^subpixel: got 'cubic'",
        "sub",
    ),
    Case(
        "CensusParams", lambda: F.CensusParams(lr_tolerance=-1), ARG, r"^lr_tolerance: got -1", "lr"
    ),
    Case(
        "CensusParams", lambda: F.CensusParams(uniqueness=100), ARG, r"^uniqueness: got 100", "uniq"
    ),
    Case(
        "CensusParams",
        lambda: F.CensusParams(vertical_tolerance=-1),
        ARG,
        r"^vertical_tolerance: got -1, expected",
        "vtol",
    ),
    Case(
        "CensusParams",
        lambda: F.CensusParams(vertical_tolerance=1.5),
        ARG,
        r"^vertical_tolerance: got 1.5",
        "vtol-float",
    ),
    Case(
        "CensusParams.replace",
        lambda: F.CensusParams().replace(p3=1),
        ARG,
        r"^changes: got unknown parameter\(s\) \['p3'\]",
    ),
    Case(
        "sgm",
        lambda: F.sgm(IMG, IMG, max_disparity=8, method="bm"),
        ARG,
        r"^method: got 'bm'",
        "method",
    ),
    Case(
        "sgm",
        lambda: F.sgm(IMG, IMG, max_disparity=8, method="census", block_size=5),
        ARG,
        r"^block_size: got 5",
        "census-block",
    ),
    Case(
        "sgm",
        lambda: F.sgm(IMG, IMG, max_disparity=16, params=F.CensusParams()),
        ARG,
        r"^params: got CensusParams",
        "opencv-params",
    ),
    Case(
        "load_stereo_scene",
        lambda: D.load_stereo_scene("Nowhere"),
        ARG,
        r"^name: got 'Nowhere'",
        "name",
    ),
    Case(
        "load_stereo_scene",
        lambda: D.load_stereo_scene("A", root="/nonexistent/x"),
        RgbdError,
        r"scenes.csv: no such file",
        "root",
    ),
    Case("load_stereo_scenes", lambda: D.load_stereo_scenes("dev"), ARG, r"^split: got 'dev'"),
    Case("scene_names", lambda: D.scene_names(3), ARG, r"^split: got 3"),
    Case(
        "colorize_with_bar",
        lambda: viz.colorize_with_bar(np.zeros((3, 3, 3))),
        SHAPE,
        r"^values: got shape",
    ),
    Case(
        "colorize_with_bar",
        lambda: viz.colorize_with_bar(np.zeros((3, 3)), vmin="0"),
        ARG,
        r"^vmin: got '0'",
        "vmin",
    ),
    Case(
        "colorize_with_bar",
        lambda: viz.colorize_with_bar(np.zeros((3, 3)), unit=1),
        ARG,
        r"^unit: got int",
        "unit",
    ),
    Case(
        "colorize_with_bar",
        lambda: viz.colorize_with_bar(np.zeros((3, 3)), title=None),
        ARG,
        r"^title: got NoneType",
        "title",
    ),
    Case("write_text", lambda: io.write_text("/tmp/x.md", b"x"), ARG, r"^text: got bytes"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_a_manifest_without_the_needed_columns_is_named(tmp_path: Path) -> None:
    with pytest.raises(RgbdError, match=r"scenes.csv: expected the columns .* missing \['right'"):
        D.scene_names(root=_bad_manifest(tmp_path))
