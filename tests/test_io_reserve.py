"""Memory-mapped cache arrays reserve their disk blocks when created: a full disk is a clear
RgbdError naming the file, not a SIGBUS ("Bus error") at the first write to a missing block."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.errors import RgbdError
from rgbd_rs.io import _create_once, _npy_writer, _reserve


@pytest.mark.skipif(not hasattr(os, "posix_fallocate"), reason="no posix_fallocate here")
def test_blocks_are_reserved(tmp_path: Path) -> None:
    _create_once(tmp_path / "a.npy", _npy_writer((64, 1024), np.float32))
    _reserve(tmp_path / "a.npy")
    _reserve(tmp_path / "a.npy")  # again: harmless (a second shard)
    st = (tmp_path / "a.npy").stat()
    assert st.st_blocks * 512 >= 64 * 1024 * 4  # allocated, not sparse
    assert np.load(tmp_path / "a.npy", mmap_mode="r").shape == (64, 1024)


def test_a_full_disk_is_an_error_naming_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(fd: int, offset: int, size: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "posix_fallocate", full, raising=False)
    _create_once(tmp_path / "depth.npy", _npy_writer((64, 1024), np.float32))
    with pytest.raises(
        RgbdError, match=r"depth\.npy: could not reserve 0\.3 MB on disk \(No space"
    ):
        _reserve(tmp_path / "depth.npy")


def test_a_filesystem_that_cannot_reserve_is_fine(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def unsupported(fd: int, offset: int, size: int) -> None:
        raise OSError(errno.EOPNOTSUPP, "Operation not supported")

    monkeypatch.setattr(os, "posix_fallocate", unsupported, raising=False)
    _create_once(tmp_path / "a.npy", _npy_writer((4, 4), np.uint8))
    _reserve(tmp_path / "a.npy")
    assert (tmp_path / "a.npy").is_file()
