"""Bad input to the segmentation metrics of :mod:`rgbd_rs.metrics` and to
:mod:`rgbd_rs.data.nyuv2` (see tests/test_bad_input.py for the contract and the meta-test that
counts these cases)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs import metrics as M
from rgbd_rs.data.nyuv2 import load_nyuv2_frame, nyuv2_frames, region_ground_truth
from rgbd_rs.io import write_png

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
FILE = RgbdError

_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_metrics_")
TMP = Path(_TMP.name)
L = np.arange(12).reshape(3, 4) % 3
T = np.arange(12).reshape(3, 4) // 4

#: The region metrics share one signature (segmentation, truth, *, ignore).
REGION: dict[str, Callable[..., float]] = {
    "variation_of_information": M.variation_of_information,
    "rand_index": M.rand_index,
    "boundary_recall": M.boundary_recall,
    "undersegmentation_error": M.undersegmentation_error,
}


def _region_cases(name: str, f: Callable[..., float]) -> list[Case]:
    return [
        Case(name, lambda: f(L, T[:2]), SHAPE, r"^truth: got shape \(2, 4\), expected \(3, 4\)"),
        Case(name, lambda: f(L.astype(float), T), ARG, r"^segmentation: got dtype float64", "f"),
        Case(name, lambda: f(L, T.astype(bool)), ARG, r"^truth: got dtype bool", "bool"),
        Case(
            name, lambda: f(L.ravel(), T.ravel()), SHAPE, r"^segmentation: got shape \(12,\)", "1d"
        ),
        Case(name, lambda: f(-np.ones_like(L), T), ARG, r"^truth: got no pixel", "nothing"),
        Case(name, lambda: f(L, np.zeros_like(T), ignore=0), ARG, r"no pixel", "all ignored"),
        Case(name, lambda: f(L, T, ignore=0.5), ARG, r"^ignore: got 0.5", "ignore"),
        Case(name, lambda: f(L, [[1, 2], [3]]), ARG, r"^truth: got list", "ragged"),
    ]


def _frames(files: dict[str, np.ndarray], index: int = 7) -> Path:
    folder = Path(tempfile.mkdtemp(dir=TMP))
    good = {
        "rgb": np.zeros((4, 5, 3), np.uint8),
        "depth": np.full((4, 5), 1000, np.uint16),
        "label13": np.ones((4, 5), np.uint8),
        "label40": np.ones((4, 5), np.uint8),
    }
    for kind, image in {**good, **files}.items():
        write_png(folder / f"{index:04d}_{kind}.png", image)
    return folder


CASES: list[Case] = [
    *(c for name, f in REGION.items() for c in _region_cases(name, f)),
    Case(
        "boundary_recall",
        lambda: M.boundary_recall(L, np.zeros_like(T)),
        ARG,
        r"^truth: got no boundary",
        "no boundary",
    ),
    Case(
        "boundary_recall",
        lambda: M.boundary_recall(L, T, tolerance=-1),
        ARG,
        r"^tolerance: got -1",
        "tolerance",
    ),
    Case(
        "boundary_recall",
        lambda: M.boundary_recall(L, T, tolerance=1.5),
        ARG,
        r"^tolerance: got 1.5",
        "tolerance float",
    ),
    Case(
        "confusion_matrix",
        lambda: M.confusion_matrix(L, T, n_classes=2),
        ARG,
        r"^pred: got class 2, expected classes in \[0, 2\)",
    ),
    Case(
        "confusion_matrix",
        lambda: M.confusion_matrix(T, L + 1, n_classes=3),
        ARG,
        r"^truth: got class 3",
        "truth class",
    ),
    Case(
        "confusion_matrix",
        lambda: M.confusion_matrix(L, T, n_classes=0),
        ARG,
        r"^n_classes: got 0",
        "n_classes",
    ),
    Case(
        "confusion_matrix",
        lambda: M.confusion_matrix(L, T, n_classes=3, ignore=3),
        ARG,
        r"^ignore: got 3",
        "ignore",
    ),
    Case(
        "confusion_matrix",
        lambda: M.confusion_matrix(L, T[:, :2], n_classes=3),
        SHAPE,
        r"^truth: got shape \(3, 2\)",
        "shape",
    ),
    Case(
        "pixel_accuracy",
        lambda: M.pixel_accuracy(L, T.astype(np.float32)),
        ARG,
        r"^truth: got dtype float32",
    ),
    Case("pixel_accuracy", lambda: M.pixel_accuracy(L, T[1:]), SHAPE, r"^truth: got shape", "s"),
    Case(
        "pixel_accuracy",
        lambda: M.pixel_accuracy(L, np.zeros_like(T)),
        ARG,
        r"^truth: got no pixel",
        "nothing",
    ),
    Case(
        "mean_class_accuracy",
        lambda: M.mean_class_accuracy(L, T, n_classes="3"),
        ARG,
        r"^n_classes: got '3'",
    ),
    Case(
        "mean_class_accuracy",
        lambda: M.mean_class_accuracy(L, -np.ones_like(T), n_classes=3),
        ARG,
        r"^truth: got no pixel",
        "nothing",
    ),
    # -- rgbd_rs.data.nyuv2 --------------------------------------------------------------------
    Case("nyuv2_frames", lambda: nyuv2_frames("val"), ARG, r"^split: got 'val'"),
    Case(
        "nyuv2_frames", lambda: nyuv2_frames(folder=TMP / "nope"), FILE, r"nope: not a folder", "f"
    ),
    Case("nyuv2_frames", lambda: nyuv2_frames(folder=TMP), FILE, r"no NNNN_", "empty"),
    Case("nyuv2_frames", lambda: nyuv2_frames(folder=3), ARG, r"^folder: got 3", "int"),
    Case("load_nyuv2_frame", lambda: load_nyuv2_frame(0), ARG, r"^index: got 0"),
    Case("load_nyuv2_frame", lambda: load_nyuv2_frame("0001"), ARG, r"^index: got '0001'", "str"),
    Case(
        "load_nyuv2_frame",
        lambda: load_nyuv2_frame(8, _frames({})),
        FILE,
        r"0008_rgb\.png",
        "missing",
    ),
    Case(
        "load_nyuv2_frame",
        lambda: load_nyuv2_frame(7, _frames({"depth": np.full((4, 5), 9, np.uint8)})),
        FILE,
        r"0007_depth\.png: got a uint8 PNG .* expected single-channel uint16",
        "8-bit depth",
    ),
    Case(
        "load_nyuv2_frame",
        lambda: load_nyuv2_frame(7, _frames({"label40": np.ones((3, 5), np.uint8)})),
        FILE,
        r"sizes differ",
        "size",
    ),
    Case(
        "load_nyuv2_frame",
        lambda: load_nyuv2_frame(7, _frames({"label13": np.full((4, 5), 14, np.uint8)})),
        FILE,
        r"0007_label13\.png: got class 14",
        "class",
    ),
    Case(
        "load_nyuv2_frame",
        lambda: load_nyuv2_frame(7, _frames({"rgb": np.zeros((4, 5), np.uint8)})),
        FILE,
        r"0007_rgb\.png: got a uint8 PNG of shape \(4, 5\), expected RGB",
        "grey rgb",
    ),
    Case(
        "region_ground_truth",
        lambda: region_ground_truth(np.ones((4, 5), np.float32)),
        ARG,
        r"^label40: got dtype float32",
    ),
    Case(
        "region_ground_truth",
        lambda: region_ground_truth(np.ones((4, 5, 3), np.uint8)),
        SHAPE,
        r"^label40: got shape \(4, 5, 3\)",
        "3d",
    ),
    Case(
        "region_ground_truth",
        lambda: region_ground_truth(np.full((4, 5), 300)),
        ARG,
        r"^label40: got labels in \[300, 300\]",
        "range",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
