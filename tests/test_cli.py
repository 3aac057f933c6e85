"""The `rgbd` command line: help, demo, reproject."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from rgbd_rs.cli import main


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rgbd_rs.cli", *args], capture_output=True, text=True, check=False
    )


def test_help_lists_commands() -> None:
    res = run("--help")
    assert res.returncode == 0
    assert "demo" in res.stdout and "reproject" in res.stdout
    assert run("demo", "--help").returncode == 0


def test_demo_prints_measurements(tmp_path: Path, shared_data: Path) -> None:
    res = run("demo", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "max error" in res.stdout and "Azure Kinect" in res.stdout
    assert (tmp_path / "synthetic_reprojection.png").stat().st_size > 1000
    assert (tmp_path / "kinect_depth_to_color.png").stat().st_size > 1000


def test_reproject_writes_outputs(tmp_path: Path, shared_data: Path) -> None:
    tof = shared_data / "tof"
    code = main(
        [
            "reproject",
            "--frame",
            str(tof / "azure_kinect_frame.npz"),
            "--calib",
            str(tof / "azure_kinect_calibration.json"),
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    with np.load(tmp_path / "depth.npz") as z:
        assert z["depth"].shape == (720, 1280)
    assert (tmp_path / "depth_mm.png").exists() and (tmp_path / "preview.png").exists()
    assert not list(tmp_path.glob("*.tmp*"))


def test_bad_input_is_a_clean_error(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(
        [
            "reproject",
            "--frame",
            str(tmp_path / "missing.npz"),
            "--calib",
            str(tmp_path / "missing.json"),
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 2
    assert "rgbd: error: path:" in capsys.readouterr().err
