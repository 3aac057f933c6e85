"""Files whose header declares more than the library processes are refused from the header,
before their data is read or decoded (a 1.2 MB PNG of 20000 x 20000 pixels took 3.5 GB and 27 s
to decode before ``rgbd stereo`` refused it; a 12 GB cloud was read whole)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rgbd_rs._rgbd_rs import MAX_ELEMENTS, MAX_PIXELS
from rgbd_rs.cli import main
from rgbd_rs.errors import RgbdError
from rgbd_rs.io import MAX_NPY_BYTES, MAX_NPY_ELEMENTS, MAX_PNG_PIXELS, read_npy, read_png
from test_bad_input_round3 import _png_header


def _npy_claiming(path: Path, shape: tuple[int, ...]) -> Path:
    with path.open("wb") as f:
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": shape}
        )
        f.write(b"\0" * 64)
    return path


def test_limits_are_what_the_library_processes() -> None:
    assert MAX_PNG_PIXELS == MAX_PIXELS and MAX_NPY_ELEMENTS == MAX_ELEMENTS


def test_a_png_beyond_the_pixel_limit_is_refused_from_its_header(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = _png_header(tmp_path, 20000, 20000)  # 4e8: over 2^28, under 2^30
    with pytest.raises(RgbdError, match=r"the PNG header says 20000x20000 pixels, expected"):
        read_png(png)
    argv = ["stereo", "--left", str(png), "--right", str(png), "--max-disparity", "64"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    assert "the PNG header says 20000x20000 pixels" in capsys.readouterr().err


def test_an_npy_beyond_the_element_limit_is_refused_from_its_header(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    big = _npy_claiming(tmp_path / "cloud.npy", (1_000_000_000, 3))
    with pytest.raises(RgbdError, match=r"header says shape \(1000000000, 3\) \(3000000000 elem"):
        read_npy(big)
    assert main(["classify", str(big)]) == 2
    assert "header says shape (1000000000, 3)" in capsys.readouterr().err
    # A version 3.0 header is read too.
    v3 = tmp_path / "v3.npy"
    with v3.open("wb") as f:
        np.lib.format.write_array_header_2_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": (1_000_000_000, 3)}
        )
    data = bytearray(v3.read_bytes())
    data[6] = 3  # version 3.0: 2.0's layout
    v3.write_bytes(bytes(data))
    with pytest.raises(RgbdError, match=r"header says shape \(1000000000, 3\)"):
        read_npy(v3)
    # Within the limit, a short file is still the truncated file it is.
    small = _npy_claiming(tmp_path / "short.npy", (1000, 3))
    with pytest.raises(RgbdError, match=r"not a readable \.npy array"):
        read_npy(small)


def test_an_npy_file_beyond_the_byte_limit_is_refused_unread(tmp_path: Path) -> None:
    # Whatever its header says (a structured dtype, data beyond it): the file's size decides.
    big = _npy_claiming(tmp_path / "padded.npy", (10, 3))
    with big.open("r+b") as f:
        f.truncate(MAX_NPY_BYTES + 1)  # sparse: no disk used
    with pytest.raises(RgbdError, match=rf"a file of {MAX_NPY_BYTES + 1} bytes, expected at most"):
        read_npy(big)
