"""The matcher's cost volume refused by the allocator (a process under an address-space limit,
``ulimit -v``, as cluster schedulers set) is a MemoryError naming what it was for, and ``rgbd``
says so in one line: the process aborted (SIGABRT, a Rust backtrace) before."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.io import write_png

# RLIMIT_AS and /proc/self/status: Linux's.
pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="needs Linux's RLIMIT_AS")

# A child that limits its own address space to what it holds plus 400 MB, then runs CALL
# (which needs a ~1 GB cost volume: 1000 x 1000 pixels x 501 disparities x 2 bytes).
_CHILD = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    import rgbd_rs.fusion, rgbd_rs.cli
    a = np.random.default_rng(0).integers(0, 256, (1000, 1000), dtype=np.uint8)
    rgbd_rs.fusion.census_match(a[:40, :60], a[:40, :60], max_disparity=8)  # threads started
    held = int(next(l for l in open("/proc/self/status") if l.startswith("VmSize")).split()[1])
    limit = held * 1024 + 400_000_000
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    {call}
    """
)


def _child(call: str) -> subprocess.CompletedProcess[str]:
    code = _CHILD.format(call=call)
    env = {**os.environ, "RAYON_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env
    )


def _memory_error(call: str) -> str:
    """What the child's MemoryError of ``call`` says ('' when it raised none)."""
    run = _child(f"try:\n    {call}\nexcept MemoryError as exc:\n    print(exc)")
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def test_census_volume_out_of_memory_is_a_memory_error() -> None:
    said = _memory_error("rgbd_rs.fusion.census_match(a, a, reference='left', max_disparity=500)")
    assert said.startswith("max_disparity: out of memory: could not reserve")
    assert "cost volume" in said


def test_cli_says_what_it_could_not_reserve(tmp_path: Path) -> None:
    img = np.random.default_rng(0).integers(0, 256, (1000, 1000), dtype=np.uint8)
    write_png(tmp_path / "l.png", img)
    argv = ["stereo", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "l.png"),
            "--max-disparity", "500", "--out", str(tmp_path / "o")]  # fmt: skip
    run = _child(f"sys.exit(rgbd_rs.cli.main({argv!r}))")
    assert run.returncode == 2, run.stderr[-2000:]
    assert run.stderr.startswith("rgbd: error: --max-disparity: out of memory: could not reserve")


def test_opencv_volume_out_of_memory_is_a_memory_error() -> None:
    # OpenCV's "Insufficient memory" cv2.error traceback, in our words.
    said = _memory_error("rgbd_rs.fusion.sgm(a, a, max_disparity=480, method='opencv')")
    assert said.startswith("max_disparity: out of memory: OpenCV SGBM could not allocate"), said


def test_opencv_refuses_a_volume_census_refuses() -> None:
    # 3000 x 2000 x 400 disparities: 2.4e9 elements, refused before OpenCV allocates ~9 GB.
    from rgbd_rs._rgbd_rs import MAX_ELEMENTS
    from rgbd_rs.errors import InvalidArgumentError
    from rgbd_rs.fusion import census_match, sgm

    img = np.zeros((2000, 3000), np.uint8)
    assert MAX_ELEMENTS < 2000 * 3000 * 400
    for call in (
        lambda: sgm(img, img, max_disparity=400, method="opencv"),
        lambda: census_match(img, img, max_disparity=399),
    ):
        with pytest.raises(
            InvalidArgumentError, match=r"^max_disparity: got 399|^max_disparity: got 400"
        ):
            call()
