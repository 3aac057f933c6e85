"""``rgbd train confidence``: train the ToF + stereo confidence ConvNet (thesis §3.6-3.7);
``rgbd train calibrate-confidence``: choose its stereo power for LC on validation scenes."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Literal

from rgbd_rs.cli._args import Commands, fail, folder, integer, named, real, shard
from rgbd_rs.errors import InvalidArgumentError


def register(commands: Commands) -> None:
    """Add ``rgbd train confidence``."""
    p = commands.group_command(
        "train",
        "confidence",
        run_train,
        help="train the ToF + stereo confidence ConvNet",
        description="Train the confidence ConvNet of thesis §3.6 on a `rgbd synth --vary-tof` "
        "dataset, validating on the Middlebury pairs with simulated ToF (never trained on). "
        "Clue caches go to OUT/cache (resumable; --shard i/n fans the caching out), checkpoints "
        "to OUT/last.pt and OUT/best.pt; re-running the same command resumes. Runs under "
        "torchrun for DistributedDataParallel training. --ship writes the best checkpoint's "
        "inference-only copy to python/rgbd_rs/nn/weights/confidence.pt.",
    )
    p.add_argument("--data", type=Path, required=True, help="rgbd synth dataset folder")
    p.add_argument(
        "--out",
        type=folder,
        default=Path("out/train_confidence"),
        help="output folder (out/train_confidence)",
    )
    p.add_argument("--width", type=integer(1, 1024), default=32, help="filters per layer (32)")
    p.add_argument("--epochs", type=integer(1), default=10, help="epochs (10)")
    p.add_argument("--batch-size", type=integer(1), default=16, help="patches per step (16)")
    p.add_argument("--lr", type=real(0, 10), default=1e-3, help="Adam learning rate (1e-3)")
    p.add_argument("--patch", type=integer(8, 1024), default=64, help="patch side (64)")
    p.add_argument("--per-scene", type=integer(1), default=30, help="patches per scene (30)")
    p.add_argument("--seed", type=integer(0, 2**32 - 1), default=0, help="seed (0)")
    p.add_argument(
        "--target-t",
        type=real(0, 3),
        default=3.0,
        help="error (px) at which the target confidence reaches 0 (3; at most 3)",
    )
    p.add_argument(
        "--disagreement-weight",
        type=real(0, 1000, low_open=False),
        default=0.0,
        help="extra loss weight on pixels where ToF and stereo errors differ by > 1 px "
        "(0: the thesis' plain MSE)",
    )
    p.add_argument("--init", type=Path, help="start from this checkpoint's weights (fine-tune)")
    p.add_argument(
        "--checkpoint-steps", type=integer(0), default=50, help="also save every N steps (50)"
    )
    p.add_argument(
        "--shard",
        type=shard,
        default=None,
        help="only cache the clues of every n-th scene from i (i/n), then stop",
    )
    p.add_argument(
        "--ship",
        action="store_true",
        help="write the best checkpoint's inference-only copy over the package's shipped weights",
    )
    p.add_argument(
        "--no-resume",
        action="store_true",
        help="start afresh in OUT, overwriting its checkpoints (default: resume from OUT/last.pt)",
    )
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress (a bar on a terminal, otherwise one line per epoch on stderr)",
    )
    register_calibration(commands)


def register_calibration(commands: Commands) -> None:
    """Add ``rgbd train calibrate-confidence``."""
    p = commands.group_command(
        "train",
        "calibrate-confidence",
        run_calibrate,
        help="choose the confidence ConvNet's stereo power for the LC fusion",
        description="Fuse validation scenes (a `rgbd synth` folder's test split; never the "
        "scenes you report on) with the stereo confidence raised to each power, pick the lowest "
        "mean fused/better-input RMS ratio among the powers that never make a good input (95 % "
        "of pixels within 1 px) more than 5 % worse, and write a copy of the checkpoint holding "
        "it. Prints the table of every power. --ship writes it over the package's weights.",
    )
    p.add_argument("--data", type=Path, required=True, help="validation `rgbd synth` folder")
    p.add_argument(
        "--checkpoint", type=Path, help="checkpoint to calibrate (default: the shipped one)"
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("out/confidence_calibrated.pt"),
        help="calibrated copy (out/confidence_calibrated.pt)",
    )
    p.add_argument(
        "--powers",
        type=real(0, 100),
        nargs="+",
        default=None,
        help="powers to try (default 1 1.5 2 3 4)",
    )
    p.add_argument("--ship", action="store_true", help="also write it over the shipped weights")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _require_scenes(data: Path, split: Literal["train", "test"]) -> None:
    """Refuse a ``--data`` set whose ``split`` has no scene (before any work)."""
    from rgbd_rs.data.synth import SynthDataset

    ds = named("--data", lambda: SynthDataset(data, split))
    if len(ds) == 0:
        raise InvalidArgumentError(
            f"--data: got {data} with no {split} scene, expected at least one (rgbd synth "
            f"--{split} N)"
        )


def run_train(args: argparse.Namespace) -> int:
    from rgbd_rs.nn.confidence_train import (
        Recipe,
        prepare_caches,
        recipe_config,
        ship,
        train_confidence,
    )
    from rgbd_rs.nn.train import is_main_process

    if not (args.data / "manifest.json").is_file():
        return fail(
            f"--data: got {args.data}, expected a dataset folder of `rgbd synth` (it has no "
            "manifest.json)"
        )
    _require_scenes(args.data, "train")
    if args.shard is not None:
        train, val = prepare_caches(
            args.data, args.out / "cache", shard=args.shard, quiet=args.quiet
        )
        print(f"cached {len(train)} training and {len(val)} validation scenes (shard {args.shard})")
        return 0
    config = recipe_config(args.epochs, args.batch_size, args.lr, args.seed, args.checkpoint_steps)
    recipe = Recipe(
        width=args.width,
        patch=args.patch,
        per_scene=args.per_scene,
        target_t=args.target_t,
        disagreement_weight=args.disagreement_weight,
    )
    best = train_confidence(
        args.data,
        args.out,
        recipe=recipe,
        config=config,
        init=args.init,
        resume=not args.no_resume,
        quiet=args.quiet,
    )
    if not is_main_process():  # under torchrun, rank 0 reports and ships
        return 0
    print(f"best checkpoint: {best}")
    if args.ship:
        print(f"shipped weights: {ship(best)}")
    return 0


def run_calibrate(args: argparse.Namespace) -> int:
    from rgbd_rs.fusion.calibrate import POWERS, calibrate_stereo_power, write_calibrated
    from rgbd_rs.fusion.evaluate import synth_samples
    from rgbd_rs.nn.confidence import WEIGHTS, ConfidenceEstimator

    if args.out.is_dir():  # before the scenes are fused
        return fail(f"--out: got {args.out}, a folder; expected the calibrated checkpoint's file")
    _require_scenes(args.data, "test")
    source = WEIGHTS if args.checkpoint is None else args.checkpoint
    estimator = ConfidenceEstimator.load(source)
    result = calibrate_stereo_power(
        estimator,
        synth_samples(args.data, "test"),
        powers=POWERS if args.powers is None else args.powers,
        quiet=args.quiet,
    )
    print(result.markdown())
    print(f"chosen power: {result.power:g}")
    if not result.within_limit:
        import warnings

        from rgbd_rs.fusion.calibrate import MAX_DAMAGE

        warnings.warn(
            f"no power keeps every good validation input within {MAX_DAMAGE:g} x its RMS; "
            f"{result.power:g} damages them least: the fusion may be worse than a clean input "
            "(more validation scenes, or another checkpoint, may help)",
            RuntimeWarning,
            stacklevel=1,
        )
    print(f"calibrated checkpoint: {write_calibrated(source, result.power, args.out)}")
    if args.ship:
        print(f"shipped weights: {write_calibrated(source, result.power, WEIGHTS)}")
    return 0
