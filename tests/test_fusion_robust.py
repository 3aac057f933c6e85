"""Fusion on data it was not tuned on: amplitude in any unit, flying ToF pixels, SGBM's parked
outputs, implausible ToF depths, swapped images, either output camera, the calibration layout."""

from __future__ import annotations

import dataclasses
import importlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError, Pose, RgbdError, ShapeMismatchError
from rgbd_rs.data.calibration import _rig_to_dict, load_rig
from rgbd_rs.data.synth import SynthSample, generate, synth3_rig
from rgbd_rs.fusion import FusionResult, fuse, sgm, tof_confidence, tof_to_reference
from rgbd_rs.fusion._inputs import far_camera_warning, tof_depth_warning, with_reference
from rgbd_rs.fusion.fuse import shipped_estimator
from rgbd_rs.fusion.stereo import (
    DISPARITY_STEP,
    MAX_RANGE_FRACTION,
    _max_search,
    _predict_search_range,
    _same_search,
    _whole_steps,
    search_range,
)
from rgbd_rs.fusion.upsample import _reproject_tof
from rgbd_rs.nn.confidence import WEIGHTS, WEIGHTS_FAR, ConfidenceEstimator

RIG = synth3_rig(0.25)  # 480 x 270
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def scene() -> SynthSample:
    return generate(0, "test", 1, RIG)[0]


@pytest.fixture(scope="module")
def fused(scene: SynthSample) -> FusionResult:
    return fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG)


def _one_warning(record: list[warnings.WarningMessage], needle: str) -> str:
    hits = [str(w.message) for w in record if needle in str(w.message)]
    assert len(hits) == 1, [str(w.message) for w in record]
    assert all(issubclass(w.category, RuntimeWarning) for w in record)
    return hits[0]


# -- 1. the amplitude's unit ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def float32_net() -> ConfidenceEstimator:
    return ConfidenceEstimator.load(precision="float32")


@pytest.fixture(scope="module")
def fused32(scene: SynthSample, float32_net: ConfidenceEstimator) -> FusionResult:
    return fuse(
        scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG, confidence=float32_net
    )


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_fuse_ignores_the_amplitude_unit(
    scene: SynthSample, fused32: FusionResult, float32_net: ConfidenceEstimator, scale: float
) -> None:
    # In float32 the network sees the same clues to rounding; in bfloat16 (the default where
    # the CPU has it) a clue's last bit may round either way: see the test below.
    fused = fused32
    amp = (scene.tof_amplitude * scale).astype(np.float32)
    out = fuse(scene.left, scene.right, scene.tof_depth, amp, RIG, confidence=float32_net)
    assert out.tof_confidence is not None and fused.tof_confidence is not None
    # Not all zero (the simulator-unit noise law gave 0 on every pixel at 1e-4).
    assert np.mean(out.tof_confidence > 0.5) > 0.5
    np.testing.assert_allclose(out.tof_confidence, fused.tof_confidence, atol=1e-5)
    np.testing.assert_array_equal(np.isnan(out.disparity), np.isnan(fused.disparity))
    np.testing.assert_allclose(out.disparity, fused.disparity, atol=1e-3)
    assert out.max_disparity == fused.max_disparity


def test_bfloat16_fusion_is_the_float32_one_within_its_rounding(
    scene: SynthSample, fused32: FusionResult, float32_net: ConfidenceEstimator
) -> None:
    amp = (scene.tof_amplitude * 1e4).astype(np.float32)
    half = float32_net.with_precision("bfloat16")
    out = fuse(scene.left, scene.right, scene.tof_depth, amp, RIG, confidence=half)
    assert out.tof_confidence is not None and fused32.tof_confidence is not None
    assert np.abs(out.tof_confidence - fused32.tof_confidence).max() < 0.03
    np.testing.assert_array_equal(np.isnan(out.disparity), np.isnan(fused32.disparity))
    both = np.isfinite(out.disparity)
    diff = np.abs(out.disparity - fused32.disparity)[both]
    assert np.median(diff) < 1e-3 and np.mean(diff > 0.25) < 0.002, (np.median(diff), diff.max())


