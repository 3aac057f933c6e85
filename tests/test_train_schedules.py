"""The trainer's cosine schedule, AdamW, and the validation metric that chooses best.pt
(rgbd_rs.nn.train), on the tiny regression of test_train.py."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import torch

from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.nn import TrainConfig, load_checkpoint, seed_everything, split, train
from test_train import ARCH, NORM, Smoothing, Tiny, assert_same_weights, mse

BASE = TrainConfig(epochs=4, batch_size=4, optimizer="sgd", lr=1e-2, seed=3, device="cpu")


def cfg(**kw: Any) -> TrainConfig:
    return TrainConfig(**(BASE.to_dict() | kw))


def fit(out: Path, config: TrainConfig, **kw: Any) -> Any:
    seed_everything(config.seed)
    model = Tiny()
    train_set, val_set = split(Smoothing(), 0.2, seed=0)
    kw = {"arch": ARCH, "arch_config": {"width": 4}, "normalisation": NORM, **kw}
    return model, train(model, train_set, val_set, mse, config, out, **kw)


def test_cosine_anneals_per_step_and_is_left_out_of_old_configs(tmp_path: Path) -> None:
    config = cfg(schedule="cosine")
    _, result = fit(tmp_path, config)
    # 16 training items, batches of 4: 4 steps an epoch, 16 in all; lr at each epoch's start
    expected = [1e-2 * 0.5 * (1 + math.cos(math.pi * 4 * e / 16)) for e in range(4)]
    assert [h.lr for h in result.history] == pytest.approx(expected)
    last = load_checkpoint(tmp_path / "last.pt")
    assert last.config["schedule"] == "cosine"
    assert TrainConfig.from_dict(last.config) == config
    assert "schedule" not in BASE.to_dict()  # checkpoints of step runs are unchanged


def test_cosine_run_does_not_resume_with_other_epochs(tmp_path: Path) -> None:
    _, result = fit(tmp_path, cfg(schedule="cosine"))
    assert result.history[-1].lr < 0.2 * result.history[0].lr
    with pytest.raises(RgbdError, match=r"config\['epochs'\] differs"):
        fit(tmp_path, cfg(schedule="cosine", epochs=6))
    fit(tmp_path / "step", BASE)  # a step run may still grow
    fit(tmp_path / "step", cfg(epochs=5))


def test_interrupted_cosine_run_equals_uninterrupted(tmp_path: Path) -> None:
    config = cfg(schedule="cosine", checkpoint_steps=3)
    whole, whole_result = fit(tmp_path / "whole", config)
    seed_everything(config.seed)
    with pytest.raises(KeyboardInterrupt):
        model = Tiny()
        train_set, val_set = split(Smoothing(interrupt_after=(16 + 4) + 3 * 4 + 2), 0.2, seed=0)
        train(
            model, train_set, val_set, mse, config, tmp_path / "cut",
            arch=ARCH, arch_config={"width": 4}, normalisation=NORM,
        )  # fmt: skip
    model, resumed = fit(tmp_path / "cut", config)
    assert_same_weights(model.state_dict(), whole.state_dict())
    assert resumed.history == whole_result.history


def test_adamw_trains_and_differs_from_adam(tmp_path: Path) -> None:
    a, ra = fit(tmp_path / "adamw", cfg(optimizer="adamw", lr=1e-2, weight_decay=0.5))
    b, _ = fit(tmp_path / "adam", cfg(optimizer="adam", lr=1e-2, weight_decay=0.5))
    assert ra.history[-1].train_loss < ra.history[0].train_loss
    assert not torch.equal(a.state_dict()["net.0.weight"], b.state_dict()["net.0.weight"])


def test_metric_is_recorded_and_chooses_best(tmp_path: Path) -> None:
    scores = iter([0.1, 0.9, 0.3, 0.2] * 1000)
    epoch_score: dict[str, float] = {}

    def metric(output: torch.Tensor, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        # training batches get a constant; validation batches (eval mode) the epoch's score
        return torch.tensor(epoch_score.get("v", 0.5))

    class Scored(Tiny):
        def train(self, mode: bool = True) -> Scored:  # type: ignore[override]
            if not mode:  # evaluation starts: draw this epoch's validation score
                epoch_score["v"] = next(scores)
            else:
                epoch_score.pop("v", None)
            return super().train(mode)  # type: ignore[return-value]

    seed_everything(BASE.seed)
    model = Scored()
    train_set, val_set = split(Smoothing(), 0.2, seed=0)
    result = train(
        model, train_set, val_set, mse, BASE, tmp_path, arch=ARCH,
        arch_config={"width": 4}, normalisation=NORM, metric_fn=metric,
    )  # fmt: skip
    assert [h.val_metric for h in result.history] == pytest.approx([0.1, 0.9, 0.3, 0.2])
    assert all(h.train_metric == pytest.approx(0.5) for h in result.history)
    assert result.best_epoch == 2 and result.best_val_metric == pytest.approx(0.9)
    best = load_checkpoint(tmp_path / "best.pt")
    assert best.epoch == 2 and best.history[-1]["val_metric"] == pytest.approx(0.9)


def test_bad_schedule_and_metric_are_named(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgumentError, match="schedule"):
        cfg(schedule="linear")
    with pytest.raises(InvalidArgumentError, match="schedule: got 'cosine' with lr_step 2"):
        cfg(schedule="cosine", lr_step=2)
    with pytest.raises(InvalidArgumentError, match="metric_fn: got int"):
        fit(tmp_path, BASE, metric_fn=3)

    def vector(output: torch.Tensor, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        return torch.zeros(3)

    with pytest.raises(RgbdError, match="metric_fn: returned Tensor, expected a scalar"):
        fit(tmp_path / "v", BASE, metric_fn=vector)

    def nan(output: torch.Tensor, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        return torch.tensor(float("nan"))

    with pytest.raises(RgbdError, match="metric_fn: returned nan"):
        fit(tmp_path / "n", BASE, metric_fn=nan)
