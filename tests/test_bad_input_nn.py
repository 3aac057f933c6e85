"""Bad input of the networks' public API (rgbd_rs.nn) and the clue / search-range stages of
fusion: each case states the exact error class and a pattern naming the argument or file."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
import torch

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.fusion import compute_clues, search_range
from rgbd_rs.nn import (
    Checkpoint,
    ConfidenceEstimator,
    ConfidenceNet,
    TrainConfig,
    load_checkpoint,
    predict,
    save_checkpoint,
    seed_everything,
    split,
    train,
)

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_nn_")
TMP = Path(_TMP.name)
(TMP / "garbage.pt").write_bytes(b"not a checkpoint")
IMG = np.zeros((8, 12, 3), np.uint8)
D = np.ones((8, 12), np.float32)
DATA = torch.utils.data.TensorDataset(torch.zeros(4, 4, 8, 8))
NET = ConfidenceNet(2)
CKPT = Checkpoint(TMP / "x.pt", "confidence-convnet/1", {"width": 2}, {}, NET.state_dict())

CASES: list[Case] = [
    Case("TrainConfig", lambda: TrainConfig(epochs=0), ARG, r"^epochs: got 0"),
    Case("TrainConfig.from_dict", lambda: TrainConfig.from_dict({"x": 1}), ARG, r"^config: got"),
    Case("split", lambda: split(DATA, 1.5), ARG, r"fraction"),
    Case("seed_everything", lambda: seed_everything(-1), ARG, r"^seed: got -1"),
    Case(
        "train",
        lambda: train(
            "net",  # type: ignore[arg-type]
            DATA,
            None,
            lambda o, b: o,
            TrainConfig(),
            TMP,
            arch="a",
            arch_config={},
            normalisation={},
        ),
        ARG,
        r"^model: got str",
    ),
    Case("load_checkpoint", lambda: load_checkpoint(TMP / "none.pt"), RgbdError, r"none\.pt"),
    Case(
        "load_checkpoint",
        lambda: load_checkpoint(TMP / "garbage.pt"),
        RgbdError,
        r"garbage\.pt",
        "garbage",
    ),
    Case(
        "save_checkpoint",
        lambda: save_checkpoint("ckpt", TMP / "y.pt"),  # type: ignore[arg-type]
        ARG,
        r"checkpoint",
    ),
    Case(
        "Checkpoint.load_weights",
        lambda: CKPT.load_weights(ConfidenceNet(3)),
        RgbdError,
        r"x\.pt: weights do not fit",
    ),
    Case("ConfidenceNet", lambda: ConfidenceNet(0), ARG, r"^width: got 0"),
    Case(
        "ConfidenceNet.body",
        lambda: NET.body(torch.zeros(1, 4, 20, 20)[:, :3]),
        SHAPE,
        r"^x: got shape \(1, 3, 20, 20\)",
    ),
    Case("predict", lambda: predict(NET, np.zeros((3, 8, 8), np.float32)), SHAPE, r"^inputs"),
    Case(
        "predict",
        lambda: predict(NET, np.full((4, 8, 8), np.nan, np.float32)),
        ARG,
        r"^inputs: got 256 non-finite",
        "NaN",
    ),
    Case("ConfidenceEstimator", lambda: ConfidenceEstimator(NET, [1.0, 2.0]), SHAPE, r"^sigmas"),
    Case(
        "ConfidenceEstimator.with_stereo_power",
        lambda: ConfidenceEstimator(NET, [1.0] * 4).with_stereo_power(-2.0),
        ARG,
        r"^stereo_power: got -2",
    ),
    Case(
        "ConfidenceEstimator.with_precision",
        lambda: ConfidenceEstimator(NET, [1.0] * 4).with_precision("float16"),  # type: ignore[arg-type]
        ARG,
        r"^precision: got 'float16'",
    ),
    Case(
        "ConfidenceEstimator.load",
        lambda: ConfidenceEstimator.load(TMP / "garbage.pt"),
        RgbdError,
        r"garbage\.pt",
    ),
    Case(
        "ConfidenceEstimator",
        lambda: ConfidenceEstimator.load()(IMG, IMG, D, D, D[:4]),
        SHAPE,
        r"^stereo_disparity: got shape",
        "call",
    ),
    Case(
        "ConfidenceNet.forward",
        lambda: NET.forward(torch.zeros(1, 3, 8, 8)),
        SHAPE,
        r"^x: got shape \(1, 3, 8, 8\)",
    ),
    Case("compute_clues", lambda: compute_clues(IMG, IMG[:4], D, D, D), SHAPE, r"^target_image"),
    Case(
        "compute_clues",
        lambda: compute_clues(IMG, IMG, np.where(D > 0, np.inf, D), D, D),
        ARG,
        r"^tof_disparity: got \d+ value\(s\) as large as inf px, expected disparities within",
        "inf tof",
    ),
    Case(
        "compute_clues",
        lambda: compute_clues(IMG, IMG, D, D, np.full_like(D, 1e30)),
        ARG,
        r"^stereo_disparity: got \d+ value\(s\) as large as 1e\+30 px",
        "huge stereo",
    ),
    Case(
        "compute_clues",
        lambda: compute_clues(IMG, IMG, D, D, D, reference="up"),  # type: ignore[arg-type]
        ARG,
        r"^reference: got 'up'",
        "reference",
    ),
    Case("search_range", lambda: search_range(D[0]), SHAPE, r"^tof_disparity: got shape"),
    Case("search_range", lambda: search_range(D, width=1), ARG, r"^width: got 1", "width"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
