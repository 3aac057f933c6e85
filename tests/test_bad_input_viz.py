"""Bad input to the figure helpers of :mod:`rgbd_rs.viz` (see tests/test_bad_input.py)."""

from __future__ import annotations

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError, viz

ARG, SHAPE = InvalidArgumentError, ShapeMismatchError
IMG = np.zeros((8, 8, 3), np.uint8)
NAMES, COLORS = ["a", "b"], [(0, 0, 0), (255, 255, 255)]

CASES: list[Case] = [
    Case("map_panel", lambda: viz.map_panel(np.zeros((3, 3, 3)), "t", unit="m"), SHAPE, r"^values"),
    Case("map_panel", lambda: viz.map_panel(np.zeros((3, 3)), "t", unit="m", width=2), ARG,
         r"^width: got 2", "width"),
    Case("map_panel", lambda: viz.map_panel(np.zeros((3, 3)), None, unit="m"), ARG,  # type: ignore[arg-type]
         r"^title: got NoneType", "title"),
    Case("image_panel", lambda: viz.image_panel(IMG.astype(np.float32), "t"), ARG,
         r"^image: got dtype float32"),
    Case("image_panel", lambda: viz.image_panel(IMG, 3), ARG, r"^title: got int", "title"),  # type: ignore[arg-type]
    Case("grid", lambda: viz.grid([], 2), ARG, r"^panels: got list"),
    Case("grid", lambda: viz.grid([IMG], 0), ARG, r"^columns: got 0", "columns"),
    Case("grid", lambda: viz.grid([IMG[:, :, 0:2]], 1), SHAPE, r"^panels\[0\]: got shape", "cell"),
    Case("class_legend", lambda: viz.class_legend(NAMES, COLORS[:1], 100), ARG,
         r"^names/colors: got 2 names and 1"),
    Case("class_legend", lambda: viz.class_legend(NAMES, COLORS, 0), ARG, r"^width: got 0", "w"),
    Case("class_picture", lambda: viz.class_picture(np.full((2, 2), 5), NAMES, COLORS, "t"), ARG,
         r"^labels: got label 5, expected < 2"),
    Case("class_picture", lambda: viz.class_picture(np.zeros((2, 2)), NAMES, COLORS, "t"), ARG,
         r"^labels: got dtype float64", "float labels"),
]  # fmt: skip


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
