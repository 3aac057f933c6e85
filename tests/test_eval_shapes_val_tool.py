"""tools/eval_shapes_val.py --combine: the folds' accuracy, per class and weighted by counts."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

TOOL = Path(__file__).resolve().parents[1] / "tools" / "eval_shapes_val.py"


def _fold(path: Path, labels: list[int], preds: list[int], names: list[str], **where: int) -> Path:
    probs = np.full((len(labels), 3), 0.1, np.float32)
    probs[np.arange(len(labels)), preds] = 0.8
    np.savez(path, probabilities=probs, labels=np.array(labels), names=np.array(names), **where)
    return path


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(TOOL), *args], capture_output=True, text=True, check=False
    )


def test_combine_per_class_and_weighted(tmp_path: Path) -> None:
    # class 0: 3 of 4 right, class 1: 2 of 2, class 2: 0 of 2
    a = _fold(tmp_path / "a.npz", [0, 0, 1, 2], [0, 1, 1, 0], ["a0", "a1", "a2", "a3"])
    b = _fold(tmp_path / "b.npz", [0, 0, 1, 2], [0, 0, 1, 1], ["b0", "b1", "b2", "b3"])
    r = _run("--combine", str(a), str(b), "--class-counts", "1,1,2")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "class 0: 75.00 % of 4 shapes" in lines and "class 2: 0.00 % of 2 shapes" in lines
    assert "weighted by --class-counts: 43.75 %" in lines  # (0.75 + 1 + 0) / 4
    assert lines[-1] == "all 2 folds: 62.50 % of 8 shapes", "the total stays the last line"
    plain = _run("--combine", str(a), str(b))
    assert plain.stdout.splitlines()[-1] == lines[-1] and "class 0" not in plain.stdout
    bad = _run("--combine", str(a), str(b), "--class-counts", "1,1")
    assert bad.returncode != 0 and "got 2 counts, expected 3" in bad.stderr
    neg = _run("--combine", str(a), "--class-counts", "1,-1,2")
    assert "expected non-negative counts" in neg.stderr and not neg.stdout, "checked first"
    assert "positive sum" in _run("--combine", str(a), "--class-counts", "0,0,0").stderr
    c = _fold(tmp_path / "c.npz", [0, 1], [0, 1], ["c0", "c1"])
    assert "class 2 has a count" in _run("--combine", str(c), "--class-counts", "1,1,1").stderr
    alone = _run("--cache", str(tmp_path), "--class-counts", "1,1,1")
    assert alone.returncode == 2 and "goes with --combine" in alone.stderr
    assert _run("--combine", str(a), str(a)).returncode != 0, "a shape in two folds"
    assert "expected N1,N2" in _run("--combine", str(a), "--class-counts", "x").stderr


def test_combine_wants_every_fold(tmp_path: Path) -> None:
    """Files saved with their fold (``--save`` with ``--folds``): a missing or foreign fold is
    refused, not averaged over fewer shapes."""
    f0 = _fold(tmp_path / "0.npz", [0, 1], [0, 1], ["a", "b"], folds=3, fold=0)
    f1 = _fold(tmp_path / "1.npz", [2, 1], [2, 1], ["c", "d"], folds=3, fold=1)
    f2 = _fold(tmp_path / "2.npz", [0, 2], [0, 0], ["e", "f"], folds=3, fold=2)
    ok = _run("--combine", str(f0), str(f1), str(f2))
    assert ok.returncode == 0 and ok.stdout.splitlines()[-1] == "all 3 folds: 83.33 % of 6 shapes"
    short = _run("--combine", str(f0), str(f2))
    assert short.returncode != 0 and "folds [1] of 3 missing" in short.stderr
    other = _fold(tmp_path / "x.npz", [0], [0], ["g"], folds=2, fold=1)
    mixed = _run("--combine", str(f0), str(f1), str(f2), str(other))
    assert mixed.returncode != 0 and "[2, 3] folds mixed" in mixed.stderr
