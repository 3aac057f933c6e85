"""Long commands report progress in a log too (stderr not a terminal): the bar stays on unless
quiet, refreshed at most every LOG_INTERVAL seconds; on a terminal it is the usual live bar."""

from __future__ import annotations

import io
import sys

import pytest
from tqdm import tqdm

from rgbd_rs._progress import LOG_INTERVAL, bar_options


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_options(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    off = bar_options(False)
    assert off["mininterval"] == LOG_INTERVAL and off["ascii"] is True and not off["disable"]
    assert bar_options(True)["disable"] is True
    monkeypatch.setattr(sys, "stderr", _Tty())
    assert bar_options(False) == {"disable": False, "dynamic_ncols": True}


def test_a_log_gets_a_status_line(monkeypatch: pytest.MonkeyPatch) -> None:
    log = io.StringIO()
    monkeypatch.setattr(sys, "stderr", log)
    for _ in tqdm(range(5), desc="rgbd synth", unit="scene", **bar_options(False)):
        pass
    text = log.getvalue()
    assert "\r" not in text and text.endswith("\n")
    assert "\n\n" not in text and not text.startswith("\n")  # no empty line, not even the first
    last = text.strip().splitlines()[-1]
    assert last.startswith("rgbd synth: 100%") and "5/5" in last and last.isascii()
    quiet = io.StringIO()
    monkeypatch.setattr(sys, "stderr", quiet)
    for _ in tqdm(range(5), **bar_options(True)):
        pass
    assert quiet.getvalue() == ""
