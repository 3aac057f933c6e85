"""The confidence ConvNet: clues (eq. 3.2-3.6), the network, its data and a tiny training run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.fusion.clues import Clues, _normalise, _target_confidence, compute_clues
from rgbd_rs.nn import confidence as confidence_module
from rgbd_rs.nn.confidence import (
    PAD,
    SQUARE_TILE,
    STRIPE_PIXELS,
    STRIPE_WIDTH,
    ConfidenceEstimator,
    ConfidenceNet,
    _fused_body,
    _fused_layers,
    _tile_shape,
    predict,
)
from rgbd_rs.nn.confidence_data import PatchDataset, TileDataset, _masked_mse
from rgbd_rs.nn.train import TrainConfig, train

RNG = np.random.default_rng(0)


def _pair(h: int = 40, w: int = 64, d: float = 5.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured right (reference) image and the left one where x_left = x_right + d."""
    xs = np.arange(w + 16, dtype=np.float32)
    tex = 128 + 60 * np.sin(xs * 0.7)[None, :] + 40 * np.cos(np.arange(h)[:, None] * 0.3)
    left_row = np.clip(tex, 0, 255)
    right = np.repeat(left_row[:, int(d) : int(d) + w, None], 3, axis=2).astype(np.uint8)
    left = np.repeat(left_row[:, :w, None], 3, axis=2).astype(np.uint8)
    return right, left, np.full((h, w), d, np.float32)


def test_clues_follow_eq_3_2_and_are_unit_free() -> None:
    right, left, disp = _pair()
    amp = RNG.uniform(100, 5000, disp.shape).astype(np.float32)
    tof = disp + RNG.normal(0, 0.1, disp.shape).astype(np.float32)
    c = compute_clues(right, left, tof, amp, disp, reference="right")
    assert c.maps.shape == (4, *disp.shape)
    # Eq. 3.2 on a correctly warped pair: the warped left equals the right image (up to the means).
    inside = np.isfinite(c.maps[0])
    assert inside[:, : disp.shape[1] - 6].all()
    assert np.nanmax(c.maps[0]) < 0.05
    np.testing.assert_array_equal(c.maps[1], tof)
    np.testing.assert_array_equal(c.maps[2], disp)
    for unit in (1e-4, 1e-2, 1e2, 1e4):
        scaled = compute_clues(right, left, tof, amp * unit, disp, reference="right")
        np.testing.assert_allclose(scaled.maps, c.maps, rtol=1e-5, equal_nan=True)
    # A wrong disparity shows in Delta_LR.
    wrong = compute_clues(right, left, tof, amp, disp + 2, reference="right")
    assert np.nanmean(wrong.maps[0]) > 5 * np.nanmean(c.maps[0])


def test_nan_never_reaches_the_network() -> None:
    right, left, disp = _pair()
    d = disp.copy()
    d[:10] = np.nan
    amp = np.ones_like(d)
    c = compute_clues(right, left, d, amp, d, reference="right")
    assert not c.valid[1, :10].any()
    x = _normalise(c, [0.1, 2.0, 2.0, 0.5])
    assert np.isfinite(x).all() and (x[1, :10] == 0).all()
    with pytest.raises(InvalidArgumentError, match="sigmas"):
        _normalise(c, [0.1, 0.0, 2.0, 0.5])
    with pytest.raises(ShapeMismatchError, match="tof_disparity"):
        compute_clues(right, left, d[:5], amp, d)


def test_target_confidence() -> None:
    t = _target_confidence([0.0, 1.0, 5.0, np.nan], [0.0, 0.0, 0.0, 0.0], 3.0)
    np.testing.assert_allclose(t[:3], [1.0, 2 / 3, 0.0])
    assert np.isnan(t[3])


def test_network_keeps_the_size_and_tiles_equal_the_whole() -> None:
    torch.manual_seed(0)
    net = ConfidenceNet(8)
    x = RNG.normal(size=(4, 37, 53)).astype(np.float32)
    with torch.no_grad():
        whole = net(torch.from_numpy(x)[None])[0].clamp(0, 1).numpy()
    assert whole.shape == (2, 37, 53)
    p_t, p_s = predict(net, x, tile=16)
    np.testing.assert_allclose(p_t, whole[0], atol=1e-5)
    np.testing.assert_allclose(p_s, whole[1], atol=1e-5)
    assert sum(p.numel() for p in ConfidenceNet(128).parameters()) == 605_570  # Fig. 3.3


