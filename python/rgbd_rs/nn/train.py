"""The one trainer of the package's networks (confidence, segmentation, shape classification).

:func:`train` runs the same code in one process or in each process started by ``torchrun``
(DistributedDataParallel: gloo on CPU, nccl on CUDA; ``torchrun --nproc_per_node=N script.py``
where the script calls :func:`train` as it would alone). Calling convention, per batch::

    batch = tuple of tensors          # the dataset's items (tuples of tensors), collated
    output = model(batch[0])          # the first element is the network input
    loss = loss_fn(output, batch)     # a scalar tensor: the MEAN loss over the batch

Deterministic by seed: call :func:`seed_everything` with ``config.seed`` before building the
model, and two runs on the same data end with bit-identical weights on CPU. Each epoch's order
is a permutation seeded with (seed, epoch) (``DistributedSampler``, which also shards it over
the processes), so a resumed run sees the same batches; ``out_dir/last.pt`` (written after
every epoch and every ``checkpoint_steps`` steps) holds the optimizer, scheduler and every
process's RNG states, so interrupted + resumed training ends with the same weights as
uninterrupted training, on CPU (on CUDA several backward kernels, cuDNN's among them, are not
deterministic: runs agree closely, not bit for bit). Datasets that draw random augmentations
should draw them from the global generators in the main process (``num_workers=0``) or derive
them from the item index, for the resumption to be exact (worker processes are seeded per
epoch, not per item). Datasets yield CPU tensors: the trainer moves each batch to the device
(from pinned memory on CUDA).
"""

from __future__ import annotations

import dataclasses
import math
import os
import random
import sys
import time
from collections.abc import Callable, Mapping, Sized
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader, Dataset, DistributedSampler, Subset
from tqdm import tqdm

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.nn.checkpoint import (
    Checkpoint,
    _capture_rng,
    _package_version,
    _plain,
    _restore_rng,
    _resume_differences,
    git_revision,
    load_checkpoint,
    save_checkpoint,
)
from rgbd_rs.nn.distributed import _Group, _setup, is_main_process

__all__ = [
    "EpochStats",
    "TrainConfig",
    "TrainResult",
    "is_main_process",
    "seed_everything",
    "split",
    "train",
]

OPTIMIZERS = ("sgd", "adam", "adamw")
#: Learning-rate schedules: StepLR / ReduceLROnPlateau ("step", see ``lr_step`` and
#: ``lr_plateau``) or cosine annealing from ``lr`` to 0 over ``epochs`` ("cosine").
SCHEDULES = ("step", "cosine")
#: File names inside ``out_dir``.
LAST, BEST = "last.pt", "best.pt"
#: TrainConfig fields that may differ when resuming: they do not change the weights' trajectory
#: (``epochs`` may grow to train further).
RESUMABLE_CHANGES = frozenset({"epochs", "num_workers", "checkpoint_steps", "device"})

Batch = tuple[Any, ...]
LossFn = Callable[[Any, Batch], torch.Tensor]
#: A score of a batch, higher is better (e.g. accuracy): a scalar tensor, the MEAN over the batch.
MetricFn = Callable[[Any, Batch], torch.Tensor]


