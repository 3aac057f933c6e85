"""Region merging (thesis §4.7): adjacency tests, Algorithm 1 with PDFs, the fit-only baseline,
replay of the history, majority labels."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.segmentation.merge import (
    T_SIM,
    adjacency,
    majority_classes,
    merge_regions,
)
from rgbd_rs.segmentation.refine import segment_classes
from rgbd_rs.surface import SegmentFits

H, W = 120, 160
CAM = PinholeCamera(fx=100.0, fy=100.0, cx=80.0, cy=60.0, width=W, height=H)


def wall_and_floor(noise: float = 0.002) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A wall 3 m ahead over a floor 1 m below the camera (they meet in a crease at row 93),
    cut into a 4 x 4 grid of blocks; returns (points, labels, floor mask)."""
    v = np.arange(H, dtype=np.float32)[:, None] + 0.5 - 60.0
    z = np.where(v > 0, np.minimum(3.0, 100.0 / np.maximum(v, 1e-3)), 3.0)
    depth = (z * np.ones((1, W))).astype(np.float32)
    depth += np.random.default_rng(0).normal(0, noise, depth.shape).astype(np.float32)
    labels = ((np.arange(H)[:, None] // 30) * 4 + np.arange(W)[None, :] // 40).astype(np.int32)
    floor = np.broadcast_to(v > 100.0 / 3.0, (H, W))
    return CAM.depth_to_points(depth), labels, floor


def test_fit_only_merges_each_surface_and_keeps_the_crease() -> None:
    pts, labels, floor = wall_and_floor()
    r = merge_regions(labels, pts)
    assert r.mode == "fit" and r.semantic is None
    wall_rows = labels < 12  # blocks entirely on the wall
    assert np.unique(r.labels[wall_rows]).size == 1, "the wall is one surface"
    assert np.unique(r.labels[floor]).size == 1, "the floor is one surface"
    assert r.labels[0, 0] != r.labels[-1, 0], "wall and floor stay apart"
    assert len(r.history) == 16 - r.n_segments
    assert all(s.score > 0 for s in r.history)


def test_history_replays_to_the_result() -> None:
    pts, labels, _ = wall_and_floor()
    r = merge_regions(labels, pts)
    np.testing.assert_array_equal(r.labels_after(0), labels)
    np.testing.assert_array_equal(r.labels_after(len(r.history)), r.labels)
    mid = r.labels_after(3)
    assert np.unique(mid).size == 16 - 3


def _pdfs(classes_of_block: dict[int, int], labels: np.ndarray, k: int = 4) -> np.ndarray:
    p = np.full((*labels.shape, k), 0.02 / (k - 1), np.float32)
    cls = np.vectorize(lambda b: classes_of_block.get(int(b), 0))(labels)
    np.put_along_axis(p, cls[..., None], 0.98, axis=2)
    return p


def test_similarity_gates_the_merging() -> None:
    pts, labels, _ = wall_and_floor()
    # The left half of the wall looks like class 1, the right half like class 2.
    cls = {b: (1 if b % 4 < 2 else 2) for b in range(12)}
    cls.update({b: 3 for b in range(12, 16)})
    r = merge_regions(labels, pts, pdfs=_pdfs(cls, labels))
    assert r.mode == "similarity"
    left, right = r.labels[:90, :80], r.labels[:90, 80:]
    assert np.unique(left).size == 1 and np.unique(right).size == 1
    assert left[0, 0] != right[0, 0], "dissimilar PDFs never merge, whatever the fit says"
    assert all(s.score >= T_SIM for s in r.history)
    assert r.semantic is not None
    assert r.semantic[0, 0] == 1 and r.semantic[0, -1] == 2 and r.semantic[-1, 0] == 3


def test_similarity_still_needs_the_fit() -> None:
    pts, labels, _ = wall_and_floor()
    r = merge_regions(labels, pts, pdfs=_pdfs({}, labels))  # every block alike
    assert r.labels[0, 0] != r.labels[-1, 0], "eq. 4.8 keeps wall and floor apart"


def test_touching_versus_boundary_tests() -> None:
    pts, labels, _ = wall_and_floor()
    touching = adjacency(labels, touching=True)
    assert len(touching) == 24  # 4 x 4 grid: 12 horizontal + 12 vertical couples
    # A colour edge between the two halves of the image cuts their couples.
    lab = np.zeros((H, W, 3), np.float32)
    lab[:, 80:, 0] = 50.0
    cut = adjacency(labels, points=pts, lab=lab)
    assert len(cut) == 24 - 4
    assert not any({int(a) % 4, int(b) % 4} == {1, 2} for a, b in cut)
    # A depth step of 0.5 m across a row boundary.
    far = pts.copy()
    far[60:, :, 2] += 0.5
    stepped = adjacency(labels, points=far)
    assert len(stepped) == 24 - 4


def test_normals_test_uses_the_angle_threshold() -> None:
    labels = np.zeros((4, 8), np.int32)
    labels[:, 4:] = 1
    n = np.zeros((4, 8, 3), np.float32)
    n[..., 2] = 1.0
    a = np.deg2rad(3.0)
    n[:, 4:] = [np.sin(a), 0.0, np.cos(a)]
    assert len(adjacency(labels, normals=n)) == 1
    assert len(adjacency(labels, normals=n, max_normal_angle=2.0)) == 0


def test_semantic_is_the_majority_of_the_final_segments() -> None:
    # Mixed per-pixel classes: the native votes (counted per initial segment, added over each
    # final segment) must equal majority_classes on the final labels.
    pts, labels, _ = wall_and_floor()
    labels = labels.copy()
    labels[:3] = -1
    rng = np.random.default_rng(3)
    p = _pdfs({}, labels)
    flip = rng.random(labels.shape) < 0.45
    other = rng.integers(1, 4, labels.shape)
    q = np.full_like(p, 0.02 / 3)
    np.put_along_axis(q, other[..., None], 0.98, axis=2)
    p = np.where(flip[..., None], q, p)
    r = merge_regions(labels, pts, pdfs=p, pooling="majority")
    assert r.history, "the scene merges"
    assert r.semantic is not None
    np.testing.assert_array_equal(r.semantic, majority_classes(r.labels, p))
    assert (r.semantic[:3] == -1).all()


def test_default_pooling_is_the_mean_pdf() -> None:
    """Where the two poolings disagree (60 % of the pixels lean to class 1, 40 % are sure of
    class 2: majority 1, mean 2), the default is the mean, as in segment()."""
    pts, labels, _ = wall_and_floor()
    sure = np.random.default_rng(5).random(labels.shape) < 0.4
    p = np.where(sure[..., None], [0.0, 0.005, 0.99, 0.005], [0.0, 0.4, 0.35, 0.25])
    p = p.astype(np.float32)
    d = merge_regions(labels, pts, pdfs=p)
    m = merge_regions(labels, pts, pdfs=p, pooling="majority")
    assert d.semantic is not None and m.semantic is not None
    valid = labels >= 0
    assert (d.semantic[valid] == 2).all() and (m.semantic[valid] == 1).all()
    np.testing.assert_array_equal(d.semantic, segment_classes(d.labels, p))


def test_majority_classes() -> None:
    labels = np.array([[0, 0, 0, 1], [0, 0, 1, 1]], np.int32)
    pdfs = np.zeros((2, 4, 3), np.float32)
    pdfs[..., 0] = 1.0
    pdfs[0, 0] = [0.0, 1.0, 0.0]
    pdfs[:, 2:] = [0.0, 0.0, 1.0]
    out = majority_classes(labels, pdfs)
    np.testing.assert_array_equal(out, [[0, 0, 0, 2], [0, 0, 2, 2]])


def test_fits_are_merged_in_place_and_reusable() -> None:
    pts, labels, _ = wall_and_floor()
    fits = SegmentFits(pts, labels)
    r = merge_regions(labels, pts, fits=fits)
    np.testing.assert_array_equal(fits.labels(), r.labels)
    with pytest.raises(ValueError, match=r"^fits: got fits of another segmentation"):
        merge_regions(labels, pts, fits=fits)


def test_deterministic() -> None:
    pts, labels, _ = wall_and_floor()
    a, b = merge_regions(labels, pts), merge_regions(labels, pts)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.history == b.history
