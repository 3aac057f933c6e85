"""ToF-stereo fusion: the stages on a rendered scene, the LC refinement, bad input, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError, ShapeMismatchError, StereoRig, cli
from rgbd_rs.data.calibration import save_rig
from rgbd_rs.data.synth import SynthSample, generate, synth3_rig
from rgbd_rs.fusion import (
    LcParams,
    fuse,
    lc_fuse,
    lc_refine,
    segment_mean_shift,
    sgm,
    tof_to_reference,
    upsample_depth,
)
from rgbd_rs.fusion.evaluate import (
    Sample,
    evaluate_sample,
    markdown_table,
    middlebury_sample,
    non_occluded,
)
from rgbd_rs.fusion.lc import REFINE_BIN_WIDTH
from rgbd_rs.io import read_npz, read_png, write_png
from rgbd_rs.metrics import rms_error

RIG = synth3_rig(0.25)  # 480 x 270: the thesis rig at a quarter of full resolution


@pytest.fixture(scope="module")
def scene() -> SynthSample:
    return generate(0, "test", 1, RIG)[0]


def test_stages_on_a_rendered_scene(scene: SynthSample) -> None:
    gt = scene.gt_disparity
    tof = tof_to_reference(scene.tof_depth, scene.tof_amplitude, RIG, scene.right)
    both = np.isfinite(tof.disparity) & np.isfinite(gt)
    assert both.mean() > 0.8
    # Upsampled ToF: most pixels within half a pixel of the truth.
    assert np.median(np.abs(tof.disparity - gt)[both]) < 0.25
    st = sgm(scene.left, scene.right, reference="right", max_disparity=64)
    ok = np.isfinite(st) & np.isfinite(gt)
    assert ok.mean() > 0.5
    assert np.median(np.abs(st - gt)[ok]) < 1.0, "right-reference SGM has the sign right"
    # The same pair seen from the left: SGM's disparities must be near the right view's
    # shifted by themselves (left x = right x + d).
    st_l = sgm(scene.left, scene.right, reference="left", max_disparity=64)
    ys, xs = np.nonzero(ok)
    xl = np.rint(xs + st[ys, xs]).astype(int)
    inside = xl < st.shape[1]
    agree = np.abs(st_l[ys[inside], xl[inside]] - st[ys[inside], xs[inside]]) < 1
    assert agree.mean() > 0.5, "a wrong sign agrees nowhere"


def test_fusion_accuracy_on_a_rendered_scene(scene: SynthSample) -> None:
    r = evaluate_sample(
        Sample(
            "s",
            scene.left,
            scene.right,
            scene.tof_depth,
            scene.tof_amplitude,
            RIG,
            scene.gt_disparity,
        )
    )
    tof, st = r.rms["Interpolated ToF"], r.rms["SGM"]
    assert r.pixels > 50_000
    # Confidences matter: the GT-derived ones beat both inputs and every estimate, the
    # heuristic ones beat stereo and stay near the (here excellent) ToF. (With OpenCV's SGBM,
    # 12.9 px RMS here against the census matcher's 5.7, equal weights were also far worse than
    # the heuristic: 6.0 vs 2.0 px; with census both beat the ToF, 1.0 and 1.4 px.)
    assert r.rms["LC oracle confidence"] < 0.8 * min(tof, st)
    assert r.rms["LC heuristic"] < min(1.2 * tof, st)
    assert r.rms["LC oracle confidence"] < min(r.rms["LC uniform"], r.rms["LC heuristic"])
    assert "| **mean** |" in markdown_table([r], "t")


def test_fuse_result_and_no_tof_warning(scene: SynthSample) -> None:
    out = fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG)
    assert out.disparity.shape == out.depth.shape == (270, 480)
    d, z = out.disparity, out.depth
    ok = np.isfinite(d) & (d > 0)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(z[ok] * d[ok], RIG.stereo.baseline * RIG.stereo.focal, rtol=1e-5)
    assert out.tof_confidence is not None and out.stereo_confidence is not None
    assert out.tof_confidence.min() >= 0 and out.tof_confidence.max() <= 1
    # A dark / dead ToF frame: stereo-only LC with a warning, never a crash.
    nan = np.full_like(scene.tof_depth, np.nan)
    with pytest.warns(RuntimeWarning, match="no valid ToF pixel"):
        only = fuse(scene.left, scene.right, nan, scene.tof_amplitude, RIG, max_disparity=64)
    assert np.isfinite(only.disparity).mean() > 0.5
    assert not np.isfinite(only.tof.disparity).any()


def test_given_confidences_steer_the_result(scene: SynthSample) -> None:
    ones, zeros = np.ones((270, 480), np.float32), np.zeros((270, 480), np.float32)
    tof_only = fuse(
        scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG, confidence=(ones, zeros)
    )
    st_only = fuse(
        scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG, confidence=(zeros, ones)
    )
    gt = scene.gt_disparity
    m = np.isfinite(gt) & np.isfinite(tof_only.disparity) & np.isfinite(st_only.disparity)
    assert rms_error(tof_only.disparity, gt, m) < 0.5 * rms_error(st_only.disparity, gt, m)
    nan = np.full((270, 480), np.nan, np.float32)
    with pytest.warns(RuntimeWarning, match="^confidence: neither map gives any pixel a weight"):
        empty = fuse(
            scene.left,
            scene.right,
            scene.tof_depth,
            scene.tof_amplitude,
            RIG,
            confidence=(nan, zeros),
        )
    assert not np.isfinite(empty.disparity).any()


def _textured_pair(d: float, w: int = 96, h: int = 40) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    tex = rng.integers(0, 255, (h, w + 64, 3)).astype(np.float32)
    tex = (tex + np.roll(tex, 1, 1) + np.roll(tex, 1, 0)) / 3
    left = tex[:, 32 : 32 + w].astype(np.uint8)
    right = tex[:, 32 + int(d) : 32 + int(d) + w].astype(np.uint8)  # right x sees left x + d
    return left, right


def test_lc_refine_removes_outliers() -> None:
    left, right = _textured_pair(6)
    rng = np.random.default_rng(1)
    noisy = np.full(left.shape[:2], 6.0, np.float32)
    outliers = rng.random(noisy.shape) < 0.15
    noisy[outliers] += rng.uniform(-5, 5, outliers.sum()).astype(np.float32)
    noisy[rng.random(noisy.shape) < 0.05] = np.nan
    core = (slice(5, -5), slice(12, -12))
    assert np.nanmean(np.abs(noisy[core] - 6) > 0.5) > 0.1
    out = lc_refine(
        noisy,
        left,
        right,
        reference="right",
        params=LcParams(radius=4, stride=1, bin_width=REFINE_BIN_WIDTH),
    )
    assert np.mean(np.abs(out[core] - 6) > 0.5) < 0.01
    # The same pair mirrored is a left-reference pair (left' x matches right' x - d).
    mirrored = lc_refine(
        noisy[:, ::-1],
        right[:, ::-1],
        left[:, ::-1],
        reference="left",
        params=LcParams(radius=4, stride=1, bin_width=REFINE_BIN_WIDTH),
    )
    assert np.mean(np.abs(mirrored[core] - 6) > 0.5) < 0.01
    with pytest.raises(InvalidArgumentError, match="only NaN"):
        lc_refine(np.full_like(noisy, np.nan), left, right)


def test_cross_check_keeps_agreeing_pixels(scene: SynthSample) -> None:
    out = fuse(scene.left, scene.right, scene.tof_depth, scene.tof_amplitude, RIG)
    srcs = [out.tof.disparity, out.stereo_disparity]
    confs = [out.tof_confidence, out.stereo_confidence]
    plain, _ = lc_fuse(scene.right, scene.left, srcs, confs)
    checked, share = lc_fuse(
        scene.right, scene.left, srcs, confs, params=LcParams(cross_check=True)
    )
    kept = np.isfinite(checked)
    assert 0.8 < kept.mean() < np.isfinite(plain).mean(), "drops some pixels, not most"
    np.testing.assert_array_equal(checked[kept], plain[kept])
    assert np.isnan(share[~kept]).all()
    gt = scene.gt_disparity
    dropped = np.isfinite(plain) & ~kept & np.isfinite(gt)
    err = np.abs(plain - gt)
    # What it drops is worse than what it keeps.
    assert np.median(err[dropped]) > 3 * np.median(err[kept & np.isfinite(gt)])


def test_upsampling_and_segmentation() -> None:
    img = np.zeros((20, 30, 3), np.uint8)
    img[:, 15:] = 200
    labels = segment_mean_shift(img)
    assert labels.dtype == np.int32
    # Each flat half is one region (mean shift may leave slivers along the step).
    assert len(np.unique(labels[:, :12])) == 1 and len(np.unique(labels[:, 18:])) == 1
    assert labels[0, 0] != labels[0, -1]
    sparse = np.full((20, 30), np.nan, np.float32)
    sparse[::2, ::2] = np.where(np.arange(30)[::2] < 15, 1.0, 2.0)
    dense = upsample_depth(sparse, img, labels)
    assert np.all(np.isfinite(dense))
    # Sharp away from the step's column, where mean shift leaves a one-pixel sliver segment.
    assert np.abs(dense[:, :14] - 1).max() < 1e-3 and np.abs(dense[:, 16:] - 2).max() < 1e-3
    # The plain joint bilateral (no labels) still separates the halves by colour.
    plain = upsample_depth(sparse, img)
    assert np.abs(plain[:, :15] - 1).max() < 1e-3 and np.abs(plain[:, 15:] - 2).max() < 1e-3


def test_non_occluded_mask() -> None:
    d = np.full((1, 20), 2.0, np.float32)
    d[0, 10:13] = 6.0  # a near object; reference = right, target x + d
    vis = non_occluded(d, 1)
    # Background right pixels 14..16 land on target 16..18, which the object (x + 6 = 16..18)
    # covers: hidden in the target view.
    assert not vis[0, 14:17].any() and vis[0, 10:13].all() and vis[0, :10].all()
    assert not vis[0, 18:].any(), "target falls off the image"


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"left": np.zeros((270, 479, 3), np.uint8)}, ShapeMismatchError, "left: got 479x270"),
        ({"right": np.zeros((270, 480, 3), np.float32)}, InvalidArgumentError, "right: got dtype"),
        ({"tof_depth": np.zeros((10, 10), np.float32)}, ShapeMismatchError, "tof_depth"),
        ({"tof_amplitude": np.zeros((424, 511), np.float32)}, ShapeMismatchError, "tof_amplitude"),
        ({"rig": "rig"}, InvalidArgumentError, "rig: got str"),
        ({"confidence": "learned"}, InvalidArgumentError, "confidence: got 'learned'"),
        (
            {"confidence": (np.full((270, 480), 2.0), np.ones((270, 480)))},
            InvalidArgumentError,
            r"^confidence\[0\]: got values in \[2, 2\], expected values in \[0, 1\]",
        ),
        ({"max_disparity": 480}, InvalidArgumentError, "max_disparity: got 480"),
    ],
)
def test_fuse_bad_input(
    scene: SynthSample, kwargs: dict[str, object], error: type, match: str
) -> None:
    args: dict[str, object] = {
        "left": scene.left,
        "right": scene.right,
        "tof_depth": scene.tof_depth,
        "tof_amplitude": scene.tof_amplitude,
        "rig": RIG,
    }
    extra = {k: kwargs.pop(k) for k in ("confidence", "max_disparity") if k in kwargs}
    args |= kwargs
    with pytest.raises(error, match=match):
        fuse(**args, **extra)  # type: ignore[arg-type]


def test_lc_fuse_bad_input() -> None:
    img = np.zeros((8, 8, 3), np.uint8)
    d = np.ones((8, 8), np.float32)
    with pytest.raises(InvalidArgumentError, match="disparities"):
        lc_fuse(img, img, [])
    with pytest.raises(InvalidArgumentError, match="confidences: got 2 maps"):
        lc_fuse(img, img, [d], [None, None])
    with pytest.raises(InvalidArgumentError, match="target_sign"):
        lc_fuse(img, img, [d], target_sign=0)
    with pytest.raises(InvalidArgumentError, match="stride"):
        lc_fuse(img, img, [d], params=LcParams(radius=2, stride=0))
    wide = np.array([[0.0, 1e4] * 4] * 8, np.float32)
    with pytest.raises(InvalidArgumentError, match="bin_width"):
        lc_fuse(img, img, [wide], params=LcParams(bin_width=1e-3))
    # Formerly Rust panics (bin-count overflow), now errors naming the argument.
    d2 = d.copy()
    d2[0, 0] = 2.0
    with pytest.raises(InvalidArgumentError, match="bin_width"):
        lc_fuse(img, img, [d2], params=LcParams(bin_width=1e-30))
    d2[0, 0] = -1e19
    with pytest.raises(
        InvalidArgumentError, match=r"^disparities\[0\]: got 1 value\(s\) as large as 1e\+19"
    ):
        lc_fuse(img, img, [d2])
    with pytest.raises(InvalidArgumentError, match="baseline"):
        StereoRig(RIG.stereo.left, RIG.stereo.right, 0.0)


def test_middlebury_simulated_tof(shared_data: Path) -> None:
    s = middlebury_sample(shared_data / "middlebury" / "Cones")
    tof = tof_to_reference(s.tof_depth, s.tof_amplitude, s.rig, s.left)
    ok = np.isfinite(tof.disparity) & np.isfinite(s.gt_disparity)
    assert ok.mean() > 0.6
    assert np.median(np.abs(tof.disparity - s.gt_disparity)[ok]) < 0.5


def test_middlebury_samples(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rgbd_rs import RgbdError
    from rgbd_rs.fusion.evaluate import middlebury_samples

    samples = middlebury_samples()
    assert [s.name for s in samples] == ["Cones", "Reindeer", "Wood2"]
    cones = middlebury_sample(shared_data / "middlebury" / "Cones")
    np.testing.assert_array_equal(samples[0].tof_depth, cones.tof_depth)  # same simulation
    monkeypatch.setenv("RGBD_DATA", str(tmp_path))
    with pytest.raises(RgbdError, match=r"middlebury: not found"):
        middlebury_samples()


def test_a_mistyped_rgbd_data_is_refused_not_replaced(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rgbd_rs import RgbdError
    from rgbd_rs.data import data_root

    monkeypatch.setenv("RGBD_DATA", str(tmp_path / "no_such_dir"))
    for required in (False, True):
        with pytest.raises(
            RgbdError, match=r"^RGBD_DATA: got '.*no_such_dir' \(no such directory\)"
        ):
            data_root(required=required)
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("RGBD_DATA", str(tmp_path / "file"))
    with pytest.raises(RgbdError, match=r"\(a file\), expected the directory"):
        data_root()
    monkeypatch.setenv("RGBD_DATA", str(tmp_path))
    assert data_root() == tmp_path


def test_cli_fuse(scene: SynthSample, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_png(tmp_path / "l.png", scene.left)
    write_png(tmp_path / "r.png", scene.right)
    np.save(tmp_path / "d.npy", scene.tof_depth)
    np.save(tmp_path / "a.npy", scene.tof_amplitude)
    save_rig(tmp_path / "c.json", RIG)
    argv = [
        "fuse",
        "--left",
        str(tmp_path / "l.png"),
        "--right",
        str(tmp_path / "r.png"),
        "--tof-depth",
        str(tmp_path / "d.npy"),
        "--tof-amplitude",
        str(tmp_path / "a.npy"),
        "--calib",
        str(tmp_path / "c.json"),
        "--out",
        str(tmp_path / "out"),
    ]
    assert cli.main(argv) == 0
    maps = read_npz(tmp_path / "out" / "fused.npz", ("disparity", "depth"))
    png = read_png(tmp_path / "out" / "disparity.png")
    assert png.dtype == np.uint16
    ok = np.isfinite(maps["disparity"])
    np.testing.assert_allclose(png[ok] / 256.0, maps["disparity"][ok], atol=1 / 256)
    assert read_png(tmp_path / "out" / "preview.png").ndim == 3
    assert "fused 480x270" in capsys.readouterr().out
    bad = json.loads((tmp_path / "c.json").read_text())
    bad["stereo"]["baseline"] = -0.1
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    argv[argv.index(str(tmp_path / "c.json"))] = str(tmp_path / "bad.json")
    assert cli.main(argv) == 2
    assert "baseline" in capsys.readouterr().err


def test_cli_fuse_keep_pose_passes_the_pose_as_given(
    scene: SynthSample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`rgbd fuse --keep-pose` is fuse(refine_pose=False); without it the refinement runs."""
    import rgbd_rs.fusion

    seen: list[bool] = []
    real = rgbd_rs.fusion.fuse

    def spy(*args: object, **kwargs: object) -> object:
        seen.append(bool(kwargs["refine_pose"]))
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(rgbd_rs.fusion, "fuse", spy)
    write_png(tmp_path / "l.png", scene.left)
    write_png(tmp_path / "r.png", scene.right)
    np.save(tmp_path / "d.npy", scene.tof_depth)
    np.save(tmp_path / "a.npy", scene.tof_amplitude)
    save_rig(tmp_path / "c.json", RIG)
    argv = ["fuse", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png")]
    argv += ["--tof-depth", str(tmp_path / "d.npy"), "--tof-amplitude", str(tmp_path / "a.npy")]
    argv += ["--calib", str(tmp_path / "c.json")]
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 0
    assert cli.main([*argv, "--keep-pose", "--out", str(tmp_path / "b")]) == 0
    assert seen == [True, False]
