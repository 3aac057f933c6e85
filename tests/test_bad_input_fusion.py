"""Bad input to :mod:`rgbd_rs.fusion` (see tests/test_bad_input.py for the contract and the
meta-test that counts these cases)."""

from __future__ import annotations

import numpy as np
import pytest

import rgbd_rs.fusion as F
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.data import synth3_rig

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

I4 = np.zeros((4, 4, 3), np.uint8)
D4 = np.arange(16, dtype=np.float32).reshape(4, 4) / 4  # non-constant, as in the issue
IMG = np.random.default_rng(0).integers(0, 255, (20, 40, 3)).astype(np.uint8)
D = np.full((20, 40), 3.0, np.float32)
RIG = synth3_rig(0.125)  # 240 x 135 stereo, 512 x 424 ToF
LEFT = np.zeros((135, 240, 3), np.uint8)
TOF = np.ones((424, 512), np.float32)


def _overflowing() -> np.ndarray:
    d = D4.copy()
    d[0, 0] = -1e19  # bin count overflow (issue 11)
    return d


CASES: list[Case] = [
    Case("lc_fuse", lambda: F.lc_fuse(I4, I4, [D4] * 9), ARG, r"^disparities: got 9 maps", "9"),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4[:2], I4, [D4]),
        SHAPE,
        r"^target_image: got 4x4 pixels, expected 4x2 \(reference_image's size\)",
        "pair size",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT.astype(np.float32), LEFT, TOF, TOF, RIG),
        ARG,
        r"^left: got dtype float32",
    ),
    Case("fuse", lambda: F.fuse(LEFT, LEFT, TOF, TOF, "rig"), ARG, r"^rig: got str", "rig"),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT[:, :-1], TOF, TOF, RIG),
        SHAPE,
        r"^right: got 239x135",
        "size",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF[:, :-1], TOF, RIG),
        SHAPE,
        r"^tof_depth: got shape",
        "tof",
    ),
    Case(
        "fuse",
        lambda: F.fuse(
            LEFT, LEFT, -np.linspace(1, 3, TOF.size, dtype=np.float32).reshape(TOF.shape), TOF, RIG
        ),
        ARG,
        r"^tof_depth: got only negative depths \(-3 to -1\), expected metres > 0 .*sign flipped",
        "negative depth",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, -TOF, RIG),
        ARG,
        r"^tof_amplitude: got 217088 negative values \(down to -1\), expected amplitudes >= 0",
        "negative amplitude",
    ),
    Case(
        "fuse",
        lambda: F.fuse(
            LEFT,
            LEFT,
            TOF,
            TOF,
            RIG,
            confidence=(np.ones(LEFT.shape[:2]), np.full(LEFT.shape[:2], 2.0)),
        ),
        ARG,
        r"^confidence\[1\]: got values in \[2, 2\], expected values in \[0, 1\]",
        "maps out of range",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, confidence="learned"),
        ARG,
        r"^confidence: got 'learned'",
        "confidence",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, max_disparity=240),
        ARG,
        r"^max_disparity: got 240",
        "max_disparity",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, params="fast"),
        ARG,
        r"^params: got str",
        "params",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, reference="middle"),
        ARG,
        r"^reference: got 'middle'",
        "reference",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, stereo="sgbm"),
        ARG,
        r"^stereo: got 'sgbm'",
        "stereo",
    ),
    Case(
        "LcParams",
        lambda: F.lc_fuse(I4, I4, [D4], params=F.LcParams(radius="x")),
        ARG,
        r"^radius: got 'x'",
    ),
    Case(
        "LcParams",
        lambda: F.lc_fuse(I4, I4, [D4], params=F.LcParams(radius=2, stride=0)),
        ARG,
        r"^stride: got 0",
        "stride",
    ),
    Case(
        "LcParams",
        lambda: F.lc_fuse(I4, I4, [D4], params=F.LcParams(gamma_c=-1.0)),
        ARG,
        r"^gamma_c: got -1",
        "gamma_c",
    ),
    # Beyond float32: refused when made, as the user wrote it (not as the inf it would become).
    Case(
        "LcParams",
        lambda: F.LcParams(gamma_c=1e300),
        ARG,
        r"^gamma_c: got 1e\+300, expected a magnitude within float32",
        "f32",
    ),
    Case(
        "LcParams", lambda: F.LcParams(bin_width=1e-300), ARG, r"^bin_width: got 1e-300", "f32-tiny"
    ),
    Case(
        "LcParams.resolved",
        lambda: F.LcParams().resolved("wide"),
        ARG,
        r"^width: got 'wide'",
    ),
    Case("LcParams.native", lambda: F.LcParams(radius=0).native(8, 1), ARG, r"^radius: got 0"),
    Case(
        "LcParams.native",
        lambda: F.LcParams().native(8, 0),
        ARG,
        r"^target_sign: got 0",
        "sign",
    ),
    Case(
        "LcParams.native",
        lambda: F.LcParams().native(2**70, 1),
        ARG,
        r"^width: got",
        "huge width",
    ),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4], params=F.LcParams(bin_width=1e-30)),
        ARG,
        r"^bin_width",
        "bin_width 1e-30",
    ),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [_overflowing()]),
        ARG,
        r"^(bin_width|disparities)",
        "disparity -1e19",
    ),
    Case("lc_fuse", lambda: F.lc_fuse(I4, I4, []), ARG, r"^disparities: got list", "empty"),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4[:3]]),
        SHAPE,
        r"^disparities\[0\]: got shape \(3, 4\)",
        "shape",
    ),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4], [None, None]),
        ARG,
        r"^confidences: got 2 maps",
        "confidences",
    ),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4], [np.full((4, 4), 2.0)]),
        ARG,
        r"^confidences\[0\]: got values",
        "confidence range",
    ),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4], target_sign=0),
        ARG,
        r"^target_sign: got 0",
        "sign",
    ),
    Case(
        "lc_refine",
        lambda: F.lc_refine(D4[:3], I4, I4),
        SHAPE,
        r"^disparity: got shape \(3, 4\)",
    ),
    Case(
        "lc_refine",
        lambda: F.lc_refine(D4, I4, I4, reference="up"),
        ARG,
        r"^reference: got 'up'",
        "reference",
    ),
    Case(
        "lc_refine",
        lambda: F.lc_refine(np.full((4, 4), np.nan, np.float32), I4, I4),
        ARG,
        r"^disparity: got only NaN",
        "all NaN",
    ),
    Case("sgm", lambda: F.sgm(IMG, IMG, max_disparity=39), ARG, r"^max_disparity: got 39"),
    Case("sgm", lambda: F.sgm([[1, 2], [3]], IMG), ARG, r"^left: got list", "ragged"),
    Case(
        "lc_fuse",
        lambda: F.lc_fuse(I4, I4, [D4], confidences=-1),
        ARG,
        r"^confidences: got int",
        "confidences not a list",
    ),
    Case(
        "sgm",
        lambda: F.sgm(IMG, IMG, max_disparity=30, min_disparity=10),
        ARG,
        r"^max_disparity: got 30",
        "with min_disparity",
    ),
    Case(
        "sgm", lambda: F.sgm(IMG[:, :12], IMG[:, :12], max_disparity=8), SHAPE, r"^left", "narrow"
    ),
    Case("sgm", lambda: F.sgm(IMG, IMG, reference="up"), ARG, r"^reference: got 'up'", "ref"),
    Case("sgm", lambda: F.sgm(IMG, IMG, max_disparity=16, block_size=4), ARG, r"^block_size", "bs"),
    Case("sgm", lambda: F.sgm(IMG, IMG[:, :30]), SHAPE, r"^right: got 30x20", "size"),
    Case(
        "cost_curve_stats",
        lambda: F.cost_curve_stats(IMG, IMG, D[:, :10]),
        SHAPE,
        r"^disparity: got shape \(20, 10\)",
    ),
    Case(
        "cost_curve_stats",
        lambda: F.cost_curve_stats(IMG, IMG, D, target_sign=0),
        ARG,
        r"^target_sign: got 0",
        "sign",
    ),
    Case(
        "cost_curve_stats",
        lambda: F.cost_curve_stats(IMG, IMG, D, max_disparity=40),
        ARG,
        r"^max_disparity: got 40",
        "range",
    ),
    Case(
        "stereo_confidence",
        lambda: F.stereo_confidence(IMG, IMG[:10], D),
        SHAPE,
        r"^target_image: got 40x10",
    ),
    Case(
        "stereo_confidence",
        lambda: F.stereo_confidence(IMG, IMG, D, max_disparity=0),
        ARG,
        r"^max_disparity: got 0",
        "range",
    ),
    Case(
        "tof_confidence",
        lambda: F.tof_confidence(D, D[:5]),
        SHAPE,
        r"^amplitude: got shape \(5, 40\)",
    ),
    Case(
        "tof_confidence",
        lambda: F.tof_confidence(D, D, read_noise=0.0, shot_noise=0.0),
        ARG,
        r"^read_noise/shot_noise: got 0 and 0",
        "no noise",
    ),
    Case(
        "tof_confidence",
        lambda: F.tof_confidence(D, D, read_noise="x"),
        ARG,
        r"^read_noise: got 'x'",
        "noise",
    ),
    Case(
        "tof_confidence",
        lambda: F.tof_confidence(D, D, ambient=-1.0),
        ARG,
        r"^ambient: got -1",
        "ambient",
    ),
    Case(
        "segment_mean_shift",
        lambda: F.segment_mean_shift(D),
        ARG,
        r"^image: got dtype float32",
    ),
    Case(
        "segment_mean_shift",
        lambda: F.segment_mean_shift(IMG, spatial_radius=0),
        ARG,
        r"^spatial_radius: got 0",
        "radius",
    ),
    Case(
        "upsample_depth",
        lambda: F.upsample_depth(D[:4], IMG),
        SHAPE,
        r"^sparse: got shape \(4, 40\)",
    ),
    Case(
        "upsample_depth",
        lambda: F.upsample_depth(D, IMG, sigma_range=0.0),
        ARG,
        r"^sigma_range: got 0",
        "sigma",
    ),
    Case(
        "upsample_depth",
        lambda: F.upsample_depth(D, IMG, np.zeros((3, 3), np.int32)),
        SHAPE,
        r"^labels: got shape \(3, 3\)",
        "labels",
    ),
    Case(
        "tof_to_reference",
        lambda: F.tof_to_reference(TOF, TOF, "rig", LEFT),
        ARG,
        r"^rig: got str",
    ),
    Case(
        "tof_to_reference",
        lambda: F.tof_to_reference(TOF * 1000, TOF, RIG, LEFT),
        ARG,
        r"^tof_depth: the ToF depths look like millimetres",
        "mm",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF * 1000, RIG, np.zeros((135, 240), np.float32)),
        ARG,
        r"^tof_depth: the ToF depths look like millimetres",
        "mm",
    ),
    Case(
        "refine_tof_scale",
        lambda: F.refine_tof_scale(TOF * 1000, RIG, np.zeros((135, 240), np.float32)),
        ARG,
        r"^tof_depth: the ToF depths look like millimetres",
        "mm",
    ),
    Case(
        "tof_to_reference",
        lambda: F.tof_to_reference(TOF[:-1], TOF, RIG, LEFT),
        SHAPE,
        r"^tof_depth: got shape \(423, 512\)",
        "shape",
    ),
    Case(
        "tof_to_reference",
        lambda: F.tof_to_reference(TOF, TOF, RIG, LEFT, radius=0),
        ARG,
        r"^radius: got 0",
        "radius",
    ),
    Case(
        "tof_to_reference",
        lambda: F.tof_to_reference(TOF, TOF, RIG, LEFT, segmentation="yes"),  # type: ignore[arg-type]
        ARG,
        r"^segmentation: got 'yes'",
        "segmentation",
    ),
    Case(
        "fuse",
        lambda: F.fuse(LEFT, LEFT, TOF, TOF, RIG, refine_pose="no"),  # type: ignore[arg-type]
        ARG,
        r"^refine_pose: got 'no', expected True or False",
        "refine",
    ),
    Case(
        "measure_row_alignment",
        lambda: F.measure_row_alignment(LEFT, LEFT, np.zeros((134, 240), np.float32)),
        SHAPE,
        r"^disparity: got shape \(134, 240\)",
        "shape",
    ),
    Case(
        "measure_row_alignment",
        lambda: F.measure_row_alignment(
            LEFT, LEFT, np.zeros((135, 240), np.float32), reference="up"
        ),
        ARG,
        r"^reference: got 'up'",
        "reference",
    ),
    Case(
        "align_rows",
        lambda: F.align_rows(LEFT, "2 px"),  # type: ignore[arg-type]
        ARG,
        r"^alignment: got str, expected a RowAlignment",
        "type",
    ),
    Case(
        "align_rows",
        lambda: F.align_rows(LEFT[:100], F.RowAlignment(1.0, 0.0, 0.0, 240, 135, 500, 0.1)),
        SHAPE,
        r"^image: got 240x100 pixels, expected 240x135",
        "size",
    ),
    Case(
        "CensusParams",
        lambda: F.CensusParams(align_rows="yes"),  # type: ignore[arg-type]
        ARG,
        r"^align_rows: got 'yes', expected True or False",
        "align_rows",
    ),
    Case(
        "refine_tof_scale",
        lambda: F.refine_tof_scale(TOF, "rig", np.zeros((135, 240), np.float32)),
        ARG,
        r"^rig: got str",
        "rig",
    ),
    Case(
        "refine_tof_scale",
        lambda: F.refine_tof_scale(TOF, RIG, np.zeros((134, 240), np.float32)),
        SHAPE,
        r"^stereo_disparity: got shape \(134, 240\)",
        "stereo",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF, "rig", np.zeros((135, 240), np.float32)),
        ARG,
        r"^rig: got str",
        "rig",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF[:-1], RIG, np.zeros((135, 240), np.float32)),
        SHAPE,
        r"^tof_depth: got shape \(423, 512\)",
        "depth",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF, RIG, np.zeros((135, 239), np.float32)),
        SHAPE,
        r"^stereo_disparity: got shape \(135, 239\)",
        "stereo",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF, RIG, np.zeros((135, 240), np.float32), max_degrees=0),
        ARG,
        r"^max_degrees: got 0",
        "zero",
    ),
    Case(
        "refine_tof_pose",
        lambda: F.refine_tof_pose(TOF, RIG, np.zeros((135, 240), np.float32), max_degrees=30),
        ARG,
        r"^max_degrees: got 30, expected at most 10",
        "large",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
