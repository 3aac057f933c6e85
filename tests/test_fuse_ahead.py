"""fuse() runs LC on a worker thread beside its input checks (`fusion._ahead`): the result, the
warnings and their order are those of the sequential code, Ctrl-C stops the worker's kernel, and
no thread outlives the call."""

from __future__ import annotations

import importlib
import subprocess
import sys
import textwrap
import threading
import time
import warnings

import numpy as np
import pytest

from forked import NEEDS_FORK, in_forked_child
from rgbd_rs import _rgbd_rs
from rgbd_rs.data.synth import SynthSample, generate, synth3_rig
from rgbd_rs.fusion import FusionResult, LcParams, fuse, lc_fuse
from rgbd_rs.fusion._ahead import Ahead, stopped_on_interrupt

RIG = synth3_rig(0.25)  # 480 x 270
FUSE = importlib.import_module("rgbd_rs.fusion.fuse")  # the name is also the function


@pytest.fixture(scope="module")
def scene() -> SynthSample:
    return generate(0, "test", 1, RIG)[0]


def _ahead_threads(wait: float = 2.0) -> list[str]:
    """Names of the worker threads still alive (after up to ``wait`` s for them to exit)."""
    end = time.monotonic() + wait
    while True:
        alive = [t.name for t in threading.enumerate() if t.name.startswith("rgbd-ahead")]
        if not alive or time.monotonic() > end:
            return alive
        time.sleep(0.01)


def test_ahead_returns_the_result_and_raises_the_exception() -> None:
    assert Ahead(lambda a, b: a + b, 2, 3).result() == 5

    def fail() -> None:
        raise ValueError("boom")

    failed = Ahead(fail)
    with pytest.raises(ValueError, match="boom"):
        failed.result()
    failed.wait()  # swallowed: the result is no longer wanted
    assert _ahead_threads() == []


def test_interrupting_with_no_kernel_running_leaves_the_next_call_alone() -> None:
    img = np.full((8, 16, 3), 128, np.uint8)
    d = np.full((8, 16), 3.0, np.float32)
    before = lc_fuse(img, img, [d])[0]
    assert np.isfinite(before).sum() > 64
    _rgbd_rs.interrupt_running()
    np.testing.assert_array_equal(lc_fuse(img, img, [d])[0], before)


def test_ctrl_c_beside_the_worker_stops_its_kernel() -> None:
    # A dense radius-64 LC on 960x540 runs ~25 s on two cores; KeyboardInterrupt on this thread
    # 0.3 s in must stop it within a few rows and propagate, and the next call runs normally.
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (540, 960, 3), dtype=np.uint8)
    d = rng.uniform(0, 64, (540, 960)).astype(np.float32)
    params = LcParams(radius=64, stride=1)
    t0 = time.monotonic()
    ahead = Ahead(_lc, img, d, params)
    with pytest.raises(KeyboardInterrupt), stopped_on_interrupt(ahead):
        time.sleep(0.3)
        raise KeyboardInterrupt
    assert time.monotonic() - t0 < 8.0
    with pytest.raises(KeyboardInterrupt):
        ahead.result()  # the kernel's own answer to the request
    assert _ahead_threads() == []
    assert np.isfinite(lc_fuse(img[:8, :16], img[:8, :16], [d[:8, :16]])[0]).any()


def test_the_callers_kernels_do_not_queue_behind_the_workers() -> None:
    # The worker's kernels run in a pool of their own: a parallel kernel called here while a
    # ~25 s LC runs there finishes in its own time, not after the worker's (as it would in one
    # shared pool, whose threads take queued jobs only once theirs are done).
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, (540, 960, 3), dtype=np.uint8)
    d = rng.uniform(0, 64, (540, 960)).astype(np.float32)
    small = (img[:96, :128], d[:96, :128])
    alone = lc_fuse(small[0], small[0], [small[1]])[0]
    ahead = Ahead(_lc, img, d, LcParams(radius=64, stride=1))
    with pytest.raises(KeyboardInterrupt), stopped_on_interrupt(ahead):
        time.sleep(0.2)
        t0 = time.monotonic()
        beside = lc_fuse(small[0], small[0], [small[1]])[0]
        took = time.monotonic() - t0
        raise KeyboardInterrupt
    assert took < 5.0, took
    np.testing.assert_array_equal(beside, alone)
    assert _ahead_threads() == []


def _lc(img: np.ndarray, d: np.ndarray, params: LcParams) -> np.ndarray:
    return lc_fuse(img, img, [d], params=params)[0]


def _fuse_heuristic(scene: SynthSample) -> FusionResult:
    return fuse(
        scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG, confidence="heuristic"
    )


