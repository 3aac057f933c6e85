"""Bad input to :mod:`rgbd_rs.segmentation.cues` (see tests/test_bad_input.py for the contract
and the meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, PinholeCamera, ShapeMismatchError
from rgbd_rs.segmentation import cue_maps, semantic_cues

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

CAM = PinholeCamera(40.0, 40.0, 15.5, 11.5, 32, 24)
RGB = np.random.default_rng(0).integers(0, 255, (24, 32, 3), dtype=np.uint8)
DEPTH = np.full((24, 32), 2.0, np.float32) + np.linspace(0, 0.2, 32, dtype=np.float32)

CASES: list[Case] = [
    Case("semantic_cues", lambda: semantic_cues(RGB, DEPTH, "cam"), ARG, r"camera"),  # type: ignore[arg-type]
    Case("semantic_cues", lambda: semantic_cues(RGB[:, :-1], DEPTH, CAM), SHAPE, r"rgb", "size"),
    Case("semantic_cues", lambda: semantic_cues(RGB, DEPTH * np.nan, CAM), ARG, r"^depth", "none"),
    Case(
        "semantic_cues",
        lambda: semantic_cues(RGB, DEPTH, CAM, n_segments=10**6),
        ARG,
        r"n_segments",
        "k",
    ),
    Case("semantic_cues", lambda: semantic_cues(RGB, DEPTH * 1000, CAM), ARG, r"^depth", "mm"),
    Case(
        "cue_maps",
        lambda: cue_maps(RGB, DEPTH, CAM, over=np.zeros((3, 3), np.int32)),
        SHAPE,
        r"^over",
    ),
    Case("cue_maps", lambda: cue_maps(RGB, DEPTH, CAM, feats=3), ARG, r"^feats: got int", "feats"),  # type: ignore[arg-type]
    Case("cue_maps", lambda: cue_maps(RGB, DEPTH, CAM, fits="x"), ARG, r"^fits: got str", "fits"),  # type: ignore[arg-type]
    Case(
        "cue_maps",
        lambda: cue_maps(RGB, DEPTH, CAM, hha_image=np.zeros((24, 32), np.uint8)),
        SHAPE,
        r"^hha_image",
        "hha",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
