"""Bad input to :mod:`rgbd_rs.segmentation.refine` (see tests/test_bad_input.py for the
contract and the meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, PinholeCamera, ShapeMismatchError
from rgbd_rs.segmentation import merge_regions, segment, segment_classes

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

L = np.repeat(np.arange(4, dtype=np.int32), 4).reshape(4, 4)
PDF = np.full((4, 4, 2), 0.5, np.float32)
CAM = PinholeCamera(40.0, 40.0, 15.5, 11.5, 32, 24)
RGB = np.zeros((24, 32, 3), np.uint8)
DEPTH = np.full((24, 32), 2.0, np.float32)
P = np.dstack([*np.meshgrid(np.arange(4.0), np.arange(4.0)), np.full((4, 4), 2.0)]).astype(
    np.float32
)

CASES: list[Case] = [
    Case("segment_classes", lambda: segment_classes(L, PDF, "max"), ARG, r"^pooling: got 'max'"),
    Case("segment_classes", lambda: segment_classes(L[0], PDF), SHAPE, r"^labels: got shape"),
    Case("segment_classes", lambda: segment_classes(L * 0.5, PDF), ARG, r"^labels: got dtype", "f"),
    Case("segment_classes", lambda: segment_classes(L, PDF[:3]), SHAPE, r"^pdfs: got shape", "hw"),
    Case("segment_classes", lambda: segment_classes(L, PDF[..., 0]), SHAPE, r"^pdfs", "2-D"),
    Case(
        "segment_classes",
        lambda: segment_classes(L, (PDF > 0).astype(np.int32)),
        ARG,
        r"^pdfs: got dtype int32",
        "int",
    ),
    Case(
        "segment_classes",
        lambda: segment_classes(L, np.where(L[..., None] == 2, np.nan, PDF)),
        ARG,
        r"^pdfs: got NaN",
        "nan",
    ),
    Case(
        "segment_classes",
        lambda: segment_classes(np.full((4, 4), 2**63, np.uint64), PDF),
        ARG,
        r"^labels: got id 9223372036854775808",
        "u64",
    ),
    Case(
        "segment_classes",
        lambda: segment_classes(L, np.where(L[..., None] == 1, -0.5, PDF)),
        ARG,
        r"^pdfs: got negative",
        "neg",
    ),
    Case("segment", lambda: segment(RGB, DEPTH, CAM, pooling="vote"), ARG, r"^pooling", "pool"),
    Case(
        "merge_regions",
        lambda: merge_regions(L, P, pdfs=PDF, pooling="max"),
        ARG,
        r"^pooling: got 'max'",
        "pool",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
