"""The ``rgbd`` command line. ``rgbd --help`` lists the commands; each has its own ``--help``.

This module parses and dispatches; each pipeline's module registers its own commands through
:class:`~rgbd_rs.cli._args.Commands` (``register(commands)``), top-level ones such as
``rgbd fuse`` and the ``WHAT`` of the shared groups (``rgbd eval fusion``, later
``rgbd eval segmentation``, ``rgbd train shapes``), so a new pipeline adds one module and one
line in :data:`PIPELINES`.

Every failure ends in one line on stderr, ``rgbd: error: ...`` naming the argument or file,
and exit status 2: bad command lines (argparse, with range checks on the numbers), bad files
and bad values (:class:`~rgbd_rs.RgbdError`), unreadable or unwritable paths (``OSError``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from rgbd_rs import __version__
from rgbd_rs.cli import (
    confidence,
    data,
    demo,
    fusion,
    indoor,
    segmentation,
    segmentation_eval,
    semantic,
    shapes,
    stereo,
)
from rgbd_rs.cli._args import (
    Commands,
    Parser,
    fail,
    finish_outputs,
    one_line,
    os_message,
    writable_out,
)
from rgbd_rs.errors import RgbdError

__all__ = ["PIPELINES", "build_parser", "main"]

#: The modules whose ``register(commands)`` adds commands, in ``rgbd --help`` order.
PIPELINES = (
    demo,
    data,
    indoor,
    fusion,
    stereo,
    confidence,
    segmentation,
    segmentation_eval,
    semantic,
    shapes,
)


def build_parser() -> argparse.ArgumentParser:
    """The ``rgbd`` parser with every pipeline's commands."""
    p = Parser(
        prog="rgbd",
        description="rgbd_rs: ToF-stereo fusion, RGB-D segmentation and 3-D shape classification "
        "with a fast Rust core.",
    )
    p.add_argument("--version", action="version", version=f"rgbd_rs {__version__}")
    commands = Commands(p.add_subparsers(dest="command", metavar="COMMAND"))
    for pipeline in PIPELINES:
        pipeline.register(commands)
    return p


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """Warnings (a dead ToF frame, ...) as one line each, without the source line."""
    print(f"rgbd: warning: {one_line(str(message))}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rgbd`` script; returns the exit status (0 ok, 2 error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    run = getattr(args, "run", None)
    if run is None:
        parser.print_help()
        return 2
    previous = _on_sigterm()
    finished = False
    try:
        out = getattr(args, "out", None)
        if isinstance(out, Path):
            writable_out(out)  # before the work, which may take minutes
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            status: int = run(args)
        finished = True
    except RgbdError as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(os_message(exc))
    except MemoryError as exc:  # the native core's say what it could not reserve, and for what
        said = str(exc)
        known = "memory" in said or "allocate" in said
        return fail(said if known else "out of memory (try smaller images or fewer scenes)")
    except _Terminated:
        print("rgbd: terminated (SIGTERM)", file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print("rgbd: interrupted", file=sys.stderr)
        return 130
    finally:
        finish_outputs(finished)
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return status


class _Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler stopping the job), raised where the program is, as Ctrl-C's
    KeyboardInterrupt is: the same clean-up runs (temporary files removed, checkpoints kept)."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise _Terminated()


def _on_sigterm() -> Any:
    """Turn SIGTERM into :class:`_Terminated` while a command runs (main thread only); returns the
    handler to restore, or None when none was installed."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_terminated)


if __name__ == "__main__":
    sys.exit(main())
