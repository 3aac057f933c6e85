"""``rgbd semantic cache``, ``rgbd semantic score``, ``rgbd train semantic``: the semantic
ConvNet's data and training commands (thesis §4.6, §4.8)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rgbd_rs.cli._args import (
    Commands,
    Parser,
    device,
    fail,
    folder,
    integer,
    named,
    real,
    shard,
    training_run_options,
)


def register(commands: Commands) -> None:
    """Add ``rgbd semantic cache``, ``rgbd semantic score`` and ``rgbd train semantic``."""
    top = commands.command(
        "semantic",
        lambda args: 2,
        help="semantic ConvNet data tools (rgbd semantic cache / score)",
        description="Semantic-labeling ConvNet (thesis §4.6) data tools.",
    )
    sub = top.add_subparsers(dest="semantic", metavar="WHAT", required=True, parser_class=Parser)
    _cache(sub)
    _score(sub)
    _train(commands)


def size_arg(text: str) -> tuple[int, int]:
    """Parse ``WxH`` (e.g. ``320x240``) into (width, height), both multiples of 4 >= 4."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"got {text!r}, expected WxH (e.g. 320x240)") from None
    if w < 4 or h < 4 or w % 4 or h % 4 or max(w, h) > 8192:
        raise argparse.ArgumentTypeError(
            f"got {text!r}, expected sides that are multiples of 4 between 4 and 8192"
        )
    return w, h


