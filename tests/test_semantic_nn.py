"""The semantic-labeling ConvNet (rgbd_rs.nn.semantic, thesis §4.6 / Fig. 4.3), its loss and
training recipe (rgbd_rs.segmentation.semantic_train), the trainer's plateau schedule and the
labeler (rgbd_rs.segmentation.labeling). Tiny widths and images: everything runs on CPU in
seconds."""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import RgbdError
from rgbd_rs.nn.checkpoint import load_checkpoint
from rgbd_rs.nn.semantic import (
    ARCH,
    SemanticNet,
    _block_filters,
    _GroupedConv,
    _LocalContrastNorm,
    class_probabilities,
    lcn_window,
)
from rgbd_rs.nn.train import TrainConfig, train
from rgbd_rs.segmentation.labeling import SemanticLabeler
from rgbd_rs.segmentation.semantic_data import LabeledFrame, build_semantic_cache
from rgbd_rs.segmentation.semantic_train import (
    SemanticLoss,
    SemanticRecipe,
    default_config,
    score,
    ship,
    train_semantic,
)
from rgbd_rs.shapes.views import local_contrast_normalize

CAMERA = PinholeCamera(fx=60.0, fy=60.0, cx=31.5, cy=23.5, width=64, height=48)


@pytest.fixture(autouse=True, scope="module")
def one_thread() -> Iterator[None]:
    """Tiny convolutions run ~40x faster on one thread than on two a busy machine shares."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


# -- the network ---------------------------------------------------------------------------------


def test_thesis_layout() -> None:
    """Fig. 4.3 at full width: 9 convolutions 7x7 (90, 128, 256 filters), tanh after all but
    the last, max-pool after blocks 1 and 2, a 256 x 14 classifier without bias."""
    net = SemanticNet()
    assert _block_filters(256) == (90, 128, 256)
    convs = [m for m in net.features if isinstance(m, (nn.Conv2d, _GroupedConv))]
    assert [c.out_channels for c in convs] == [90] * 3 + [128] * 3 + [256] * 3
    assert all(c.kernel_size == (7, 7) for c in convs)
    kinds = [type(m).__name__ for m in net.features]
    assert kinds.count("Tanh") == 8 and kinds.count("MaxPool2d") == 2
    assert kinds[-1] == "Conv2d"  # no activation after the last convolution
    pools = [i for i, k in enumerate(kinds) if k == "MaxPool2d"]
    assert [sum(k.endswith("Conv2d") or k == "_GroupedConv" for k in kinds[:i]) for i in pools] == [
        3,
        6,
    ]
    assert net.classifier.weight.shape == (14, 256, 1, 1) and net.classifier.bias is None
    with torch.no_grad():
        out = net(torch.zeros(1, 9, 32, 40))
    assert out.shape == (1, 14, 8, 10)


def test_output_is_a_quarter_and_pdfs_sum_to_one() -> None:
    torch.manual_seed(0)
    net = SemanticNet(14, width=16, lcn_window=5)
    x = torch.randn(2, 9, 48, 64)
    with torch.no_grad():
        logits = net(x)
    assert logits.shape == (2, 14, 12, 16)
    p = class_probabilities(logits, (48, 64))
    assert p.shape == (2, 14, 48, 64)
    assert torch.allclose(p.sum(dim=1), torch.ones(2, 48, 64), atol=1e-5)
    assert float(p[:, 0].abs().max()) == 0.0  # the unlabeled class is never predicted
    assert float(p.min()) >= 0
    every = class_probabilities(logits, None, ignore_index=None)
    assert every.shape == (2, 14, 12, 16) and float(every[:, 0].min()) > 0
    # Bilinear upsampling of the PDFs: no value beyond the low-resolution ones, and away from
    # the borders each output pixel lies between its low-resolution neighbours.
    low = class_probabilities(logits)
    assert float(p.max()) <= float(low.max()) + 1e-6
    ref = torch.nn.functional.interpolate(low, size=(48, 64), mode="bilinear")
    assert torch.allclose(p, ref, atol=1e-6)


def test_first_layer_is_grouped_by_channel() -> None:
    torch.manual_seed(0)
    net = SemanticNet(width=64, lcn_window=5)  # 27 first-block filters: 3 per channel
    first = net.features[0]
    assert isinstance(first, _GroupedConv)
    assert first.groups == 9 and first.weight.shape == (27, 1, 7, 7)
    # The same as torch's grouped convolution with these weights.
    ref = nn.Conv2d(9, 27, 7, padding=3, groups=9)
    ref.load_state_dict(first.state_dict())
    x0 = torch.randn(2, 9, 12, 16)
    with torch.no_grad():
        assert torch.allclose(first(x0), ref(x0), atol=1e-5)
    x = torch.randn(1, 9, 16, 16)
    first.requires_grad_(False)
    base = first(x)
    for ch in (0, 4, 8):
        y = x.clone()
        y[:, ch] += torch.randn(16, 16)
        changed = (first(y) - base).abs().amax(dim=(0, 2, 3)) > 0
        assert changed.nonzero().flatten().tolist() == list(range(3 * ch, 3 * ch + 3))


def test_lcn_matches_the_rust_kernel_and_is_per_channel() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(2, 9, 20, 28)).astype(np.float32) * rng.uniform(0.01, 100, (1, 9, 1, 1))
    x[0, 3] = 2.5  # a constant map normalises to 0
    lcn = _LocalContrastNorm(7)
    y = lcn(torch.from_numpy(x)).numpy()
    assert np.allclose(y, local_contrast_normalize(x, 7), atol=2e-5)
    assert np.abs(y[0, 3]).max() == 0
    # Each channel on its own: scaling one channel changes nothing (LCN is scale-free), and
    # changing one channel leaves the others.
    z = x.copy()
    z[:, 5] *= 1000
    z[:, 6] += rng.normal(size=(2, 20, 28)).astype(np.float32)
    yz = lcn(torch.from_numpy(z)).numpy()
    keep = [c for c in range(9) if c != 6]
    assert np.allclose(yz[:, keep], y[:, keep], atol=1e-4)
    assert not np.allclose(yz[:, 6], y[:, 6], atol=1e-3)
    # Local: the mean over each window is about 0 and the map's spread about 1.
    assert abs(float(y[1].mean())) < 0.1 and 0.5 < float(y[1].std()) < 1.5


def test_lcn_window_and_width_rules() -> None:
    assert lcn_window(320) == 15 and lcn_window(160) == 9 and lcn_window(640) == 31
    assert lcn_window(16) == 3
    assert _block_filters(32) == (9, 16, 32) and _block_filters(64) == (27, 32, 64)
    net = SemanticNet(5, width=8, lcn_window=3)
    again = SemanticNet.from_config(net.arch_config())
    assert again.arch_config() == {"n_classes": 5, "width": 8, "lcn_window": 3}


# -- the loss ------------------------------------------------------------------------------------


def test_loss_ignores_unlabeled_pixels() -> None:
    torch.manual_seed(0)
    logits = torch.randn(2, 5, 4, 6, requires_grad=True)
    target = torch.randint(1, 5, (2, 16, 24))
    target[0, :8] = 0
    loss_fn = SemanticLoss(0)
    loss = loss_fn(logits, (None, target))
    # By hand: -log of the upsampled probability of the true class, mean over labeled pixels.
    p = class_probabilities(logits.detach(), (16, 24))
    picked = p.gather(1, target[:, None])[:, 0]
    mask = target != 0
    assert torch.allclose(loss, -torch.log(picked[mask]).mean(), atol=1e-6)
    # Logits that only reach unlabeled pixels do not matter: moving them leaves the loss.
    loss.backward()
    assert logits.grad is not None and float(logits.grad[:, 0].abs().max()) == 0  # class 0
    none = torch.zeros_like(target)
    zero = loss_fn(logits, (None, none))
    assert float(zero.detach()) == 0.0
    zero.backward()  # no NaN gradient on an unlabeled batch


# -- the trainer's plateau schedule --------------------------------------------------------------


class _Const(torch.utils.data.Dataset[tuple[torch.Tensor, torch.Tensor]]):
    def __len__(self) -> int:
        return 4

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        return torch.ones(1, 2, 2), torch.zeros(1)


def _const_loss(out: torch.Tensor, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
    return (out * 0).sum() + 1.0  # the validation loss never improves after epoch 1


def test_plateau_schedule_reduces_after_n_bad_epochs(tmp_path: Path) -> None:
    cfg = TrainConfig(
        epochs=7, batch_size=2, optimizer="sgd", lr=1.0, lr_plateau=2, lr_gamma=0.5, device="cpu"
    )
    model = nn.Conv2d(1, 1, 1)
    res = train(
        model, _Const(), _Const(), _const_loss, cfg, tmp_path / "a", arch="c", arch_config={},
        normalisation={}, quiet=True,
    )  # fmt: skip
    assert [h.lr for h in res.history] == [1.0, 1.0, 1.0, 0.5, 0.5, 0.25, 0.25]
    # Resumed (4 epochs, then 7) ends with the same schedule.
    short = TrainConfig(**{**cfg.to_dict(), "epochs": 4})
    train(
        nn.Conv2d(1, 1, 1), _Const(), _Const(), _const_loss, short, tmp_path / "b",
        arch="c", arch_config={}, normalisation={}, quiet=True,
    )  # fmt: skip
    res2 = train(
        nn.Conv2d(1, 1, 1), _Const(), _Const(), _const_loss, cfg, tmp_path / "b",
        arch="c", arch_config={}, normalisation={}, quiet=True,
    )  # fmt: skip
    assert [h.lr for h in res2.history] == [h.lr for h in res.history]
    # Checkpoints written before the option existed still compare equal (the field is left out
    # at its default).
    assert "lr_plateau" not in TrainConfig().to_dict() and cfg.to_dict()["lr_plateau"] == 2


# -- a tiny model overfits two tiny frames -------------------------------------------------------


def _colour_cues(
    rgb: np.ndarray, depth: np.ndarray, camera: object, *, seed: int = 0
) -> np.ndarray:
    """Cheap stand-in cues: colour and depth, the rest 0."""
    x = np.zeros((9, *depth.shape), np.float32)
    x[:3] = np.moveaxis(rgb, -1, 0) / 255.0
    x[3] = np.nan_to_num(depth)
    return x


def tiny_frames(n: int = 2, seed: int = 0) -> list[LabeledFrame]:
    """Frames of 64 x 48 whose classes show as colour blobs (class k has its own colour) over a
    wall (12) and floor (5), some pixels unlabeled."""
    rng = np.random.default_rng(seed)
    palette = rng.integers(0, 256, (14, 3))
    out = []
    for i in range(n):
        lab = np.full((48, 64), 12, np.uint8)
        lab[32:] = 5
        for k in (1, 4, 10):
            r, c = rng.integers(4, 36), rng.integers(4, 52)
            lab[r : r + 10, c : c + 10] = k
        lab[:3] = 0
        rgb = palette[lab].astype(np.float64) + rng.normal(0, 10, (48, 64, 3))
        rgb = np.clip(rgb, 0, 255).astype(np.uint8)
        depth = np.full((48, 64), 2.0, np.float32)
        out.append(LabeledFrame(f"f{i}", rgb, depth, lab, CAMERA))
    return out


@pytest.fixture(scope="module")
def tiny_run() -> tuple[Path, Path, list[dict[str, float]]]:
    tmp = Path(tempfile.mkdtemp(prefix="rgbd_semantic_nn_"))
    cache = build_semantic_cache(
        tiny_frames(), tmp / "cache", size=(64, 48), cues=_colour_cues, quiet=True
    )
    cfg = default_config(epochs=60, batch_size=1, lr=0.02, checkpoint_steps=0, device="cpu")
    recipe = SemanticRecipe(width=16, val_fraction=0, augment=False, lcn_window=5)
    best = train_semantic(cache, tmp / "run", recipe=recipe, config=cfg, quiet=True)
    history = load_checkpoint(best).history
    return tmp, best, history


def test_tiny_model_overfits_two_frames(
    tiny_run: tuple[Path, Path, list[dict[str, float]]],
) -> None:
    tmp, best, history = tiny_run
    losses = [h["train_loss"] for h in history]
    assert losses[-1] < 0.5 * losses[0], losses
    # The untrained network at its initial weights vs the trained one.
    first = score(best, tmp / "cache")
    assert first.pixel_accuracy > 0.8, first.summary()
    assert first.class_accuracy > 0.6, first.summary()
    assert np.isnan(first.per_class[0])  # unlabeled is never scored
    ckpt = load_checkpoint(best)
    assert ckpt.arch == ARCH and ckpt.normalisation["input_size"] == [64, 48]
    assert ckpt.config["lr_plateau"] == 10 and ckpt.config["weight_decay"] == 1e-3
    assert ckpt.config["grad_clip"] == 1.0 and ckpt.config["momentum"] == 0.0


def test_untrained_network_is_worse(tiny_run: tuple[Path, Path, list[dict[str, float]]]) -> None:
    tmp, best, _ = tiny_run
    cfg = default_config(epochs=1, batch_size=2, lr=1e-9, checkpoint_steps=0, device="cpu")
    recipe = SemanticRecipe(width=16, val_fraction=0, augment=False, lcn_window=5)
    untrained = train_semantic(
        tmp / "cache", tmp / "untrained", recipe=recipe, config=cfg, quiet=True
    )
    assert (
        score(untrained, tmp / "cache").pixel_accuracy < score(best, tmp / "cache").pixel_accuracy
    )


def test_same_seed_same_weights(tiny_run: tuple[Path, Path, list[dict[str, float]]]) -> None:
    """Deterministic by seed (flips included); another seed gives other weights."""
    tmp, _, _ = tiny_run
    recipe = SemanticRecipe(width=8, val_fraction=0, augment=True, lcn_window=5)
    states = []
    for name, seed in (("s0", 0), ("s0b", 0), ("s1", 1)):
        cfg = default_config(epochs=2, batch_size=1, checkpoint_steps=0, device="cpu", seed=seed)
        best = train_semantic(tmp / "cache", tmp / name, recipe=recipe, config=cfg, quiet=True)
        states.append(load_checkpoint(best).model_state)
    assert all(torch.equal(states[0][k], states[1][k]) for k in states[0])
    assert not torch.equal(states[0]["classifier.weight"], states[2]["classifier.weight"])


def test_fine_tune_ship_and_label(tiny_run: tuple[Path, Path, list[dict[str, float]]]) -> None:
    tmp, best, _ = tiny_run
    other = build_semantic_cache(
        tiny_frames(2, seed=5), tmp / "cache2", size=(64, 48), cues=_colour_cues, quiet=True
    )
    cfg = default_config(epochs=1, batch_size=2, lr=0.01, checkpoint_steps=0, device="cpu")
    recipe = SemanticRecipe(width=16, val_fraction=0, augment=False, lcn_window=5)
    tuned = train_semantic(other, tmp / "tuned", recipe=recipe, config=cfg, init=best, quiet=True)
    # Fine-tuning starts from the pre-trained weights: one small step leaves them close.
    a, b = load_checkpoint(best).model_state, load_checkpoint(tuned).model_state
    key = "classifier.weight"
    assert (a[key] - b[key]).abs().max() < 0.1 * a[key].abs().max()
    # A network of another width cannot start from it.
    with pytest.raises(RgbdError, match="do not fit"):
        train_semantic(
            other, tmp / "wide", recipe=SemanticRecipe(width=32, val_fraction=0, lcn_window=5),
            config=cfg, init=best, quiet=True,
        )  # fmt: skip
    shipped = ship(best, tmp / "ship.pt")
    light = load_checkpoint(shipped)
    assert light.optimizer_state is None
    assert all(v.dtype == torch.float16 for v in light.model_state.values())
    lab = SemanticLabeler.load(shipped)
    assert lab.input_size == (64, 48) and len(lab.classes) == 14 and lab.ignore_index == 0
    frame = tiny_frames()[0]
    cues = _colour_cues(frame.rgb, frame.depth, CAMERA)
    pdfs = lab.pdfs_from_full_cues(cues)
    assert pdfs.shape == (48, 64, 14) and pdfs.dtype == np.float32
    assert np.allclose(pdfs.sum(axis=-1), 1, atol=1e-5) and pdfs[..., 0].max() == 0
    # Same answer for the cues at another frame size (reduced to the input size first).
    big = np.repeat(np.repeat(cues, 2, axis=1), 2, axis=2)
    assert lab.pdfs_from_full_cues(big).shape == (96, 128, 14)
    pred = pdfs.argmax(-1)
    truth = frame.label13
    assert np.mean(pred[truth > 0] == truth[truth > 0]) > 0.7
    with pytest.raises(RgbdError, match="14 classes, expected 40"):
        SemanticLabeler.load(shipped, n_classes=40)
    with pytest.raises(RgbdError, match="64 x 48 inputs, expected 320 x 240"):
        SemanticLabeler.load(shipped, input_size=(320, 240))


# -- the shipped weights -------------------------------------------------------------------------


def test_shipped_weights_label_a_real_frame_with_holes() -> None:
    """The package's semantic_nyuv2.pt (skipped until shipped): small, float16, inference-only,
    14 classes; on a NYUv2 test frame with half its depth missing every pixel gets a PDF over
    the 13 real classes (holes are labeled from the colour cues, no crash)."""
    from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame
    from rgbd_rs.data.paths import data_root
    from rgbd_rs.segmentation.labeling import _weights_path

    file = _weights_path()
    if not file.is_file():
        pytest.skip(f"{file} not shipped yet")
    assert file.stat().st_size < 5_000_000
    ckpt = load_checkpoint(file, arch=ARCH)
    assert ckpt.optimizer_state is None and ckpt.rng_state is None
    assert all(v.dtype == torch.float16 for v in ckpt.model_state.values())
    lab = SemanticLabeler.load(n_classes=14)
    assert lab.ignore_index == 0 and lab.classes[0] == "unlabeled"
    if data_root() is None:
        pytest.skip("needs ../shared/data for a NYUv2 frame")
    frame = load_nyuv2_frame(46)
    depth = frame.depth.copy()
    depth[:, :320] = np.nan
    pdfs = lab.pdfs(frame.rgb, depth, NYUV2_CAMERA)
    assert pdfs.shape == (480, 640, 14) and pdfs.dtype == np.float32
    assert np.allclose(pdfs.sum(axis=-1), 1, atol=1e-5) and pdfs[..., 0].max() == 0
    labels = lab.labels(frame.rgb, depth, NYUV2_CAMERA)
    assert labels.min() >= 1 and labels.max() <= 13
