"""Bad input to :mod:`rgbd_rs.segmentation.oversegment` (see tests/test_bad_input.py for the
contract and the meta-test that counts these cases)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError

OV = importlib.import_module("rgbd_rs.segmentation.oversegment")  # the module, not the function


SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

F = np.random.default_rng(0).normal(size=(12, 16, 9)).astype(np.float32)
NAN = np.full((12, 16, 9), np.nan, np.float32)
ONE = NAN.copy()
ONE[3, 4] = 0.0  # a single valid pixel
INF = F.copy()
INF[0, 0, 2] = np.inf

CASES: list[Case] = [
    Case("oversegment", lambda: OV.oversegment(F[:, :, 0], 4), SHAPE, r"^features: got shape"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F[None], 4),
        SHAPE,
        r"^features: got shape \(1, 12, 16, 9\)",
        "4-D",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F.astype(np.int32), 4),
        ARG,
        r"^features: got dtype int32",
        "dtype",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F[:, :, :0], 4),
        SHAPE,
        r"^features: got an empty array",
        "no channel",
    ),
    Case("oversegment", lambda: OV.oversegment(NAN, 4), ARG, r"^features: got 0 valid", "all NaN"),
    Case("oversegment", lambda: OV.oversegment(ONE, 1), ARG, r"^features: got 1 valid", "one"),
    Case("oversegment", lambda: OV.oversegment(INF, 4), ARG, r"^features: got 1 infinite", "inf"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 12 * 16 + 1),
        ARG,
        r"^n_segments: got 193, expected at most the 192 valid",
        "k > valid",
    ),
    Case("oversegment", lambda: OV.oversegment(F, 0), ARG, r"^n_segments: got 0", "k = 0"),
    Case("oversegment", lambda: OV.oversegment(F, 4, sigma=0.0), ARG, r"^sigma: got 0", "sigma"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, sigma=float("nan")),
        ARG,
        r"^sigma: got nan",
        "sigma nan",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, n_samples=1),
        ARG,
        r"^n_samples: got 1",
        "samples",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, n_samples=10, n_vectors=10),
        ARG,
        r"^n_vectors: got 10, expected fewer than the 10",
        "vectors",
    ),
    Case("oversegment", lambda: OV.oversegment(F, 4, seed=-1), ARG, r"^seed: got -1", "seed"),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, min_size=0),
        ARG,
        r"^min_size: got 0",
        "min_size",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, spatial_weight=-1.0),
        ARG,
        r"^spatial_weight: got -1",
        "spatial",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, feature_weight=float("inf")),
        ARG,
        r"^feature_weight: got inf",
        "feature_weight",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 8, fit_points=5),
        ARG,
        r"^fit_points: got 5, expected >= n_segments = 8",
        "fit_points",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, channel_weights=np.ones(3)),
        SHAPE,
        r"^channel_weights: got shape \(3,\)",
        "weights shape",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, channel_weights=np.zeros(9)),
        ARG,
        r"^channel_weights: got \[0\.0",
        "weights zero",
    ),
    Case(
        "oversegment",
        lambda: OV.oversegment(F, 4, quiet="yes"),  # type: ignore[arg-type]
        ARG,
        r"^quiet: got 'yes'",
        "quiet",
    ),
    Case(
        "default_channel_weights",
        lambda: OV.default_channel_weights(0),
        ARG,
        r"^n_channels: got 0",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
