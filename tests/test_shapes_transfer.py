"""Fine-tuning a shape network trained on other classes (``train_shapes(init=...)``, issue 31's
transfer from ModelNet40's other classes to ModelNet10): every weight but the classifier's is
taken, the classifier starts afresh from the seed; inputs and architecture must match."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn.checkpoint import load_checkpoint
from rgbd_rs.nn.shapes import ShapeNet
from rgbd_rs.nn.train import TrainConfig, seed_everything
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, ShapeCache, build_cache
from rgbd_rs.shapes.train import ShapeRecipe, _load_init, normalisation_of, train_shapes

PER_CLASS = 6


def _pack(src: PointCloudSet, classes: tuple[int, ...], path: Path) -> Path:
    pick: list[int] = []
    for c in classes:
        for split, n in ((0, PER_CLASS), (1, 2)):
            pick += list(np.flatnonzero((src.labels == c) & (src.splits == split))[:n])
    np.savez(
        path,
        points=src.points[pick],
        label=np.searchsorted(list(classes), src.labels[pick]).astype(np.int16),
        split=src.splits[pick],
        classes=np.array([src.classes[i] for i in classes]),
        name=np.array([src.names[i] for i in pick]),
    )
    return path


@pytest.fixture(scope="module")
def caches(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> dict[str, Path]:
    """``pre``: sofa and toilet; ``target``: bed, chair and monitor (the same volume spec);
    ``other_spec``: the target's shapes with another normalisation."""
    src = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz")
    root = tmp_path_factory.mktemp("shapes_transfer")
    spec = InputSpec(representations=("volume",), normalisation="standardize")
    out = {}
    for name, classes, s in (
        ("pre", (7, 9), spec),
        ("target", (1, 2, 5), spec),
        ("other_spec", (1, 2, 5), InputSpec(representations=("volume",), normalisation="lcn")),
    ):
        pack = _pack(src, classes, root / f"{name}.npz")
        build_cache(pack, root / name, spec=s, quiet=True)
        out[name] = root / name
    out["root"] = root
    return out


def _cfg(seed: int = 1, epochs: int = 2) -> TrainConfig:
    return TrainConfig(
        epochs=epochs, batch_size=4, optimizer="sgd", lr=0.05, seed=seed, device="cpu"
    )


@pytest.fixture(scope="module")
def pretrained(caches: dict[str, Path]) -> Path:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    return train_shapes(
        caches["pre"], caches["root"] / "pre_run", recipe=recipe, config=_cfg(), quiet=True
    )


def _target_net(
    caches: dict[str, Path], seed: int, **kw: object
) -> tuple[ShapeNet, dict[str, Any]]:
    cache = ShapeCache(caches["target"])
    reps = cache.spec.representations
    seed_everything(seed)
    net = ShapeNet(
        len(cache.classes),
        representations=reps,
        view_resolution=cache.spec.view_resolution,
        volume_resolution=cache.spec.volume_resolution,
        **({"width": 4, "batch_norm": True} | kw),  # type: ignore[arg-type]
    )
    return net, normalisation_of(cache, reps)


def test_other_classes_give_the_backbone_and_a_fresh_seeded_classifier(
    caches: dict[str, Path], pretrained: Path
) -> None:
    start = load_checkpoint(pretrained)
    assert start.normalisation["classes"] == ["sofa", "toilet"]
    net, norm = _target_net(caches, seed=3)
    fresh = net.classifier.weight.detach().clone()
    _load_init(net, pretrained, norm)
    state = net.state_dict()
    backbone = [k for k in start.model_state if not k.startswith("classifier.")]
    assert any("running_mean" in k for k in backbone)  # batch norm statistics travel too
    for k in backbone:
        assert torch.equal(state[k], start.model_state[k]), k
    assert net.classifier.weight.shape == (3, start.model_state["classifier.weight"].shape[1])
    assert torch.equal(net.classifier.weight, fresh)  # the seed's, untouched