def _checks_that_warn(monkeypatch: pytest.MonkeyPatch) -> None:
    """fuse()'s checks, saying "from the checks" first."""
    checks = FUSE.check_maps

    def noisy_checks(*args: object, **kwargs: object) -> object:
        warnings.warn("from the checks", RuntimeWarning, stacklevel=2)
        return checks(*args, **kwargs)

    monkeypatch.setattr(FUSE, "check_maps", noisy_checks)


def test_fuse_says_the_checks_warnings_before_the_confidences(
    scene: SynthSample, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The confidences are computed before the checks run (LC starts on them), but their
    # warnings come after the checks', as when everything ran in order.
    confidence = FUSE.tof_confidence

    def noisy_confidence(*args: object, **kwargs: object) -> object:
        warnings.warn("from the confidences", RuntimeWarning, stacklevel=2)
        return confidence(*args, **kwargs)

    _checks_that_warn(monkeypatch)
    monkeypatch.setattr(FUSE, "tof_confidence", noisy_confidence)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = _fuse_heuristic(scene)
    said = [str(c.message) for c in caught if str(c.message).startswith("from the")]
    assert said == ["from the checks", "from the confidences"]
    assert np.isfinite(out.disparity).any()
    assert _ahead_threads() == []


def test_a_failing_confidence_still_lets_the_checks_speak_first(
    scene: SynthSample, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The confidences run before the checks now; where they raise, the error comes after the
    # checks' warnings, as it did when everything ran in order.

    def failing(*_: object, **__: object) -> None:
        raise RuntimeError("the confidence failed")

    _checks_that_warn(monkeypatch)
    monkeypatch.setattr(FUSE, "stereo_confidence", failing)
    with (
        warnings.catch_warnings(record=True) as caught,
        pytest.raises(RuntimeError, match="failed"),
    ):
        warnings.simplefilter("always")
        _fuse_heuristic(scene)
    assert "from the checks" in [str(c.message) for c in caught]


def test_ctrl_c_while_fuse_waits_for_a_discarded_lc_interrupts() -> None:
    # Where the checks correct the ToF, fuse() waits for the LC started on the old maps before
    # fusing again: Ctrl-C during that wait must stop it and raise, not be swallowed. SIGINT
    # comes 0.5 s into a slow LC (radius 48, stride 1: seconds at 480 x 270).
    code = """
        import dataclasses, importlib, os, signal, threading, time, warnings
        signal.signal(signal.SIGINT, signal.default_int_handler)
        from rgbd_rs.data.synth import generate, synth3_rig
        from rgbd_rs.fusion import LcParams, fuse
        FUSE = importlib.import_module("rgbd_rs.fusion.fuse")
        rig = synth3_rig(0.25)
        s = generate(0, "test", 1, rig)[0]
        checks = FUSE.check_maps
        def corrected(*a, **k):
            c = checks(*a, **k)
            threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
            return dataclasses.replace(c, found=object())  # as if the pose were corrected
        FUSE.check_maps = corrected
        t0 = time.monotonic()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fuse(s.left, s.right, s.tof_depth, s.tof_amplitude, rig,
                     confidence="heuristic", params=LcParams(radius=48, stride=1))
            print("returned", time.monotonic() - t0)
        except KeyboardInterrupt:
            print("interrupted", time.monotonic() - t0)
        end = time.monotonic() + 2.0  # the worker thread exits just after its call
        while True:
            alive = [t for t in threading.enumerate() if t.name.startswith("rgbd-ahead")]
            if not alive or time.monotonic() > end:
                break
            time.sleep(0.01)
        print("alive", len(alive))
        """
    out = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    words = out.stdout.split()
    assert out.returncode == 0, out.stderr
    assert words[0] == "interrupted", out.stdout
    assert float(words[1]) < 8.0, out.stdout
    assert words[2:] == ["alive", "0"], out.stdout


def test_fuse_equals_lc_of_its_own_maps(scene: SynthSample) -> None:
    # What fuse() returns is LC of the maps and confidences it returns (the ones the checks
    # kept), with the single-source steps after it.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG)
    assert out.tof_confidence is not None and out.stereo_confidence is not None
    lc = lc_fuse(
        scene.right,
        scene.left,
        [out.tof_fused, out.stereo_disparity],
        [out.tof_confidence, out.stereo_confidence],
        target_sign=1,
    )[0]
    from_lc = out.source == FUSE.SOURCE_LC
    assert from_lc.mean() > 0.5
    np.testing.assert_array_equal(out.disparity[from_lc], lc[from_lc])


def _heuristic(scene: SynthSample) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _fuse_heuristic(scene).disparity


@NEEDS_FORK
def test_fuse_works_in_a_forked_child(scene: SynthSample) -> None:
    # The parent's side pool (and its worker threads) exist before the fork; the child builds
    # its own instead of waiting for threads it did not inherit. (Heuristic confidences: torch's
    # OpenMP threads are not the subject here.)
    here = _heuristic(scene)
    np.testing.assert_array_equal(in_forked_child(_heuristic, scene), here)
