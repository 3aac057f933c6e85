"""tools/choose_confidence_real.py refuses to choose among the epochs of an unfinished run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

TOOL = Path(__file__).resolve().parents[1] / "tools" / "choose_confidence_real.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(TOOL), *args], capture_output=True, text=True, check=False
    )


def test_a_missing_epoch_is_refused_before_any_scene_is_read(tmp_path: Path) -> None:
    for k in (1, 3):
        (tmp_path / f"ep{k}.pt").write_bytes(b"")
    gap = _run("--out", str(tmp_path))
    assert gap.returncode == 1 and "ep2.pt missing (1 of epochs 1..3)" in gap.stderr
    (tmp_path / "ep2.pt").write_bytes(b"")
    short = _run("--out", str(tmp_path), "--epochs", "5")
    assert short.returncode == 1 and "ep4.pt missing (2 of epochs 1..5)" in short.stderr