def test_default_tiles_cover_the_image_in_equal_stripes() -> None:
    assert _tile_shape(540, 960, half=False) == (SQUARE_TILE, SQUARE_TILE)
    assert _tile_shape(540, 960, half=True) == (135, 960)  # four stripes of 135 x 960
    assert _tile_shape(1080, 1920, half=True) == (135, 960)  # two columns of eight stripes
    for h, w in [(1, 1), (7, 5000), (5000, 3), (65536, 2), (481, 641), (1110, 1390), (8192, 8192)]:
        th, tw = _tile_shape(h, w, half=True)
        assert 1 <= th <= h and 1 <= tw <= min(w, STRIPE_WIDTH)
        assert (th + 2 * PAD) * (tw + 2 * PAD) <= STRIPE_PIXELS  # the halo counts
        rows, cols = -(-h // th), -(-w // tw)
        assert (rows - 1) * th < h and (cols - 1) * tw < w  # no empty tile
    torch.manual_seed(0)
    net = ConfidenceNet(8)
    x = RNG.normal(size=(4, 300, 1100)).astype(np.float32)
    for half in (False, True):
        precision = "bfloat16" if half else "float32"
        tiled = predict(net, x, precision=precision)
        squares = predict(net, x, tile=64, precision=precision)
        np.testing.assert_allclose(tiled, squares, atol=1e-5 if not half else 1e-2)


@pytest.mark.parametrize("half", [False, True])
def test_fused_relus_give_the_plain_networks_values(half: bool) -> None:
    # predict() runs each ReLU as a oneDNN post-op of its convolution where it can: the same
    # convolutions and ReLU, so the same values as the plain forward (with autocast in bfloat16).
    torch.manual_seed(0)
    net = ConfidenceNet(16).eval()
    x = torch.randn(1, 4, 40, 70).contiguous(memory_format=torch.channels_last)
    layers = _fused_layers(net, half)
    if layers is None:
        pytest.skip("this torch has no oneDNN fused convolution")
    with torch.inference_mode():
        fused = _fused_body(layers, x, half)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=half):
            plain = net.body(x)
    if fused is None:  # predict() then runs the plain forward, as here
        pytest.skip("oneDNN refused the fused convolution on this CPU")
    assert fused.dtype == plain.dtype and fused.shape == plain.shape == (1, 2, 26, 56)
    assert torch.equal(fused, plain)


def test_predict_without_the_fused_path_gives_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    torch.manual_seed(0)
    net = ConfidenceNet(8)
    x = RNG.normal(size=(4, 30, 45)).astype(np.float32)
    fused = predict(net, x, tile=16)
    monkeypatch.setattr(confidence_module, "_fused_layers", lambda *_: None)
    plain = predict(net, x, tile=16)
    # (On inputs this small torch's plain float32 convolution is not oneDNN's: the sums differ
    # in order there.)
    np.testing.assert_allclose(fused[0], plain[0], atol=1e-5)
    np.testing.assert_allclose(fused[1], plain[1], atol=1e-5)


def _scene(h: int = 48, w: int = 64) -> dict[str, np.ndarray]:
    clues = RNG.normal(size=(4, h, w)).astype(np.float16)
    target = np.clip(0.5 + 0.2 * clues[1:3].astype(np.float32), 0, 1)
    target[0, :4] = np.nan  # undefined targets are masked
    return {"clues": clues, "target": target.astype(np.float16), "sigmas": np.ones(4, np.float32)}


def test_patches_are_deterministic_and_masked() -> None:
    scenes = [_scene(), _scene()]
    a = PatchDataset(scenes, np.ones(4), patch=16, per_scene=5, seed=3)
    b = PatchDataset(scenes, np.ones(4), patch=16, per_scene=5, seed=3)
    assert len(a) == 10
    for k in (0, 7):
        for x, y in zip(a[k], b[k], strict=True):
            assert torch.equal(x, y)
    inp, tgt, mask = a[0]
    assert inp.shape == (4, 16, 16) and tgt.shape == mask.shape == (2, 16, 16)
    assert torch.isfinite(tgt).all()
    out = torch.zeros(1, 2, 16, 16)
    loss = _masked_mse(out, (inp[None], tgt[None], mask[None]))
    expect = (tgt * mask).square().sum() / mask.sum()
    assert torch.isclose(loss, expect)
    with pytest.raises(InvalidArgumentError, match="patch"):
        PatchDataset(scenes, np.ones(4), patch=100)
    assert len(TileDataset(scenes, np.ones(4), tile=16)) == 2 * 3 * 4