def test_tof_confidence_over_eight_orders_of_magnitude(scene: SynthSample) -> None:
    tof = tof_to_reference(scene.tof_depth, scene.tof_amplitude, RIG, scene.right)
    base = tof_confidence(tof.disparity, tof.amplitude)
    for scale in np.logspace(-4, 4, 9):
        scaled = tof_confidence(tof.disparity, (tof.amplitude * scale).astype(np.float32))
        np.testing.assert_allclose(scaled, base, atol=1e-5, err_msg=f"scale {scale:g}")
    # Amplitude in 0.1 ... 1 (another sensor's unit): the same map.
    a = tof.amplitude / np.nanmax(tof.amplitude)
    np.testing.assert_allclose(tof_confidence(tof.disparity, a), base, atol=1e-5)


def test_tof_confidence_distrusts_dark_pixels_relative_to_the_frame() -> None:
    d = np.full((40, 60), 20.0, np.float32)
    amp = np.ones((40, 60), np.float32)
    amp[10:20, 10:20] = 1e-3  # shot noise x sqrt(1000) ~ 32 times the frame's typical pixel
    amp[25:35, 30:40] = 0.5  # x 1.4: still trusted
    for unit in (1e-3, 1.0, 2e4):
        c = tof_confidence(d, amp * unit)
        assert c[12:18, 12:18].max() == 0
        assert c[27:33, 32:38].min() == 1 and c[:5, 45:].min() == 1
    d[0, 0] = np.nan
    assert tof_confidence(d, amp)[0, 0] == 0


# -- 2. the SGM search range ---------------------------------------------------------------------


