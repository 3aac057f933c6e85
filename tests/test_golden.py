"""Golden files for end-to-end outputs (kornia-rs style: the parameters are in the file name).

Each case builds its input deterministically, runs the public function with the parameters its
file name spells out, and compares with ``tests/golden/<name>.npz`` under the tolerance written
beside it. After a deliberate change of behaviour, regenerate with
``RGBD_UPDATE_GOLDEN=1 python -m pytest tests/test_golden.py`` and say why in the commit.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.data.synth import generate, synth3_rig
from rgbd_rs.fusion import LcParams, fuse
from rgbd_rs.io import read_npz, write_npz
from rgbd_rs.surface import fit_grid

GOLDEN = Path(__file__).parent / "golden"
UPDATE = os.environ.get("RGBD_UPDATE_GOLDEN") == "1"


def _fuse(confidence: str, radius: int, stride: int) -> dict[str, np.ndarray]:
    rig = synth3_rig(0.125)  # 240 x 135
    s = generate(0, "test", 0, rig, meshes=[])[0]
    out = fuse(
        s.left,
        s.right,
        s.tof_depth,
        s.tof_amplitude,
        rig,
        confidence=confidence,  # type: ignore[arg-type]
        params=LcParams(radius=radius, stride=stride),
    )
    return {"disparity": out.disparity, "plausibility": out.plausibility}


def _fit_grid(spacing: float, degree: int) -> dict[str, np.ndarray]:
    h, w = 48, 64
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    x, y = (u - w / 2) / 100.0, (v - h / 2) / 100.0
    z = 1.5 + 0.8 * x * x - 0.5 * y * y + 0.3 * x * y
    z += np.random.default_rng(0).normal(0.0, 0.001, z.shape)  # 1 mm noise, seed 0
    pts = np.stack([x, y, z], axis=-1).astype(np.float32)
    fit = fit_grid(pts, spacing=spacing, degree=degree)
    return {"fitted": fit.fitted, "k1": fit.k1, "k2": fit.k2}


# name -> (builder, absolute tolerance per key, fraction of pixels that must be within it)
CASES: dict[str, tuple[Callable[[], dict[str, np.ndarray]], dict[str, float], float]] = {
    "fuse_synth-test0-nomesh_240x135_heuristic_radius3_stride2": (
        lambda: _fuse("heuristic", 3, 2),
        {"disparity": 0.05, "plausibility": 0.02},
        0.99,
    ),
    "fuse_synth-test0-nomesh_240x135_uniform_radius3_stride1": (
        lambda: _fuse("uniform", 3, 1),
        {"disparity": 0.05, "plausibility": 0.02},
        0.99,
    ),
    "fit_grid_quadric-noise1mm-seed0_64x48_spacing16_degree3": (
        lambda: _fit_grid(16.0, 3),
        {"fitted": 1e-5, "k1": 1e-3, "k2": 1e-3},
        1.0,
    ),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_matches_golden(name: str) -> None:
    build, tolerance, fraction = CASES[name]
    got = build()
    path = GOLDEN / f"{name}.npz"
    if UPDATE:
        write_npz(path, got)
    want = read_npz(path)
    assert set(want) == set(got), f"{path.name}: keys {sorted(want)} vs {sorted(got)}"
    for key, tol in tolerance.items():
        a, b = got[key], want[key]
        assert a.shape == b.shape, f"{key}: shape {a.shape} vs golden {b.shape}"
        same_nan = np.isnan(a) == np.isnan(b)
        assert same_nan.mean() >= fraction, f"{key}: NaN masks differ on {1 - same_nan.mean():.2%}"
        both = ~np.isnan(a) & ~np.isnan(b)
        close = np.abs(a[both] - b[both]) <= tol
        assert close.mean() >= fraction, (
            f"{key}: {1 - close.mean():.2%} of pixels differ by more than {tol} from {path.name} "
            f"(max {np.abs(a[both] - b[both]).max():.3g})"
        )
