"""tools/train_shapes_gpu.sh, the prepared GPU run of issue 31, at toy size on this CPU: the
same cache, training and bring-back steps the device runs (its `smoke` mode), so the script
keeps working while no device is lent. No GPU is used or needed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tools" / "train_shapes_gpu.sh"


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_the_gpu_script_runs_its_steps_at_toy_size(shared_data: Path) -> None:
    env = {**os.environ, "RGBD_DATA": str(shared_data), "PYTHON": sys.executable}
    run = subprocess.run(
        ["bash", str(SCRIPT), "smoke"], env=env, capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    out = Path(run.stdout.strip().splitlines()[-1].split("(")[-1].rstrip(")"))
    try:
        ckpt = torch.load(out / "best.pt", map_location="cpu", weights_only=False)
        assert ckpt["arch_config"]["width"] == 8
        assert ckpt["arch_config"]["view_resolution"] == 32
        assert (out / "curve.png").stat().st_size > 0
        log = (out / "log.txt").read_text()
        assert "training finished" in log
        assert "epoch 1/1, train loss" in log, log  # one line per epoch in the log
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_the_gpu_scripts_cross_validation_runs_at_toy_size(shared_data: Path) -> None:
    # Two folds of the 20 toy training shapes, two seeds each: every shape read once, by the
    # networks that never trained on it.
    env = {**os.environ, "RGBD_DATA": str(shared_data), "PYTHON": sys.executable}
    env["SCALE_RANGE_CV"] = "0.8 1.25"
    run = subprocess.run(
        ["bash", str(SCRIPT), "smoke", "cv"], env=env, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    out = Path(run.stdout.strip().splitlines()[-1].split("(")[-1].rstrip(")"))
    try:
        log = (out / "log.txt").read_text()
        assert log.count("all 2 folds: ") == 2 and "% of 20 shapes" in log, log
        assert log.count("weighted by --class-counts: ") == 2, log
        meta = json.loads((out.parent / "cache" / "meta.json").read_text())
        assert meta["augmentation"]["scale_range"] == [0.8, 1.25]
        folds = [(out.parent / f"fold{i}.txt").read_text().split() for i in (0, 1)]
        assert len(folds[0]) == len(folds[1]) == 10 and not set(folds[0]) & set(folds[1])
        with tarfile.open(out / "cv.tgz") as tar:
            assert {"cv0.npz", "cv1.npz", "fold0.txt"} <= set(tar.getnames())
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)


def test_the_gpu_script_explains_itself_without_a_step() -> None:
    run = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, timeout=30)
    assert run.returncode == 2
    assert "prepare" in run.stdout and "carry" in run.stdout


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_the_cross_validation_stops_at_a_failed_run(shared_data: Path, tmp_path: Path) -> None:
    """A fold's run that fails after writing a last.pt (killed part-way) stops the loop with
    its fold and status: its checkpoint is never read as a finished network."""
    fake = tmp_path / "python"
    fake.write_text(
        "#!/bin/bash\n"
        'if [[ "$*" == *"train shapes"* ]]; then\n'
        '  out=$(printf "%s\\n" "$@" | grep -A1 -x -- --out | tail -1)\n'
        '  mkdir -p "$out" && echo partial > "$out/last.pt"; exit 9\n'
        "fi\n"
        f'exec "{sys.executable}" "$@"\n'
    )
    fake.chmod(0o755)
    env = {**os.environ, "RGBD_DATA": str(shared_data), "PYTHON": str(fake)}
    run = subprocess.run(
        ["bash", str(SCRIPT), "smoke", "cv"], env=env, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 3, run.stdout[-2000:] + run.stderr[-2000:]
    assert "train_shapes_gpu: fold 0 seed 1 failed (status 9)" in run.stderr
    assert "all 2 folds" not in run.stdout
