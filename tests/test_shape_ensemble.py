"""ShapeEnsemble: several shape networks shipped as one checkpoint whose class probabilities
are the members' average (issue 31's model averaging)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from rgbd_rs import InvalidArgumentError, RgbdError
from rgbd_rs.nn import ShapeEnsemble, ShapeNet, TrainConfig, load_checkpoint
from rgbd_rs.nn.shape_ensemble import _shape_network
from rgbd_rs.shapes.classify import ShapeClassifier
from rgbd_rs.shapes.dataset import ShapeCache
from rgbd_rs.shapes.train import ShapeRecipe, ship, ship_ensemble, train_shapes
from test_shapes_nn import tiny_cache  # noqa: F401  (the module-scoped fixture)


def _net(seed: int, **kw: object) -> ShapeNet:
    torch.manual_seed(seed)
    cfg: dict[str, object] = {"representations": ("volume",), "volume_resolution": 32, "width": 4}
    return ShapeNet(3, **(cfg | kw)).eval()  # type: ignore[arg-type]


def test_forward_is_the_log_of_the_mean_probability() -> None:
    a, b = _net(0), _net(1)
    ens = ShapeEnsemble([a, b]).eval()
    x = torch.randn(5, 3, 32, 32)
    with torch.no_grad():
        want = (torch.softmax(a({"volume": x}), 1) + torch.softmax(b({"volume": x}), 1)) / 2
        got = torch.softmax(ens({"volume": x}), 1)
    torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-6)
    assert ens.n_classes == 3 and ens.representations == a.representations
    assert ens.shapes == a.shapes
    rebuilt = _shape_network(ens.arch_config())
    assert isinstance(rebuilt, ShapeEnsemble) and rebuilt.arch_config() == ens.arch_config()
    assert isinstance(_shape_network(a.arch_config()), ShapeNet)


def test_bad_members_and_configs_are_refused() -> None:
    with pytest.raises(InvalidArgumentError, match=r"^members: got 1 members"):
        ShapeEnsemble([_net(0)])
    with pytest.raises(InvalidArgumentError, match=r"^members\[1\]: got arch_config"):
        ShapeEnsemble([_net(0), _net(1, width=8)])
    with pytest.raises(InvalidArgumentError, match=r"^members\[1\]: got Linear"):
        ShapeEnsemble([_net(0), torch.nn.Linear(2, 2)])  # type: ignore[list-item]
    with pytest.raises(InvalidArgumentError, match=r"^arch_config: got \['members'\]"):
        ShapeEnsemble.from_config({"members": 2})
    with pytest.raises(InvalidArgumentError, match=r"^members: got 1, expected an integer >= 2"):
        ShapeEnsemble.from_config({"members": 1, "member": _net(0).arch_config()})


def _run(cache: Path, out: Path, seed: int, width: int = 4) -> Path:
    cfg = TrainConfig(epochs=1, batch_size=8, optimizer="sgd", lr=0.05, seed=seed, device="cpu")
    recipe = ShapeRecipe(width=width, val_fraction=0)
    return train_shapes(cache, out, recipe=recipe, config=cfg, quiet=True)


def test_shipped_ensemble_averages_its_members(tiny_cache: Path) -> None:  # noqa: F811
    cache = tiny_cache / "cache"
    runs = [_run(cache, tiny_cache / f"ens{s}", s) for s in (1, 2)]
    dest = ship_ensemble(runs, tiny_cache / "ensemble.pt")
    light = load_checkpoint(dest)
    assert light.optimizer_state is None and light.arch_config["members"] == 2
    assert all(v.dtype == torch.float16 for v in light.model_state.values())
    # Each member alone, shipped in float16 too: the same weights the ensemble holds.
    singles = [ShapeClassifier.load(ship(r, tiny_cache / f"one{i}.pt")) for i, r in enumerate(runs)]
    ens = ShapeClassifier.load(dest)
    assert isinstance(ens.net, ShapeEnsemble) and ens.classes == singles[0].classes
    rows = ShapeCache(cache).dataset("train", ens.spec.representations)
    x = torch.stack([rows[i][0] for i in range(6)])
    want = np.mean([c.probabilities_of_inputs(x) for c in singles], axis=0)
    np.testing.assert_allclose(ens.probabilities_of_inputs(x), want, rtol=1e-4, atol=1e-6)


def test_ship_ensemble_refuses_mismatched_runs(tiny_cache: Path) -> None:  # noqa: F811
    cache = tiny_cache / "cache"
    a = _run(cache, tiny_cache / "mis_a", 1)
    b = _run(cache, tiny_cache / "mis_b", 2, width=8)
    with pytest.raises(InvalidArgumentError, match=r"^checkpoints: .* has arch_config"):
        ship_ensemble([a, b], tiny_cache / "bad.pt")
    with pytest.raises(InvalidArgumentError, match=r"^checkpoints: got 1, expected 2 to 16"):
        ship_ensemble([a], tiny_cache / "bad.pt")
    with pytest.raises(InvalidArgumentError, match=r"^checkpoints: got str"):
        ship_ensemble(str(a), tiny_cache / "bad.pt")  # type: ignore[arg-type]
    with pytest.raises(RgbdError):
        ship_ensemble([a, tiny_cache / "missing.pt"], tiny_cache / "bad.pt")


def test_split_seed_gives_runs_of_other_seeds_one_validation_split(
    tiny_cache: Path,  # noqa: F811
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import rgbd_rs.shapes.train as train_mod

    seen: list[int] = []
    real = train_mod._split_by_shape

    def spy(cache: object, data: object, fraction: float, seed: int) -> object:
        seen.append(seed)
        return real(cache, data, fraction, seed)  # type: ignore[arg-type]

    monkeypatch.setattr(train_mod, "_split_by_shape", spy)
    cfg = TrainConfig(epochs=1, batch_size=8, optimizer="sgd", lr=0.05, seed=2, device="cpu")
    for split_seed, out in ((1, "split_a"), (None, "split_b")):
        recipe = ShapeRecipe(width=4, val_fraction=0.25, split_seed=split_seed)
        train_shapes(tiny_cache / "cache", tiny_cache / out, recipe=recipe, config=cfg, quiet=True)
    assert seen == [1, 2]
    with pytest.raises(InvalidArgumentError, match=r"^split_seed: got -1"):
        ShapeRecipe(split_seed=-1)


def test_an_ensemble_cannot_seed_training(tiny_cache: Path) -> None:  # noqa: F811
    cache = tiny_cache / "cache"
    runs = [_run(cache, tiny_cache / f"init{s}", s) for s in (1, 2)]
    ens = ship_ensemble(runs, tiny_cache / "init_ens.pt")
    cfg = TrainConfig(epochs=1, batch_size=8, optimizer="sgd", lr=0.05, seed=3, device="cpu")
    with pytest.raises(InvalidArgumentError, match=r"^init: got .*init_ens\.pt, an ensemble of 2"):
        train_shapes(
            cache,
            tiny_cache / "init_run",
            recipe=ShapeRecipe(width=4, val_fraction=0),
            config=cfg,
            init=ens,
            quiet=True,
        )
