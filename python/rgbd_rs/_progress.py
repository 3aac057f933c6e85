"""Progress bars that also report when stderr is not a terminal (a scheduler's log, ``2>log``).

tqdm's ``disable=None`` turns a bar off without a terminal, so a long job under a scheduler said
nothing until it ended. :func:`bar_options` keeps the bar on unless ``quiet`` and, off a
terminal, refreshes it at most every :data:`LOG_INTERVAL` seconds, one plain line each, so a
log gets a status line now and then, not thousands, nor one ever-growing line.
"""

from __future__ import annotations

import sys
from typing import Any

#: Seconds between two refreshes of a bar written to a file or a pipe.
LOG_INTERVAL = 30.0


class _Lines:
    """A text stream for tqdm off a terminal: each refresh (tqdm starts it with a carriage
    return) becomes a line of its own, so a log reads line by line, with no empty line (the
    first refresh's carriage return starts none)."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.line_open = False

    def write(self, text: str) -> int:
        text = text.replace("\r", "\n")
        while "\n\n" in text:
            text = text.replace("\n\n", "\n")
        if not self.line_open:
            text = text.lstrip("\n")
        if text:
            self.line_open = not text.endswith("\n")
        return int(self.stream.write(text) or 0)

    def flush(self) -> None:
        self.stream.flush()


def bar_options(quiet: bool) -> dict[str, Any]:
    """tqdm keyword arguments for a bar on stderr: none when ``quiet``; a live bar on a
    terminal; otherwise one line per :data:`LOG_INTERVAL` seconds, 80 plain columns wide."""
    tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
    if tty:
        return {"disable": bool(quiet), "dynamic_ncols": True}
    return {
        "disable": bool(quiet),
        "mininterval": LOG_INTERVAL,
        "ncols": 80,
        "ascii": True,
        "file": _Lines(sys.stderr),
    }