def test_search_range_ignores_flying_pixels(scene: SynthSample, fused: FusionResult) -> None:
    gt_max = float(np.nanmax(scene.gt_disparity))
    # On the reference lattice: 0.4 % of the pixels in 2 x 2 blobs at tiny depth (300 px).
    rng = np.random.default_rng(7)
    disp = fused.tof.disparity.copy()
    ys = rng.integers(0, disp.shape[0] - 1, disp.size // 1000)
    xs = rng.integers(0, disp.shape[1] - 1, disp.size // 1000)
    for dy in (0, 1):
        for dx in (0, 1):
            disp[ys + dy, xs + dx] = 300.0
    finite = disp[np.isfinite(disp)]
    assert 0.003 < np.mean(finite == 300) < 0.005
    # The former rule (99.9th percentile x 1.15) is fooled; the robust one is not.
    assert np.percentile(finite, 99.9) * 1.15 > 3 * gt_max
    assert gt_max < search_range(disp) < 1.3 * gt_max
    # End to end: 0.4 % of the ToF frame's pixels flying at 0.2-0.5 m change nothing.
    depth = scene.tof_depth.copy()
    flying = rng.random(depth.shape) < 0.004
    depth[flying] = rng.uniform(0.2, 0.5, flying.sum())
    out = fuse(scene.left, scene.right, depth, scene.tof_amplitude, RIG)
    assert gt_max < out.max_disparity < 1.3 * gt_max
    assert abs(out.max_disparity - fused.max_disparity) <= 2
    clean_cover = np.isfinite(fused.stereo_disparity).mean()
    assert np.isfinite(out.stereo_disparity).mean() > clean_cover - 0.02


def test_search_range_clamps_and_falls_back() -> None:
    w = 300
    near = np.full((50, w), 250.0, np.float32)  # a wall nearer than SGM can search well
    assert search_range(near) == int(MAX_RANGE_FRACTION * w)
    assert search_range(np.full((50, w), np.nan, np.float32)) == int(MAX_RANGE_FRACTION * w)
    assert search_range(np.full((50, w), 3.0, np.float32)) == DISPARITY_STEP
    # a ToF valid on a handful of pixels bounds nothing: the widest range, as with none
    few = np.full((50, w), np.nan, np.float32)
    few[20:26, 100:106] = 3.0  # 36 pixels of 15,000, 4 after the 5 x 5 median filter
    assert search_range(few) == int(MAX_RANGE_FRACTION * w)
    few[20:35, 100:120] = 3.0  # 176 after the filter: over MIN_RANGE_COVERAGE (1 %)
    assert search_range(few) == DISPARITY_STEP
    far = np.full((50, w), 40.0, np.float32)
    far[::7, ::9] = 280.0  # isolated spikes: gone after the median filter
    assert search_range(far) == int(np.ceil(40 * 1.15))
    # The map's width by default; a given width bounds it (and OpenCV's limit does too).
    assert search_range(near, width=2000) == 288
    assert search_range(np.full((5, 40), 30.0, np.float32)) <= max(1, _max_search(40))
    # Bad input names the argument (search_range is not in rgbd_rs.fusion.__all__, so its cases
    # live here rather than in the bad-input suite).
    with pytest.raises(ShapeMismatchError, match=r"^tof_disparity: got shape \(300,\)"):
        search_range(near[0])
    with pytest.raises(InvalidArgumentError, match=r"^width: got 1"):
        search_range(near, width=1)


def test_search_range_predicted_from_the_sparse_tof(
    scene: SynthSample, fused: FusionResult
) -> None:
    sparse = _reproject_tof(scene.tof_depth, scene.tof_amplitude, RIG)
    disp = RIG.stereo.baseline * RIG.stereo.focal / sparse.depth
    assert abs(_predict_search_range(disp) - fused.max_disparity) <= 2
    assert _same_search(16, 1) and _same_search(33, 48) and not _same_search(48, 49)
    with pytest.raises(ShapeMismatchError, match=r"^sparse_disparity: got shape"):
        _predict_search_range(disp[0])


@pytest.mark.parametrize("spacing", [2, 5, 7, 12])
def test_predicted_range_from_samples_far_apart(spacing: int) -> None:
    # A ToF of a quarter of the camera's pixels per axis (512 x 424 on 4K) leaves its samples
    # 4-8 px apart: the 3 x 3 spread once left dots the median filter removed, and the guess
    # fell back to the widest range (1279 px at 4K: a cost volume refused).
    dense = np.full((540, 960), np.nan, np.float32)
    dense[60:500, 100:900] = np.linspace(20.0, 40.0, 800, dtype=np.float32)
    sparse = np.full_like(dense, np.nan)
    sparse[::spacing, ::spacing] = dense[::spacing, ::spacing]
    assert abs(_predict_search_range(sparse) - search_range(dense)) <= 1
    assert _predict_search_range(np.full_like(dense, np.nan)) == search_range(dense * np.nan)
    # A ToF that sees a corner under MIN_RANGE_COVERAGE of the map bounds nothing, however
    # wide its samples are spread (a 33-px spread once read it as enough): the widest range.
    corner = np.full((720, 1280), np.nan, np.float32)
    corner[:90:2, :90:2] = 30.0
    assert _predict_search_range(corner) == search_range(corner * np.nan)


@pytest.mark.parametrize("guess", [16, 120])
def test_fuse_reruns_sgm_when_the_predicted_range_misses(
    scene: SynthSample, fused: FusionResult, guess: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # SGM starts early with the range predicted from the sparse ToF; a prediction in another
    # SGBM step than the upsampled ToF's range is redone, so the output never depends on it.
    fuse_module = importlib.import_module("rgbd_rs.fusion.fuse")  # the name is also the function
    assert not _same_search(guess, fused.max_disparity)
    monkeypatch.setattr(fuse_module, "_predict_search_range", lambda *_: guess)
    out = fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG)
    assert out.max_disparity == fused.max_disparity
    np.testing.assert_array_equal(out.stereo_disparity, fused.stereo_disparity)
    np.testing.assert_array_equal(out.disparity, fused.disparity)
    # The census matcher searched the range in OpenCV's whole steps, as SGBM does.
    top = _whole_steps(fused.max_disparity)
    expect = sgm(
        scene.left,
        scene.right,
        max_disparity=top,
        method="census",
        params=fuse_module.FUSION_CENSUS,
    )
    np.testing.assert_array_equal(out.stereo_disparity, expect)


# -- 3. SGBM's parked outputs --------------------------------------------------------------------


def test_sgm_zero_and_invalid_outputs_are_nan(scene: SynthSample) -> None:
    # Identical views: every match is d = 0, where SGBM also parks what it cannot match.
    same = sgm(scene.right, scene.right, max_disparity=32)
    assert not (np.nan_to_num(same, nan=1.0) == 0).any()
    st = sgm(scene.left, scene.right, max_disparity=64, min_disparity=16)
    ok = np.isfinite(st)
    assert ok.mean() > 0.3 and (st[ok] > 16).all()
    st0 = sgm(scene.left, scene.right, max_disparity=64)
    assert (st0[np.isfinite(st0)] > 0).all()


# -- 4. implausible input warns once -------------------------------------------------------------


def test_depth_in_millimetres_is_refused(scene: SynthSample) -> None:
    # As segment() does: nothing useful can come of it, so before any work.
    with pytest.raises(InvalidArgumentError, match=r"^tof_depth: the ToF depths look like milli"):
        fuse(scene.left, scene.right, scene.tof_depth * 1000, scene.tof_amplitude, RIG)
    with pytest.raises(InvalidArgumentError, match=r"look like kilometres.*check the depth unit"):
        fuse(scene.left, scene.right, scene.tof_depth / 1000, scene.tof_amplitude, RIG)
    # the same disparities come of a baseline in millimetres: the message names it too
    mm = dataclasses.replace(
        RIG, stereo=dataclasses.replace(RIG.stereo, baseline=RIG.stereo.baseline * 1000)
    )
    with pytest.raises(
        InvalidArgumentError, match=r"kilometres.*or the calibration's baseline \(\d"
    ):
        fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, mm)


def test_depths_beyond_the_stereo_range_warn_once(scene: SynthSample) -> None:
    # b f = 43.6 px m on this rig: 60 m is 0.7 px of disparity (and 6 cm would be 727 px).
    far = np.where(np.isfinite(scene.tof_depth), 60.0, np.nan).astype(np.float32)
    with pytest.warns(RuntimeWarning) as record:
        fuse(scene.left, scene.right, far, scene.tof_amplitude, RIG)
    msg = _one_warning(record, "beyond the stereo rig's range")
    assert "baseline" in msg and "millimetres" not in msg


def test_an_amplitude_passed_as_depth_warns(scene: SynthSample) -> None:
    # Most values far beyond the rig's range, a few plausible: the message asks whether the map
    # is the depth at all (a helper swapped --tof-depth and --tof-amplitude and got no word).
    amp = scene.tof_amplitude
    scaled = (222.0 * amp / np.nanmedian(amp[amp > 0])).astype(np.float32)
    with pytest.warns(RuntimeWarning) as record:
        fuse(scene.left, scene.right, scaled, scene.tof_amplitude, RIG)
    msg = _one_warning(record, "of the ToF depths lie outside the stereo rig's range")
    assert "not the amplitude" in msg and "median 222 m" in msg
    # The scene's own depths: nothing to say.
    assert tof_depth_warning(scene.tof_depth, RIG) is None


def test_swapped_images_warn_once(scene: SynthSample) -> None:
    with pytest.warns(RuntimeWarning) as record:
        fuse(scene.right, scene.left, scene.tof_depth, scene.tof_amplitude, RIG)
    msg = _one_warning(record, "look swapped")
    assert msg.startswith("left/right:") and "left camera's" in msg


def test_swapped_images_warn_without_a_tof_too(scene: SynthSample) -> None:
    nan = np.full_like(scene.tof_depth, np.nan)
    with pytest.warns(RuntimeWarning) as record:
        fuse(scene.right, scene.left, nan, scene.tof_amplitude, RIG, max_disparity=64)
    messages = [str(w.message) for w in record]
    assert any("no valid ToF pixel" in m for m in messages)
    _one_warning(record, "look swapped")


# -- 5. either output camera; the calibration layout ---------------------------------------------


def test_reference_left_is_consistent_with_right(scene: SynthSample, fused: FusionResult) -> None:
    # The synthetic ToF sits below the right camera: the left one is the far camera.
    with pytest.warns(RuntimeWarning, match=r"^reference: the ToF sits 0\.04 m from the right"):
        left = fuse(
            scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG, reference="left"
        )
    # There the ConvNet trained for the far camera runs, here the default one.
    far_net = ConfidenceEstimator.load(WEIGHTS_FAR)
    assert shipped_estimator(far=True).source == str(WEIGHTS_FAR)
    assert shipped_estimator().source == str(WEIGHTS)
    for net, result, images in (
        (far_net, left, (scene.left, scene.right)),
        (ConfidenceEstimator.load(), fused, (scene.right, scene.left)),
    ):
        maps = (result.tof_fused, result.tof.amplitude, result.stereo_disparity)
        p_s = net(*images, *maps, reference=result.reference)[1]
        np.testing.assert_allclose(p_s, result.stereo_confidence, atol=1e-6)
    assert left.reference == "left" and fused.reference == "right"
    # Right pixel x sees what left pixel x + d sees, with the same disparity.
    for key in ("tof", "disparity"):
        r_map = fused.tof.disparity if key == "tof" else fused.disparity
        l_map = left.tof.disparity if key == "tof" else left.disparity
        ys, xs = np.nonzero(np.isfinite(r_map) & np.isfinite(scene.gt_disparity))
        xl = np.rint(xs + r_map[ys, xs]).astype(int)
        inside = xl < r_map.shape[1]
        diff = np.abs(l_map[ys[inside], xl[inside]] - r_map[ys[inside], xs[inside]])
        assert np.mean(diff < 1) > 0.85, key


def test_the_far_camera_warning_speaks_only_for_the_camera_farther_from_the_tof() -> None:
    assert far_camera_warning(RIG) is None  # the ToF below the right (reference) camera
    left = with_reference(RIG, "left")
    msg = far_camera_warning(left)
    assert msg is not None and "reference='right' (rgbd fuse --reference right)" in msg
    # A ToF midway between the cameras, or just off the middle: either camera is fine.
    b = RIG.stereo.baseline
    for x in (-b / 2, -b / 2 + 0.04 * b, -b / 2 - 0.04 * b):
        mid = dataclasses.replace(RIG, tof_to_reference=Pose(np.eye(3), np.array([x, 0.04, 0.0])))
        assert far_camera_warning(mid) is None
    # Beside the left camera while fusing on the right: warned, naming the left camera.
    by_left = dataclasses.replace(RIG, tof_to_reference=Pose(np.eye(3), np.array([-b, 0.0, 0.0])))
    assert "Fuse on the left camera" in (far_camera_warning(by_left) or "")


def test_with_reference_carries_the_pose_across_the_baseline() -> None:
    left = with_reference(RIG, "left")
    np.testing.assert_allclose(left.tof_to_reference.translation, [0.12, 0.04, 0.0])
    back = with_reference(left, "right")
    np.testing.assert_allclose(back.tof_to_reference.translation, RIG.tof_to_reference.translation)
    assert with_reference(RIG, "right") is RIG


def test_example_calibration_is_the_synthetic_rig() -> None:
    rig = load_rig(EXAMPLES / "calibration.json")
    assert _rig_to_dict(rig) == _rig_to_dict(synth3_rig(0.5))
    assert json.loads((EXAMPLES / "calibration.json").read_text()) == _rig_to_dict(rig)


@pytest.mark.parametrize(
    ("path", "match"),
    [
        (("tof", "fx"), r"calibration: camera 'tof' has no key 'fx'"),
        (("stereo", "left", "width"), r"calibration: camera 'stereo\.left' has no key 'width'"),
        (("stereo", "baseline"), r"calibration: 'stereo' has no key 'baseline'"),
        (("tof_to_reference", "rotation"), r"calibration: 'tof_to_reference' has no key 'rotat"),
        (("tof",), r"calibration: the file has no key 'tof'"),
    ],
)
def test_missing_calibration_keys_are_named(
    tmp_path: Path, path: tuple[str, ...], match: str
) -> None:
    doc = _rig_to_dict(RIG)
    where = doc
    for key in path[:-1]:
        where = where[key]
    del where[path[-1]]
    (tmp_path / "c.json").write_text(json.dumps(doc))
    with pytest.raises(RgbdError, match=r"c\.json: " + match):
        load_rig(tmp_path / "c.json")


def test_an_amplitude_without_any_positive_value_warns(scene: SynthSample) -> None:
    # Estimated confidences read the amplitude: all zero / NaN / inf gives the ToF no weight.
    for bad in (0.0, np.nan, np.inf):
        amp = np.full_like(scene.tof_amplitude, bad)
        with pytest.warns(RuntimeWarning) as record:
            fuse(scene.left, scene.right, scene.tof_depth, amp, RIG, confidence="heuristic")
        msg = _one_warning(record, "no ToF pixel has a finite amplitude > 0")
        assert msg.startswith("tof_amplitude:") and "heuristic confidences give the ToF no" in msg
    # The ConvNet reads it as a clue: the warning says that, not "no weight".
    zero = np.zeros_like(scene.tof_amplitude)
    with pytest.warns(RuntimeWarning) as record:
        fuse(scene.left, scene.right, scene.tof_depth, zero, RIG)
    assert "reads it as one of its clues" in _one_warning(record, "finite amplitude > 0")
    # Uniform weights do not read it: no warning (the suite turns warnings into errors).
    fuse(scene.left, scene.right, scene.tof_depth, zero, RIG, confidence="uniform")
