"""tools/plot_learning_curve.py's panels: the legend never runs into a long title, a series with
no value is not named, and a first epoch far above the rest gets a logarithmic loss axis."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np


def _tool() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "tools" / "plot_learning_curve.py"
    spec = importlib.util.spec_from_file_location("plot_learning_curve", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _rows_with(img: np.ndarray, color: tuple[int, ...]) -> set[int]:
    return set(np.flatnonzero((img == np.array(color, np.uint8)).all(axis=2).any(axis=1)).tolist())


def test_legend_moves_below_a_long_title_and_skips_empty_series() -> None:
    t = _tool()
    epochs = [1, 2, 3]
    series = [("train", [1.0, 0.7, 0.6], t.TRAIN), ("validation", [None, None, None], t.VAL)]
    short = t.panel("loss", epochs, series, None, percent=False)
    long = t.panel("ModelNet10, 320 px, width 128 (H200) loss", epochs, series, None, False)
    assert short.shape == long.shape == (t.H, t.W, 3)
    assert not _rows_with(short, t.VAL) and not _rows_with(long, t.VAL)  # no validation: unnamed
    # The legend's train stroke: in the title row for a short title, in a row of its own below.
    assert 16 in _rows_with(short, t.TRAIN) and 16 not in _rows_with(long, t.TRAIN)
    assert 34 in _rows_with(long, t.TRAIN)


def test_loss_axis_is_logarithmic_past_a_ratio_of_eight() -> None:
    t = _tool()
    epochs = [1, 2, 3]
    img = t.panel("loss", epochs, [("train", [12.0, 1.2, 0.6], t.TRAIN)], None, percent=False)
    x = int(t.M + 0.5 * (t.W - 16 - t.M))  # epoch 2
    ys = np.flatnonzero((img[60:, x - 1 : x + 2] == np.array(t.TRAIN, np.uint8)).all(2).any(1))
    above_bottom = (t.H - 40) - (60 + float(ys.mean()))
    # 1.2 of 0.6..12: 5 % of the height on a linear axis (~27 px with the padding), 23 % on the
    # log axis (~69 px).
    assert above_bottom > 50, above_bottom


def test_tick_labels_are_exact_and_missing_values_are_not_drawn() -> None:
    t = _tool()
    assert t._labels([87.5, 90.0, 92.5]) == ["87.5", "90.0", "92.5"]
    assert t._labels([90.0, 90.25, 90.5]) == ["90.00", "90.25", "90.50"]
    assert t._labels([0.5, 1.0, 2.0]) == ["0.5", "1.0", "2.0"]
    assert t._labels([90.0, 95.0]) == ["90", "95"]
    # No value at all (a run without a metric) and a NaN metric: a panel, not a crash.
    empty = t.panel("accuracy", [1, 2], [("train", [None, None], t.TRAIN)], None, percent=True)
    assert empty.shape == (t.H, t.W, 3) and not _rows_with(empty, t.TRAIN)
    nan = t.panel("accuracy", [1, 2], [("train", [0.9, float("nan")], t.TRAIN)], 1, True)
    assert _rows_with(nan, t.TRAIN)