def test_tiny_training_run_loads_as_an_estimator(tmp_path: Path) -> None:
    scenes = [_scene(), _scene()]
    sig = np.ones(4, np.float32)
    config = TrainConfig(epochs=2, batch_size=4, lr=1e-2, seed=0, device="cpu")
    net = ConfidenceNet(4)
    res = train(
        net,
        PatchDataset(scenes, sig, patch=16, per_scene=4),
        TileDataset(scenes, sig, tile=32),
        _masked_mse,
        config,
        tmp_path,
        arch="confidence-convnet/1",
        arch_config={"width": 4},
        normalisation={"sigmas": sig.tolist(), "target_t": 3.0},
        quiet=True,
    )
    assert res.best_checkpoint is not None
    est = ConfidenceEstimator.load(res.best_checkpoint)
    right, left, disp = _pair()
    p_t, _ = est(right, left, disp, np.ones_like(disp), disp, reference="right")
    assert p_t.shape == disp.shape and ((p_t >= 0) & (p_t <= 1)).all()
    with pytest.raises(RgbdError, match=r"best\.pt"):
        torch.save({"format": "something else"}, tmp_path / "best.pt")
        ConfidenceEstimator.load(tmp_path / "best.pt")


def test_clues_dataclass_valid_mask() -> None:
    c = Clues(np.array([[[np.nan, 1.0]]] * 4, np.float32))
    assert c.valid.shape == (4, 1, 2) and not c.valid[:, 0, 0].any()


def test_the_shipped_weights_fuse_by_default_and_ignore_the_amplitude_unit() -> None:
    from rgbd_rs.data.synth import generate, synth3_rig
    from rgbd_rs.fusion import LcParams, fuse
    from rgbd_rs.nn.confidence import ARCH, WEIGHTS

    est = ConfidenceEstimator.load()
    assert est.source == str(WEIGHTS) and WEIGHTS.stat().st_size < 4_000_000
    from rgbd_rs.nn.checkpoint import load_checkpoint

    ckpt = load_checkpoint(WEIGHTS, arch=ARCH)
    assert ckpt.optimizer_state is None, "ship the inference-only copy"
    rig = synth3_rig(0.125)
    s = generate(0, "test", 0, rig, meshes=[])[0]
    params = LcParams(radius=3)
    out = fuse(s.left, s.right, s.tof_depth, s.tof_amplitude, rig, params=params)
    assert out.tof_confidence is not None and out.stereo_confidence is not None
    for conf in (out.tof_confidence, out.stereo_confidence):
        assert ((conf >= 0) & (conf <= 1)).all()
    # The unit invariance is exact in float32; bfloat16 ("auto" on CPUs that have it) may round
    # a confidence one bfloat16 step (1/256) apart when the amplitude's scale changes.
    est32 = est.with_precision("float32")
    out32 = fuse(
        s.left, s.right, s.tof_depth, s.tof_amplitude, rig, params=params, confidence=est32
    )
    for unit in (1e-4, 1e4):
        scaled = fuse(
            s.left, s.right, s.tof_depth, s.tof_amplitude * unit, rig, params=params,
            confidence=est32,
        )  # fmt: skip
        assert out32.tof_confidence is not None
        np.testing.assert_allclose(scaled.tof_confidence, out32.tof_confidence, atol=1e-4)
        same = np.isfinite(scaled.disparity) == np.isfinite(out32.disparity)
        assert same.mean() > 0.999
        both = np.isfinite(scaled.disparity) & np.isfinite(out32.disparity)
        assert np.abs(scaled.disparity[both] - out32.disparity[both]).max() < 0.05
    # Your own checkpoint works the same way.
    mine = fuse(s.left, s.right, s.tof_depth, s.tof_amplitude, rig, confidence=est, params=params)
    np.testing.assert_array_equal(mine.disparity, out.disparity)


