"""What a forked child (multiprocessing's default start method on Linux before Python 3.14, a
scheduler's worker pool) must undo of its parent's state before it calls the library.

- torch's intra-op thread pool does not survive a fork: a child whose parent had run a network
  (``fuse()``, ``segment()``, ``classify()``) hung for good in its first forward pass (plain torch
  does the same). The child gets one torch thread, as torch gives its DataLoader workers; the
  native kernels do the same for their own pool (``num_threads()``, docs/design.md).
- The native core's count of running calls is inherited with the calls of the parent's other
  threads, which do not exist in the child: it never fell back to 0, so one Ctrl-C in the child
  stopped every later call there.
"""

from __future__ import annotations

import contextlib
import os
import sys

from rgbd_rs import _rgbd_rs

_installed = False


def _in_child() -> None:
    _rgbd_rs.after_fork_in_child()
    torch = sys.modules.get("torch")  # only when the parent used it: never imported here
    set_threads = getattr(torch, "set_num_threads", None)  # a stub or half-imported module
    if callable(set_threads):
        with contextlib.suppress(Exception):  # a hook must not fail every child's start
            set_threads(1)


def install() -> None:
    """Registers :func:`_in_child` to run in every forked child (once per process)."""
    global _installed
    if not _installed and hasattr(os, "register_at_fork"):
        os.register_at_fork(after_in_child=_in_child)
        _installed = True
