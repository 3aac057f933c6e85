"""Training recipe of the semantic ConvNet (``rgbd train semantic``), thesis §4.6 and §4.8.

1. A cue cache (:func:`rgbd_rs.segmentation.semantic_data.build_semantic_cache`; resumable,
   shardable).
2. A seeded ``val_fraction`` of its frames held out for validation (frames drawn independently:
   a cache whose frames are consecutive views of one room should be validated on another cache
   instead, ``val_fraction=0`` then).
3. :func:`rgbd_rs.nn.train.train` (checkpoints every epoch and every ``checkpoint_steps``
   steps, resume, DDP under torchrun): :class:`~rgbd_rs.nn.semantic.SemanticNet`, the
   multi-class cross-entropy of §4.6 over the labeled pixels (:class:`SemanticLoss`), SGD with
   quadratic regularisation 0.001 (weight decay) and lr 0.01 multiplied by 0.7 after 10 epochs
   without a lower validation loss (§4.8, ``TrainConfig.lr_plateau``).
4. Pre-train on one cache (synthetic scenes), fine-tune from its checkpoint on another
   (``init=``, NYUv2's training frames); :func:`ship` copies the best checkpoint, inference-only
   and float16, into ``rgbd_rs/nn/weights/semantic_nyuv2.pt``.

Choices the thesis leaves open (:func:`default_config`): plain SGD (no momentum: the thesis
names none; with momentum 0.9 at lr 0.01 the loss diverged on NYUv2 frames), gradients clipped
to a global L2 norm of 1 (at lr 0.01 unclipped, gradient norms of 25-90 drove the loss of 192
synthetic frames from 3.8 to 8-13 within 30 steps; clipped it fell to 2.2, like lr 0.001
unclipped), batch 4 frames,
``checkpoint_steps`` 50; the loss is the mean over the batch's labeled pixels of the negative log
of the upsampled PDFs (what inference hands on: the PDFs of the 1/4-resolution output
bilinearly upsampled to the labels' resolution), so training and inference see one model.
Torch's ``weight_decay`` ``w`` adds ``w * theta`` to the gradient, i.e. minimises
``w / 2 * |theta|^2``.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.nn.semantic import ARCH, THESIS_WIDTH, SemanticNet, class_probabilities, lcn_window
from rgbd_rs.segmentation.semantic_data import SemanticCache

__all__ = [
    "SemanticLoss",
    "SemanticRecipe",
    "SemanticScores",
    "default_config",
    "normalisation_of",
    "score",
    "ship",
    "train_semantic",
]

#: Smallest probability the loss takes the log of (a pixel whose class got exactly 0).
LOG_FLOOR = 1e-12


@dataclass(frozen=True)
class SemanticRecipe:
    """What ``rgbd train semantic`` varies besides :class:`~rgbd_rs.nn.train.TrainConfig`:
    ``width`` (last block's filters, 256 in the thesis), ``val_fraction`` of the cache's frames
    held out for validation, ``augment`` (random left-right mirroring), ``ignore_index`` (the
    unlabeled class, never a target, probability 0) and ``lcn_window`` (None:
    :func:`~rgbd_rs.nn.semantic.lcn_window` of the cache's width)."""

    width: int = THESIS_WIDTH
    val_fraction: float = 0.2
    augment: bool = True
    ignore_index: int = 0
    lcn_window: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "width", _validate.integer("width", self.width, minimum=1, maximum=4096)
        )
        f = _validate.real("val_fraction", self.val_fraction, nonnegative=True)
        if f >= 1:
            raise InvalidArgumentError(
                f"val_fraction: got {self.val_fraction}, expected 0 <= val_fraction < 1"
            )
        object.__setattr__(self, "val_fraction", f)
        if not isinstance(self.augment, bool):
            raise InvalidArgumentError(f"augment: got {self.augment!r}, expected a bool")
        _validate.integer("ignore_index", self.ignore_index)
        if self.lcn_window is not None:
            w = _validate.integer("lcn_window", self.lcn_window, minimum=1, maximum=1023)
            if w % 2 == 0:
                raise InvalidArgumentError(f"lcn_window: got {w}, expected an odd number")


def default_config(**overrides: Any) -> Any:
    """The recipe's :class:`~rgbd_rs.nn.train.TrainConfig`: SGD, lr 0.01 multiplied by 0.7
    after 10 epochs without a validation gain, weight decay 0.001 (§4.8); no momentum, gradient
    norm clipped to 1, batch 4, 100 epochs, a checkpoint every 50 steps (ours); ``overrides``
    replace fields."""
    from rgbd_rs.nn.train import TrainConfig

    base: dict[str, Any] = {
        "epochs": 100,
        "batch_size": 4,
        "optimizer": "sgd",
        "lr": 0.01,
        "momentum": 0.0,
        "weight_decay": 1e-3,
        "lr_plateau": 10,
        "lr_gamma": 0.7,
        "checkpoint_steps": 50,
        "grad_clip": 1.0,
    }
    return TrainConfig(**(base | overrides))


class SemanticLoss:
    """The trainer's loss: the mean over ``batch[1]``'s labeled pixels (label !=
    ``ignore_index``) of ``-log p``, ``p`` the true class' probability in
    :func:`~rgbd_rs.nn.semantic.class_probabilities` of the logits upsampled to the labels' size.
    A batch without labeled pixels gives 0 (no gradient)."""

    def __init__(self, ignore_index: int = 0) -> None:
        self.ignore_index = _validate.integer("ignore_index", ignore_index)

    def __call__(self, output: torch.Tensor, batch: tuple[Any, ...]) -> torch.Tensor:
        target = batch[1]
        p = class_probabilities(
            output, (int(target.shape[-2]), int(target.shape[-1])), ignore_index=self.ignore_index
        )
        labeled = target != self.ignore_index
        picked = p.gather(1, target.clamp(0, p.shape[1] - 1)[:, None])[:, 0]
        nll = -torch.log(picked.clamp_min(LOG_FLOOR))
        count = labeled.sum()
        loss: torch.Tensor = torch.where(labeled, nll, torch.zeros_like(nll)).sum()
        return loss / count.clamp_min(1)  # type: ignore[no-any-return]


def _cache(cache: SemanticCache | str | os.PathLike[str]) -> SemanticCache:
    return cache if isinstance(cache, SemanticCache) else SemanticCache(cache)


def normalisation_of(cache: SemanticCache, ignore_index: int) -> dict[str, Any]:
    """What inference must repeat (stored in the checkpoint): the input size (w, h) the cues
    are reduced to, the class names, the ignored class, the cue function and its seed."""
    return {
        "input_size": list(cache.size),
        "classes": list(cache.classes),
        "ignore_index": ignore_index,
        "cues": cache.meta.get("cues"),
        "cue_seed": cache.meta.get("seed"),
        "dataset": cache.meta.get("source"),
    }


def train_semantic(
    cache: SemanticCache | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    recipe: SemanticRecipe | None = None,
    config: Any | None = None,
    init: str | os.PathLike[str] | None = None,
    val_cache: SemanticCache | str | os.PathLike[str] | None = None,
    resume: bool = True,
    quiet: bool = False,
) -> Path:
    """Train on ``cache``'s frames; return the best checkpoint's path (the last one without
    validation). ``init`` starts from a checkpoint's weights (fine-tuning: same class count,
    input size and width). ``val_cache`` validates on another cache's frames instead of a
    ``val_fraction`` of ``cache``'s. Re-running resumes from ``out/last.pt`` (see
    :func:`rgbd_rs.nn.train.train`). A cache (or ``val_cache``) with frames still to compute
    raises :class:`RgbdError`."""
    from rgbd_rs.nn.train import TrainConfig, seed_everything, split, train

    quiet = _validate.flag("quiet", quiet)
    resume = _validate.flag("resume", resume)
    out = _validate.out_folder("out", out)

    c = _cache(cache)
    r = recipe if recipe is not None else SemanticRecipe()
    if not isinstance(r, SemanticRecipe):
        raise InvalidArgumentError(f"recipe: got {type(r).__name__}, expected a SemanticRecipe")
    cfg = config if config is not None else default_config()
    if not isinstance(cfg, TrainConfig):
        raise InvalidArgumentError(f"config: got {type(cfg).__name__}, expected a TrainConfig")
    n_classes = len(c.classes)
    if not r.ignore_index < n_classes:
        raise InvalidArgumentError(
            f"ignore_index: got {r.ignore_index}, expected a class of the cache (< {n_classes})"
        )
    train_set: Any = c.dataset(augment=r.augment)
    val_set: Any = None
    if val_cache is not None:
        v = _cache(val_cache)
        if v.size != c.size or v.classes != c.classes:
            raise RgbdError(
                f"{v.path}: validation cache of size {v.size} and classes {len(v.classes)}, "
                f"expected {c.size} and {n_classes} like {c.path}"
            )
        val_set = v.dataset()
    elif r.val_fraction > 0:
        if len(train_set) < 2:
            raise RgbdError(f"{c.path}: {len(train_set)} computed frame(s), too few to validate")
        train_idx, val_idx = split(c.dataset(), r.val_fraction, seed=cfg.seed)
        train_set = c.dataset(c.indices()[train_idx.indices], augment=r.augment)
        val_set = c.dataset(c.indices()[val_idx.indices])
    seed_everything(cfg.seed)  # the initial weights come from the seed too
    window = r.lcn_window if r.lcn_window is not None else lcn_window(c.size[0])
    model = SemanticNet(n_classes, width=r.width, lcn_window=window)
    norm = normalisation_of(c, r.ignore_index)
    if init is not None:
        _load_init(_validate.path("init", init), model, norm)
    result = train(
        model,
        train_set,
        val_set,
        SemanticLoss(r.ignore_index),
        cfg,
        out,
        arch=ARCH,
        arch_config=model.arch_config(),
        normalisation=norm,
        quiet=quiet,
        resume=resume,
    )
    return Path(result.best_checkpoint or result.last_checkpoint)


def _as_list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _load_init(init: str | os.PathLike[str], model: SemanticNet, norm: dict[str, Any]) -> None:
    from rgbd_rs.nn.checkpoint import load_checkpoint

    ckpt = load_checkpoint(init, arch=ARCH, normalisation_keys=("input_size", "classes"))
    have = ckpt.normalisation
    for key in ("input_size", "classes", "ignore_index"):
        if _as_list(have.get(key)) != _as_list(norm[key]):
            raise RgbdError(
                f"{ckpt.path}: --init checkpoint has {key} {have.get(key)!r}, expected "
                f"{norm[key]!r} like the cache; fine-tune on a cache built with its settings"
            )
    state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt.model_state.items()}
    dataclasses.replace(ckpt, model_state=state).load_weights(model)


