"""mkdocs hook: the command-line reference, generated from the ``rgbd`` argparse parsers.

A page containing the marker ``<!-- rgbd-cli-reference -->`` gets, in its place, one section
per command (``rgbd fuse``, ``rgbd eval fusion``, ...) with the command's own ``--help`` text,
so the reference cannot drift from the code.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from typing import Any

MARKER = "<!-- rgbd-cli-reference -->"


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return list(action.choices.items())
    return []


def _walk(
    parser: argparse.ArgumentParser, path: tuple[str, ...]
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    subs = _subcommands(parser)
    if not subs or path == ():
        yield path, parser
    for name, sub in subs:
        yield from _walk(sub, (*path, name))


def _help(parser: argparse.ArgumentParser) -> str:
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: fix it for a stable page
    return parser.format_help().rstrip()


def reference() -> str:
    """The reference as Markdown: the top-level help, then each command's."""
    from rgbd_rs.cli import build_parser

    out = []
    for path, parser in _walk(build_parser(), ()):
        title = " ".join(("rgbd", *path))
        out.append(f"### `{title}`\n\n```text\n{_help(parser)}\n```\n")
    return "\n".join(out)


def on_page_markdown(markdown: str, **_: Any) -> str:
    """Replace the marker with the generated reference."""
    return markdown.replace(MARKER, reference()) if MARKER in markdown else markdown
