"""The segment refinement of §4.7 (rgbd_rs.segmentation.refine)."""

from __future__ import annotations

import numpy as np

from rgbd_rs.data.nyuv2 import load_nyuv2_frame
from rgbd_rs.segmentation import majority_classes, segment, segment_classes


def _random(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    labels = rng.integers(-1, 7, (30, 40)).astype(np.int32)
    pdfs = rng.dirichlet(np.full(5, 0.7), (30, 40)).astype(np.float32)
    return labels, pdfs


def test_majority_equals_the_native_vote() -> None:
    for seed in range(5):
        labels, pdfs = _random(seed)
        np.testing.assert_array_equal(
            segment_classes(labels, pdfs, "majority"), majority_classes(labels, pdfs)
        )


def test_mean_is_the_argmax_of_each_segments_mean_pdf() -> None:
    for seed in range(5):
        labels, pdfs = _random(seed)
        out = segment_classes(labels, pdfs)
        assert (out[labels < 0] == -1).all()
        for s in np.unique(labels[labels >= 0]):
            mean = pdfs[labels == s].astype(np.float64).mean(axis=0)
            assert (out[labels == s] == mean.argmax()).all()


def test_mean_and_majority_differ_where_the_pixels_doubt() -> None:
    # Two pixels lean to class 0 (0.51), one is sure of class 1: the vote says 0, the mean 1.
    labels = np.zeros((1, 3), np.int32)
    pdfs = np.array([[[0.51, 0.49], [0.51, 0.49], [0.0, 1.0]]], np.float32)
    assert (segment_classes(labels, pdfs, "majority") == 0).all()
    assert (segment_classes(labels, pdfs, "mean") == 1).all()


def test_sparse_ids_and_no_segment() -> None:
    labels, pdfs = _random(1)
    far = np.where(labels >= 0, labels.astype(np.int64) * 10**9, -1)
    np.testing.assert_array_equal(segment_classes(far, pdfs), segment_classes(labels, pdfs))
    assert (segment_classes(np.full((30, 40), -1), pdfs) == -1).all()


def test_segment_pools_as_asked() -> None:
    f = load_nyuv2_frame(46)
    rng = np.random.default_rng(0)
    pdfs = rng.dirichlet(np.full(4, 0.5), f.depth.shape).astype(np.float32)
    a = segment(f.rgb, f.depth, f.camera, pdfs=pdfs, n_segments=60, pooling="majority")
    b = segment(f.rgb, f.depth, f.camera, pdfs=pdfs, n_segments=60)
    assert b.pooling == "mean" and a.pooling == "majority"
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.semantic, a.merge.semantic)
    np.testing.assert_array_equal(a.semantic, segment_classes(a.labels, pdfs, "majority"))
    # Mean pooling from the merge's native descriptor sums equals the numpy pooling.
    np.testing.assert_array_equal(b.semantic, b.merge.semantic)
    np.testing.assert_array_equal(b.semantic, segment_classes(b.labels, pdfs, "mean"))
    assert not np.array_equal(a.semantic, b.semantic), "the two poolings differ on this frame"
    assert b.refined_labels is not None and (b.refined_labels >= 0).all()
