"""The native fusion stages that replaced OpenCV / numpy equal them bit for bit.

- mean shift (``_rgbd_rs.mean_shift_filter``) against ``cv2.pyrMeanShiftFiltering``;
- the stereo cost-curve statistics (``cost_curve_stats``) against the numpy/OpenCV formulation
  kept in ``rgbd_rs.fusion.stereo._cost_curve_stats_numpy``.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rgbd_rs import _rgbd_rs
from rgbd_rs.data.synth import generate, synth3_rig
from rgbd_rs.fusion import cost_curve_stats, segment_mean_shift
from rgbd_rs.fusion.stereo import _cost_curve_stats_numpy, _sgm


@pytest.fixture(scope="module")
def scene():  # type: ignore[no-untyped-def]
    return generate(0, "test", 1, synth3_rig(0.25))[0]  # 480 x 270


def _images(scene) -> list[tuple[str, np.ndarray]]:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(0)
    out = [("scene right", scene.right), ("scene left", scene.left)]
    for h, w in ((37, 53), (1, 7), (8, 1), (2, 2), (101, 77)):
        noise = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        out.append((f"noise {h}x{w}", noise))
        out.append((f"smooth {h}x{w}", cv2.GaussianBlur(noise, (5, 5), 2)))
    return out


@pytest.mark.parametrize(("sp", "sr"), [(8, 16), (5, 10), (3, 30)])
def test_mean_shift_equals_opencv(scene, sp: int, sr: int) -> None:  # type: ignore[no-untyped-def]
    for name, img in _images(scene):
        want = cv2.pyrMeanShiftFiltering(img, sp, sr)
        got = _rgbd_rs.mean_shift_filter(img, sp, sr)
        differ = int((got != want).any(-1).sum())
        assert differ == 0, f"{name}: {differ} pixels differ from OpenCV (sp {sp}, sr {sr})"


def test_mean_shift_pyramid_levels_and_iterations_equal_opencv(scene) -> None:  # type: ignore[no-untyped-def]
    img = np.ascontiguousarray(scene.right[:135, :240])
    for level, iters, eps in ((0, 5, 1.0), (2, 3, 0.0), (1, 10, 2.0)):
        crit = (cv2.TERM_CRITERIA_MAX_ITER + cv2.TERM_CRITERIA_EPS, iters, eps)
        want = cv2.pyrMeanShiftFiltering(img, 8, 16, maxLevel=level, termcrit=crit)
        got = _rgbd_rs.mean_shift_filter(img, 8, 16, level, iters, eps)
        np.testing.assert_array_equal(got, want, err_msg=f"level {level} iters {iters} eps {eps}")


def test_segmentation_labels_are_opencvs(scene) -> None:  # type: ignore[no-untyped-def]
    filtered = cv2.pyrMeanShiftFiltering(scene.right, 8, 16)
    want, _ = _rgbd_rs.label_regions(np.ascontiguousarray(filtered), 2.0)
    np.testing.assert_array_equal(segment_mean_shift(scene.right), want)


@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize(("dmax", "block"), [(48, 7), (20, 4), (9, 1)])
def test_cost_curve_equals_numpy(scene, sign: int, dmax: int, block: int) -> None:  # type: ignore[no-untyped-def]
    ref, tgt = (scene.right, scene.left) if sign > 0 else (scene.left, scene.right)
    # any map will do (its range-cut warning is not this test's business)
    disp = _sgm(
        scene.left, scene.right, max_disparity=48, reference="right" if sign > 0 else "left"
    )
    disp[::7, ::5] = 99.5  # outside the search: NaN in c_at
    got = cost_curve_stats(ref, tgt, disp, target_sign=sign, max_disparity=dmax, block_size=block)
    grey = [cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in (ref, tgt)]
    want = _cost_curve_stats_numpy(grey[0], grey[1], disp, sign, dmax, block)
    for name, a, b in zip(("c1", "c2", "c_at"), got, want, strict=True):
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert np.isinf(got[1]).any() or dmax > 9, "c2 is +inf only where no far disparity exists"
    assert np.isfinite(got[2]).mean() > 0.3
