"""HHA (rgbd_rs.segmentation.hha): parity with Gupta's MATLAB output, robustness where the
Python port breaks (holes, raw depth, millimetres, no floor), normals of known planes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError, PinholeCamera
from rgbd_rs.segmentation.hha import hha, hha_details, square_normals

#: NYU colour intrinsics as the NYU toolbox / MATLAB code writes them (1-based pixels).
NYU = (518.857901, 519.469611, 325.582449, 253.736166)
#: Mean absolute difference per channel allowed against the MATLAB reference (the issue).
PARITY_GREY_LEVELS = 1.0


def nyu_camera(width: int = 640, height: int = 480) -> PinholeCamera:
    """The NYU intrinsics in rgbd_rs' 0-based pixel convention."""
    fx, fy, cx, cy = NYU
    return PinholeCamera(fx, fy, cx - 1.0, cy - 1.0, width, height)


@pytest.fixture(scope="module")
def frame(shared_data: Path) -> dict[str, np.ndarray]:
    root = shared_data / "hha"
    read = lambda name: cv2.imread(str(root / name), cv2.IMREAD_UNCHANGED)  # noqa: E731
    return {
        "depth": read("depth_filled.png").astype(np.float32) / 10000,
        "raw": read("depth_raw.png").astype(np.float32) / 10000,
        # cv2 reads the PNG as BGR: reversed, channel 0 is disparity as in MATLAB.
        "reference": read("hha_reference_matlab.png")[:, :, ::-1],
    }


def test_parity_with_matlab(frame: dict[str, np.ndarray]) -> None:
    out = hha(frame["depth"], nyu_camera())
    assert out.shape == (480, 640, 3) and out.dtype == np.uint8
    diff = np.abs(out.astype(np.int16) - frame["reference"].astype(np.int16))
    mad = diff.reshape(-1, 3).mean(axis=0)
    assert (mad <= PARITY_GREY_LEVELS).all(), mad
    # Measured: [0, 6.5e-6, 2.0e-5], i.e. 2 of 307200 pixels differ by one level.
    assert (mad < 1e-3).all(), mad
    # The disparity channel has no estimation in it: exact.
    assert (diff[:, :, 0] == 0).all()


def test_raw_mask_and_pixel_convention_matter(frame: dict[str, np.ndarray]) -> None:
    """The reference was made with the filled depth as its own mask and 1-based pixels: both
    other readings are measurably worse (so the parity test can tell them apart)."""
    ref = frame["reference"].astype(np.int16)
    fx, fy, cx, cy = NYU
    zero_based = PinholeCamera(fx, fy, cx, cy, 640, 480)
    mad = np.abs(hha(frame["depth"], zero_based).astype(np.int16) - ref).mean(axis=(0, 1))
    assert mad[1] > 0.01
    masked = hha(frame["depth"], nyu_camera(), raw_depth=frame["raw"]).astype(np.int16)
    assert np.abs(masked - ref).mean(axis=(0, 1))[2] > 1.0


def test_gravity_and_floor(frame: dict[str, np.ndarray]) -> None:
    r = hha_details(frame["depth"], nyu_camera())
    assert np.isclose(np.linalg.norm(r.gravity), 1.0)
    # Kinect held roughly level, floor visible: gravity close to +y, floor ~1 m below.
    assert r.gravity[1] > 0.99
    assert -2.0 < r.floor < -0.9
    assert np.array_equal(r.image, hha(frame["depth"], nyu_camera()))


def test_deterministic(frame: dict[str, np.ndarray]) -> None:
    a = hha_details(frame["depth"], nyu_camera(), raw_depth=frame["raw"])
    b = hha_details(frame["depth"], nyu_camera(), raw_depth=frame["raw"])
    assert np.array_equal(a.image, b.image)
    assert np.array_equal(a.gravity, b.gravity)
    assert np.array_equal(a.normals, b.normals, equal_nan=True)


def test_raw_depth_as_depth_and_nan_holes(frame: dict[str, np.ndarray]) -> None:
    """Raw depth with 0-holes given as ``depth`` itself (the port divides by zero there)."""
    raw = frame["raw"]
    holes = raw == 0
    out = hha(raw, nyu_camera())
    assert (out[holes][:, :2] == 0).all(), "no depth: 0 disparity and height"
    assert (out[~holes][:, 0] > 0).all()
    nan_raw = np.where(holes, np.nan, raw).astype(np.float32)
    assert np.array_equal(hha(nan_raw, nyu_camera()), out), "NaN and 0 are the same hole"
    # Away from holes the encoding stays close to the one from the filled map.
    ref = hha(frame["depth"], nyu_camera()).astype(np.int16)
    near = cv2.dilate(holes.astype(np.uint8), np.ones((21, 21), np.uint8)) == 0
    assert np.abs(out.astype(np.int16) - ref)[near].mean() < 3.0


