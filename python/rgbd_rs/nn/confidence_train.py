"""Training recipe of the confidence ConvNet (``rgbd train confidence``), thesis §3.7 adapted.

1. Cache the clues and targets of every training scene of a ``rgbd synth --vary-tof`` dataset
   (:func:`rgbd_rs.nn.confidence_data.prepare`; resumable, shardable) and of the held-out
   validation set: the Middlebury pairs with simulated ToF, which the training never sees.
2. sigma of eq. 3.3-3.6 from the training scenes; random ``patch``-pixel crops with flips.
3. :func:`rgbd_rs.nn.train.train` (checkpoints, resume, DDP): masked MSE, Adam by default (the
   thesis' SGD at lr 1e-7 needs far more steps than a CPU run allows), LR x0.9 every 10 epochs.
The best checkpoint (lowest validation loss) is what ships in ``rgbd_rs/nn/weights``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rgbd_rs.data.paths import data_root
from rgbd_rs.errors import RgbdError
from rgbd_rs.fusion.evaluate import ORACLE_T as TARGET_T

#: Middlebury scenes of the shared data (validation only).
MIDDLEBURY = ("Cones", "Reindeer", "Wood2")


@dataclass(frozen=True)
class Recipe:
    """What ``rgbd train confidence`` varies; the rest is :class:`~rgbd_rs.nn.train.TrainConfig`."""

    width: int = 32
    patch: int = 64
    per_scene: int = 30
    val_tile: int = 128
    #: Error (px) at which the target confidence reaches 0 (at most the caches' TARGET_T).
    target_t: float = TARGET_T
    #: Extra loss weight where the sources disagree (DisagreementMSE; 0 = the thesis' MSE).
    disagreement_weight: float = 0.0


def recipe_config(
    epochs: int, batch_size: int, lr: float, seed: int, checkpoint_steps: int = 0
) -> object:
    """The recipe's :class:`~rgbd_rs.nn.train.TrainConfig`: Adam, the learning rate x0.9 every
    10 epochs."""
    from rgbd_rs.nn.train import TrainConfig

    return TrainConfig(
        epochs=epochs,
        batch_size=batch_size,
        optimizer="adam",
        lr=lr,
        lr_step=10,
        lr_gamma=0.9,
        seed=seed,
        checkpoint_steps=checkpoint_steps,
    )


def prepare_caches(
    data: Path, cache: Path, *, shard: tuple[int, int] = (0, 1), quiet: bool = False
) -> tuple[list[Path], list[Path]]:
    """Clue caches of the training scenes of ``data`` and of the Middlebury validation scenes."""
    from rgbd_rs.fusion.evaluate import middlebury_sample, synth_samples
    from rgbd_rs.nn.confidence_data import prepare

    train = prepare(synth_samples(data, "train"), cache / "train", shard=shard, quiet=quiet)
    root = data_root()
    val: list[Path] = []
    if root is not None and (root / "middlebury").is_dir():
        samples = (
            middlebury_sample(root / "middlebury" / name)
            for name in MIDDLEBURY
            if (root / "middlebury" / name).is_dir()
        )
        val = prepare(samples, cache / "middlebury", shard=shard, quiet=quiet)
    return train, val


def train_confidence(
    data: str | Path,
    out: str | Path,
    *,
    recipe: Recipe | None = None,
    config: object | None = None,
    cache: str | Path | None = None,
    init: str | Path | None = None,
    resume: bool = True,
    quiet: bool = False,
) -> Path:
    """Prepare (or reuse) the caches, train, and return the best checkpoint's path. ``init``
    starts from a checkpoint's weights (fine-tuning) instead of Xavier initialisation."""
    out = Path(out)
    cache_dir = Path(cache) if cache is not None else out / "cache"
    train_files, val_files = prepare_caches(Path(data), cache_dir, quiet=quiet)
    return train_on_caches(
        train_files,
        val_files,
        out,
        recipe=recipe,
        config=config,
        init=init,
        resume=resume,
        quiet=quiet,
    )


def train_on_caches(
    train_files: list[Path],
    val_files: list[Path],
    out: str | Path,
    *,
    recipe: Recipe | None = None,
    config: object | None = None,
    init: str | Path | None = None,
    resume: bool = True,
    quiet: bool = False,
    matcher: str = "opencv",
) -> Path:
    """Train on clue caches written by :func:`~rgbd_rs.nn.confidence_data.prepare` (with
    ``matcher``'s stereo disparities, recorded in the checkpoint) and return the best
    checkpoint's path (lowest validation loss; the last one without validation files)."""
    import numpy as np

    from rgbd_rs.nn.confidence import ARCH, MATCHER_KEY, MATCHERS, ConfidenceNet
    from rgbd_rs.nn.confidence_data import (
        DisagreementMSE,
        PatchDataset,
        TileDataset,
        _masked_mse,
        _sigmas_of,
        load_scenes,
    )
    from rgbd_rs.nn.train import TrainConfig, seed_everything, train

    r = recipe or Recipe()
    cfg = config if config is not None else TrainConfig()
    if not isinstance(cfg, TrainConfig):
        raise RgbdError(f"config: got {type(cfg).__name__}, expected a TrainConfig")
    if matcher not in MATCHERS:
        raise RgbdError(f"matcher: got {matcher!r}, expected one of {MATCHERS}")
    out = Path(out)
    scenes = load_scenes(sorted(train_files))
    sig = _sigmas_of(scenes)
    train_set = PatchDataset(
        scenes,
        sig,
        patch=r.patch,
        per_scene=r.per_scene,
        seed=cfg.seed,
        target_t=r.target_t,
    )
    val_set = (
        TileDataset(load_scenes(sorted(val_files)), sig, tile=r.val_tile, target_t=r.target_t)
        if val_files
        else None
    )
    seed_everything(cfg.seed)  # the initial weights come from the seed too
    model = ConfidenceNet(r.width)
    if init is not None:
        from rgbd_rs.nn.checkpoint import load_checkpoint

        load_checkpoint(init, arch=ARCH).load_weights(model)
    loss = (
        DisagreementMSE(r.disagreement_weight, r.target_t) if r.disagreement_weight else _masked_mse
    )
    result = train(
        model,
        train_set,
        val_set,
        loss,
        cfg,
        out,
        arch=ARCH,
        arch_config={"width": r.width},
        normalisation={
            "sigmas": [float(v) for v in np.asarray(sig)],
            "target_t": r.target_t,
            MATCHER_KEY: matcher,
        },
        quiet=quiet,
        resume=resume,
    )
    return Path(result.best_checkpoint or result.last_checkpoint)


def ship(checkpoint: str | Path, dest: str | Path | None = None) -> Path:
    """Write the inference-only copy of ``checkpoint`` (no optimizer or RNG state) to ``dest``,
    by default the weights the package ships (``rgbd_rs/nn/weights/confidence.pt``)."""
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.nn.confidence import ARCH, WEIGHTS

    ckpt = load_checkpoint(checkpoint, arch=ARCH, normalisation_keys=("sigmas",))
    return save_checkpoint(ckpt.stripped(), WEIGHTS if dest is None else dest)
