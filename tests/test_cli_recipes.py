"""The recipes of the docs' getting-started page run as written (tiny sizes)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


def rgbd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rgbd_rs.cli", *args], capture_output=True, text=True, check=False
    )


@pytest.mark.slow
def test_synth_output_feeds_fuse(tmp_path: Path) -> None:
    """`rgbd synth` writes data.npz with both ToF maps; `rgbd fuse` takes it for both flags."""
    res = rgbd("synth", "--out", str(tmp_path / "s"), "--train", "0", "--test", "1", "--scale",
               "0.1", "--quiet")  # fmt: skip
    assert res.returncode == 0, res.stderr
    scene = tmp_path / "s" / "test" / "scene_0000"
    res = rgbd(
        "fuse", "--left", str(scene / "left.png"), "--right", str(scene / "right.png"),
        "--tof-depth", str(scene / "data.npz"), "--tof-amplitude", str(scene / "data.npz"),
        "--calib", str(tmp_path / "s" / "calibration.json"), "--out", str(tmp_path / "f"),
        "--confidence", "heuristic",
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    with np.load(tmp_path / "f" / "fused.npz") as out, np.load(scene / "data.npz") as data:
        fused, gt = out["disparity"], data["gt_disparity"]
        assert fused.shape == gt.shape
        ok = np.isfinite(fused) & np.isfinite(gt)
        assert ok.mean() > 0.5
        assert np.median(np.abs(fused[ok] - gt[ok])) < 1.0  # px: a real fusion, not noise


def test_load_map_picks_named_tof_maps(tmp_path: Path) -> None:
    from rgbd_rs.cli.fusion import load_map
    from rgbd_rs.errors import InvalidArgumentError

    npz = tmp_path / "data.npz"
    depth, amp = np.full((2, 3), 1.5, np.float32), np.full((2, 3), 7.0, np.float32)
    np.savez(npz, tof_depth=depth, tof_amplitude=amp, gt_depth=depth + 1)
    got = load_map("--tof-depth", npz, depth=True, names=("tof_depth",))
    np.testing.assert_array_equal(got, depth)
    got = load_map("--tof-amplitude", npz, names=("tof_amplitude", "amplitude"))
    np.testing.assert_array_equal(got, amp)
    with pytest.raises(InvalidArgumentError, match=r"or one named 'tof_depth', or one named 'dep"):
        np.savez(npz, a=depth, b=amp)
        load_map("--tof-depth", npz, depth=True, names=("tof_depth",))
