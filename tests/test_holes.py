"""Depth holes: the nearest-pixel fill, and segment() on depth with holes (rgbd_rs.holes)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.data import NYUV2_CAMERA
from rgbd_rs.holes import DEFAULT_FILL_RADIUS, _isolated_share, fill_depth_holes
from rgbd_rs.io import read_png
from rgbd_rs.segmentation import segment

nan = np.nan


def test_a_hole_takes_its_nearest_measured_depth_within_the_radius() -> None:
    d = np.full((1, 9), nan, np.float32)
    d[0, 0], d[0, 8] = 1.0, 2.0
    # Distances 1..4 from the left pixel, 4..1 from the right one.
    np.testing.assert_array_equal(
        fill_depth_holes(d, 2), np.float32([[1, 1, 1, nan, nan, nan, 2, 2, 2]])
    )
    np.testing.assert_array_equal(fill_depth_holes(d, None)[0, [3, 5]], [1, 2])
    # 0, negative and infinite depths are holes too; radius 0 only marks them NaN.
    e = np.float32([[1.0, 0.0, -1.0, np.inf, 3.0]])
    np.testing.assert_array_equal(fill_depth_holes(e, 0), [[1, nan, nan, nan, 3]])
    np.testing.assert_array_equal(fill_depth_holes(e, 1), [[1, 1, nan, 3, 3]])
    # No value between two surfaces: every filled value is a measured one.
    rng = np.random.default_rng(0)
    f = rng.uniform(0.5, 4.0, (40, 50)).astype(np.float32)
    f[rng.random(f.shape) < 0.4] = 0
    filled = fill_depth_holes(f, None)
    assert np.isin(filled, f[f > 0]).all()
    np.testing.assert_array_equal(filled[f > 0], f[f > 0])


def test_the_radius_is_euclidean() -> None:
    one = np.full((41, 41), nan, np.float32)
    one[20, 20] = 1.0
    yy, xx = np.mgrid[:41, :41]
    for r in (1, 3, 7, 8, 12.5):
        disk = (yy - 20) ** 2 + (xx - 20) ** 2 <= r * r
        np.testing.assert_array_equal(np.isfinite(fill_depth_holes(one, r)), disk)


def test_edge_cases_and_bad_input() -> None:
    assert np.isnan(fill_depth_holes(np.zeros((3, 4)), None)).all()  # nothing measured
    full = np.ones((3, 4), np.float32)
    np.testing.assert_array_equal(fill_depth_holes(full), full)
    assert fill_depth_holes(np.ones((2, 2), np.float64)).dtype == np.float32
    with pytest.raises(ShapeMismatchError, match=r"^depth: got shape \(4,\)"):
        fill_depth_holes(np.ones(4))
    with pytest.raises(InvalidArgumentError, match=r"^radius: got -1"):
        fill_depth_holes(full, -1)
    with pytest.raises(InvalidArgumentError, match=r"^radius: got nan"):
        fill_depth_holes(full, nan)
    grid = np.zeros((9, 9), np.float32)
    grid[::3, ::3] = 1.0
    assert _isolated_share(grid) == 1.0 and _isolated_share(full) == 0.0
    assert _isolated_share(np.zeros((2, 2))) == 0.0
    assert _isolated_share(fill_depth_holes(grid, DEFAULT_FILL_RADIUS)) == 0.0


@pytest.fixture(scope="module")
def frame(shared_data: Path) -> tuple[np.ndarray, np.ndarray]:
    base = shared_data / "nyuv2" / "frames" / "0001"
    rgb = read_png(f"{base}_rgb.png")
    depth = read_png(f"{base}_depth.png").astype(np.float32) / 1000
    return rgb, depth


def test_sparse_depth_is_closed_up_instead_of_one_segment_a_pixel(
    frame: tuple[np.ndarray, np.ndarray],
) -> None:
    rgb, depth = frame
    sparse = np.zeros_like(depth)
    sparse[::3, ::3] = depth[::3, ::3]  # a ToF reprojected without splats: one pixel in 3 x 3
    with pytest.warns(RuntimeWarning, match=r"^depth: 100% of its measured pixels have no"):
        raw = segment(rgb, sparse, NYUV2_CAMERA, labeler=None, fill_radius=0)
    assert np.unique(raw.over).size > 30_000  # the confetti the fill prevents
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        filled = segment(rgb, sparse, NYUV2_CAMERA, labeler=None)
    assert np.unique(filled.over).size < 1_000
    assert (filled.labels >= 0).all()


def test_scattered_holes_leave_the_network_labels_as_they_were(
    frame: tuple[np.ndarray, np.ndarray],
) -> None:
    rgb, depth = frame
    clean = segment(rgb, depth, NYUV2_CAMERA)
    holed = depth.copy()
    holed[np.random.default_rng(0).random(depth.shape) < 0.05] = 0
    for radius in (0, DEFAULT_FILL_RADIUS):
        out = segment(rgb, holed, NYUV2_CAMERA, fill_radius=radius)
        assert clean.network_labels is not None and out.network_labels is not None
        same = (out.network_labels == clean.network_labels)[holed > 0].mean()
        # Before the HHA cue was computed on the filled depth, 5 % holes changed the network's
        # class of half the pixels (pixel accuracy 0.54 -> 0.32 on this frame).
        assert same > 0.9, (radius, same)
    assert (out.labels >= 0).all()  # the holes filled: every pixel segmented
    kept = segment(rgb, holed, NYUV2_CAMERA, labeler=None, fill_radius=0)
    assert ((kept.labels < 0) == (holed == 0)).all()  # radius 0: every hole stays one
    big = holed.copy()
    big[100:200, 100:300] = 0  # a hole far wider than the radius
    near = segment(rgb, big, NYUV2_CAMERA, labeler=None)
    assert (near.labels[140:160, 140:260] < 0).all()  # stays a hole, but for its rim
    every = segment(rgb, big, NYUV2_CAMERA, labeler=None, fill_radius=None)
    assert (every.labels >= 0).all()


def test_the_cli_passes_the_radius_and_names_its_flag(
    frame: tuple[np.ndarray, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from rgbd_rs.cli import main
    from rgbd_rs.io import write_png

    rgb, depth = frame[0][::2, ::2].copy(), frame[1][::2, ::2]
    sparse = np.zeros_like(depth)
    sparse[::3, ::3] = depth[::3, ::3]
    cam = NYUV2_CAMERA.scaled(0.5)
    write_png(tmp_path / "rgb.png", rgb)
    np.save(tmp_path / "d.npy", sparse)
    (tmp_path / "cam.json").write_text(
        json.dumps({k: getattr(cam, k) for k in ("fx", "fy", "cx", "cy", "width", "height")})
    )
    args = ["segment", "--rgb", str(tmp_path / "rgb.png"), "--depth", str(tmp_path / "d.npy")]
    args += ["--calib", str(tmp_path / "cam.json"), "--labeler", "none", "--quiet"]
    counts = []
    for radius in ("0", "3"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # radius 0: the sparse-depth warning
            assert main([*args, "--out", str(tmp_path / radius), "--fill-radius", radius]) == 0
        counts.append(np.unique(np.load(tmp_path / radius / "over.npy")).size)
    assert counts[0] > 5_000 > 500 > counts[1]
    with pytest.raises(SystemExit):
        main([*args, "--out", str(tmp_path / "x"), "--fill-radius", "-1"])
    assert "--fill-radius: got -1, expected a number >= 0" in capsys.readouterr().err
