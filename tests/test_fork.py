"""A forked child (multiprocessing's default start method on Linux before Python 3.14) after the
parent used the library: torch gets one thread there (its pool does not survive a fork: the
child hung for good in its first forward pass), the native core forgets the calls the parent's
other threads were in (one Ctrl-C in the child then stopped every later call), and errors cross
processes by pickle with their type and message (a PicklingError lost both)."""

from __future__ import annotations

import pickle
import subprocess
import sys
import textwrap

import pytest

from rgbd_rs import errors

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="no fork")


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=240,
    )


def test_a_fork_child_runs_torch_after_the_parent_did() -> None:
    run = _run(
        """
        import multiprocessing as mp
        import torch
        import rgbd_rs  # noqa: F401 (installs the fork hook)

        def forward(_):
            x = torch.randn(1, 8, 240, 320, generator=torch.Generator().manual_seed(0))
            conv = torch.nn.Conv2d(8, 16, 3)
            with torch.no_grad():
                conv(x)
            return torch.get_num_threads()

        if __name__ == "__main__":
            torch.set_num_threads(2)
            forward(0)  # the parent's intra-op pool now runs
            with mp.get_context("fork").Pool(1) as pool:
                try:
                    print("child threads", pool.apply_async(forward, (0,)).get(timeout=60))
                except mp.TimeoutError:
                    print("child hung")
                pool.terminate()
        """
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "child threads 1" in run.stdout, run.stdout


def test_a_fork_child_forgets_the_parents_running_calls() -> None:
    # Forked while another thread is inside a native call: the child's count of running calls
    # once kept that call, so an interrupt request there never cleared.
    run = _run(
        """
        import multiprocessing as mp, threading, time
        import numpy as np
        from rgbd_rs import _rgbd_rs
        from rgbd_rs.fusion import census_match

        big = np.random.default_rng(0).integers(0, 256, (600, 900), dtype=np.uint8)
        small = big[:60, :120]
        stop = False

        def busy():
            while not stop:
                census_match(big, big, reference="left", max_disparity=200)

        def child(q):
            _rgbd_rs.interrupt_running()  # what a Ctrl-C's clean-up asks, with nothing running
            try:
                census_match(small, small, reference="left", max_disparity=16)
                q.put("ran")
            except KeyboardInterrupt:
                q.put("interrupted")

        if __name__ == "__main__":
            t = threading.Thread(target=busy)
            t.start()
            time.sleep(0.5)
            q = mp.get_context("fork").Queue()
            p = mp.get_context("fork").Process(target=child, args=(q,))
            p.start()
            print("child", q.get(timeout=60))
            p.join()
            stop = True
            t.join()
        """
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "child ran" in run.stdout, run.stdout


@pytest.mark.parametrize(
    "cls", [errors.RgbdError, errors.InvalidArgumentError, errors.ShapeMismatchError]
)
def test_errors_pickle_with_their_type_and_message(cls: type[errors.RgbdError]) -> None:
    back = pickle.loads(pickle.dumps(cls("left: got shape (2,), expected (H, W, 3)")))
    assert type(back) is cls and isinstance(back, errors.RgbdError)
    assert str(back) == "left: got shape (2,), expected (H, W, 3)"
    assert cls.__module__ == "rgbd_rs.errors"


def test_num_threads_is_the_pools_size_beyond_the_cores() -> None:
    # RAYON_NUM_THREADS above the cores: the pool runs that many, and num_threads() said the
    # cores.
    import os

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    wanted = (cores or 1) + 3
    run = subprocess.run(
        [sys.executable, "-c", "from rgbd_rs import _rgbd_rs; print(_rgbd_rs.num_threads())"],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "RAYON_NUM_THREADS": str(wanted)},
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert int(run.stdout) == wanted