def _cache(sub: argparse._SubParsersAction[Parser]) -> None:
    p = sub.add_parser(
        "cache",
        help="precompute the ConvNet's 9 cues and labels of labeled frames",
        description="Compute every frame's 9 cues of eq. 4.2 (colour, HHA, fitting error and "
        "principal curvatures of the over-segmentation's spline fits) at full size, reduce "
        "them (block means) and the labels (block majority of labeled pixels) to --size, and "
        "store them in DIR as memory-mappable float16 / uint8 arrays. Resumable (re-run to "
        "continue) and sharded: --shard i/n computes every n-th frame from i, so n processes "
        "fill one cache. A folder holding a cache of other frames or settings is refused.",
    )
    p.set_defaults(run=run_cache)
    p.add_argument(
        "--frames",
        required=True,
        metavar="SRC",
        help="nyuv2 (the shared NYUv2 frames), the official nyu_depth_v2_labeled.mat (795/654 "
        "split), a folder in the NYUv2 layout, a folder of synthetic "
        "indoor frames (rgbd synth-indoor) or a folder of NAME_{rgb,depth,label13}.png with a "
        "camera.json (or --calib)",
    )
    p.add_argument(
        "--split",
        choices=("train", "test", "all"),
        default=None,
        help="NYUv2 split (default train, so evaluation frames never reach training; of the "
        ".mat: the official 795/654); other folders have only all (their default)",
    )
    p.add_argument("--out", type=folder, required=True, metavar="DIR", help="cache folder")
    p.add_argument(
        "--size",
        type=size_arg,
        default=(320, 240),
        metavar="WxH",
        help="network input size (default 320x240, the thesis'; the shipped network, which "
        "`rgbd semantic score` uses without --checkpoint, takes 160x120)",
    )
    p.add_argument("--calib", type=Path, metavar="FILE", help="camera JSON of a frame folder")
    p.add_argument(
        "--shard", type=shard, default=(0, 1), metavar="i/n", help="compute shard i of n (i/n)"
    )
    p.add_argument(
        "--seed", type=integer(0, 2**32 - 1), default=0, metavar="N", help="cue seed (0)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run_cache(args: argparse.Namespace) -> int:
    from rgbd_rs.segmentation.semantic_data import build_semantic_cache, open_frames

    if args.split is None:
        from rgbd_rs.segmentation.semantic_data import _frames_have_splits

        args.split = "train" if _frames_have_splits(args.frames, args.calib) else "all"
    frames = named("--frames", lambda: open_frames(args.frames, args.split, args.calib))
    source = (
        f"nyuv2-{args.split}"
        if args.frames.lower() == "nyuv2"
        else f"{Path(args.frames).resolve().stem}-{args.split}"
    )
    before = 0
    if (args.out / "done.npy").is_file():
        from rgbd_rs.segmentation.semantic_data import SemanticCache

        before = int((named("--out", lambda: SemanticCache(args.out)).done != 0).sum())
    t0 = time.perf_counter()
    cache = build_semantic_cache(
        frames, args.out, size=args.size, shard=args.shard, seed=args.seed, source=source,
        quiet=args.quiet,
    )  # fmt: skip
    seconds = time.perf_counter() - t0
    done = cache.done
    made = int((done != 0).sum()) - before
    rate = f", {seconds / made:.1f} s per frame" if made > 0 else ""
    print(
        f"{args.out}: {int((done == 1).sum())}/{len(cache)} frames done, "
        f"{int((done == 2).sum())} failed; this run computed {made} in {seconds:.1f} s{rate}"
    )
    if (done == 2).any() and not (done == 1).any():
        return fail(f"--frames: every frame failed (see the warnings); {args.out} holds none")
    return 0


def _score(sub: argparse._SubParsersAction[Parser]) -> None:
    p = sub.add_parser(
        "score",
        help="pixel and class accuracy of a semantic ConvNet on a cache",
        description="Per-pixel accuracy of a checkpoint (default: the shipped weights) on a "
        "`rgbd semantic cache` folder, at the cache's resolution, labeled pixels only: pixel "
        "accuracy, mean class accuracy and per-class accuracy.",
    )
    p.set_defaults(run=run_score)
    p.add_argument("--cache", type=Path, required=True, metavar="DIR", help="cache folder")
    p.add_argument("--checkpoint", type=Path, metavar="FILE", help="(default: shipped weights)")
    p.add_argument(
        "--device",
        type=device(auto=False),
        default="cpu",
        metavar="DEV",
        help="cpu, cuda or cuda:N (cpu)",
    )


def run_score(args: argparse.Namespace) -> int:
    from rgbd_rs.segmentation.labeling import _weights_path
    from rgbd_rs.segmentation.semantic_data import SemanticCache
    from rgbd_rs.segmentation.semantic_train import score

    cache = named("--cache", lambda: SemanticCache(args.cache))
    named("--cache", cache.require_complete)
    ckpt = args.checkpoint if args.checkpoint is not None else _weights_path()
    if args.checkpoint is None:
        from rgbd_rs.segmentation.labeling import SemanticLabeler

        size = SemanticLabeler.load().input_size
        if tuple(size) != tuple(cache.size):
            return fail(
                f"--cache: got a cache of {cache.size[0]}x{cache.size[1]} inputs, expected "
                f"{size[0]}x{size[1]}, the shipped network's (build one with `rgbd semantic "
                f"cache --size {size[0]}x{size[1]}`, or pass --checkpoint)"
            )
    res = named("--checkpoint", lambda: score(ckpt, cache, device=args.device))
    print(f"{ckpt} on {args.cache} ({len(cache.indices())} frames): {res.summary()}")
    for name, acc in zip(res.classes, res.per_class, strict=True):
        if acc == acc:  # not NaN: the class occurs
            print(f"  {acc:6.1%}  {name}")
    return 0


def _train(commands: Commands) -> None:
    p = commands.group_command(
        "train",
        "semantic",
        run_train,
        help="train the semantic-labeling ConvNet",
        description="Train the ConvNet of thesis §4.6 on a `rgbd semantic cache` folder: "
        "cross-entropy over the labeled pixels, SGD with weight decay 0.001, lr 0.01 times 0.7 "
        "after 10 epochs without a validation gain (§4.8). --val-fraction of the frames (or "
        "--val-cache) validates. --init CKPT fine-tunes a pre-trained network (same width, "
        "input size and classes). Checkpoints go to last.pt (every epoch and every "
        "--checkpoint-steps steps) and best.pt in --out; re-running the same command resumes. "
        "Runs under torchrun for DistributedDataParallel training. --ship writes the best "
        "checkpoint's inference-only float16 copy into the package's weights.",
    )
    p.add_argument("--cache", type=Path, required=True, metavar="DIR", help="cache folder")
    p.add_argument(
        "--out",
        type=folder,
        default=Path("out/train_semantic"),
        metavar="DIR",
        help="output folder (out/train_semantic)",
    )
    p.add_argument(
        "--val-cache", type=Path, metavar="DIR", help="validate on this cache's frames instead"
    )
    p.add_argument(
        "--val-fraction",
        type=real(0, 0.9, low_open=False),
        default=0.2,
        metavar="X",
        help="fraction of the frames held out for validation (0.2; 0 = none)",
    )
    p.add_argument(
        "--width",
        type=integer(1, 4096),
        default=256,
        metavar="N",
        help="last block's filters (256, thesis; 90/128/256 scale with it)",
    )
    p.add_argument("--epochs", type=integer(1), default=100, metavar="N", help="epochs (100)")
    p.add_argument(
        "--batch-size", type=integer(1), default=4, metavar="N", help="frames per step (4)"
    )
    p.add_argument("--lr", type=real(0, 10), default=0.01, metavar="X", help="SGD lr (0.01)")
    p.add_argument(
        "--momentum", type=real(0, 0.999, low_open=False), default=0.0, metavar="X", help="(0)"
    )
    p.add_argument(
        "--weight-decay", type=real(0, 1, low_open=False), default=1e-3, metavar="X", help="(1e-3)"
    )
    p.add_argument(
        "--plateau",
        type=integer(1),
        default=10,
        metavar="N",
        help="multiply lr by 0.7 after N epochs without validation gain (10)",
    )
    p.add_argument(
        "--grad-clip",
        type=real(0, 1e6, low_open=False),
        default=1.0,
        metavar="X",
        help="clip the gradients' global L2 norm to X (1; 0 = no clipping)",
    )
    p.add_argument("--no-augment", action="store_true", help="no random left-right mirroring")
    p.add_argument(
        "--threads",
        type=integer(1, 1024),
        metavar="N",
        help="torch CPU threads (default: torch's; 1 is fastest on a machine other jobs share)",
    )
    training_run_options(p)


def run_train(args: argparse.Namespace) -> int:
    import torch

    from rgbd_rs.nn.train import is_main_process
    from rgbd_rs.segmentation.semantic_data import SemanticCache
    from rgbd_rs.segmentation.semantic_train import (
        SemanticRecipe,
        default_config,
        score,
        ship,
        train_semantic,
    )

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    cache = named("--cache", lambda: SemanticCache(args.cache))
    named("--cache", cache.require_complete)
    val = None
    if args.val_cache is not None:
        val = named("--val-cache", lambda: SemanticCache(args.val_cache))
        named("--val-cache", val.require_complete)
    config = default_config(
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        momentum=args.momentum,
        weight_decay=args.weight_decay,
        lr_plateau=args.plateau,
        grad_clip=args.grad_clip or None,
        seed=args.seed,
        num_workers=args.workers,
        checkpoint_steps=args.checkpoint_steps,
        device=args.device,
    )
    recipe = SemanticRecipe(
        width=args.width, val_fraction=args.val_fraction, augment=not args.no_augment
    )
    t0 = time.perf_counter()
    best = train_semantic(
        cache, args.out, recipe=recipe, config=config, init=args.init, val_cache=val,
        resume=not args.no_resume, quiet=args.quiet,
    )  # fmt: skip
    if not is_main_process():  # under torchrun, rank 0 reports and ships
        return 0
    print(f"best checkpoint: {best} ({time.perf_counter() - t0:.0f} s)")
    if val is not None:
        # Scored where it trained ("auto": the GPU when there is one).
        device = args.device
        if device == "auto":
            device = "cuda" if torch.cuda.is_available() else "cpu"
        print(f"validation ({args.val_cache}): {score(best, val, device=device).summary()}")
    if args.ship:
        print(f"shipped weights: {ship(best)}")
    return 0
