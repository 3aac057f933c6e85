"""The input checks' agreement count (rgbd_fusion::agreement) against numpy's: the pixels both
maps measure and those within the tolerance, compared in float32 as numpy compares a float32
map with a Python float."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs import _rgbd_rs
from rgbd_rs.fusion._inputs import disagreement_warning


def test_agreement_counts_equal_numpy() -> None:
    rng = np.random.default_rng(0)
    for tol in (2.0, 1.1, 2.6666667, 0.3):
        a = rng.uniform(0, 50, (54, 96)).astype(np.float32)
        b = a + rng.normal(0, tol, a.shape).astype(np.float32)
        a[rng.random(a.shape) < 0.2] = np.nan
        b[rng.random(a.shape) < 0.2] = np.inf
        both = np.isfinite(a) & np.isfinite(b)
        want = (int(both.sum()), int((np.abs(a[both] - b[both]) <= tol).sum()))
        assert _rgbd_rs.agreement(a, b, tol) == want
        assert 0 < want[1] < want[0] < a.size


def test_disagreement_warning_reads_the_counts() -> None:
    rng = np.random.default_rng(1)
    a = rng.uniform(5, 50, (40, 60)).astype(np.float32)
    assert disagreement_warning(a, a + 1) is None
    warned = disagreement_warning(a, a + 10)
    assert warned is not None and "on only 0%" in warned
    few = np.full_like(a, np.nan)
    few[0, :50] = 1
    assert disagreement_warning(few, few + 10) is None  # under 100 pixels: no judgement


def test_agreement_refuses_maps_of_other_shapes() -> None:
    from rgbd_rs.errors import RgbdError

    with pytest.raises(RgbdError, match=r"stereo_disparity: got shape \[6, 4\]"):
        _rgbd_rs.agreement(np.zeros((4, 6), np.float32), np.zeros((6, 4), np.float32), 1.0)
