"""The segmentation metrics of rgbd_rs.metrics: hand-computed tiny cases, naive references, and
parity with scikit-image (variation_of_information, in bits) and scikit-learn (rand_score,
confusion_matrix) on random and real (NYUv2) label images."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rgbd_rs import metrics as M

skm = pytest.importorskip("skimage.metrics")
sk_metrics = pytest.importorskip("sklearn.metrics")

LN2 = math.log(2.0)


def _sk_voi(seg: np.ndarray, truth: np.ndarray) -> float:
    """scikit-image's VoI (bits) in nats, on the compared pixels given as 1-D arrays (renumbered:
    scikit-image sizes its table by the largest label)."""
    s = np.unique(seg, return_inverse=True)[1]
    t = np.unique(truth, return_inverse=True)[1]
    return float(np.sum(skm.variation_of_information(t, s)) * LN2)


def _naive_ue(seg: np.ndarray, truth: np.ndarray) -> float:
    total = 0
    for g in np.unique(truth):
        for s in np.unique(seg):
            inside = np.sum((seg == s) & (truth == g))
            if inside:
                total += min(inside, np.sum(seg == s) - inside)
    return total / seg.size


def _naive_br(seg: np.ndarray, truth: np.ndarray, tol: int) -> float:
    h, w = truth.shape

    def edge(lab: np.ndarray, y: int, x: int) -> bool:
        return any(
            0 <= y + dy < h and 0 <= x + dx < w and lab[y + dy, x + dx] != lab[y, x]
            for dy, dx in ((0, 1), (1, 0), (0, -1), (-1, 0))
        )

    hits = total = 0
    for y in range(h):
        for x in range(w):
            if edge(truth, y, x):
                total += 1
                win = [
                    (yy, xx)
                    for yy in range(max(0, y - tol), min(h, y + tol + 1))
                    for xx in range(max(0, x - tol), min(w, x + tol + 1))
                ]
                hits += any(edge(seg, yy, xx) for yy, xx in win)
    return hits / total


# -- hand-computed cases -----------------------------------------------------------------------


def test_identical_partitions_up_to_renaming() -> None:
    truth = np.array([[0, 0, 1], [2, 2, 1]])
    seg = np.array([[7, 7, 3], [9, 9, 3]])
    assert M.variation_of_information(seg, truth) == pytest.approx(0.0, abs=1e-12)
    assert M.rand_index(seg, truth) == 1.0
    assert M.undersegmentation_error(seg, truth) == 0.0
    assert M.boundary_recall(seg, truth, tolerance=0) == 1.0


def test_split_and_merge_by_hand() -> None:
    halves = np.array([[0, 0], [1, 1]])
    whole = np.zeros((2, 2), np.int32)
    # Splitting one region in two: H(S|T) = ln 2, H(T|S) = 0; 2 of the 6 pairs agree.
    assert M.variation_of_information(halves, whole) == pytest.approx(LN2)
    assert M.rand_index(halves, whole) == pytest.approx(2 / 6)
    assert M.undersegmentation_error(halves, whole) == 0.0  # each segment inside the region
    # One segment over two regions: each region costs min(2, 2) = 2, over 4 pixels.
    assert M.variation_of_information(whole, halves) == pytest.approx(LN2)
    assert M.undersegmentation_error(whole, halves) == 1.0


def test_small_contingency_by_hand() -> None:
    seg = np.array([[0, 0, 1, 1]])
    truth = np.array([[0, 1, 1, 1]])
    # cells (S0,T0)=1, (S0,T1)=1, (S1,T1)=2: VoI = 2 H(S,T) - H(S) - H(T).
    h_st = -(2 * 0.25 * math.log(0.25) + 0.5 * math.log(0.5))
    h_s = math.log(2)
    h_t = -(0.25 * math.log(0.25) + 0.75 * math.log(0.75))
    assert M.variation_of_information(seg, truth) == pytest.approx(2 * h_st - h_s - h_t)
    # Pairs (0,2), (0,3), (2,3) agree; (0,1), (1,2), (1,3) do not.
    assert M.rand_index(seg, truth) == pytest.approx(0.5)
    # S0 costs min(1, 1) twice, S1 nothing.
    assert M.undersegmentation_error(seg, truth) == pytest.approx(0.5)


def test_unlabelled_pixels_are_left_out_everywhere() -> None:
    rng = np.random.default_rng(3)
    seg = rng.integers(0, 4, (12, 10))
    truth = rng.integers(1, 4, (12, 10))
    seg_out, truth_out = seg.copy(), truth.copy()
    truth_out[:, -3:] = 0  # unlabelled truth (ignore=0)
    seg_out[-2:, :] = -1  # no segment
    keep = (slice(0, 10), slice(0, 7))
    for metric in (M.variation_of_information, M.rand_index, M.undersegmentation_error):
        assert metric(seg_out, truth_out, ignore=0) == pytest.approx(
            metric(seg[keep], truth[keep])
        ), metric.__name__
    # Without ignore=0, the unlabelled truth is a region of its own and changes the figure.
    assert M.rand_index(seg_out, truth_out) != pytest.approx(
        M.rand_index(seg_out, truth_out, ignore=0)
    )
    # Negative truth labels (region_ground_truth's -1) are unlabelled without any ignore.
    truth_neg = np.where(truth_out == 0, -1, truth_out)
    assert M.variation_of_information(seg_out, truth_neg) == pytest.approx(
        M.variation_of_information(seg[keep], truth[keep])
    )


def test_boundary_recall_by_hand() -> None:
    truth = np.zeros((4, 6), np.int32)
    truth[:, 3:] = 1  # GT boundary pixels: columns 2 and 3
    seg = np.zeros((4, 6), np.int32)
    seg[:, 4:] = 1  # segment boundary pixels: columns 3 and 4
    assert M.boundary_recall(seg, truth, tolerance=0) == 0.5
    assert M.boundary_recall(seg, truth, tolerance=1) == 1.0
    assert M.boundary_recall(np.zeros_like(seg), truth, tolerance=2) == 0.0
    # A column of unlabelled truth between the regions (as NYUv2's annotators leave them): each
    # region's outline against it counts, on the labelled side (columns 1 and 3), the
    # unlabelled column itself does not.
    gap = truth.copy()
    gap[:, :2] = 1
    gap[:, 2] = 0
    gap[:, 3:] = 2
    assert M.boundary_recall(seg, gap, ignore=0, tolerance=0) == 0.5  # column 3 found
    assert M.boundary_recall(seg, gap, ignore=0, tolerance=1) == 0.5  # column 1 is 2 px away
    assert M.boundary_recall(seg, gap, ignore=0, tolerance=2) == 1.0
    with pytest.raises(M.InvalidArgumentError, match="no boundary"):
        M.boundary_recall(seg, np.ones_like(gap))
    # A pixel without a segment is not compared, even on a GT boundary.
    none = seg.copy()
    none[:, 2] = -1  # column 2 held the GT boundary the segmentation missed at tolerance 0
    assert M.boundary_recall(none, truth, tolerance=0) == 1.0


def test_boundary_recall_matches_a_naive_loop() -> None:
    rng = np.random.default_rng(5)
    for trial in range(5):
        truth = np.repeat(np.repeat(rng.integers(0, 3, (4, 5)), 3, 0), 3, 1)
        seg = np.repeat(np.repeat(rng.integers(0, 4, (6, 8)), 2, 0), 2, 1)[:12, :15]
        for tol in (0, 1, 2):
            assert M.boundary_recall(seg, truth, tolerance=tol) == pytest.approx(
                _naive_br(seg, truth, tol)
            ), (trial, tol)


def test_undersegmentation_error_matches_a_naive_loop() -> None:
    rng = np.random.default_rng(6)
    for _ in range(5):
        seg = rng.integers(0, 6, (9, 11))
        truth = rng.integers(0, 4, (9, 11))
        assert M.undersegmentation_error(seg, truth) == pytest.approx(_naive_ue(seg, truth))


def test_class_metrics_by_hand() -> None:
    truth = np.array([[0, 1, 1, 2], [2, 2, 1, 0]])
    pred = np.array([[1, 1, 0, 2], [2, 1, -1, 2]])
    cm = M.confusion_matrix(pred, truth, n_classes=3)  # ignore=0 by default
    # compared: (1->1), (1->0), (2->2), (2->2), (2->1); (1 -> -1) has no prediction.
    want = np.array([[0, 0, 0], [1, 1, 0], [0, 1, 2]])
    np.testing.assert_array_equal(cm, want)
    assert M.pixel_accuracy(pred, truth) == pytest.approx(3 / 5)
    assert M.mean_class_accuracy(pred, truth, n_classes=3) == pytest.approx((1 / 2 + 2 / 3) / 2)
    # ignore=None: class 0 is a class like the others.
    assert M.confusion_matrix(pred, truth, n_classes=3, ignore=None).sum() == 7
    # A class absent from the truth is left out of the mean, not counted as 0.
    assert M.mean_class_accuracy(pred, truth, n_classes=5) == pytest.approx((1 / 2 + 2 / 3) / 2)


# -- parity ------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(6))
def test_parity_random_labels(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(5, 60)), int(rng.integers(5, 60)))
    seg = rng.integers(-1, int(rng.integers(2, 40)), shape)
    truth = rng.integers(0, int(rng.integers(2, 15)), shape)
    if seed % 2:  # large, sparse label values take the np.unique path of the compaction
        seg = seg * 1_000_003 + np.sign(seg) * 2**40
    valid = (seg >= 0) & (truth != 0)
    s, t = seg[valid], truth[valid]
    assert M.variation_of_information(seg, truth, ignore=0) == pytest.approx(
        _sk_voi(s, t), rel=1e-9, abs=1e-12
    )
    assert M.rand_index(seg, truth, ignore=0) == pytest.approx(
        sk_metrics.rand_score(t, s), rel=1e-12
    )
    pred = np.where(seg >= 0, np.abs(seg) % 7, -1)
    truth7 = truth % 7
    v = (pred >= 0) & (truth7 != 0)
    np.testing.assert_array_equal(
        M.confusion_matrix(pred, truth7, n_classes=7),
        sk_metrics.confusion_matrix(truth7[v], pred[v], labels=range(7)),
    )
    assert M.pixel_accuracy(pred, truth7) == pytest.approx(
        sk_metrics.accuracy_score(truth7[v], pred[v])
    )


def test_parity_on_nyuv2_frames() -> None:
    from skimage.segmentation import felzenszwalb, slic

    from rgbd_rs.data.nyuv2 import load_nyuv2_frame, nyuv2_frames, region_ground_truth

    for index in nyuv2_frames("test")[:2]:
        frame = load_nyuv2_frame(index)
        gt = region_ground_truth(frame.label40)
        for seg in (
            felzenszwalb(frame.rgb, scale=300, min_size=200),
            slic(frame.rgb, n_segments=200, start_label=0),
            frame.label13.astype(np.int64) - 1,  # class regions, -1 = unlabelled
        ):
            valid = (gt >= 0) & (seg >= 0)
            s, t = seg[valid], gt[valid]
            assert M.variation_of_information(seg, gt) == pytest.approx(_sk_voi(s, t), rel=1e-9)
            assert M.rand_index(seg, gt) == pytest.approx(sk_metrics.rand_score(t, s), rel=1e-9)
        assert M.variation_of_information(gt, gt) == pytest.approx(0.0, abs=1e-9)
        assert M.undersegmentation_error(gt, gt) == 0.0
        assert M.boundary_recall(gt, gt, tolerance=0) == 1.0
        np.testing.assert_array_equal(
            M.confusion_matrix(frame.label13, frame.label13, n_classes=14).sum(axis=1)[1:],
            np.bincount(frame.label13.ravel(), minlength=14)[1:],
        )