def test_millimetres_are_refused(frame: dict[str, np.ndarray]) -> None:
    with pytest.raises(InvalidArgumentError, match="depth looks like millimetres; divide by 1000"):
        hha(frame["depth"] * 1000, nyu_camera())
    # Centimetres (a median of a few hundred) could be either: both are named.
    with pytest.raises(InvalidArgumentError, match=r"centimetres \(divide by 100\) or millimetres"):
        hha(frame["depth"] * 100, nyu_camera())
    # uint16 millimetres straight from a PNG, as users often pass them.
    mm = np.round(frame["depth"] * 1000).astype(np.uint16)
    with pytest.raises(InvalidArgumentError, match="millimetres"):
        hha(mm, nyu_camera())


def test_no_floor_uses_the_assumed_floor(frame: dict[str, np.ndarray]) -> None:
    """A crop of the upper part of the image (no floor): the -130 cm rule applies."""
    crop = frame["depth"][:160]
    cam = nyu_camera().cropped(0, 0, 640, 160)
    r = hha_details(crop, cam)
    assert r.floor == pytest.approx(-1.30)
    full = hha_details(frame["depth"], nyu_camera())
    # Heights are measured from 1.3 m below the camera, so the channel is not saturated and
    # not all zero.
    h = r.image[:, :, 1].astype(float)
    assert 30 < h.mean() < 250
    assert full.floor < -0.9


def test_plane_normals_and_angle() -> None:
    """A tilted plane: every normal is the plane's, toward the camera; a horizontal floor seen
    by a level camera has angle 0 (+38) and a wall 90 (+38)."""
    cam = PinholeCamera(100.0, 100.0, 79.5, 59.5, 160, 120)
    n = np.array([0.3, -0.4, -1.0])
    n /= np.linalg.norm(n)
    v, u = np.mgrid[0:120, 0:160].astype(np.float64)
    rays = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], -1)
    depth = (-2.0 / (rays @ n)).astype(np.float32)  # n . p = -2
    got = square_normals(depth, cam, radius=3)
    assert np.abs(got - n).max() < 1e-4
    away = square_normals(depth, cam, radius=10, toward_camera=False)
    assert np.abs(away + n).max() < 1e-4
    # Floor 1.5 m below the camera in the lower half, a wall 6 m away above it.
    floor = (1.5 / rays[:, :, 1]).astype(np.float32)
    depth = np.where((rays[:, :, 1] > 0) & (floor < 6.0), floor, np.float32(6.0))
    r = hha_details(depth, cam)
    assert r.gravity[1] > 0.999
    assert r.floor == pytest.approx(-1.5, abs=0.05)  # normals at the crease tilt it a little
    assert np.median(r.image[110:, :, 2]) == 38
    assert np.median(r.image[:20, :, 2]) == 128
    assert np.median(r.image[110:, :, 1]) <= 3  # cm above the lowest (tilted) floor point
    # HhaResult.normals are square_normals of the same depth.
    assert np.array_equal(r.normals, square_normals(depth, cam), equal_nan=True)


def test_thread_count_does_not_change_the_result(shared_data: Path) -> None:
    """Partial sums are added in a fixed order: 1 and 2 rayon threads give identical bytes."""
    script = (
        "import hashlib, sys, numpy as np, cv2\n"
        "from rgbd_rs import PinholeCamera\n"
        "from rgbd_rs.segmentation.hha import hha_details\n"
        "d = cv2.imread(sys.argv[1], -1).astype(np.float32) / 10000\n"
        f"cam = PinholeCamera({NYU[0]}, {NYU[1]}, {NYU[2] - 1}, {NYU[3] - 1}, 640, 480)\n"
        "r = hha_details(d, cam)\n"
        "h = hashlib.sha256(r.image.tobytes() + r.gravity.tobytes() + r.normals.tobytes())\n"
        "print(h.hexdigest())\n"
    )
    path = str(shared_data / "hha" / "depth_filled.png")
    outs = []
    for threads in ("1", "2"):
        env = {**os.environ, "RAYON_NUM_THREADS": threads}
        res = subprocess.run(
            [sys.executable, "-c", script, path],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        assert res.returncode == 0, res.stderr
        outs.append(res.stdout)
    assert outs[0] == outs[1]
