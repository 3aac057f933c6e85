"""Training recipe of the shape classifier (``rgbd train shapes``), thesis §5.4-5.5.

1. A representation cache (:func:`rgbd_rs.shapes.dataset.build_cache`; resumable, shardable).
2. The cache's training split, a seeded ``val_fraction`` of it held out for validation (the
   official test split is never seen; ``rgbd eval shapes`` measures it).
3. :func:`rgbd_rs.nn.train.train` (checkpoints every epoch and every ``checkpoint_steps`` steps,
   resume, DDP under torchrun): :class:`~rgbd_rs.nn.shapes.ShapeNet`, cross-entropy, SGD as in
   the thesis. The thesis gives no learning rate, momentum, batch size or decay (METHOD_NOTES
   §10): ours are :func:`default_config`'s, stated with every result.

:func:`train_ablation` trains one network per row of Table 5.2 (each representation alone, then
all combined) into ``OUT/<row>/``. The best checkpoint (lowest validation loss) is what
:func:`ship` copies, inference-only and in float16, into ``rgbd_rs/nn/weights``.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as F
from torch.utils.data import Subset

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.nn.shapes import ARCH, THESIS_WIDTH, ShapeNet, _parse_representations
from rgbd_rs.shapes.augment import (
    MAX_MIXUP_ALPHA,
    MIN_MIXUP_ALPHA,
    AugmentedShapes,
    MixedShapes,
)
from rgbd_rs.shapes.dataset import ShapeCache
from rgbd_rs.shapes.scaling import original_name, original_rows

__all__ = [
    "ShapeRecipe",
    "ablation_rows",
    "accuracy",
    "cross_entropy",
    "default_config",
    "ship",
    "ship_ensemble",
    "train_ablation",
    "train_shapes",
]

#: Table 5.2's combined row.
COMBINED = "combined"


@dataclass(frozen=True)
class ShapeRecipe:
    """What ``rgbd train shapes`` varies besides :class:`~rgbd_rs.nn.train.TrainConfig`:
    ``representations`` (None: every one in the cache), ``width`` (descriptor length per branch,
    128 in the thesis), ``val_fraction`` of the training split held out for validation and
    ``rotate``: turn each training shape by a random number of quarter turns about z at every
    step (:mod:`rgbd_rs.shapes.augment`; exact on the cached inputs; not in the thesis). Off by
    default: on ModelNet, whose shapes are aligned, it cost accuracy (90.3 % -> 84.9 % on
    ModelNet10); turn it on for shapes in arbitrary orientation about z. ``mirror``: replace each
    training shape by its mirror image (x -> -x) with probability 1/2 at every step (exact on the
    cached inputs; not in the thesis; keeps an aligned shape's front where it was).
    ``batch_norm`` and ``dropout``: see :class:`~rgbd_rs.nn.shapes.ShapeNet` (not in the thesis;
    off by default). ``label_smoothing``: the cross-entropy's target puts that mass uniformly
    over the classes (0: none, the thesis' loss). ``split_seed``: the seed of the validation
    hold-out (None: the run's seed), so runs of other seeds, e.g. the members of an ensemble,
    can share one validation split that none of them trained on. ``exclude``: names of original
    training shapes (e.g. ``chair_0001``) that are neither trained nor validated on, nor are
    their scaled copies: a network of another class list (ModelNet40) can then be measured on
    shapes it never saw (the validation shapes of a ModelNet10 run); each must name a training
    shape of the cache. ``mixup``: the ``alpha`` of mixup
    (:class:`~rgbd_rs.shapes.augment.MixedShapes`: each training item mixed with another, inputs
    and targets alike; 0: off, the default; not in the thesis)."""

    representations: tuple[str, ...] | None = None
    width: int = THESIS_WIDTH
    val_fraction: float = 0.1
    rotate: bool = False
    mirror: bool = False
    batch_norm: bool = False
    dropout: float = 0.0
    label_smoothing: float = 0.0
    split_seed: int | None = None
    exclude: tuple[str, ...] = ()
    mixup: float = 0.0

    def __post_init__(self) -> None:
        ex = self.exclude
        if isinstance(ex, str) or not isinstance(ex, (tuple, list, frozenset, set)):
            raise InvalidArgumentError(
                f"exclude: got {type(ex).__name__}, expected a list of shape names (str)"
            )
        bad = [x for x in ex if not isinstance(x, str) or not x]
        if bad:
            raise InvalidArgumentError(
                f"exclude: got {bad[0]!r}, expected shape names (non-empty str)"
            )
        object.__setattr__(self, "exclude", tuple(sorted(set(ex))))
        if self.split_seed is not None:
            _validate.integer("split_seed", self.split_seed, maximum=2**63 - 1)
        if self.representations is not None:
            object.__setattr__(
                self, "representations", _parse_representations(self.representations)
            )
        object.__setattr__(
            self, "width", _validate.integer("width", self.width, minimum=1, maximum=4096)
        )
        f = _validate.real("val_fraction", self.val_fraction, nonnegative=True)
        if f >= 1:
            raise InvalidArgumentError(
                f"val_fraction: got {self.val_fraction}, expected 0 <= val_fraction < 1"
            )
        object.__setattr__(self, "val_fraction", f)
        for name in ("rotate", "mirror", "batch_norm"):
            flag = getattr(self, name)
            if not isinstance(flag, bool):
                raise InvalidArgumentError(f"{name}: got {flag!r}, expected True or False")
        for name in ("dropout", "label_smoothing"):
            v = _validate.real(name, getattr(self, name), nonnegative=True)
            if v >= 1:
                raise InvalidArgumentError(
                    f"{name}: got {getattr(self, name)}, expected 0 <= {name} < 1"
                )
            object.__setattr__(self, name, v)
        m = _validate.real("mixup", self.mixup)
        if m != 0 and not MIN_MIXUP_ALPHA <= m <= MAX_MIXUP_ALPHA:
            raise InvalidArgumentError(
                f"mixup: got {self.mixup}, expected 0 (off) or "
                f"{MIN_MIXUP_ALPHA:g} <= mixup <= {MAX_MIXUP_ALPHA:g}"
            )
        object.__setattr__(self, "mixup", m)


def default_config(**overrides: Any) -> Any:
    """The recipe's :class:`~rgbd_rs.nn.train.TrainConfig`: SGD (thesis) with momentum 0.9,
    lr 0.01 halved every 10 epochs, weight decay 5e-4, batch 32, 30 epochs, a checkpoint every
    50 steps; ``overrides`` replace fields."""
    from rgbd_rs.nn.train import TrainConfig

    base: dict[str, Any] = {
        "epochs": 30,
        "batch_size": 32,
        "optimizer": "sgd",
        "lr": 0.01,
        "momentum": 0.9,
        "weight_decay": 5e-4,
        "lr_step": 10,
        "lr_gamma": 0.5,
        "checkpoint_steps": 50,
    }
    return TrainConfig(**(base | overrides))


def cross_entropy(
    output: torch.Tensor, batch: tuple[Any, ...], label_smoothing: float = 0.0
) -> torch.Tensor:
    """The trainer's loss: mean cross-entropy of the logits against ``batch[1]``, class
    indices or (mixup, :class:`~rgbd_rs.shapes.augment.MixedShapes`) a probability vector per
    item (with ``label_smoothing`` of the targets)."""
    loss: torch.Tensor = F.cross_entropy(output, batch[1], label_smoothing=label_smoothing)
    return loss


def accuracy(output: torch.Tensor, batch: tuple[Any, ...]) -> torch.Tensor:
    """The trainer's metric: the fraction of the batch whose highest score is its label, the
    largest entry of a probability target (what chooses ``best.pt``)."""
    labels: torch.Tensor = batch[1]
    if labels.ndim == 2:  # mixup's targets
        labels = labels.argmax(1)
    return (output.argmax(1) == labels).to(torch.float64).mean()


def _cache(cache: ShapeCache | str | os.PathLike[str]) -> ShapeCache:
    return cache if isinstance(cache, ShapeCache) else ShapeCache(cache)


def normalisation_of(cache: ShapeCache, representations: tuple[str, ...]) -> dict[str, Any]:
    """What inference must repeat (stored in the checkpoint): the input spec restricted to
    ``representations``, the class names, the data kind and its points per shape."""
    spec = cache.spec.to_dict() | {"representations": list(representations)}
    return {
        "spec": spec,
        "classes": list(cache.classes),
        "kind": cache.kind,
        "points_per_shape": cache.meta.get("points_per_shape"),
        "dataset": cache.meta.get("source"),
    }


def train_shapes(
    cache: ShapeCache | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    recipe: ShapeRecipe | None = None,
    config: Any | None = None,
    init: str | os.PathLike[str] | None = None,
    resume: bool = True,
    quiet: bool = False,
) -> Path:
    """Train on ``cache``'s training split; return the best checkpoint's path: the epoch of the
    highest validation accuracy (ties: the lower validation loss); the last one without
    validation. ``init`` starts from a checkpoint's weights (fine-tuning; from a network of
    other classes, every weight but the classifier's, which starts afresh: see
    :func:`_load_init` for what must match); a resumed run ignores it. Re-running
    resumes from ``out/last.pt`` (see :func:`rgbd_rs.nn.train.train`). A cache with training
    shapes still to compute raises :class:`RgbdError` (:meth:`ShapeCache.dataset`)."""
    from rgbd_rs.nn.train import TrainConfig, seed_everything, train

    quiet = _validate.flag("quiet", quiet)
    resume = _validate.flag("resume", resume)
    out = _validate.out_folder("out", out)

    c = _cache(cache)
    r = recipe if recipe is not None else ShapeRecipe()
    if not isinstance(r, ShapeRecipe):
        raise InvalidArgumentError(f"recipe: got {type(r).__name__}, expected a ShapeRecipe")
    cfg = config if config is not None else default_config()
    if not isinstance(cfg, TrainConfig):
        raise InvalidArgumentError(f"config: got {type(cfg).__name__}, expected a TrainConfig")
    reps = r.representations or c.spec.representations
    data = c.dataset("train", reps)
    train_set: Any = data
    val_set: Any = None
    if r.val_fraction > 0:
        if len(data) < 2:
            raise RgbdError(f"{c.path}: {len(data)} training shape(s), too few to validate")
        split_seed = cfg.seed if r.split_seed is None else r.split_seed
        train_set, val_set = _split_by_shape(c, data, r.val_fraction, split_seed)
    if r.exclude:
        train_set = _without(c, data, train_set, r.exclude)
        val_set = (
            None
            if val_set is None
            else _without(c, data, val_set, r.exclude, check=False, what="validation")
        )
    if r.rotate or r.mirror:
        train_set = AugmentedShapes(train_set, data.shapes, turns=r.rotate, mirror=r.mirror)
    if r.mixup > 0:
        train_set = MixedShapes(train_set, len(c.classes), r.mixup)
    seed_everything(cfg.seed)  # the initial weights come from the seed too
    model = ShapeNet(
        len(c.classes),
        representations=reps,
        view_resolution=c.spec.view_resolution,
        volume_resolution=c.spec.volume_resolution,
        width=r.width,
        batch_norm=r.batch_norm,
        dropout=r.dropout,
    )
    if init is not None and not (resume and (out / "last.pt").is_file()):  # resume: last.pt's
        _load_init(model, init, normalisation_of(c, reps))
    result = train(
        model,
        train_set,
        val_set,
        functools.partial(cross_entropy, label_smoothing=r.label_smoothing),
        cfg,
        out,
        arch=ARCH,
        arch_config=model.arch_config(),
        # what shapes training but not the network is recorded (when not the default), so a
        # resume with another exclude list, split, augmentation or loss is refused
        normalisation=normalisation_of(c, reps) | _recorded(r, out if resume else None),
        quiet=quiet,
        resume=resume,
        metric_fn=accuracy,
    )
    return Path(result.best_checkpoint or result.last_checkpoint)


#: The recipe's fields that shape training but not the network (a resume must repeat them).
_TRAINING_FIELDS = ("val_fraction", "split_seed", "rotate", "mirror", "label_smoothing", "mixup")


def _recorded(r: ShapeRecipe, resuming: Path | None = None) -> dict[str, Any]:
    """What a run's checkpoints record of recipe ``r`` beside the input statistics: ``exclude``
    and ``recipe`` (the :data:`_TRAINING_FIELDS` not at their defaults), each only when used, so
    checkpoints of runs that left them at their defaults read as before. A run being resumed
    from ``resuming/last.pt`` written before ``recipe`` was recorded keeps its record (its
    recipe cannot be checked; a warning says so)."""
    default = ShapeRecipe()
    changed = {k: getattr(r, k) for k in _TRAINING_FIELDS if getattr(r, k) != getattr(default, k)}
    out = ({"exclude": list(r.exclude)} if r.exclude else {}) | (
        {"recipe": changed} if changed else {}
    )
    last = None if resuming is None else resuming / "last.pt"
    if changed and last is not None and last.is_file() and "recipe" not in _stored_norm(last):
        warnings.warn(
            f"{last}: written before runs recorded their recipe; resuming it without checking "
            f"that it was trained with {changed}",
            RuntimeWarning,
            stacklevel=3,
        )
        del out["recipe"]
    return out


def _stored_norm(path: Path) -> dict[str, Any]:
    """The ``normalisation`` record of checkpoint ``path`` ({} when it cannot be read: the
    trainer's own reading then says why)."""
    from rgbd_rs.nn.checkpoint import load_checkpoint

    try:
        return dict(load_checkpoint(path, map_location="cpu").normalisation)
    except RgbdError:
        return {}


#: The architecture settings an init must share with the run, and the flag that sets each
#: (``dropout`` has no weights: a run may add or change it).
_ARCH_FLAGS = {"width": "--width", "batch_norm": "--batch-norm"}


def _load_init(
    model: ShapeNet, init: str | os.PathLike[str], normalisation: dict[str, Any]
) -> None:
    """Start ``model`` from the network of checkpoint ``init``. It must have been trained on
    inputs of the cache's spec (view and volume resolution, representations, normalisation) and
    with the run's width and batch normalisation (dropout may differ: it has no weights). Of
    the same classes, in any order, every weight is taken (the classifier's rows by class
    name). Of other classes (a ModelNet40 network fine-tuned on ModelNet10, or classes the cache
    does not have at all), every weight but the classifier's is taken and the classifier keeps
    the fresh weights the run's seed gave it: transfer to a new class list."""
    from rgbd_rs.nn.checkpoint import load_checkpoint

    start = load_checkpoint(
        _validate.path("init", init), arch=ARCH, normalisation_keys=("spec", "classes")
    )
    if "members" in start.arch_config:
        raise InvalidArgumentError(
            f"init: got {start.path}, an ensemble of {start.arch_config['members']} "
            "networks; expected one network's checkpoint (a member's own run)"
        )
    theirs, ours = start.normalisation["spec"], normalisation["spec"]
    differ = [
        f"{k} {theirs.get(k)!r} in the network, {ours.get(k)!r} in this run"
        for k in sorted(set(theirs) | set(ours))
        if theirs.get(k) != ours.get(k)
    ]
    if differ:
        raise InvalidArgumentError(
            f"init: got {start.path}, a network of other inputs ({'; '.join(differ)}); "
            "expected one trained on a cache of the same settings and --representations"
        )
    mine, arch = model.arch_config(), start.arch_config
    differ = [
        f"{k} {arch.get(k, False)!r} in the network, {mine.get(k, False)!r} in this run "
        f"(pass {flag} as it was trained)"
        for k, flag in _ARCH_FLAGS.items()
        if arch.get(k, False) != mine.get(k, False)
    ]
    if differ:
        raise InvalidArgumentError(f"init: got {start.path}, {'; '.join(differ)}")
    classes, own = list(start.normalisation["classes"]), list(normalisation["classes"])
    state = {k: v for k, v in start.model_state.items() if not k.startswith("classifier.")}
    if sorted(classes) == sorted(own):  # the same classes (a cache names each once)
        rows = start.model_state["classifier.weight"]
        state["classifier.weight"] = rows[[classes.index(c) for c in own]]
    missing, unexpected = model.load_state_dict(state, strict=False)
    if unexpected or set(missing) - {"classifier.weight"}:
        raise RgbdError(
            f"{start.path}: weights do not fit the model (missing {missing}, "
            f"unexpected {unexpected})"
        )


def _without(
    cache: ShapeCache,
    data: Any,
    subset: Any,
    names: Sequence[str],
    *,
    check: bool = True,
    what: str = "training",
) -> Subset[Any]:
    """``subset`` of ``data`` (or ``data`` itself) less the rows whose original shape is named
    in ``names``; with ``check``, every name must be an original training shape of ``cache``."""
    positions = list(subset.indices) if isinstance(subset, Subset) else list(range(len(data)))
    rows = np.asarray(data.indices, np.int64)
    origin = original_rows(cache.meta.get("augmentation"), cache.splits)[rows]
    drop = set(names)
    if check:
        originals = [cache.names[o] for o in sorted(set(origin.tolist()))]
        missing = sorted(drop - set(originals))
        if missing:
            copies = [n for n in missing if original_name(n) != n]
            hint = f"; {copies[0]!r} is a scaled copy: name its original" if copies else ""
            raise InvalidArgumentError(
                f"exclude: {len(missing)} name(s) are not training shapes of {cache.path} "
                f"(e.g. {missing[:3]}), expected names from its names.json with split 0{hint}"
            )
        count = Counter(originals)
        twice = sorted(n for n in drop if count[n] > 1)
        if twice:
            raise InvalidArgumentError(
                f"exclude: {twice[0]!r} names {count[twice[0]]} training shapes of "
                f"{cache.path}, expected names that each name one shape"
            )
    keep = [p for p in positions if cache.names[int(origin[p])] not in drop]
    if not keep:
        raise RgbdError(f"{cache.path}: no {what} shape is left once exclude is applied")
    return Subset(data, keep)


def _split_by_shape(
    cache: ShapeCache, data: Any, fraction: float, seed: int
) -> tuple[Subset[Any], Subset[Any]]:
    """(train, validation) subsets of ``data``. Without scaled copies in the cache (its
    meta.json has no ``augmentation``) this is :func:`rgbd_rs.nn.train.split`; with them (see
    :mod:`rgbd_rs.shapes.scaling`) the split is drawn over the original shapes, a validation
    shape's copies are left out, and every copy follows its original into training."""
    from rgbd_rs.nn.train import split

    augmentation = cache.meta.get("augmentation")
    if not augmentation:
        return split(data, fraction, seed=seed)
    rows = np.asarray(data.indices, np.int64)
    origin = original_rows(augmentation, cache.splits)[rows]
    originals = np.flatnonzero(origin == rows).tolist()
    if len(originals) < 2:
        raise RgbdError(
            f"{cache.path}: {len(originals)} original training shape(s) (+"
            f"{len(rows) - len(originals)} scaled copies), too few to validate; train with "
            "val_fraction=0"
        )
    _, val = split(Subset(data, originals), fraction, seed=seed)
    val_pos = [originals[j] for j in val.indices]
    held = set(rows[val_pos].tolist())
    train_pos = [i for i, o in enumerate(origin.tolist()) if o not in held]
    return Subset(data, train_pos), Subset(data, val_pos)


def ablation_rows(available: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """Table 5.2's rows over the ``available`` representations: each alone, then combined (the
    combined row only when there are two or more)."""
    reps = _parse_representations(available)
    rows: dict[str, tuple[str, ...]] = {name: (name,) for name in reps}
    if len(reps) > 1:
        rows[COMBINED] = reps
    return rows


def train_ablation(
    cache: ShapeCache | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    recipe: ShapeRecipe | None = None,
    config: Any | None = None,
    resume: bool = True,
    quiet: bool = False,
) -> dict[str, Path]:
    """One :func:`train_shapes` per row of :func:`ablation_rows` (the recipe's representations,
    default every cached one) into ``out/<row>/``; returns each row's best checkpoint."""
    c = _cache(cache)
    r = recipe if recipe is not None else ShapeRecipe()
    if not isinstance(r, ShapeRecipe):
        raise InvalidArgumentError(f"recipe: got {type(r).__name__}, expected a ShapeRecipe")
    out_dir = Path(out)
    best: dict[str, Path] = {}
    for row, reps in ablation_rows(r.representations or c.spec.representations).items():
        row_recipe = dataclasses.replace(r, representations=reps)
        best[row] = train_shapes(
            c, out_dir / row, recipe=row_recipe, config=config, resume=resume, quiet=quiet
        )
    return best


def ship(checkpoint: str | os.PathLike[str], dest: str | os.PathLike[str] | None = None) -> Path:
    """Write the inference-only, float16 copy of ``checkpoint`` (a few MB) to ``dest``, by default
    the package's shipped weights for its dataset (``rgbd_rs/nn/weights/shapes_<dataset>.pt``)."""
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.shapes.classify import WEIGHT_FILES, _weights_path

    ckpt = load_checkpoint(checkpoint, arch=ARCH, normalisation_keys=("spec", "classes"))
    half = {k: v.half() if v.is_floating_point() else v for k, v in ckpt.model_state.items()}
    light = dataclasses.replace(ckpt.stripped(), model_state=half)
    if dest is None:
        n = len(ckpt.normalisation["classes"])
        if f"modelnet{n}" not in WEIGHT_FILES:
            raise InvalidArgumentError(
                f"dest: none given for a {n}-class checkpoint, expected a path (the package "
                f"ships {sorted(WEIGHT_FILES)} only)"
            )
        dest = _weights_path(f"modelnet{n}")
    return save_checkpoint(light, dest)


def ship_ensemble(
    checkpoints: Sequence[str | os.PathLike[str]], dest: str | os.PathLike[str]
) -> Path:
    """Write one inference-only, float16 checkpoint holding the networks of ``checkpoints``
    (2 or more ``rgbd train shapes`` runs of one architecture, input spec and class list) as a
    :class:`~rgbd_rs.nn.shape_ensemble.ShapeEnsemble`: ``ShapeClassifier.load(dest)``,
    ``classify(..., checkpoint=dest)`` and ``rgbd classify / eval shapes --checkpoint dest``
    average their class probabilities. The first checkpoint's metadata (spec, classes, history)
    is kept."""
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.nn.shape_ensemble import MAX_MEMBERS

    if isinstance(checkpoints, (str, os.PathLike)) or not isinstance(checkpoints, Sequence):
        raise InvalidArgumentError(
            f"checkpoints: got {type(checkpoints).__name__}, expected a list of checkpoint paths"
        )
    if not 2 <= len(checkpoints) <= MAX_MEMBERS:
        raise InvalidArgumentError(
            f"checkpoints: got {len(checkpoints)}, expected 2 to {MAX_MEMBERS} checkpoints"
        )
    ckpts = [
        load_checkpoint(p, arch=ARCH, normalisation_keys=("spec", "classes")) for p in checkpoints
    ]
    first = ckpts[0]
    for c in ckpts[1:]:
        if "members" in c.arch_config or c.arch_config != first.arch_config:
            raise InvalidArgumentError(
                f"checkpoints: {c.path} has arch_config {c.arch_config}, expected "
                f"{first.path}'s {first.arch_config} (one architecture, no nested ensembles)"
            )
        for key in ("spec", "classes", "kind", "points_per_shape"):
            if c.normalisation.get(key) != first.normalisation.get(key):
                raise InvalidArgumentError(
                    f"checkpoints: {c.path} has another {key!r} than {first.path}"
                )
    state = {
        f"members.{i}.{k}": v.half() if v.is_floating_point() else v
        for i, c in enumerate(ckpts)
        for k, v in c.model_state.items()
    }
    config = {"members": len(ckpts), "member": first.arch_config}
    light = dataclasses.replace(first.stripped(), model_state=state, arch_config=config)
    return save_checkpoint(light, _validate.path("dest", dest))
