"""The CLI's 16-bit disparity PNGs: 0 means "none" and nothing else."""

from __future__ import annotations

import numpy as np

from rgbd_rs.cli._maps import depth_mm_png16, disparity_png16


def test_only_missing_pixels_read_back_as_none() -> None:
    d = np.array([[np.nan, 0.0, -3.0, 1e-3], [1.5, 255.99, 300.0, np.inf]], np.float32)
    png = disparity_png16(d)
    assert png.dtype == np.uint16
    np.testing.assert_array_equal(png, [[0, 1, 1, 1], [384, 65533, 65535, 0]])
    # Within half a step of the value everywhere in range.
    x = np.linspace(0.01, 255.0, 1001, dtype=np.float32)[None]
    assert np.abs(disparity_png16(x) / 256.0 - x).max() <= 0.5 / 256 + 1e-6


def test_depth_png_keeps_every_measured_pixel() -> None:
    d = np.array([[np.nan, 0.0, 0.0004, 1.2344], [70.0, np.inf, -1.0, 0.0015]], np.float32)
    np.testing.assert_array_equal(depth_mm_png16(d), [[0, 1, 1, 1234], [65535, 65535, 1, 2]])
