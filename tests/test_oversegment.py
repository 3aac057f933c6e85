"""Nyström normalized-cuts over-segmentation (rgbd_rs.segmentation.oversegment)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.data.paths import data_root
from rgbd_rs.segmentation.oversegment import (
    DEFAULT_N_SEGMENTS,
    GROUP_WEIGHTS,
    MIN_SIZE_FRACTION,
    default_channel_weights,
    oversegment,
)

CAM = PinholeCamera(60.0, 60.0, 31.5, 23.5, 64, 48)


def _groups(lab: np.ndarray, pts: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """Eq. 4.1 layout, each group divided by its average standard deviation."""
    out = []
    for g in (lab, pts, nrm):
        s = float(np.nanmean(np.nanstd(g.reshape(-1, 3), axis=0)))
        out.append(g / (s if s > 0 else 1.0))
    return np.concatenate(out, axis=2).astype(np.float32)


def _two_colours(h: int = 48, w: int = 64, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lab = np.zeros((h, w, 3), np.float32)
    lab[:, : w // 2] = (30.0, 20.0, -10.0)
    lab[:, w // 2 :] = (70.0, -20.0, 30.0)
    lab += rng.normal(0, 1.0, lab.shape).astype(np.float32)
    depth = np.full((h, w), 2.0, np.float32)
    pts = CAM.depth_to_points(depth)
    nrm = np.zeros_like(pts)
    nrm[..., 2] = -1.0
    return _groups(lab, pts, nrm)


def _two_planes() -> np.ndarray:
    """One colour; a wall at z = 3 m (left) and a floor-like slanted plane (right)."""
    h, w = CAM.height, CAM.width
    lab = np.full((h, w, 3), 50.0, np.float32)  # no spread: left unscaled
    depth = np.full((h, w), 3.0, np.float32)
    u = np.arange(w, dtype=np.float32)
    depth[:, w // 2 :] = 1.0 + 0.03 * (u[w // 2 :] - w // 2)
    pts = CAM.depth_to_points(depth)
    nrm = np.zeros_like(pts)
    nrm[:, : w // 2] = (0.0, 0.0, -1.0)
    nrm[:, w // 2 :] = (-0.7, 0.0, -0.7)
    return _groups(lab, pts, nrm)


def _no_segment_crosses(labels: np.ndarray, col: int) -> None:
    left = set(np.unique(labels[:, :col])) - {-1}
    right = set(np.unique(labels[:, col:])) - {-1}
    assert not left & right, f"segments {sorted(left & right)} cross column {col}"


def _contiguous(labels: np.ndarray) -> None:
    used = np.unique(labels[labels >= 0])
    assert used.tolist() == list(range(len(used)))
    assert labels.dtype == np.int32


def test_two_colours_are_separated() -> None:
    f = _two_colours()
    labels = oversegment(f, 8, n_samples=60, n_vectors=6)
    _no_segment_crosses(labels, 32)
    _contiguous(labels)
    assert (labels >= 0).all()


def test_two_planes_are_separated() -> None:
    f = _two_planes()
    labels = oversegment(f, 6, n_samples=60, n_vectors=6)
    _no_segment_crosses(labels, CAM.width // 2)


def test_nan_pixels_are_exactly_minus_one() -> None:
    f = _two_colours()
    rng = np.random.default_rng(3)
    holes = rng.random(f.shape[:2]) < 0.1
    holes[10:20, 5:15] = True
    f[holes, rng.integers(0, 9, holes.sum())] = np.nan  # one channel is enough
    labels = oversegment(f, 8, n_samples=60, n_vectors=6)
    np.testing.assert_array_equal(labels < 0, holes)
    assert (labels[holes] == -1).all()
    _contiguous(labels)


def test_same_seed_same_labels_other_seed_differs() -> None:
    f = _two_colours(seed=5)
    a = oversegment(f, 12, n_samples=50, n_vectors=6, seed=3)
    b = oversegment(f, 12, n_samples=50, n_vectors=6, seed=3)
    c = oversegment(f, 12, n_samples=50, n_vectors=6, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_no_islands_below_min_size() -> None:
    f = _two_colours(seed=2)
    labels = oversegment(f, 20, n_samples=60, n_vectors=6, min_size=40)
    sizes = np.bincount(labels.ravel())
    assert sizes.min() >= 40, sizes
    # Each segment is one 4-connected component.
    import cv2

    for lab in range(len(sizes)):
        n, _ = cv2.connectedComponents((labels == lab).astype(np.uint8), connectivity=4)
        assert n == 2, f"segment {lab} has {n - 1} components"


def test_default_channel_weights() -> None:
    np.testing.assert_array_equal(
        default_channel_weights(9), np.repeat(np.asarray(GROUP_WEIGHTS, np.float32), 3)
    )
    np.testing.assert_array_equal(default_channel_weights(4), np.ones(4))
    f = _two_colours()
    a = oversegment(f, 8, n_samples=60, n_vectors=6)
    b = oversegment(f, 8, n_samples=60, n_vectors=6, channel_weights=default_channel_weights(9))
    c = oversegment(f, 8, n_samples=60, n_vectors=6, channel_weights=np.ones(9))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def _nyu_features(index: int = 1) -> np.ndarray:
    import cv2

    from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame
    from rgbd_rs.geometry import normals_from_points

    fr = load_nyuv2_frame(index)
    lab = cv2.cvtColor(fr.rgb.astype(np.float32) / 255, cv2.COLOR_RGB2LAB)
    pts = NYUV2_CAMERA.depth_to_points(fr.depth)
    return _groups(lab, pts, normals_from_points(pts))


needs_data = pytest.mark.skipif(
    data_root() is None or not (data_root() / "nyuv2" / "frames").is_dir(),  # type: ignore[operator]
    reason="needs ../shared/data/nyuv2",
)


@needs_data
def test_nyu_frame_count_and_no_tiny_islands() -> None:
    f = _nyu_features()
    labels = oversegment(f)
    n = int(labels.max()) + 1
    assert 200 <= n <= 450, n
    _contiguous(labels)
    sizes = np.bincount(labels[labels >= 0])
    valid = int((labels >= 0).sum())
    assert valid == labels.size  # the labelled frames' depth is filled
    assert sizes.min() >= round(MIN_SIZE_FRACTION * valid / DEFAULT_N_SEGMENTS), sizes.min()


_SCRIPT = textwrap.dedent(
    """
    import hashlib, sys
    import numpy as np
    from rgbd_rs.segmentation.oversegment import oversegment
    f = np.load(sys.argv[1])
    print(hashlib.sha256(oversegment(f, 60, n_samples=80).tobytes()).hexdigest())
    """
)


def test_independent_of_thread_count(tmp_path: object) -> None:
    """Same labels with 1 and 2 rayon threads (fixed blocks, ordered reductions)."""
    import pathlib

    assert isinstance(tmp_path, pathlib.Path)
    rng = np.random.default_rng(7)
    # Large enough for several 2048-row blocks and k-means tasks of 1024 rows.
    f = rng.normal(size=(120, 160, 9)).astype(np.float32)
    f[:, 80:, :3] += 4.0
    path = tmp_path / "f.npy"
    np.save(path, f)
    digests = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        out = subprocess.run(
            [sys.executable, "-c", _SCRIPT, str(path)],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
        digests.append(out.stdout.strip())
    assert digests[0] == digests[1]
    here = hashlib.sha256(oversegment(f, 60, n_samples=80).tobytes()).hexdigest()
    assert here == digests[0]


def test_accepts_the_features_result() -> None:
    from rgbd_rs.segmentation.features import features

    cam = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)
    rgb = np.zeros((24, 32, 3), np.uint8)
    rgb[:, 16:] = (200, 40, 40)
    depth = np.linspace(1.0, 3.0, 32 * 24, dtype=np.float32).reshape(24, 32)
    feats = features(rgb, depth, cam)
    a = oversegment(feats, 4, n_samples=40, n_vectors=4)
    b = oversegment(feats.vectors, 4, n_samples=40, n_vectors=4)
    np.testing.assert_array_equal(a, b)
    _no_segment_crosses(a, 16)
