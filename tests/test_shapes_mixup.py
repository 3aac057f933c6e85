"""mixup of training shapes (``ShapeRecipe(mixup=alpha)``, ``rgbd train shapes --mixup``, issue
31's regularisation levers): each item is a convex mix of two training items, inputs and
targets alike, its own class keeping the larger weight; loss and metric take the soft targets."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import torch
from torch.nn import functional as F

from modelnet_packs import modelnet10_subset
from rgbd_rs.cli import main
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn.checkpoint import load_checkpoint
from rgbd_rs.nn.train import TrainConfig
from rgbd_rs.shapes.augment import MixedShapes
from rgbd_rs.shapes.dataset import InputSpec, build_cache
from rgbd_rs.shapes.train import ShapeRecipe, accuracy, cross_entropy, train_shapes

N = 7


def _basis() -> list[tuple[torch.Tensor, torch.Tensor]]:
    """Item k: the k-th basis vector of length N (so a mix shows which items it took), label
    k % 3."""
    return [(torch.eye(N)[k], torch.tensor(k % 3)) for k in range(N)]


def _draws(seed: int, alpha: float = 0.4) -> list[tuple[torch.Tensor, torch.Tensor]]:
    torch.manual_seed(seed)
    mixed = MixedShapes(_basis(), 3, alpha)
    return [mixed[k] for k in range(N) for _ in range(3)]


def test_each_item_is_its_own_mix_with_another_and_the_targets_mix_alike() -> None:
    partners = set()
    for n, (x, target) in enumerate(_draws(seed=0)):
        k = n // 3
        assert x.shape == (N,) and target.shape == (3,) and target.dtype == torch.float32
        assert math.isclose(float(x.sum()), 1.0, abs_tol=1e-6) and bool((x >= 0).all())
        lam = float(x[k])  # its own weight (the whole of it when it drew itself)
        assert lam >= 0.5 - 1e-6
        others = [j for j in range(N) if j != k and x[j] > 0]
        assert len(others) <= 1
        j = others[0] if others else k
        partners.add(j)
        want = lam * F.one_hot(torch.tensor(k % 3), 3) + (1 - lam) * F.one_hot(
            torch.tensor(j % 3), 3
        )
        torch.testing.assert_close(target, want.float())
        assert int(target.argmax()) == k % 3 or math.isclose(lam, 0.5, abs_tol=1e-6)
    assert len(partners) > 3  # partners drawn across the dataset
    again = _draws(seed=0)
    other = _draws(seed=1)
    assert all(torch.equal(a[0], b[0]) for a, b in zip(_draws(seed=0), again, strict=True))
    assert not all(torch.equal(a[0], b[0]) for a, b in zip(again, other, strict=True))


def test_small_alpha_mixes_little_and_large_alpha_mixes_evenly() -> None:
    def weights(alpha: float) -> list[float]:
        torch.manual_seed(3)
        mixed = MixedShapes(_basis(), 3, alpha)
        return [float(mixed[k][0][k]) for k in range(N) for _ in range(20)]

    assert sum(weights(0.01)) / (20 * N) > 0.95
    even = weights(100.0)
    assert all(w < 0.75 for w in even if w < 1)  # 1: the item drew itself (1 in N)
    assert sum(w == 1 for w in even) < 20 * N / 3


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"alpha": 0}, r"alpha: got 0, expected 0\.01 <= alpha <= 100"),
        ({"alpha": 0.001}, "alpha: got 0.001"),
        ({"alpha": float("nan")}, "alpha: got nan, expected a finite number"),
        ({"alpha": 101}, "alpha: got 101"),
        ({"alpha": True}, "alpha: got True, expected a real number"),
        ({"classes": 1}, "classes: got 1"),
    ],
)
def test_mixed_shapes_refuses_bad_arguments(kw: dict[str, Any], match: str) -> None:
    args: dict[str, Any] = {"classes": 3, "alpha": 0.2} | kw
    with pytest.raises(InvalidArgumentError, match=match):
        MixedShapes(_basis(), args["classes"], args["alpha"])


def test_recipe_takes_zero_or_an_alpha_in_range() -> None:
    assert ShapeRecipe().mixup == 0.0 and ShapeRecipe(mixup=0.2).mixup == 0.2
    for bad in (-0.1, 0.005, 100.5):
        with pytest.raises(InvalidArgumentError, match=f"mixup: got {bad}, expected 0 .off. or"):
            ShapeRecipe(mixup=bad)


def test_loss_and_metric_take_soft_targets() -> None:
    logits = torch.tensor([[2.0, 0.0, -1.0], [0.0, 1.0, 3.0]])
    soft = torch.tensor([[0.7, 0.3, 0.0], [0.0, 0.4, 0.6]])
    want = -(soft * logits.log_softmax(1)).sum(1).mean()
    torch.testing.assert_close(cross_entropy(logits, (None, soft)), want)
    hard = torch.tensor([0, 2])
    torch.testing.assert_close(
        cross_entropy(logits, (None, F.one_hot(hard, 3).float()), 0.1),
        cross_entropy(logits, (None, hard), 0.1),
    )
    assert float(accuracy(logits, (None, soft))) == 1.0
    assert float(accuracy(logits, (None, soft.flip(1)))) == 0.0


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    root = tmp_path_factory.mktemp("shapes_mixup")
    pack = modelnet10_subset(shared_data, root / "pack.npz", (1, 2, 5), ((0, 6), (1, 2)))
    spec = InputSpec(representations=("volume",), normalisation="standardize")
    build_cache(pack, root / "cache", spec=spec, quiet=True)
    return root / "cache"


def _train(cache: Path, out: Path, mixup: float) -> dict[str, torch.Tensor]:
    cfg = TrainConfig(epochs=2, batch_size=4, optimizer="sgd", lr=0.05, seed=1, device="cpu")
    recipe = ShapeRecipe(width=4, val_fraction=0.25, mixup=mixup)
    train_shapes(cache, out, recipe=recipe, config=cfg, quiet=True)
    return load_checkpoint(out / "last.pt").model_state


def test_training_with_mixup_is_deterministic_and_differs_from_without(
    cache: Path, tmp_path: Path
) -> None:
    a = _train(cache, tmp_path / "a", 0.2)
    b = _train(cache, tmp_path / "b", 0.2)
    plain = _train(cache, tmp_path / "plain", 0.0)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert any(not torch.equal(a[k], plain[k]) for k in a)  # the mixing reached the trainer
    history = load_checkpoint(tmp_path / "a" / "last.pt").history
    assert all(0 <= h["val_metric"] <= 1 and 0 <= h["train_metric"] <= 1 for h in history)


def test_cli_flag(cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    train = ["train", "shapes", "--cache", str(cache), "--width", "2", "--epochs", "1"]
    train += ["--quiet", "--device", "cpu", "--out", str(tmp_path / "run")]
    assert main([*train, "--mixup", "0.3"]) == 0
    assert (tmp_path / "run" / "last.pt").is_file()
    capsys.readouterr()
    assert main([*train, "--mixup", "0.001"]) == 2
    assert "mixup: got 0.001" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main([*train, "--mixup", "-1"])
    assert exit_.value.code == 2 and "--mixup: got -1" in capsys.readouterr().err