def ship(checkpoint: str | os.PathLike[str], dest: str | os.PathLike[str] | None = None) -> Path:
    """Write the inference-only, float16 copy of ``checkpoint`` to ``dest``, by default the
    package's shipped weights (``rgbd_rs/nn/weights/semantic_nyuv2.pt``)."""
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.segmentation.labeling import _weights_path

    ckpt = load_checkpoint(checkpoint, arch=ARCH, normalisation_keys=("input_size", "classes"))
    half = {k: v.half() if v.is_floating_point() else v for k, v in ckpt.model_state.items()}
    light = dataclasses.replace(ckpt.stripped(), model_state=half)
    return save_checkpoint(light, _weights_path() if dest is None else dest)


@array_eq
@dataclass(frozen=True)
class SemanticScores:
    """Per-pixel accuracy of a network on a cache at its resolution (labeled pixels only):
    ``confusion`` (rows truth, columns prediction; :func:`rgbd_rs.metrics.confusion_matrix`),
    pixel and mean class accuracy (classes present in the truth), per-class accuracy (NaN for
    absent classes), the class names."""

    classes: tuple[str, ...]
    confusion: np.ndarray
    pixel_accuracy: float
    class_accuracy: float
    per_class: tuple[float, ...]

    def summary(self) -> str:
        """One line: pixel and class accuracy."""
        return (
            f"pixel accuracy {100 * self.pixel_accuracy:.1f}%, "
            f"class accuracy {100 * self.class_accuracy:.1f}% "
            f"({int(self.confusion.sum())} labeled pixels)"
        )


