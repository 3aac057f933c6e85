"""A fresh fuzz of the public surface after issue 32 (extreme finite inputs, file writers): each
case ended in inf/NaN without a word, a foreign exception or a silently short read before its
fix; each must now raise the RgbdError subclass named, in our words, or give the right value."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import PinholeCamera, RgbdError
from rgbd_rs.errors import InvalidArgumentError

ARG, FILE = InvalidArgumentError, RgbdError
CAM = PinholeCamera(fx=40.0, fy=40.0, cx=15.5, cy=11.5, width=32, height=24)


def _camera(fx: float) -> object:
    return PinholeCamera(fx=fx, fy=40.0, cx=15.5, cy=11.5, width=32, height=24)


def _disparity(depth: float, baseline: float = 0.1, focal: float = 40.0) -> object:
    from rgbd_rs.geometry import depth_to_disparity

    return depth_to_disparity(np.full((2, 2), depth, np.float32), baseline, focal)


def _depth(baseline: float, focal: float) -> object:
    from rgbd_rs.geometry import disparity_to_depth

    return disparity_to_depth(np.ones((2, 2), np.float32), baseline, focal)


def _colorize(vmin: float, vmax: float) -> object:
    from rgbd_rs.viz import colorize

    return colorize(np.linspace(0, 1, 4, dtype=np.float32)[None], vmin, vmax)


def _colorize_bar(vmin: float, vmax: float) -> object:
    from rgbd_rs.viz import colorize_with_bar

    return colorize_with_bar(np.linspace(0, 1, 4, dtype=np.float32)[None], vmin, vmax)


def _write_text(tmp: Path) -> object:
    from rgbd_rs.io import write_text

    return write_text(tmp / "t.txt", "ok \ud800")


def _write_json(tmp: Path, value: float) -> object:
    from rgbd_rs.io import write_json

    return write_json(tmp / "o.json", {"a": value})


def _read_json(tmp: Path) -> object:
    from rgbd_rs.io import read_json

    path = tmp / "nan.json"
    path.write_text('{"a": NaN}\n')
    return read_json(path)


def _truncated_ply(tmp: Path) -> Path:
    path = tmp / "trunc.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n0 0 0\n"
    )
    return path


def _load_shape_ply(tmp: Path) -> object:
    from rgbd_rs.shapes import load_shape

    return load_shape(_truncated_ply(tmp))


CASES = [
    Case("PinholeCamera", lambda: _camera(1e-40), ARG, r"^fx: got 1e-40 px, expected a focal", "0"),
    Case("PinholeCamera", lambda: _camera(1e30), ARG, r"^fx: got 1e\+30 px", "huge"),
    Case(
        "PinholeCamera.scaled",
        lambda: CAM.scaled(1e-40),
        ARG,
        r"^sx: got 1e-40, which makes the 32 px side .* at least one pixel",
    ),
    Case(
        "depth_to_disparity",
        lambda: _disparity(1e-40),
        ARG,
        r"^depth: got values down to 1e-40 .* beyond float32's range",
        "subnormal depth",
    ),
    Case(
        "disparity_to_depth",
        lambda: _depth(1e30, 1e30),
        ARG,
        r"^focal: got 1e\+30 with baseline 1e\+30: baseline x focal = 1e\+60",
        "product",
    ),
    Case(
        "ToFModel",
        lambda: __import__("rgbd_rs.render", fromlist=["ToFModel"]).ToFModel(read_noise=1e30),
        ARG,
        r"^read_noise: got 1e\+30, expected at most 1e\+15",
    ),
    Case(
        "box",
        lambda: __import__("rgbd_rs.meshes", fromlist=["box"]).box((1, 1, 1), (1e30, 0, 0)),
        ARG,
        r"^center: got \[1e\+30, 0\.0, 0\.0\], where float32 .* cannot hold a primitive 1 across",
    ),
    Case(
        "sphere",
        lambda: __import__("rgbd_rs.meshes", fromlist=["sphere"]).sphere(1.0, (1e9, 0, 0)),
        ARG,
        r"^center: got \[1000000000\.0",
    ),
    Case(
        "features",
        lambda: __import__("rgbd_rs.segmentation", fromlist=["features"]).features(
            np.zeros((24, 32, 3), np.uint8), np.full((24, 32), 1e-40, np.float32), CAM
        ),
        ARG,
        r"^depth: got a median valid depth of 1e-40, expected metres",
    ),
    Case("colorize", lambda: _colorize(5.0, 1.0), ARG, r"^vmax: got 1\.0, expected a value >= "),
    Case("colorize_with_bar", lambda: _colorize_bar(2.0, -1.0), ARG, r"^vmax: got -1\.0"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_case(case: Case) -> None:
    check(case)


def test_file_cases(tmp_path: Path) -> None:
    check(Case("write_text", lambda: _write_text(tmp_path), ARG, r"^text: got a lone surrogate"))
    for v in (math.nan, math.inf):
        check(Case("write_json", lambda v=v: _write_json(tmp_path, v), ARG, r"^obj: got a value"))
    check(Case("read_json", lambda: _read_json(tmp_path), FILE, r"nan\.json: malformed JSON"))
    check(
        Case(
            "load_shape",
            lambda: _load_shape_ply(tmp_path),
            FILE,
            r"trunc\.ply: not a valid PLY file \(the header says 3 vertices, found 1",
        )
    )
    from rgbd_rs.meshes import load_mesh

    with pytest.raises(RgbdError, match=r"trunc\.ply: "):
        load_mesh(_truncated_ply(tmp_path))


def test_writers_still_write_valid_input(tmp_path: Path) -> None:
    from rgbd_rs.io import read_json, write_json, write_text

    assert write_text(tmp_path / "a.txt", "é ✓").read_text(encoding="utf-8") == "é ✓"
    out = write_json(tmp_path / "b.json", {"a": 1.5, "b": [1, 2]})
    assert json.loads(out.read_text()) == read_json(out) == {"a": 1.5, "b": [1, 2]}


def test_equal_colour_range_and_valid_depths_still_work() -> None:
    from rgbd_rs.geometry import depth_to_disparity

    assert _colorize(1.0, 1.0).shape == (1, 4, 3)  # type: ignore[attr-defined]
    d = depth_to_disparity(np.array([np.inf, 0.0, -1.0, np.nan, 2.0], np.float32), 0.1, 40.0)
    assert np.isnan(d[:4]).all() and d[4] == pytest.approx(2.0)
    from rgbd_rs.camera import FOCAL_RANGE

    assert FOCAL_RANGE[0] < 1.0 < 1e6 < FOCAL_RANGE[1]  # any real lens lies inside
    assert CAM.scaled(0.05).size == (2, 1)  # a factor leaving >= 1 px still scales


def test_rms_error_beyond_float32_squares() -> None:
    from rgbd_rs.metrics import rms_error

    big = np.full((4, 4), 1e20, np.float32)
    assert rms_error(big, np.zeros((4, 4), np.float32)) == pytest.approx(1e20, rel=1e-6)
    # Ordinary errors keep their float32 figure.
    e = np.array([1.0, 2.0, 3.0], np.float32)
    want = float(np.sqrt(np.mean((e - 0) ** 2, dtype=np.float32)))
    assert rms_error(e, np.zeros(3, np.float32)) == want


def test_tof_confidence_of_huge_disparities_is_finite() -> None:
    from rgbd_rs.fusion import tof_confidence

    amp = np.full((6, 6), 100.0, np.float32)
    for d in (1e30, 10.0):  # equal disparities: no local variation, full confidence
        c = tof_confidence(np.full((6, 6), d, np.float32), amp)
        assert np.isfinite(c).all() and (c == 1).all(), (d, c)
    ramp = np.tile(np.array([1e30, 2e30], np.float32), (6, 3))
    assert (tof_confidence(ramp, amp) == 0).all()  # a huge local spread: no confidence


def test_primitives_far_out_but_resolved_keep_their_size() -> None:
    from rgbd_rs.meshes import box, cylinder

    lo, hi = box((1, 2, 3), (1e3, 0, 0)).bounds()
    np.testing.assert_allclose(hi - lo, (1, 2, 3), rtol=1e-4)
    assert cylinder(0.5, 2.0, (0, 0, 50)).vertices.shape[1] == 3


def test_upsampling_refuses_values_whose_window_sums_overflow() -> None:
    from rgbd_rs.fusion import upsample_depth

    img = np.zeros((24, 32, 3), np.uint8)
    with pytest.raises(InvalidArgumentError, match=r"^sparse: got values up to 3e\+38, expected"):
        upsample_depth(np.full((24, 32), 3e38, np.float32), img)
    ok = upsample_depth(np.full((24, 32), 1e30, np.float32), img)  # large but summable
    assert np.isfinite(ok).all() and np.allclose(ok, 1e30, rtol=1e-5)


def test_cue_block_means_near_float32s_limit() -> None:
    from rgbd_rs.segmentation import downsample_cues

    out = downsample_cues(np.full((1, 24, 32), 3e38, np.float32), (8, 6))
    assert np.isfinite(out).all() and np.allclose(out, 3e38, rtol=1e-6)


@pytest.mark.parametrize("scale", [2.0**70, 2.0**100, 2.0**-70, 2.0**-100])
def test_normals_do_not_depend_on_the_unit(scale: float) -> None:
    from rgbd_rs.geometry import normals_from_points

    ys, xs = np.mgrid[0:24, 0:32].astype(np.float32)
    depth = 1.0 + 0.02 * xs + 0.01 * ys  # a slanted surface
    pts = CAM.depth_to_points(depth.astype(np.float32))
    ref = normals_from_points(pts)
    # A power of two scales exactly: the same normals, bit for bit (they overflowed to 0-length
    # or underflowed to NaN before).
    out = normals_from_points((pts * np.float32(scale)).astype(np.float32))
    np.testing.assert_array_equal(out, ref)
    unit = normals_from_points((pts * np.float32(1e19)).astype(np.float32))[1:-1, 1:-1]
    np.testing.assert_allclose(np.linalg.norm(unit, axis=-1), 1.0, atol=1e-5)


def test_a_textured_ply_keeps_its_vertices(tmp_path: Path) -> None:
    """Per-face texture coordinates must not split shared vertices (the PLY loader would, and the
    vertex-count check would then call a valid file truncated)."""
    from rgbd_rs.meshes import load_mesh
    from rgbd_rs.shapes import load_shape

    path = tmp_path / "tex.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
        "property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
        "3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 6 0.5 0.5 1 1 0 1\n"
    )
    assert load_mesh(path).vertices.shape == (4, 3)
    shape = load_shape(path)
    assert getattr(shape, "vertices", shape).shape == (4, 3)
