"""Bad input to :mod:`rgbd_rs.segmentation.oversegment` (see tests/test_bad_input.py for the
contract and the meta-test that counts these cases)."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError

OV = importlib.import_module("rgbd_rs.segmentation.oversegment")  # the module, not the function


SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

F = np.random.default_rng(0).normal(size=(12, 16, 9)).astype(np.float32)
NAN = np.full((12, 16, 9), np.nan, np.float32)
ONE = NAN.copy()
ONE[3, 4] = 0.0  # a single valid pixel
INF = F.copy()
INF[0, 0, 2] = np.inf

CASES: list[Case] = [
    Case("oversegment", lambda: OV.oversegment(F[:, :, 0], 4), SHAPE, r"^features: got shape"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F[None], 4),
        SHAPE,
        r"^features: got shape \(1, 12, 16, 9\)",
        "4-D",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F.astype(np.int32), 4),
        ARG,
        r"^features: got dtype int32",
        "dtype",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F[:, :, :0], 4),
        SHAPE,
        r"^features: got an empty array",
        "no channel",
    ),
    Case("oversegment", lambda: OV.oversegment(NAN, 4), ARG, r"^features: got 0 valid", "all NaN"),
    Case("oversegment", lambda: OV.oversegment(ONE, 1), ARG, r"^features: got 1 valid", "one"),
    Case("oversegment", lambda: OV.oversegment(INF, 4), ARG, r"^features: got 1 infinite", "inf"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 12 * 16 + 1),
        ARG,
        r"^n_segments: got 193, expected at most the 192 valid",
        "k > valid",
    ),
    Case("oversegment", lambda: OV.oversegment(F, 0), ARG, r"^n_segments: got 0", "k = 0"),
    Case("oversegment", lambda: OV.oversegment(F, 4, sigma=0.0), ARG, r"^sigma: got 0", "sigma"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, sigma=float("nan")),
        ARG,
        r"^sigma: got nan",
        "sigma nan",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, n_samples=1),
        ARG,
        r"^n_samples: got 1",
        "samples",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, n_samples=10, n_vectors=10),
        ARG,
        r"^n_vectors: got 10, expected fewer than the 10",
        "vectors",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, n_samples=2**31),  # issue 32: clamped, then ran O(n^3)
        ARG,
        r"^n_samples: got 2147483648, expected an integer >= 2 and <= 4096",
        "samples huge",
    ),
    Case("oversegment", lambda: OV.oversegment(F, 4, seed=-1), ARG, r"^seed: got -1", "seed"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, min_size=0),
        ARG,
        r"^min_size: got 0",
        "min_size",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, spatial_weight=-1.0),
        ARG,
        r"^spatial_weight: got -1",
        "spatial",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, feature_weight=float("inf")),
        ARG,
        r"^feature_weight: got inf",
        "feature_weight",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 8, fit_points=5),
        ARG,
        r"^fit_points: got 5, expected >= n_segments = 8",
        "fit_points",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, channel_weights=np.ones(3)),
        SHAPE,
        r"^channel_weights: got shape \(3,\)",
        "weights shape",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, channel_weights=np.zeros(9)),
        ARG,
        r"^channel_weights: got \[0\.0",
        "weights zero",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, quiet="yes"),  # type: ignore[arg-type]
        ARG,
        r"^quiet: got 'yes'",
        "quiet",
    ),
    Case(
        "default_channel_weights",
        lambda: OV.default_channel_weights(0),
        ARG,
        r"^n_channels: got 0",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


# Issue 32: faer's x86 matrix product gives each thread a packing buffer of twice the detected
# L3 (hundreds of MiB, whatever the frame size) with an infallible allocation, so a 64 x 48
# frame aborted the interpreter when memory was short. The kernels now reserve it fallibly
# first. Run under an address-space limit just above what the process already maps.
_LIMITED = """
import resource, sys
import numpy as np
from rgbd_rs.segmentation import oversegment
f = np.random.default_rng(0).random((48, 64, 9), dtype=np.float32)
with open("/proc/self/status") as s:
    vm = next(int(l.split()[1]) * 1024 for l in s if l.startswith("VmSize"))
resource.setrlimit(resource.RLIMIT_AS, (vm + int(sys.argv[1]) * 2**20, resource.RLIM_INFINITY))
for _ in range(3):
    try:
        print("labels", oversegment(f, 20).max() + 1, flush=True)
    except MemoryError as e:
        print("MemoryError:", e, flush=True)
"""


def _limited(headroom_mib: int) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", _LIMITED, str(headroom_mib)],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "RAYON_NUM_THREADS": "2"},
    )


@pytest.mark.skipif(
    not Path("/sys/devices/system/cpu/cpu0/cache").is_dir(), reason="no cache description"
)
def test_short_of_memory_is_a_memory_error_not_an_abort() -> None:
    res = _limited(32)  # far less than one thread's buffer
    assert res.returncode == 0, res.stderr[-2000:]
    lines = res.stdout.splitlines()
    assert len(lines) == 3, res.stdout
    assert all(line.startswith("MemoryError: oversegment: out of memory") for line in lines)
    assert "RAYON_NUM_THREADS=1" in lines[0]
    per_thread = int(re.search(r"(\d+) MiB for each of", lines[0]).group(1))  # type: ignore[union-attr]
    res = _limited(4 * per_thread + 256)  # room for the 3 threads' buffers once, not 3 times
    assert res.returncode == 0, res.stderr[-2000:]
    assert [line.split()[0] for line in res.stdout.splitlines()] == ["labels"] * 3, res.stdout
