"""Fine-tuning a shape network trained on other classes (``train_shapes(init=...)``, issue 31's
transfer from ModelNet40's other classes to ModelNet10): every weight but the classifier's is
taken, the classifier starts afresh from the seed; inputs and architecture must match."""

from __future__ import annotations

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


def test_fine_tuning_on_new_classes_trains_and_records_them(
    caches: dict[str, Path], pretrained: Path
) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    best = train_shapes(
        caches["target"],
        caches["root"] / "tuned",
        recipe=recipe,
        config=_cfg(seed=2, epochs=3),
        init=pretrained,
        quiet=True,
    )
    ckpt = load_checkpoint(best)
    assert ckpt.normalisation["classes"] == ["bed", "chair", "monitor"]
    assert ckpt.arch_config["n_classes"] == 3
    losses = [h["train_loss"] for h in ckpt.history]
    assert losses[-1] < losses[0], losses


def test_same_classes_load_every_weight(caches: dict[str, Path], pretrained: Path) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    run = train_shapes(
        caches["target"], caches["root"] / "own", recipe=recipe, config=_cfg(), quiet=True
    )
    net, norm = _target_net(caches, seed=4)
    _load_init(net, run, norm)
    own = load_checkpoint(run).model_state
    assert all(torch.equal(v, own[k]) for k, v in net.state_dict().items())


def test_other_inputs_or_architecture_are_refused(
    caches: dict[str, Path], pretrained: Path
) -> None:
    recipe = ShapeRecipe(width=4, val_fraction=0, batch_norm=True)
    with pytest.raises(
        InvalidArgumentError,
        match=r"^init: got .*pre_run.*other inputs.*normalisation 'standardize' instead of 'lcn'",
    ):
        train_shapes(
            caches["other_spec"],
            caches["root"] / "bad_spec",
            recipe=recipe,
            config=_cfg(),
            init=pretrained,
            quiet=True,
        )
    net, norm = _target_net(caches, seed=1, width=8)
    with pytest.raises(InvalidArgumentError, match=r"^init: got .*'width': 4.*'width': 8"):
        _load_init(net, pretrained, norm)
    net, norm = _target_net(caches, seed=1, batch_norm=False)
    with pytest.raises(InvalidArgumentError, match=r"^init: got .*batch_norm"):
        _load_init(net, pretrained, norm)
