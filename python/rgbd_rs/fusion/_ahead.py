"""Native work started on a worker thread beside the caller's: :func:`~rgbd_rs.fusion.fuse` runs
its matcher this way beside the ToF upsampling, and LC beside its input checks, before they
decide whether its result is used (the native kernels release the GIL; the checks are mostly
single-threaded numpy). The worker's kernels run in a rayon pool of their own, so the caller's
native calls do not queue behind them in the process's pool."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from concurrent import futures
from concurrent.futures import ThreadPoolExecutor
from typing import Generic, TypeVar

from rgbd_rs import _rgbd_rs

T = TypeVar("T", covariant=True)
#: How often :meth:`Ahead.stop` repeats its request (seconds).
STOP_POLL = 0.01


class Ahead(Generic[T]):
    """``fn(*args)`` running on a thread of its own, started here; the thread ends with the
    call (a new one per call: a thread kept between calls would not survive a fork)."""

    def __init__(self, fn: Callable[..., T], *args: object) -> None:
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rgbd-ahead")
        self._future = pool.submit(_beside, fn, *args)
        pool.shutdown(wait=False)  # the thread exits once the call returns

    def result(self) -> T:
        """The call's result (waiting for it); its exception is raised here."""
        return self._future.result()

    def wait(self) -> None:
        """Waits for the call to end, whatever its outcome (a result no longer needed); Ctrl-C
        while waiting propagates."""
        futures.wait([self._future])

    def stop(self) -> None:
        """Asks the native kernels running now to stop (as Ctrl-C does; the request is
        process-wide), again every :data:`STOP_POLL` s until the call has ended, since it may be
        between two kernels, and waits for it."""
        while True:
            _rgbd_rs.interrupt_running()
            done, _ = futures.wait([self._future], timeout=STOP_POLL)
            if done:
                return


def _beside(fn: Callable[..., T], *args: object) -> T:
    """``fn(*args)`` with the calling thread's kernels in the side pool."""
    _rgbd_rs.use_side_pool(True)
    try:
        return fn(*args)
    finally:
        _rgbd_rs.use_side_pool(False)


@contextlib.contextmanager
def stopped_on_interrupt(ahead: Ahead[object] | None) -> Iterator[None]:
    """Around the code that waits for ``ahead``: on Ctrl-C (``KeyboardInterrupt`` on this
    thread, which the worker does not see) the call is stopped (:meth:`Ahead.stop`), as Ctrl-C
    stops a kernel running on the main thread, before the interrupt propagates; on any other
    exception the call is waited for (so no work outlives the caller's)."""
    try:
        yield
    except KeyboardInterrupt:
        if ahead is not None:
            ahead.stop()
        raise
    except BaseException:
        if ahead is not None:
            ahead.wait()
        raise
