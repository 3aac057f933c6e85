"""Bad input to :mod:`rgbd_rs.data.synth_indoor` (see tests/test_bad_input.py for the contract
and the meta-test that counts these cases)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

import rgbd_rs.data.synth_indoor as S
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, RgbdError

ARG = InvalidArgumentError


def _file(tmp: str) -> Path:
    p = Path(tmp) / "a_file"
    p.write_text("x")
    return p


def _other_seed(tmp: str) -> None:
    S.generate_indoor(tmp, 0, seed=1, width=16, height=16, quiet=True)
    S.generate_indoor(tmp, 0, seed=2, width=16, height=16, quiet=True)


def _corrupt(tmp: str) -> object:
    S.generate_indoor(tmp, 1, seed=0, width=16, height=16, quiet=True)
    (Path(tmp) / "000000_depth.png").write_bytes(b"not a png")
    return S.IndoorFrames(tmp)[0]


_ROOT = tempfile.TemporaryDirectory(prefix="rgbd_indoor_bad_")  # removed at exit


def _tmp() -> str:
    return tempfile.mkdtemp(dir=_ROOT.name)


CASES: list[Case] = [
    Case("render_indoor_frame", lambda: S.render_indoor_frame(-1, 0), ARG, r"^seed: got -1"),
    Case(
        "render_indoor_frame",
        lambda: S.render_indoor_frame(0, "3"),  # type: ignore[arg-type]
        ARG,
        r"^index: got",
        "index",
    ),
    Case(
        "render_indoor_frame",
        lambda: S.render_indoor_frame(0, 0, width=8),
        ARG,
        r"^width: got 8",
        "width",
    ),
    Case(
        "render_indoor_frame",
        lambda: S.render_indoor_frame(0, 0, height=10**6),
        ARG,
        r"^height: got",
        "height",
    ),
    Case("generate_indoor", lambda: S.generate_indoor(None, 1), ARG, r"^out: got None"),  # type: ignore[arg-type]
    Case(
        "generate_indoor",
        lambda: S.generate_indoor(_file(_tmp()), 1),
        ARG,
        r"^out: got .*a_file, a file; expected a folder",
        "file",
    ),
    Case("generate_indoor", lambda: S.generate_indoor(_tmp(), -1), ARG, r"^count: got -1", "count"),
    Case(
        "generate_indoor",
        lambda: S.generate_indoor(_tmp(), 2, shard=(2, 2)),
        ARG,
        r"^shard: got \(2, 2\)",
        "shard",
    ),
    Case(
        "generate_indoor",
        lambda: S.generate_indoor(_tmp(), 2, quiet="no"),  # type: ignore[arg-type]
        ARG,
        r"^quiet: got 'no'",
        "quiet",
    ),
    Case("generate_indoor", lambda: _other_seed(_tmp()), ARG, r"^out: got a folder holding", "mix"),
    Case("IndoorFrames", lambda: S.IndoorFrames(3), ARG, r"^folder: got 3"),  # type: ignore[arg-type]
    Case(
        "IndoorFrames",
        lambda: S.IndoorFrames("/nonexistent/indoor"),
        RgbdError,
        r"/nonexistent/indoor: not a folder",
        "missing",
    ),
    Case("IndoorFrames", lambda: _corrupt(_tmp()), RgbdError, r"000000_depth.png", "corrupt"),
    Case(
        "label_colors",
        lambda: S.label_colors(np.zeros((4, 4), np.int32)),
        ARG,
        r"^label13: got int32",
    ),
    Case("write_indoor_preview", lambda: S.write_indoor_preview("/tmp/x.png", []), ARG, r"^frames"),
    Case(
        "class_frequencies",
        lambda: S.class_frequencies([np.zeros((2, 2), np.float32)]),
        ARG,
        r"^labels\[0\]: got dtype float32",
    ),
    Case("class_frequencies", lambda: S.class_frequencies([]), ARG, r"^labels: got no", "empty"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_frame_position_out_of_range_is_an_index_error(tmp_path: Path) -> None:
    S.generate_indoor(tmp_path, 1, seed=0, width=16, height=16, quiet=True)
    frames = S.IndoorFrames(tmp_path)
    with pytest.raises(IndexError):
        frames[1]
    with pytest.raises(InvalidArgumentError, match=r"^k: got"):
        frames["0"]  # type: ignore[index]
