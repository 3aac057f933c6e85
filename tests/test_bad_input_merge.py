"""Bad input to :mod:`rgbd_rs.segmentation.merge` (see tests/test_bad_input.py for the
contract and the meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

import rgbd_rs.segmentation.merge as M
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, PinholeCamera, ShapeMismatchError
from rgbd_rs.segmentation import fill_depth_holes, segment
from rgbd_rs.surface import SegmentFits

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

L = np.repeat(np.arange(4, dtype=np.int32), 4).reshape(4, 4)
P = np.dstack([*np.meshgrid(np.arange(4.0), np.arange(4.0)), np.full((4, 4), 2.0)]).astype(
    np.float32
)
PDF = np.full((4, 4, 2), 0.5, np.float32)
CAM = PinholeCamera(40.0, 40.0, 15.5, 11.5, 32, 24)
RGB = np.random.default_rng(0).integers(0, 255, (24, 32, 3), dtype=np.uint8)
DEPTH = np.full((24, 32), 2.0, np.float32) + np.linspace(0, 0.2, 32, dtype=np.float32)

CASES: list[Case] = [
    Case("adjacency", lambda: M.adjacency(L.astype(np.float32)), ARG, r"^labels: got dtype"),
    Case("adjacency", lambda: M.adjacency(L[0]), SHAPE, r"^labels: got shape", "1-D"),
    Case("adjacency", lambda: M.adjacency(-np.ones((4, 4), int)), ARG, r"^labels: got no", "none"),
    Case("adjacency", lambda: M.adjacency(L, points=P[:3]), SHAPE, r"^points: got shape", "pts"),
    # Millimetres where the metric defaults expect metres; no depth at all (a fuzz round).
    Case(
        "adjacency", lambda: M.adjacency(L, points=P * 1000), ARG, r"^points: .*millimetres", "mm"
    ),
    Case(
        "merge_regions", lambda: M.merge_regions(L, P * 1000), ARG, r"^points: .*millimetres", "mm"
    ),
    Case(
        "merge_regions", lambda: M.merge_regions(L, P * np.nan), ARG, r"^points: got no point", "0"
    ),
    Case("SegmentFits", lambda: SegmentFits(P * 1000, L), ARG, r"^points: .*millimetres", "mm"),
    Case("SegmentFits", lambda: SegmentFits(P * np.nan, L), ARG, r"^points: got no point", "none"),
    Case("adjacency", lambda: M.adjacency(L, lab=P[..., :2]), SHAPE, r"^lab: got shape", "lab"),
    Case(
        "adjacency",
        lambda: M.adjacency(L, normals=P, max_normal_angle=200),
        ARG,
        r"^max_normal_angle: got 200",
        "angle",
    ),
    Case(
        "adjacency",
        lambda: M.adjacency(L, points=P, max_depth_step=-1),
        ARG,
        r"^max_depth_step",
        "step",
    ),
    Case("adjacency", lambda: M.adjacency(L, touching=1), ARG, r"^touching", "touching"),
    Case("merge_regions", lambda: M.merge_regions(L, P[..., :2]), SHAPE, r"^points: got shape"),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, pdfs=PDF * 2),
        ARG,
        r"^pdfs: got per-pixel sums off 1",
        "sum",
    ),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, pdfs=PDF[..., :1] * 2),
        SHAPE,
        r"^pdfs: got 1 class",
        "classes",
    ),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, pdfs=PDF[:2]),
        SHAPE,
        r"^pdfs: got shape",
        "pdf-shape",
    ),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, pdfs=np.where(PDF > 0, np.nan, 0)),
        ARG,
        r"^pdfs: got 32 non-finite",
        "nan",
    ),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, pdfs=np.dstack([PDF[..., 0] * 3, PDF[..., 1] - 1])),
        ARG,
        r"^pdfs: got a negative",
        "negative",
    ),
    Case("merge_regions", lambda: M.merge_regions(L, P, t_sim=1.5), ARG, r"^t_sim", "t_sim"),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, fits="fits"),  # type: ignore[arg-type]
        ARG,
        r"^fits: got str",
        "fits-type",
    ),
    Case(
        "merge_regions",
        lambda: M.merge_regions(L, P, fits=SegmentFits(P, L.T.copy())),
        ARG,
        r"^fits: got fits of another",
        "fits-labels",
    ),
    Case(
        "majority_classes",
        lambda: M.majority_classes(L, PDF[..., :1] * 2),
        SHAPE,
        r"^pdfs: got 1 class",
    ),
    Case("majority_classes", lambda: M.majority_classes(L[:2], PDF), SHAPE, r"^pdfs", "shape"),
    Case("segment", lambda: segment(RGB, DEPTH, "cam"), ARG, r"^camera: got str"),  # type: ignore[arg-type]
    Case("segment", lambda: segment(RGB, DEPTH, CAM, n_segments=1), ARG, r"^n_segments", "k"),
    Case("segment", lambda: segment(RGB[:, :-1], DEPTH, CAM), SHAPE, r"rgb|depth", "size"),
    # segment() names its own arguments for frames too small for a stage (a fuzz round)
    Case(
        "segment",
        lambda: segment(RGB[:2, :2], DEPTH[:2, :2], CAM.scaled(2 / 32, 2 / 24), labeler=None),
        SHAPE,
        r"^depth: got a 2x2 frame, expected at least 3 px",
        "tiny",
    ),
    Case(
        "segment",
        lambda: segment(RGB, DEPTH, CAM),
        SHAPE,
        r"^rgb: got a 32x24 frame, smaller than the labeling .*rgbd segment --labeler none",
        "below the network",
    ),
    Case(
        "segment",
        lambda: segment(RGB, DEPTH[::2, ::2], CAM),
        SHAPE,
        r"^depth: got 16x12 pixels, expected the rgb image's 32x24: register the depth",
        "lattice",
    ),
    Case("segment", lambda: segment(RGB, DEPTH * np.nan, CAM), ARG, r"^depth", "no-depth"),
    Case("segment", lambda: segment(RGB, DEPTH, CAM, n_segments=10**6), ARG, r"n_segments", "k>n"),
    Case("segment", lambda: segment(RGB, DEPTH, CAM, fill_radius=-2), ARG, r"^fill_radius: got -2"),
    Case(
        "segment",
        lambda: segment(
            RGB, np.where(np.arange(768).reshape(24, 32) < 100, DEPTH, 0), CAM, fill_radius=0
        ),
        ARG,
        r"^depth: got 100 pixels with usable depth .* expected at least n_segments=230",
        "too few",
    ),
    Case("fill_depth_holes", lambda: fill_depth_holes(DEPTH[0]), SHAPE, r"^depth: got shape"),
    Case("fill_depth_holes", lambda: fill_depth_holes(DEPTH, "2"), ARG, r"^radius: got '2'", "str"),
    Case(
        "fill_depth_holes",
        lambda: fill_depth_holes(DEPTH.astype(bool)),
        ARG,
        r"^depth: got dtype bool",
        "bool",
    ),
    Case(
        "MergeResult.labels_after",
        lambda: M.merge_regions(L, P).labels_after(99),
        ARG,
        r"^steps: got 99",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
