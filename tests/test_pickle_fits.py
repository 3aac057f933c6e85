"""`SegmentFits` pickles (a process pool's worker can hand back fits, or a `segment()` result
holding them): unpickling builds the same fits from the inputs and replays the merges."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import pytest

from rgbd_rs import PinholeCamera
from rgbd_rs.surface import SegmentFits

CAM = PinholeCamera(fx=200.0, fy=200.0, cx=63.5, cy=47.5, width=128, height=96)


def _scene(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A noisy plane with a step, cut into 4 x 4 blocks of 24 x 32 px (16 segments)."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:96, 0:128].astype(np.float32)
    z = 2.0 + 0.004 * u - 0.003 * v + np.where(u >= 64, 0.3, 0.0)
    points = CAM.depth_to_points((z + rng.normal(0, 0.002, z.shape)).astype(np.float32))
    labels = (v // 24 * 4 + u // 32).astype(np.int32)
    labels[:3, :3] = -1
    return points, labels


def _same(a: SegmentFits, b: SegmentFits, points: np.ndarray) -> None:
    np.testing.assert_array_equal(a.labels(), b.labels())
    assert (a.n_labels, a.label_ids, a.criterion, a.shape) == (
        b.n_labels,
        b.label_ids,
        b.criterion,
        b.shape,
    )
    live = np.unique(a.labels()[a.labels() >= 0])
    for i in live:
        assert a.fit_error(i) == b.fit_error(i)
        assert a.size(i) == b.size(i)
        for j in live[live > i]:
            assert a.union_error(i, j) == b.union_error(i, j)
    np.testing.assert_array_equal(a.maps(points).error, b.maps(points).error)


@pytest.mark.parametrize("criterion", ["seam", "gcv"])
def test_round_trip_after_merges(criterion: str) -> None:
    points, labels = _scene()
    fits = SegmentFits(points, labels, spacing=8, criterion=criterion)
    fresh = pickle.loads(pickle.dumps(fits))
    _same(fits, fresh, points)
    for i, j in ((0, 1), (0, 4), (2, 3), (0, 5)):
        fits.merge(i, j)
    back = pickle.loads(pickle.dumps(fits))
    _same(fits, back, points)
    assert back.find(5) == 0 and back.find(3) == 2
    # The copy goes on merging as the original would.
    assert back.merge(2, 6) == fits.merge(2, 6)
    _same(fits, back, points)


def test_the_pickle_holds_the_inputs_as_built() -> None:
    """The caller's arrays changed in place after building do not change what unpickles."""
    points, labels = _scene(1)
    fits = SegmentFits(points, labels, spacing=8)
    fits.merge(0, 1)
    want = pickle.loads(pickle.dumps(fits))
    points[:] = 0.0
    labels[:] = 0
    got = pickle.loads(pickle.dumps(fits))
    _same(want, got, _scene(1)[0])


def test_seam_test_alone_and_options_survive() -> None:
    points, labels = _scene(2)
    fits = SegmentFits(points, labels, surfaces=False, tolerance=2.0, test_window=None)
    fits.merge(4, 5)
    back = pickle.loads(pickle.dumps(fits))
    np.testing.assert_array_equal(back.labels(), fits.labels())
    assert back.union_error(0, 1) == fits.union_error(0, 1)
    with pytest.raises(Exception, match="surfaces=False"):
        back.mse(0)


def test_merges_from_threads_replay_in_their_order() -> None:
    points, labels = _scene(3)
    fits = SegmentFits(points, labels, spacing=8)
    pairs = [(0, 1), (2, 3), (8, 9), (10, 11), (12, 13), (14, 15)]
    threads = [threading.Thread(target=fits.merge, args=p) for p in pairs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    back = pickle.loads(pickle.dumps(fits))
    _same(fits, back, points)


def test_merge_regions_merges_are_recorded() -> None:
    from rgbd_rs.segmentation import merge_regions

    points, labels = _scene(4)
    fits = SegmentFits(points, labels, surfaces=False, noise_scale=0.002, noise_power=0.0)
    m = merge_regions(labels, points, fits=fits, touching=True)
    assert m.history, "the coplanar blocks merge"
    back = pickle.loads(pickle.dumps(fits))
    np.testing.assert_array_equal(back.labels(), m.labels)


def test_merges_it_did_not_see_are_refused() -> None:
    """Fits merged behind the wrapper's back (as by a merge_regions() stopped part way) cannot
    be rebuilt: a clear error, not a pickle of other fits."""
    from rgbd_rs.errors import RgbdError

    points, labels = _scene(5)
    fits = SegmentFits(points, labels, spacing=8)
    fits._native.merge(0, 1)
    with pytest.raises(RgbdError, match=r"fits: got fits merged 1 times, 0 of them recorded"):
        pickle.dumps(fits)


class Mine(SegmentFits):
    """A subclass: it unpickles as itself."""


def test_a_subclass_and_a_buffer_that_is_not_an_array() -> None:
    points, labels = _scene(6)
    assert type(pickle.loads(pickle.dumps(Mine(points, labels, spacing=8)))) is Mine
    buf = memoryview(points)  # the caller's buffer, not an ndarray: copied too
    fits = SegmentFits(buf, labels, spacing=8)
    want = pickle.loads(pickle.dumps(fits))
    points[:] = 0.0
    _same(want, pickle.loads(pickle.dumps(fits)), _scene(6)[0])