def test_a_checkpoint_of_another_architecture_is_refused(tmp_path: Path) -> None:
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.nn.confidence import WEIGHTS

    ckpt = load_checkpoint(WEIGHTS)
    import dataclasses

    other = dataclasses.replace(ckpt, arch="segmentation/1", path=tmp_path / "other.pt")
    save_checkpoint(other, tmp_path / "other.pt")
    with pytest.raises(RgbdError, match=r"other\.pt"):
        ConfidenceEstimator.load(tmp_path / "other.pt")
    wide = dataclasses.replace(ckpt, arch_config={"width": 7}, path=tmp_path / "wide.pt")
    save_checkpoint(wide, tmp_path / "wide.pt")
    with pytest.raises(RgbdError, match=r"wide\.pt"):
        ConfidenceEstimator.load(tmp_path / "wide.pt")
    nonorm = dataclasses.replace(ckpt, normalisation={}, path=tmp_path / "nonorm.pt")
    save_checkpoint(nonorm, tmp_path / "nonorm.pt")
    with pytest.raises(RgbdError, match=r"nonorm\.pt.*sigmas"):
        ConfidenceEstimator.load(tmp_path / "nonorm.pt")


def test_cached_targets_retarget_to_a_smaller_threshold() -> None:
    from rgbd_rs.nn.confidence_data import TARGET_T, retarget

    d = np.linspace(0, 5, 51, dtype=np.float32)[None]
    gt = np.zeros_like(d)
    cached = _target_confidence(d, gt, TARGET_T)
    np.testing.assert_allclose(retarget(cached, 1.0), _target_confidence(d, gt, 1.0), atol=1e-5)
    assert retarget(cached, TARGET_T) is cached
    with pytest.raises(InvalidArgumentError, match="target_t"):
        PatchDataset([_scene()], np.ones(4), patch=16, target_t=4.0)


def test_disagreement_weighted_loss() -> None:
    from rgbd_rs.nn.confidence_data import DisagreementMSE

    target = torch.zeros(1, 2, 2, 2)
    target[0, 0, 0, 0] = 1.0  # ToF right, stereo >= 3 px off: the sources disagree here
    target[0, 1, 1, 1] = 0.2  # 0.6 px apart: agree
    mask = torch.ones(1, 2, 2, 2)
    mask[0, 1, 1, 0] = 0.0  # undefined stereo target: never a disagreement
    target[0, 0, 1, 0] = 1.0
    out = torch.full((1, 2, 2, 2), 0.5)
    batch = (torch.zeros(1, 4, 2, 2), target, mask)
    torch.testing.assert_close(DisagreementMSE(0.0)(out, batch), _masked_mse(out, batch))
    err = (out - target).square() * mask
    w = mask.clone()
    w[0, :, 0, 0] *= 5.0  # the one disagreeing pixel, both channels
    expected = (err * w).sum() / w.sum()
    torch.testing.assert_close(DisagreementMSE(4.0)(out, batch), expected)
    with pytest.raises(InvalidArgumentError, match="weight"):
        DisagreementMSE(-1.0)


def test_float32_on_cuda_switches_tf32_off_for_the_pass() -> None:
    # cuDNN runs float32 convolutions in TF32 by default (~1e-3 off the CPU's result); predict's
    # float32 pass on CUDA turns that off and restores it. The flags need no GPU to be read.
    from rgbd_rs.nn.confidence import _exact_float32

    cudnn = torch.backends.cudnn
    before = (cudnn.allow_tf32, cudnn.deterministic, cudnn.benchmark)
    cudnn.allow_tf32, cudnn.deterministic, cudnn.benchmark = True, True, True
    try:
        with _exact_float32(torch.device("cuda", 0), half=False):
            # Only TF32 changes: a user's deterministic / benchmark settings stay.
            assert (cudnn.allow_tf32, cudnn.deterministic, cudnn.benchmark) == (False, True, True)
        assert torch.backends.cudnn.allow_tf32 is True
        for device, half in ((torch.device("cpu"), False), (torch.device("cuda", 0), True)):
            with _exact_float32(device, half):
                assert torch.backends.cudnn.allow_tf32 is True
    finally:
        cudnn.allow_tf32, cudnn.deterministic, cudnn.benchmark = before