@dataclass(frozen=True)
class TrainConfig:
    """Hyper-parameters of one training run; every field is validated on construction.

    ``batch_size`` is per process (under torchrun the effective batch is ``batch_size`` times the
    number of processes). ``lr`` decays by ``lr_gamma`` every ``lr_step`` epochs (StepLR;
    ``lr_step=0`` keeps it constant), or, with ``lr_plateau > 0`` instead, after every
    ``lr_plateau`` epochs in a row without a new lowest validation loss (training loss without a
    validation set; ReduceLROnPlateau, any decrease counts as a gain). ``momentum`` is used by
    SGD only. ``checkpoint_steps > 0`` also writes ``last.pt`` every that many optimizer steps
    within an epoch, so an interrupted epoch loses at most that many steps. ``grad_clip`` clips
    the gradients' global L2 norm.
    ``device``: ``"auto"`` (CUDA when available, else CPU), ``"cpu"``, ``"cuda"``, ``"cuda:N"``
    (under torchrun ``"auto"`` or ``"cuda"`` only: each process takes GPU ``LOCAL_RANK``).
    ``optimizer``: ``"sgd"``, ``"adam"`` or ``"adamw"`` (decoupled weight decay).
    ``schedule="cosine"`` anneals the lr from ``lr`` to 0 over ``epochs``, once per step (the
    ``lr_*`` fields must then be 0); a cosine run cannot be resumed with another ``epochs``.
    """

    epochs: int = 10
    batch_size: int = 8
    optimizer: str = "adam"
    lr: float = 1e-3
    momentum: float = 0.9
    weight_decay: float = 0.0
    lr_step: int = 0
    lr_gamma: float = 0.1
    lr_plateau: int = 0
    seed: int = 0
    num_workers: int = 0
    checkpoint_steps: int = 0
    grad_clip: float | None = None
    device: str = "auto"
    schedule: str = "step"

    def __post_init__(self) -> None:
        _validate.integer("epochs", self.epochs, minimum=1)
        _validate.integer("batch_size", self.batch_size, minimum=1)
        _validate.choice("optimizer", self.optimizer, OPTIMIZERS)
        reals = {
            "lr": _validate.real("lr", self.lr, positive=True),
            "momentum": _validate.real("momentum", self.momentum, nonnegative=True),
            "weight_decay": _validate.real("weight_decay", self.weight_decay, nonnegative=True),
            "lr_gamma": _validate.real("lr_gamma", self.lr_gamma, positive=True),
        }
        if reals["momentum"] >= 1:
            raise InvalidArgumentError(f"momentum: got {self.momentum}, expected 0 <= momentum < 1")
        if self.grad_clip is not None:
            reals["grad_clip"] = _validate.real("grad_clip", self.grad_clip, positive=True)
        _validate.integer("lr_step", self.lr_step)
        _validate.integer("lr_plateau", self.lr_plateau)
        if self.lr_plateau and self.lr_step:
            raise InvalidArgumentError(
                f"lr_plateau: got {self.lr_plateau} with lr_step {self.lr_step}, expected one "
                "schedule (set the other to 0)"
            )
        if self.lr_plateau and reals["lr_gamma"] >= 1:
            raise InvalidArgumentError(
                f"lr_gamma: got {self.lr_gamma} with lr_plateau, expected 0 < lr_gamma < 1"
            )
        _validate.choice("schedule", self.schedule, SCHEDULES)
        if self.schedule == "cosine" and (self.lr_step or self.lr_plateau):
            raise InvalidArgumentError(
                f"schedule: got 'cosine' with lr_step {self.lr_step} and lr_plateau "
                f"{self.lr_plateau}, expected both 0 (one schedule)"
            )
        _validate.integer("seed", self.seed, maximum=2**32 - 1)  # numpy's seed range
        _validate.integer("num_workers", self.num_workers)
        _validate.integer("checkpoint_steps", self.checkpoint_steps)
        _validate.device("device", self.device, auto=True, available=False)  # checked at setup
        for name, value in reals.items():  # one type per field, so saved configs compare equal
            object.__setattr__(self, name, value)
        for name in (
            "epochs", "batch_size", "lr_step", "lr_plateau", "seed", "num_workers",
            "checkpoint_steps",
        ):  # fmt: skip
            object.__setattr__(self, name, int(getattr(self, name)))

    def to_dict(self) -> dict[str, Any]:
        """The fields as a plain dict (what checkpoints store). ``lr_plateau`` is left out at
        its default 0 and ``schedule`` at its default "step", so checkpoints written before they
        existed still resume."""
        out = dataclasses.asdict(self)
        if not out["lr_plateau"]:
            del out["lr_plateau"]
        if out["schedule"] == "step":
            del out["schedule"]
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrainConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise naming them."""
        known = {f.name for f in dataclasses.fields(cls)}
        if not isinstance(data, Mapping) or not all(isinstance(k, str) for k in data):
            raise InvalidArgumentError(
                f"config: got {type(data).__name__}, expected a dict of TrainConfig fields"
            )
        unknown = sorted(set(data) - known)
        if unknown:
            raise InvalidArgumentError(f"config: got unknown fields {unknown}, expected {known}")
        return cls(**data)


@dataclass(frozen=True)
class EpochStats:
    """One completed epoch: 1-based number, mean train loss, mean validation loss, its LR (at the
    epoch's start), and with a ``metric_fn`` the metric's means over the epoch's training batches
    (in train mode, as they were drawn) and over the validation set."""

    epoch: int
    train_loss: float
    val_loss: float | None
    lr: float
    train_metric: float | None = None
    val_metric: float | None = None


@dataclass(frozen=True)
class TrainResult:
    """What :func:`train` did. ``best_*`` are None when there was no validation set;
    ``best_val_metric`` also without a ``metric_fn``."""

    history: tuple[EpochStats, ...]
    best_epoch: int | None
    best_val_loss: float | None
    last_checkpoint: Path
    best_checkpoint: Path | None
    best_val_metric: float | None = None


def seed_everything(seed: int) -> None:
    """Seed Python's, numpy's and torch's (CPU and CUDA) global generators."""
    seed = _validate.integer("seed", seed, maximum=2**32 - 1)
    random.seed(seed)
    np.random.seed(seed)  # noqa: NPY002 - datasets draw augmentations from the global generator
    torch.manual_seed(seed)


def split(dataset: Dataset[Any], fraction: float, seed: int = 0) -> tuple[Subset[Any], Subset[Any]]:
    """Split ``dataset`` into (train, validation) subsets, ``fraction`` of it for validation.

    Deterministic for a given ``seed`` and length; each side gets at least one item. Items are
    drawn independently: data with correlated items (frames of one scene) should be split by
    group by the caller instead.
    """
    fraction = _validate.real("fraction", fraction)
    if not 0 < fraction < 1:
        raise InvalidArgumentError(f"fraction: got {fraction}, expected 0 < fraction < 1")
    n = _length("dataset", dataset)
    if n < 2:
        raise InvalidArgumentError(f"dataset: got {n} items, expected at least 2 to split")
    seed = _validate.integer("seed", seed, maximum=_validate.MAX_SEED)
    n_val = min(max(round(n * fraction), 1), n - 1)
    order = torch.randperm(n, generator=torch.Generator().manual_seed(seed)).tolist()
    return Subset(dataset, sorted(order[n_val:])), Subset(dataset, sorted(order[:n_val]))


def _epoch_line(entry: Mapping[str, Any], epochs: int, seconds: float, resumed: int = 0) -> str:
    """One epoch's summary, for output that is not a terminal (``resumed``: the step this
    process resumed the epoch after; its seconds count from there)."""
    parts = [f"epoch {entry['epoch']}/{epochs}", f"train loss {entry['train_loss']:.4g}"]
    for key, name in (("train_metric", "train metric"), ("val_loss", "val loss"),
                      ("val_metric", "val metric")):  # fmt: skip
        if entry.get(key) is not None:
            parts.append(f"{name} {entry[key]:.4g}")
    took = f"{seconds:.1f} s" + (f" (resumed after step {resumed})" if resumed else "")
    return ", ".join(parts) + f", lr {entry['lr']:.3g}, {took}"


def _length(name: str, dataset: object) -> int:
    if not isinstance(dataset, Dataset) or not isinstance(dataset, Sized):
        raise InvalidArgumentError(
            f"{name}: got {type(dataset).__name__}, expected a torch.utils.data.Dataset with len()"
        )
    return len(dataset)


def _to_device(batch: Any, device: torch.device) -> Batch:
    items = (batch,) if isinstance(batch, torch.Tensor) else tuple(batch)
    return tuple(
        x.to(device, non_blocking=True) if isinstance(x, torch.Tensor) else x for x in items
    )


def _count(x: Any) -> int:
    return int(x.shape[0]) if isinstance(x, torch.Tensor) else len(x)


def _seed_worker(worker_id: int) -> None:
    s = torch.initial_seed() % 2**32  # distinct per worker, derived from the loader's generator
    np.random.seed(s)  # noqa: NPY002 - the global generator, as in the main process
    random.seed(s)


def _loader(
    data: Dataset[Any], indices: list[int], cfg: TrainConfig, g: _Group, stream: list[int]
) -> DataLoader[Any]:
    """Batches of ``data[indices]`` in that order; worker seeds from (seed, *stream)."""
    seed = int(np.random.SeedSequence([cfg.seed, *stream]).generate_state(1)[0])
    gen = torch.Generator().manual_seed(seed)
    return DataLoader(
        data,
        batch_size=cfg.batch_size,
        sampler=indices,
        num_workers=cfg.num_workers,
        generator=gen,  # also keeps the loader from drawing from the global torch generator
        worker_init_fn=_seed_worker if cfg.num_workers else None,
        pin_memory=g.device.type == "cuda",
    )


def _mean_loss(loss: torch.Tensor, where: str) -> float:
    if not isinstance(loss, torch.Tensor) or loss.numel() != 1:
        raise RgbdError(f"loss_fn: returned {type(loss).__name__}, expected a scalar tensor")
    value = float(loss.item())
    if not math.isfinite(value):
        raise RgbdError(
            f"loss_fn: returned {value} at {where}; lower lr, set grad_clip or check the data "
            "(the last finite state is in last.pt)"
        )
    return value


def _mean_metric(value: Any) -> float:
    if not isinstance(value, torch.Tensor) or value.numel() != 1:
        raise RgbdError(f"metric_fn: returned {type(value).__name__}, expected a scalar tensor")
    out = float(value.item())
    if not math.isfinite(out):
        raise RgbdError(f"metric_fn: returned {out}, expected a finite score")
    return out


def _evaluate(
    model: nn.Module,
    data: Dataset[Any],
    loss_fn: LossFn,
    metric_fn: MetricFn | None,
    cfg: TrainConfig,
    g: _Group,
) -> tuple[float, float | None]:
    """(mean loss, mean metric or None) over ``data``."""
    model.eval()
    total = score = count = 0.0
    with torch.no_grad():
        indices = list(range(g.rank, _length("val_set", data), g.world))  # no padding: exact mean
        for raw in _loader(data, indices, cfg, g, [1]):
            batch = _to_device(raw, g.device)
            n = _count(batch[0])
            output = model(batch[0])
            total += _mean_loss(loss_fn(output, batch), "validation") * n
            if metric_fn is not None:
                score += _mean_metric(metric_fn(output, batch)) * n
            count += n
    model.train()
    total, score, count = g.sum([total, score, count])
    return total / count, (score / count if metric_fn is not None else None)


def _better(
    val: float | None, metric: float | None, best_val: float | None, best_metric: float | None
) -> bool:
    """Is this epoch the new best: the higher metric (ties: the lower loss), else the lower loss."""
    if val is None:
        return False
    if best_val is None:
        return True
    if metric is not None and best_metric is not None:
        return metric > best_metric or (metric == best_metric and val < best_val)
    return val < best_val


def _cosine(total_steps: int) -> Callable[[int], float]:
    """LambdaLR factor of a cosine from 1 at step 0 to 0 at ``total_steps``."""

    def factor(step: int) -> float:
        return 0.5 * (1.0 + math.cos(math.pi * min(step, total_steps) / total_steps))

    return factor


def train(
    model: nn.Module,
    train_set: Dataset[Any],
    val_set: Dataset[Any] | None,
    loss_fn: LossFn,
    config: TrainConfig,
    out_dir: str | os.PathLike[str],
    *,
    arch: str,
    arch_config: Mapping[str, Any],
    normalisation: Mapping[str, Any],
    quiet: bool = False,
    resume: bool = True,
    metric_fn: MetricFn | None = None,
) -> TrainResult:
    """Train ``model`` in place; write ``out_dir/last.pt`` and (with validation) ``best.pt``.

    ``arch`` names the architecture and ``arch_config`` holds its constructor arguments, so
    :func:`~rgbd_rs.nn.checkpoint.load_checkpoint` can rebuild and check it; ``normalisation``
    holds the input statistics inference must apply (plain values or tensors). ``val_set=None``
    trains without validation (no ``best.pt``; see :func:`split` to make one). ``resume=True``
    continues from ``out_dir/last.pt`` when it exists (a finished run returns at once; a larger
    ``config.epochs`` trains further); any other difference in arch, arch_config, normalisation
    or the fields that shape training raises :class:`RgbdError` listing what differs.
    ``resume=False`` starts afresh and overwrites ``out_dir``'s checkpoints. Under torchrun every
    process calls this; only rank 0 writes files and shows the progress: a bar on a terminal, one
    line per epoch on stderr otherwise (a log file, a cluster job), nothing when ``quiet``.
    See the module docstring for the calling convention.
    ``metric_fn(output, batch)`` (a score, higher is better, e.g. accuracy) is recorded per
    epoch on the training batches and the validation set, and then chooses ``best.pt``: the
    epoch of the highest validation metric (ties: the lower validation loss), instead of the
    lowest validation loss.
    """
    quiet = _validate.flag("quiet", quiet)
    resume = _validate.flag("resume", resume)
    out_dir = _validate.out_folder("out_dir", out_dir)
    if not isinstance(model, nn.Module):
        raise InvalidArgumentError(f"model: got {type(model).__name__}, expected a torch nn.Module")
    if _length("train_set", train_set) == 0:
        raise InvalidArgumentError("train_set: got an empty dataset, expected at least one item")
    if val_set is not None and _length("val_set", val_set) == 0:
        raise InvalidArgumentError("val_set: got an empty dataset, expected at least one item")
    if not callable(loss_fn):
        raise InvalidArgumentError(f"loss_fn: got {type(loss_fn).__name__}, expected a callable")
    if metric_fn is not None and not callable(metric_fn):
        raise InvalidArgumentError(
            f"metric_fn: got {type(metric_fn).__name__}, expected a callable or None"
        )
    if not isinstance(config, TrainConfig):
        raise InvalidArgumentError(f"config: got {type(config).__name__}, expected TrainConfig")
    if not isinstance(arch, str) or not arch:
        raise InvalidArgumentError(f"arch: got {arch!r}, expected a non-empty str")
    for name, value in (("arch_config", arch_config), ("normalisation", normalisation)):
        if not isinstance(value, Mapping):
            raise InvalidArgumentError(f"{name}: got {type(value).__name__}, expected a dict")
    now: dict[str, Any] = {
        "arch": arch,
        "arch_config": _plain("arch_config", arch_config),
        "normalisation": _plain("normalisation", normalisation),
        "config": config.to_dict(),
    }
    g = _setup(config.device)
    now["world_size"] = g.world
    try:
        return _run(
            model, train_set, val_set, loss_fn, metric_fn, config, Path(out_dir), now, g, quiet,
            resume,
        )  # fmt: skip
    finally:
        g.close()


def _run(
    model: nn.Module,
    train_set: Dataset[Any],
    val_set: Dataset[Any] | None,
    loss_fn: LossFn,
    metric_fn: MetricFn | None,
    cfg: TrainConfig,
    out: Path,
    now: dict[str, Any],
    g: _Group,
    quiet: bool,
    resume: bool,
) -> TrainResult:
    main = g.rank == 0
    last_path, best_path = out / LAST, out / BEST
    model.to(g.device)
    params = [p for p in model.parameters() if p.requires_grad]
    opt: torch.optim.Optimizer
    if cfg.optimizer == "sgd":
        opt = torch.optim.SGD(params, cfg.lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay)
    elif cfg.optimizer == "adamw":
        opt = torch.optim.AdamW(params, cfg.lr, weight_decay=cfg.weight_decay)
    else:
        opt = torch.optim.Adam(params, cfg.lr, weight_decay=cfg.weight_decay)
    per_rank = math.ceil(_length("train_set", train_set) / g.world)  # DistributedSampler pads
    steps = math.ceil(per_rank / cfg.batch_size)
    sched: Any
    if cfg.schedule == "cosine":  # stepped once per optimizer step
        sched = torch.optim.lr_scheduler.LambdaLR(opt, _cosine(cfg.epochs * steps))
    elif cfg.lr_plateau:  # reduce after lr_plateau bad epochs in a row (torch counts patience + 1)
        sched = torch.optim.lr_scheduler.ReduceLROnPlateau(
            opt, "min", factor=cfg.lr_gamma, patience=cfg.lr_plateau - 1, threshold=0.0
        )
    else:
        gamma = cfg.lr_gamma if cfg.lr_step else 1.0
        sched = torch.optim.lr_scheduler.StepLR(opt, step_size=cfg.lr_step or 1, gamma=gamma)
    history: list[dict[str, Any]] = []
    best_val: float | None = None
    best_metric: float | None = None
    best_epoch: int | None = None
    start_epoch = start_step = 0
    partial = {"loss_sum": 0.0, "samples": 0.0, "metric_sum": 0.0}
    # Rank 0 reads last.pt (after its own previous writes: no race, no shared disk needed) and
    # sends it to the others; an unreadable file fails every rank alike instead of hanging.
    found: Checkpoint | str | None = None
    if main and resume and last_path.is_file():
        try:
            found = load_checkpoint(last_path, map_location="cpu")
        except RgbdError as exc:
            found = str(exc)
    found = g.broadcast(found)
    if isinstance(found, str):
        raise RgbdError(found)
    if found is not None:
        ckpt = found
        may_change = RESUMABLE_CHANGES - ({"epochs"} if cfg.schedule == "cosine" else set())
        diffs = _resume_differences(ckpt, **now, may_change=may_change)
        if diffs:
            raise RgbdError(
                f"{last_path}: cannot resume: " + "; ".join(diffs) + ". Pass resume=False "
                f"(CLI: --no-resume) to start afresh in {out}, or choose another output folder"
            )
        model.load_state_dict(ckpt.model_state)
        opt.load_state_dict(ckpt.optimizer_state)  # type: ignore[arg-type]
        sched.load_state_dict(ckpt.scheduler_state)
        _restore_rng(ckpt.rng_state["ranks"][g.rank])  # type: ignore[index]
        history, best_val, best_epoch = list(ckpt.history), ckpt.best_val_loss, ckpt.best_epoch
        if best_epoch is not None and 0 < best_epoch <= len(history):
            best_metric = history[best_epoch - 1].get("val_metric")
        start_epoch, start_step = ckpt.epoch, ckpt.step
        if main and ckpt.partial:
            partial = dict(ckpt.partial)  # the other ranks' shares are already summed in
    else:
        # Each rank its own stream (dropout, augmentations); rank 0 = a single process's.
        seed_everything((cfg.seed + g.rank) % 2**32)
        if main:
            best_path.unlink(missing_ok=True)  # a stale best.pt from an earlier run
    net: nn.Module = model
    if g.world > 1:
        ids = [g.device.index or 0] if g.device.type == "cuda" else None
        net = DistributedDataParallel(model, device_ids=ids)
    version, revision = _package_version(), git_revision()

    def save(epoch: int, step: int, sums: dict[str, float], paths: list[Path]) -> None:
        """Called by every rank (each contributes its RNG state); rank 0 writes ``paths``."""
        rng = g.gather(_capture_rng())
        if not main:
            return
        ckpt = Checkpoint(
            path=paths[0], arch=now["arch"], arch_config=now["arch_config"],
            normalisation=now["normalisation"], model_state=model.state_dict(),
            config=now["config"], version=version, git_revision=revision, epoch=epoch,
            step=step, world_size=g.world, optimizer_state=opt.state_dict(),
            scheduler_state=sched.state_dict(), rng_state={"ranks": rng}, history=history,
            best_val_loss=best_val, best_epoch=best_epoch, partial=sums,
        )  # fmt: skip
        for path in paths:
            save_checkpoint(ckpt, path)

    show = not quiet and main and sys.stderr.isatty()
    # Not a terminal (a log file, a cluster job): one line per epoch instead of a bar.
    lines = not quiet and main and not show
    net.train()
    for epoch in range(start_epoch, cfg.epochs):
        started = time.perf_counter()
        sampler: DistributedSampler[Any] = DistributedSampler(
            train_set, num_replicas=g.world, rank=g.rank, shuffle=True, seed=cfg.seed
        )
        sampler.set_epoch(epoch)
        order = list(sampler)
        skip = start_step if epoch == start_epoch else 0
        loss_sum, samples = (partial["loss_sum"], partial["samples"]) if skip else (0.0, 0.0)
        metric_sum = float(partial.get("metric_sum", 0.0)) if skip else 0.0
        lr = float(opt.param_groups[0]["lr"])  # at the epoch's start (also when resumed within)
        if cfg.schedule == "cosine":
            lr = cfg.lr * _cosine(cfg.epochs * steps)(epoch * steps)
        loader = _loader(train_set, order[skip * cfg.batch_size :], cfg, g, [0, epoch])
        bar = tqdm(
            total=steps, initial=skip, desc=f"epoch {epoch + 1}/{cfg.epochs}", unit="step",
            disable=not show, dynamic_ncols=True,
        )  # fmt: skip
        with bar:
            for step, raw in enumerate(loader, start=skip + 1):
                batch = _to_device(raw, g.device)
                opt.zero_grad(set_to_none=True)
                output = net(batch[0])
                loss = loss_fn(output, batch)
                value = _mean_loss(loss, f"epoch {epoch + 1} step {step}")
                loss.backward()  # type: ignore[no-untyped-call]
                if cfg.grad_clip is not None:
                    nn.utils.clip_grad_norm_(params, cfg.grad_clip)
                opt.step()
                if cfg.schedule == "cosine":
                    sched.step()
                n = _count(batch[0])
                loss_sum, samples = loss_sum + value * n, samples + n
                if metric_fn is not None:
                    with torch.no_grad():
                        metric_sum += _mean_metric(metric_fn(output, batch)) * n
                bar.update()
                bar.set_postfix(loss=f"{loss_sum / samples:.4g}")
                if cfg.checkpoint_steps and step % cfg.checkpoint_steps == 0 and step < steps:
                    total = g.sum([loss_sum, samples, metric_sum])
                    sums = {"loss_sum": total[0], "samples": total[1], "metric_sum": total[2]}
                    save(epoch, step, sums, [last_path])
            loss_sum, samples, metric_sum = g.sum([loss_sum, samples, metric_sum])
            val, val_metric = (None, None)
            if val_set is not None:
                val, val_metric = _evaluate(model, val_set, loss_fn, metric_fn, cfg, g)
            train_loss = loss_sum / samples
            if cfg.lr_plateau:
                sched.step(val if val is not None else train_loss)
            elif cfg.schedule != "cosine":
                sched.step()
            entry: dict[str, Any] = {
                "epoch": epoch + 1, "train_loss": train_loss, "val_loss": val, "lr": lr,
            }  # fmt: skip
            if metric_fn is not None:
                entry |= {"train_metric": metric_sum / samples, "val_metric": val_metric}
            history.append(entry)
            improved = _better(val, val_metric, best_val, best_metric)
            if improved:
                best_val, best_metric, best_epoch = val, val_metric, epoch + 1
            save(epoch + 1, 0, {}, [last_path, best_path] if improved else [last_path])
            shown = {"loss": f"{train_loss:.4g}"} | ({} if val is None else {"val": f"{val:.4g}"})
            bar.set_postfix(shown)
        if lines:
            took = time.perf_counter() - started
            print(_epoch_line(entry, cfg.epochs, took, skip), file=sys.stderr)
    g.barrier()
    return TrainResult(
        history=tuple(EpochStats(**h) for h in history),
        best_epoch=best_epoch,
        best_val_loss=best_val,
        last_checkpoint=last_path,
        best_checkpoint=best_path if best_epoch is not None else None,
        best_val_metric=best_metric,
    )
