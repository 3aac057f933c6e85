"""The stereo-power calibration of the confidence ConvNet for LC (rgbd_rs.fusion.calibrate)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import InvalidArgumentError, RgbdError, cli
from rgbd_rs.data.synth import generate, synth3_rig
from rgbd_rs.fusion import LcParams
from rgbd_rs.fusion.calibrate import (
    MAX_DAMAGE,
    Calibration,
    PowerScore,
    calibrate_stereo_power,
    choose,
    write_calibrated,
)
from rgbd_rs.fusion.evaluate import Sample
from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
from rgbd_rs.nn.confidence import STEREO_POWER_KEY, WEIGHTS, ConfidenceEstimator

RIG = synth3_rig(0.125)


def test_choose_prefers_the_best_mean_among_the_safe_powers() -> None:
    scores = [
        PowerScore(1.0, 1.0, 0.70, 1.30),  # best mean, but damages a good input
        PowerScore(2.0, 1.1, 0.75, 1.02),
        PowerScore(3.0, 1.2, 0.80, 1.01),
    ]
    assert choose(scores) == 2.0
    unsafe = [
        dataclasses.replace(s, worst_damage=MAX_DAMAGE + d)
        for s, d in zip(scores, (3, 2, 1), strict=True)
    ]
    assert choose(unsafe) == 3.0, "none is safe: the least damage wins"
    with pytest.raises(InvalidArgumentError, match="scores"):
        choose([])
    table = Calibration(2.0, tuple(scores), 4).markdown()
    assert "| **2** |" in table and "4 validation scenes" in table
    assert Calibration(choose(scores), tuple(scores), 4).within_limit
    assert not Calibration(choose(unsafe), tuple(unsafe), 4).within_limit


def test_the_power_is_applied_stored_and_read_back(tmp_path: Path) -> None:
    est = ConfidenceEstimator.load()
    s = generate(0, "test", 0, RIG, meshes=[])[0]
    from rgbd_rs.fusion import fuse

    stages = fuse(s.left, s.right, s.tof_depth, s.tof_amplitude, RIG, confidence="uniform")
    args = (s.right, s.left, stages.tof_fused, stages.tof.amplitude, stages.stereo_disparity)
    p_t1, p_s1 = est.with_stereo_power(1.0)(*args)
    p_t3, p_s3 = est.with_stereo_power(3.0)(*args)
    np.testing.assert_array_equal(p_t1, p_t3)
    np.testing.assert_allclose(p_s3, p_s1.astype(np.float64) ** 3, atol=1e-6)
    assert p_s3.dtype == np.float32 and p_s3.mean() < p_s1.mean()
    out = write_calibrated(WEIGHTS, 2.5, tmp_path / "cal.pt")
    assert ConfidenceEstimator.load(out).stereo_power == 2.5
    # A checkpoint without the key uses the network's output as it is.
    ckpt = load_checkpoint(out)
    bare = {k: v for k, v in ckpt.normalisation.items() if k != STEREO_POWER_KEY}
    save_checkpoint(dataclasses.replace(ckpt, normalisation=bare), tmp_path / "bare.pt")
    assert ConfidenceEstimator.load(tmp_path / "bare.pt").stereo_power == 1.0
    bad = dataclasses.replace(ckpt, normalisation=bare | {STEREO_POWER_KEY: -1.0})
    save_checkpoint(bad, tmp_path / "bad.pt")
    with pytest.raises(RgbdError, match=r"bad\.pt.*lc_stereo_power"):
        ConfidenceEstimator.load(tmp_path / "bad.pt")
    with pytest.raises(InvalidArgumentError, match="stereo_power"):
        est.with_stereo_power(0.0)
    with pytest.raises(InvalidArgumentError, match="power"):
        write_calibrated(WEIGHTS, -2.0, tmp_path / "x.pt")


def test_calibration_scores_each_power_on_rendered_scenes() -> None:
    s = generate(0, "test", 0, RIG, meshes=[])[0]
    sample = Sample("s", s.left, s.right, s.tof_depth, s.tof_amplitude, RIG, s.gt_disparity)
    res = calibrate_stereo_power(
        ConfidenceEstimator.load(),
        [sample],
        powers=(1.0, 4.0),
        params=LcParams(radius=3),
        quiet=True,
    )
    assert res.scenes == 1 and [p.power for p in res.scores] == [1.0, 4.0]
    assert res.power in (1.0, 4.0)
    for p in res.scores:
        assert 0 < p.mean_rms < 5 and 0 < p.mean_ratio < 3 and p.worst_damage >= 0
    assert res.scores[0].mean_rms != res.scores[1].mean_rms, "the power changes the fusion"
    with pytest.raises(InvalidArgumentError, match=r"powers\[0\]"):
        calibrate_stereo_power(ConfidenceEstimator.load(), [sample], powers=(0.0,))


def test_cli_writes_a_calibrated_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "val"
    assert (
        cli.main(
            [
                "synth",
                "--out",
                str(data),
                "--train",
                "0",
                "--test",
                "1",
                "--scale",
                "0.125",
                "--quiet",
            ]
        )
        == 0
    )
    out = tmp_path / "cal.pt"
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # the CLI prints a warning as one stderr line
        code = cli.main(
            [
                "train",
                "calibrate-confidence",
                "--data",
                str(data),
                "--out",
                str(out),
                "--powers",
                "1",
                "2",
                "--quiet",
            ]
        )
    assert code == 0
    captured = capsys.readouterr()
    text = captured.out
    assert "chosen power:" in text and "| power |" in text
    for line in captured.err.splitlines():  # only when no power is within the limit
        assert line.startswith("rgbd: warning: no power keeps every good validation input")
    assert ConfidenceEstimator.load(out).stereo_power in (1.0, 2.0)


@pytest.mark.parametrize("safe", [True, False])
def test_cli_warns_when_no_power_is_within_the_limit(
    safe: bool,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import rgbd_rs.fusion.calibrate as C

    worst = MAX_DAMAGE - 0.01 if safe else MAX_DAMAGE + 0.2
    scores = (PowerScore(1.0, 2.0, 0.9, worst + 0.1), PowerScore(2.0, 2.1, 0.95, worst))
    fake = Calibration(choose(scores), scores, 3)
    monkeypatch.setattr(C, "calibrate_stereo_power", lambda *a, **k: fake)
    # no dataset behind --data: the calibration is faked, so is the check of its test scenes
    monkeypatch.setattr("rgbd_rs.cli.confidence._require_scenes", lambda *a: None)
    argv = ["train", "calibrate-confidence", "--data", str(tmp_path), "--out"]
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert cli.main([*argv, str(tmp_path / "c.pt"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert ("rgbd: warning: no power keeps every good validation input" in err) is not safe
    assert ConfidenceEstimator.load(tmp_path / "c.pt").stereo_power == 2.0
