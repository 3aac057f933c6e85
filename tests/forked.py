"""A function run in a forked child, its result sent back: the tests of fork safety (a forked
child inherits the parent's native pools without their threads)."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable
from typing import Any

import pytest

#: Skips a test where this platform cannot fork.
NEEDS_FORK = pytest.mark.skipif(
    "fork" not in multiprocessing.get_all_start_methods(), reason="no fork on this platform"
)


def in_forked_child(target: Callable[..., Any], *args: object, timeout: float = 120.0) -> Any:
    """``target(*args)`` in a child forked from this process (waiting ``timeout`` s at most for
    its result; a child that hangs is killed and the wait raises ``queue.Empty``)."""
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_send, args=(queue, target, args))
    child.start()
    try:
        return queue.get(timeout=timeout)
    finally:
        child.join(timeout=10)
        if child.is_alive():
            child.kill()


def _send(queue: Any, target: Callable[..., Any], args: tuple[object, ...]) -> None:
    queue.put(target(*args))