def test_fine_tuning_hands_the_trainer_the_pretrained_backbone(
    caches: dict[str, Path], pretrained: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What the trainer receives, captured without training: not the run's fresh network."""
    trainer = importlib.import_module("rgbd_rs.nn.train")  # the module, not rgbd_rs.nn.train()
    seen: list[torch.nn.Module] = []

    def capture(model: torch.nn.Module, *args: object, **kw: object) -> object:
        seen.append(model)
        raise RuntimeError("captured")

    monkeypatch.setattr(trainer, "train", capture)
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True, dropout=0.5)
    with pytest.raises(RuntimeError, match="captured"):
        train_shapes(
            caches["target"],
            caches["root"] / "captured",
            recipe=recipe,
            config=_cfg(seed=2),
            init=pretrained,
            quiet=True,
        )
    start = load_checkpoint(pretrained).model_state
    got = seen[0].state_dict()
    fresh, _ = _target_net(caches, seed=2, dropout=0.5)  # dropout may differ: no weights
    for k, v in got.items():
        want = fresh.state_dict()[k] if k.startswith("classifier.") else start[k]
        assert torch.equal(v, want), k


def test_fine_tuning_on_new_classes_trains_and_records_them(
    caches: dict[str, Path], pretrained: Path
) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    out = caches["root"] / "tuned"
    best = train_shapes(
        caches["target"], out, recipe=recipe, config=_cfg(seed=2, epochs=3), init=pretrained,
        quiet=True,
    )  # fmt: skip
    ckpt = load_checkpoint(best)
    assert ckpt.normalisation["classes"] == ["bed", "chair", "monitor"]
    assert ckpt.arch_config["n_classes"] == 3
    losses = [h["train_loss"] for h in ckpt.history]
    assert losses[-1] < losses[0], losses
    # A resumed run continues from last.pt and does not need the init any more.
    again = train_shapes(
        caches["target"], out, recipe=recipe, config=_cfg(seed=2, epochs=3),
        init=caches["root"] / "moved_away.pt", quiet=True,
    )  # fmt: skip
    assert again == best


def test_same_classes_in_any_order_load_every_weight(caches: dict[str, Path]) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    run = train_shapes(
        caches["target"], caches["root"] / "own", recipe=recipe, config=_cfg(), quiet=True
    )
    own = load_checkpoint(run).model_state
    net, norm = _target_net(caches, seed=4)
    _load_init(net, run, norm)
    assert all(torch.equal(v, own[k]) for k, v in net.state_dict().items())
    # The same classes listed in another order: the classifier's rows follow their names.
    net, norm = _target_net(caches, seed=4)
    norm = norm | {"classes": ["monitor", "bed", "chair"]}
    _load_init(net, run, norm)
    assert torch.equal(net.classifier.weight, own["classifier.weight"][[2, 0, 1]])


def test_other_inputs_or_architecture_are_refused(
    caches: dict[str, Path], pretrained: Path
) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    with pytest.raises(
        InvalidArgumentError,
        match=r"^init: got .*pre_run.*other inputs \(normalisation 'standardize' in the "
        r"network, 'lcn' in this run; view_lcn_window None in the network, 9",
    ):
        train_shapes(
            caches["other_spec"],
            caches["root"] / "bad_spec",
            recipe=recipe,
            config=_cfg(),
            init=pretrained,
            quiet=True,
        )
    for kw, said in (
        ({"width": 8}, r"width 4 in the network, 8 in this run \(pass --width as it was trained"),
        ({"batch_norm": False}, r"batch_norm True in the network, False in this run \(pass "),
    ):
        net, norm = _target_net(caches, seed=1, **kw)
        with pytest.raises(InvalidArgumentError, match=rf"^init: got .*pre_run.*, {said}"):
            _load_init(net, pretrained, norm)
    # The same classes are held to the same rules (they used to meet torch's own message).
    own = caches["root"] / "own_wide"
    run = train_shapes(
        caches["target"], own, recipe=ShapeRecipe(width=8, val_fraction=0), config=_cfg(),
        quiet=True,
    )  # fmt: skip
    net, norm = _target_net(caches, seed=1, batch_norm=False)
    with pytest.raises(InvalidArgumentError, match=r"^init: got .*own_wide.*width 8 in the net"):
        _load_init(net, run, norm)


def test_an_init_without_its_classes_or_spec_is_refused(
    caches: dict[str, Path], pretrained: Path, tmp_path: Path
) -> None:
    from rgbd_rs.errors import RgbdError

    raw = torch.load(pretrained, weights_only=False)
    for key in ("classes", "spec"):
        broken = dict(raw)
        broken["normalisation"] = {k: v for k, v in raw["normalisation"].items() if k != key}
        path = tmp_path / f"no_{key}.pt"
        torch.save(broken, path)
        net, norm = _target_net(caches, seed=1)
        with pytest.raises(RgbdError, match=rf"no_{key}\.pt.*{key}"):
            _load_init(net, path, norm)
