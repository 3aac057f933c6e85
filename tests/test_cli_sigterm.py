"""SIGTERM (a scheduler stopping a job) ends `rgbd` as Ctrl-C does: one line, exit 143, no
temporary file left; a full disk while writing a checkpoint is one line naming the file, not
torch's traceback."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from rgbd_rs.cli import main
from rgbd_rs.errors import RgbdError
from rgbd_rs.nn.checkpoint import Checkpoint, save_checkpoint


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_is_a_clean_exit(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "c"
    argv = ["shapes", "cache", "--data", "modelnet10", "--out", str(out), "--resolution", "16"]
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from rgbd_rs.cli import main; sys.exit(main())",
         *argv, "--representations", "volume", "--workers", "1", "--quiet"],
        stderr=subprocess.PIPE, text=True, env=os.environ | {"OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (out / "done.npy").is_file() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.0)  # into the work
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "rgbd: terminated (SIGTERM)" in err and "Traceback" not in err
    assert not list(out.glob(".*.tmp")), "no temporary file left"


def test_handler_restored_after_a_command(tmp_path: Path) -> None:
    before = signal.getsignal(signal.SIGTERM)
    assert main(["shapes", "cache", "--data", str(tmp_path / "none.npz"), "--out",
                 str(tmp_path / "c")]) == 2  # fmt: skip
    assert signal.getsignal(signal.SIGTERM) == before


def test_full_disk_while_saving_a_checkpoint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(obj: object, f: object) -> None:
        try:
            raise OSError(28, "No space left on device")
        except OSError:
            raise RuntimeError("[enforce fail at inline_container.cc:671] . unexpected pos")  # noqa: B904

    ckpt = Checkpoint(
        path=tmp_path / "x", arch="tiny", arch_config={}, normalisation={},
        model_state={"w": torch.zeros(2)},
    )  # fmt: skip
    monkeypatch.setattr(torch, "save", full)
    with pytest.raises(RgbdError, match=r"last\.pt: could not be written \(No space left"):
        save_checkpoint(ckpt, tmp_path / "last.pt")
    assert list(tmp_path.iterdir()) == []
