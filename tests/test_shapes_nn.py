"""The 15-branch shape ConvNet (rgbd_rs.nn.shapes, thesis Table 5.1) and its training recipe on
a handful of cached shapes (rgbd_rs.shapes.train): layer sizes, the pool rule, weight sharing,
representation switches, packing, and a tiny model that learns in seconds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn.checkpoint import load_checkpoint
from rgbd_rs.nn.shapes import (
    CAP_VIEWS,
    SIDE_VIEWS,
    ShapeNet,
    _input_shapes,
    _parse_representations,
    _view_pools,
    _volume_pools,
    pack,
    unpack,
)
from rgbd_rs.nn.train import TrainConfig
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, build_cache
from rgbd_rs.shapes.train import (
    ShapeRecipe,
    ablation_rows,
    default_config,
    ship,
    train_ablation,
    train_shapes,
)


def _inputs(net: ShapeNet, n: int, seed: int = 0) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    return {k: torch.randn(n, *s, generator=g) for k, s in net.shapes.items()}


def test_pool_rule_gives_the_thesis_pools_at_320_and_a_1x1_map_everywhere() -> None:
    assert _view_pools(320) == (4, 4, 4, 5)  # Table 5.1
    assert _volume_pools(32) == (2, 2, 2, 2, 2)  # Table 5.1, volumetric row
    assert _view_pools(64) == (2, 2, 2, 8)
    assert _view_pools(32) == (2, 2, 2, 4)
    for r in (8, 17, 32, 50, 64, 100, 128, 320):
        side = r
        for p in _view_pools(r):
            side //= p
        assert side == 1, r
        net = ShapeNet(3, representations=("depth",), view_resolution=r, width=4)
        assert net(_inputs(net, 2)).shape == (2, 3)


def test_thesis_network_has_table_5_1_layers_and_1920_features() -> None:
    net = ShapeNet(10, representations="combined", view_resolution=320)
    assert net.n_features == 15 * 128 == 1920
    assert net.classifier.bias is None
    assert tuple(net.classifier.weight.shape) == (10, 1920)
    convs = {k: [m for m in b if isinstance(m, torch.nn.Conv2d)] for k, b in net.branches.items()}
    assert sorted(convs) == [
        "curvature_caps",
        "curvature_side",
        "depth_caps",
        "depth_side",
        "volume_x",
        "volume_y",
        "volume_z",
    ]
    for name in ("depth_side", "depth_caps"):
        assert [c.out_channels for c in convs[name]] == [48, 128, 128, 128]
        assert convs[name][0].in_channels == 1
    assert convs["curvature_side"][0].in_channels == 2
    for axis in "xyz":
        assert [c.out_channels for c in convs[f"volume_{axis}"]] == [48, 128, 128, 128, 128]
    assert all(c.kernel_size == (3, 3) for cs in convs.values() for c in cs)
    pools = [m.kernel_size for m in net.branches["depth_side"] if isinstance(m, torch.nn.MaxPool2d)]
    assert pools == [4, 4, 4, 5]


def test_side_views_share_weights_and_caps_have_their_own() -> None:
    net = ShapeNet(4, representations=("depth",), view_resolution=16, width=8).eval()
    x = _inputs(net, 1)["depth"]
    feats = net.features({"depth": x}).reshape(6, 8)  # 4 side descriptors, then 2 caps
    rolled = x[:, [1, 2, 3, 0, 4, 5]]
    feats_r = net.features({"depth": rolled}).reshape(6, 8)
    # the same side branch sees each side view: rolling the views rolls their descriptors
    assert torch.allclose(feats_r[:4], feats[[1, 2, 3, 0]], atol=1e-6)
    assert torch.allclose(feats_r[4:], feats[4:])
    swapped = x[:, [0, 1, 2, 3, 5, 4]]
    assert torch.allclose(net.features({"depth": swapped}).reshape(6, 8)[4:], feats[[5, 4]])
    # a side view given to the cap branch gives another descriptor: separate weights
    side_as_cap = x.clone()
    side_as_cap[:, 4] = x[:, 0]
    assert not torch.allclose(net.features({"depth": side_as_cap}).reshape(6, 8)[4], feats[0])
    assert SIDE_VIEWS == (0, 1, 2, 3) and CAP_VIEWS == (4, 5)


def test_volume_branches_are_independent() -> None:
    net = ShapeNet(3, representations=("volume",), width=8).eval()
    x = _inputs(net, 1)["volume"]
    same = x[:, [0, 0, 0]]
    f = net.features({"volume": same}).reshape(3, 8)
    assert not torch.allclose(f[0], f[1]) and not torch.allclose(f[1], f[2])


def test_representations_switch_branches_off() -> None:
    assert _parse_representations("volume, depth") == ("depth", "volume")
    assert _parse_representations("combined") == ("depth", "volume", "curvature")
    for reps, n in (
        (("depth",), 6),
        (("volume",), 3),
        (("curvature",), 6),
        (("depth", "volume"), 9),
    ):
        net = ShapeNet(5, representations=reps, view_resolution=16, width=4)
        assert net.n_features == 4 * n
        assert all(k.split("_")[0] in reps for k in net.branches)
        assert net(_inputs(net, 3)).shape == (3, 5)


def test_packed_and_dict_inputs_agree() -> None:
    net = ShapeNet(4, representations="combined", view_resolution=16, width=4).eval()
    x = _inputs(net, 2)
    packed = pack(x, net.shapes)
    assert packed.shape == (2, 6 * 256 + 3 * 1024 + 12 * 256)
    back = unpack(packed, net.shapes)
    assert all(torch.equal(back[k], x[k]) for k in x)
    assert torch.allclose(net(packed), net(x))
    single = pack({k: v[0].numpy() for k, v in x.items()}, net.shapes)  # no batch axis
    assert torch.equal(single, packed[:1])
    assert _input_shapes(["volume"], 16, 32) == {"volume": (3, 32, 32)}


def test_arch_config_rebuilds_the_network() -> None:
    net = ShapeNet(7, representations=("volume",), volume_resolution=64, width=6)
    again = ShapeNet.from_config(net.arch_config())
    again.load_state_dict(net.state_dict())
    assert again.arch_config() == net.arch_config()


# -- training on a handful of shapes -----------------------------------------------------------

CLASSES = 3
PER_CLASS = 8


@pytest.fixture(scope="module")
def tiny_cache(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """3 ModelNet10 classes x (8 train + 2 test) point clouds, volume profiles only."""
    src = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz")
    pick = []
    for c in (1, 2, 5):  # bed, chair, monitor: distinct shapes
        for split, n in ((0, PER_CLASS), (1, 2)):
            pick += list(np.flatnonzero((src.labels == c) & (src.splits == split))[:n])
    root = tmp_path_factory.mktemp("shapes_nn")
    np.savez(
        root / "tiny.npz",
        points=src.points[pick],
        label=np.searchsorted([1, 2, 5], src.labels[pick]).astype(np.int16),
        split=src.splits[pick],
        classes=np.array([src.classes[i] for i in (1, 2, 5)]),
        name=np.array([src.names[i] for i in pick]),
    )
    spec = InputSpec(representations=("volume",), normalisation="standardize")
    build_cache(root / "tiny.npz", root / "cache", spec=spec, quiet=True)
    return root


def _config(**kw: object) -> TrainConfig:
    base: dict[str, object] = {
        "epochs": 12,
        "batch_size": 8,
        "optimizer": "sgd",
        "lr": 0.05,
        "momentum": 0.9,
        "device": "cpu",
    }
    return TrainConfig(**(base | kw))  # type: ignore[arg-type]


def test_tiny_network_learns_its_training_shapes(tiny_cache: Path) -> None:
    from rgbd_rs.shapes.evaluate import evaluate

    out = tiny_cache / "run"
    best = train_shapes(
        tiny_cache / "cache",
        out,
        recipe=ShapeRecipe(width=8, val_fraction=0),
        config=_config(),
        quiet=True,
    )
    ckpt = load_checkpoint(best)
    losses = [h["train_loss"] for h in ckpt.history]
    assert losses[-1] < 0.5 * losses[0], losses
    assert ckpt.normalisation["classes"] == ["bed", "chair", "monitor"]
    assert ckpt.normalisation["spec"]["representations"] == ["volume"]
    train_acc = evaluate(best, tiny_cache / "cache", split="train").accuracy
    assert train_acc >= 0.8, train_acc  # chance is 1/3


def test_training_resumes_and_ships(tiny_cache: Path) -> None:
    out = tiny_cache / "resume"
    cfg = _config(epochs=1)
    recipe = ShapeRecipe(width=4, val_fraction=0.25)
    train_shapes(tiny_cache / "cache", out, recipe=recipe, config=cfg, quiet=True)
    best = train_shapes(
        tiny_cache / "cache", out, recipe=recipe, config=_config(epochs=2), quiet=True
    )
    last = load_checkpoint(out / "last.pt")
    assert [h["epoch"] for h in last.history] == [1, 2]
    assert all(h["val_loss"] is not None for h in last.history)
    shipped = ship(best, tiny_cache / "shipped.pt")
    light = load_checkpoint(shipped)
    assert light.optimizer_state is None
    assert all(v.dtype == torch.float16 for v in light.model_state.values())
    assert shipped.stat().st_size < (out / "last.pt").stat().st_size


def test_ablation_trains_one_network_per_row(tiny_cache: Path) -> None:
    assert list(ablation_rows(("depth", "volume"))) == ["depth", "volume", "combined"]
    assert list(ablation_rows(("volume",))) == ["volume"]
    rows = train_ablation(
        tiny_cache / "cache",
        tiny_cache / "ablation",
        recipe=ShapeRecipe(width=4, val_fraction=0),
        config=_config(epochs=1),
        quiet=True,
    )
    assert list(rows) == ["volume"] and rows["volume"].is_file()
    assert default_config().optimizer == "sgd"


def test_rotate_turns_the_training_shapes(tiny_cache: Path) -> None:
    """rotate=True trains on turned inputs (other weights than the same run without), with
    the same seed giving the same weights twice."""
    runs = {}
    for name, rotate in (("plain", False), ("turned", True), ("turned_again", True)):
        best = train_shapes(
            tiny_cache / "cache",
            tiny_cache / f"rot_{name}",
            recipe=ShapeRecipe(width=4, val_fraction=0, rotate=rotate),
            config=_config(epochs=1),
            quiet=True,
        )
        runs[name] = load_checkpoint(best).model_state
    key = next(k for k in runs["plain"] if k.endswith("weight"))
    assert not torch.equal(runs["plain"][key], runs["turned"][key])
    assert all(torch.equal(runs["turned"][k], runs["turned_again"][k]) for k in runs["turned"])


def test_mirror_trains_on_mirror_images_and_evaluates_both(tiny_cache: Path) -> None:
    """mirror=True trains on mirrored inputs (other weights, reproducible); evaluate(mirror=True)
    averages a shape with its mirror image, and turns with it when both are asked for."""
    from rgbd_rs.shapes.evaluate import evaluate

    runs = {}
    for name, mirror in (("plain", False), ("mirrored", True), ("mirrored_again", True)):
        best = train_shapes(
            tiny_cache / "cache",
            tiny_cache / f"mir_{name}",
            recipe=ShapeRecipe(width=4, val_fraction=0, mirror=mirror),
            config=_config(epochs=1),
            quiet=True,
        )
        runs[name] = (best, load_checkpoint(best).model_state)
    key = next(k for k in runs["plain"][1] if k.endswith("weight"))
    assert not torch.equal(runs["plain"][1][key], runs["mirrored"][1][key])
    assert all(torch.equal(v, runs["mirrored_again"][1][k]) for k, v in runs["mirrored"][1].items())
    best = runs["mirrored"][0]
    both = evaluate(best, tiny_cache / "cache", split="train", mirror=True, turns=True)
    assert both.mirror and both.turns and both.count == CLASSES * PER_CLASS
    assert "mirror averaged" in both.summary() and "4 turns averaged" in both.summary()
    # Turned shapes: the same shapes read after k quarter turns; averaged over the four turns
    # the confusion does not depend on how the shapes were turned first.
    cache = tiny_cache / "cache"
    turned = [evaluate(best, cache, split="train", turned=k) for k in range(4)]
    assert turned[0].turned == 0 and "turned" not in turned[0].summary()
    assert "shapes turned 90 degrees" in turned[1].summary()
    assert all(t.count == CLASSES * PER_CLASS for t in turned)
    avg = [evaluate(best, cache, split="train", turns=True, turned=k).confusion for k in (0, 3)]
    np.testing.assert_array_equal(avg[0], avg[1])
    with pytest.raises(InvalidArgumentError, match=r"^turned: got 4"):
        evaluate(best, cache, turned=4)
    with pytest.raises(InvalidArgumentError, match="mirror"):
        evaluate(best, tiny_cache / "cache", mirror="yes")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match="mirror"):
        ShapeRecipe(mirror=1)  # type: ignore[arg-type]


def test_batch_norm_and_dropout_rebuild_and_old_configs_still_load() -> None:
    plain = ShapeNet(4, representations=("volume",), volume_resolution=16, width=4)
    assert set(plain.arch_config()) == {
        "n_classes", "representations", "view_resolution", "volume_resolution", "width",
    }  # fmt: skip  # what checkpoints stored before batch_norm / dropout existed
    net = ShapeNet(
        4, representations=("volume",), volume_resolution=16, width=4, batch_norm=True,
        dropout=0.25,
    )  # fmt: skip
    assert net.arch_config()["batch_norm"] is True and net.arch_config()["dropout"] == 0.25
    assert any(isinstance(m, torch.nn.BatchNorm2d) for m in net.modules())
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in plain.modules())
    again = ShapeNet.from_config(net.arch_config())
    again.load_state_dict(net.state_dict())
    x = _inputs(net, 3)
    net.eval()
    again.eval()
    assert torch.equal(net(x), again(x))  # eval mode: dropout off, running statistics
    net.train()
    torch.manual_seed(0)
    assert not torch.equal(net(x), again(x))  # dropout (and batch statistics) in training
    with pytest.raises(InvalidArgumentError, match=r"dropout: got 1\.0"):
        ShapeNet(4, representations=("volume",), volume_resolution=16, dropout=1.0)
    with pytest.raises(InvalidArgumentError, match="batch_norm"):
        ShapeNet(4, representations=("volume",), volume_resolution=16, batch_norm=1)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match="optionally"):
        ShapeNet.from_config(plain.arch_config() | {"depth": 3})


def test_regularised_recipe_records_accuracy_chooses_by_it_and_ships(tiny_cache: Path) -> None:
    from rgbd_rs.shapes.evaluate import evaluate

    out = tiny_cache / "regularised"
    recipe = ShapeRecipe(width=8, val_fraction=0.25, batch_norm=True, dropout=0.2,
                         label_smoothing=0.1)  # fmt: skip
    best = train_shapes(
        tiny_cache / "cache", out, recipe=recipe,
        config=_config(epochs=6, lr_step=0, schedule="cosine", optimizer="adamw", lr=0.01),
        quiet=True,
    )  # fmt: skip
    last = load_checkpoint(out / "last.pt")
    accs = [h["val_metric"] for h in last.history]
    assert all(0 <= a <= 1 for a in accs) and all("train_metric" in h for h in last.history)
    chosen = load_checkpoint(best)
    assert chosen.history[-1]["val_metric"] == max(accs)
    assert chosen.arch_config["batch_norm"] is True
    shipped = ship(best, tiny_cache / "regularised.pt")
    light = load_checkpoint(shipped)
    assert all(
        v.dtype == torch.float16 for k, v in light.model_state.items() if "num_batches" not in k
    )
    full = evaluate(best, tiny_cache / "cache", split="train").accuracy
    half = evaluate(shipped, tiny_cache / "cache", split="train").accuracy
    assert full >= 0.6 and abs(full - half) <= 1 / 16, (full, half)  # chance is 1/3
    with pytest.raises(InvalidArgumentError, match="label_smoothing: got 1"):
        ShapeRecipe(label_smoothing=1)