def score(
    checkpoint: str | os.PathLike[str],
    cache: SemanticCache | str | os.PathLike[str],
    *,
    indices: Any | None = None,
    device: str = "cpu",
    batch_size: int = 4,
) -> SemanticScores:
    """Accuracy of ``checkpoint`` on ``cache``'s frames (or ``indices``) at the cache's
    resolution: the argmax of the upsampled PDFs against the cached labels. Without
    ``indices``, a cache with frames still to compute raises :class:`RgbdError`."""
    from rgbd_rs.metrics import confusion_matrix
    from rgbd_rs.segmentation.labeling import SemanticLabeler

    c = _cache(cache)
    lab = SemanticLabeler.load(checkpoint, device=device)
    if lab.input_size != c.size or len(lab.classes) != len(c.classes):
        raise RgbdError(
            f"{checkpoint}: network for {lab.input_size} inputs and {len(lab.classes)} classes, "
            f"cache {c.path} of {c.size} and {len(c.classes)}"
        )
    bs = _validate.integer("batch_size", batch_size, minimum=1)
    data = c.dataset(indices)
    k = len(c.classes)
    cm = np.zeros((k, k), np.int64)
    for start in range(0, len(data), bs):
        items = [data[i] for i in range(start, min(start + bs, len(data)))]
        x = torch.stack([a for a, _ in items])
        y = torch.stack([b for _, b in items]).numpy()
        pred = lab.pdfs_of_cues(x).argmax(axis=-1)
        w = y.shape[-1]  # frames stacked as one tall image
        cm += confusion_matrix(
            pred.reshape(-1, w), y.reshape(-1, w), n_classes=k, ignore=lab.ignore_index
        )
    support = cm.sum(axis=1)
    present = support > 0
    per = np.full(k, np.nan)
    per[present] = np.diag(cm)[present] / support[present]
    if lab.ignore_index is not None:
        per[lab.ignore_index] = np.nan
    total = int(cm.sum())
    return SemanticScores(
        classes=lab.classes,
        confusion=cm,
        pixel_accuracy=float(np.trace(cm) / total) if total else float("nan"),
        class_accuracy=float(np.nanmean(per)) if present.any() else float("nan"),
        per_class=tuple(float(v) for v in per),
    )
