"""``rgbd classify``, ``rgbd shapes cache``, ``rgbd train shapes``, ``rgbd eval shapes``: the
shape-classification pipeline's commands (thesis ch. 5)."""

from __future__ import annotations

import argparse
import time
from functools import partial
from pathlib import Path

from rgbd_rs.cli._args import (
    Commands,
    Parser,
    device,
    fail,
    flagged,
    folder,
    integer,
    named,
    real,
    shard,
    training_run_options,
    without_name,
)


def register(commands: Commands) -> None:
    """Add ``rgbd classify``, ``rgbd shapes cache``, ``rgbd train shapes``, ``rgbd eval shapes``."""
    _classify(commands)
    _cache(commands)
    _train(commands)
    _eval(commands)


def _representations(text: str) -> tuple[str, ...]:
    from rgbd_rs.errors import RgbdError
    from rgbd_rs.nn.shapes import _parse_representations

    try:
        return _parse_representations(text)
    except RgbdError as exc:  # argparse names the flag itself
        raise argparse.ArgumentTypeError(without_name("--representations", str(exc))) from None


#: The recipe parameter ``--exclude-names`` sets (its errors name the flag).
EXCLUDE = {"exclude": "--exclude-names", "init": "--init"}


def _names_file(path: Path) -> tuple[str, ...]:
    """The shape names of a UTF-8 text file, one a line (blank lines and lines that start with
    ``#`` skipped; a ``#`` inside a name is part of it)."""

    def read() -> tuple[str, ...]:
        from rgbd_rs.errors import RgbdError

        try:
            text = path.read_text(encoding="utf-8-sig")
        except UnicodeDecodeError as exc:
            raise RgbdError(
                f"{path}: not UTF-8 text (byte {exc.start}), expected one shape name a line"
            ) from None
        lines = (ln.strip() for ln in text.splitlines())
        names = tuple(ln for ln in lines if ln and not ln.startswith("#"))
        if not names:
            raise RgbdError(f"{path}: no shape name in it, expected one name a line")
        return names

    return named("--exclude-names", read)


def _classify(commands: Commands) -> None:
    p = commands.command(
        "classify",
        run_classify,
        help="classify a 3-D shape (mesh or point cloud) with the shape ConvNet",
        description="Classify a mesh (.off, .obj, .ply) or a point cloud (.npy, .npz, .ply "
        "without faces, .pcd) with the 15-branch ConvNet of thesis ch. 5: the weights shipped "
        "in the package (ModelNet40 when shipped, else ModelNet10) or --checkpoint. Prints the "
        "top classes with their probabilities. Shapes are taken as z-up (ModelNet's "
        "alignment); --up y for y-up files.",
    )
    p.add_argument("file", type=Path, metavar="FILE", help="mesh or point-cloud file")
    weights = p.add_mutually_exclusive_group()
    weights.add_argument(
        "--checkpoint", type=Path, metavar="CKPT", help="a `rgbd train shapes` checkpoint"
    )
    weights.add_argument(
        "--dataset",
        choices=("modelnet10", "modelnet40"),
        help="which shipped weights to use (default modelnet40: 40 classes)",
    )
    p.add_argument("--top", type=integer(1), default=5, metavar="N", help="classes to print (5)")
    p.add_argument(
        "--up",
        choices=("z", "y", "x"),
        default="z",
        help="the shape's up axis (default z, ModelNet's; many PLY/OBJ files are y-up): the "
        "networks were trained on z-up shapes, and a shape on its side is misclassified",
    )
    p.add_argument(
        "--turns",
        action="store_true",
        help="average over the shape's four quarter turns about the up axis: for a shape that "
        "may face any way (the networks read ModelNet's heading; ModelNet10 test: 92.7 %% "
        "aligned, 45-69 %% turned, 81.1 %% with --turns whichever way)",
    )


def run_classify(args: argparse.Namespace) -> int:
    from rgbd_rs.shapes.classify import ShapeClassifier
    from rgbd_rs.shapes.dataset import load_shape

    clf = named(
        "--checkpoint",
        lambda: ShapeClassifier.load(args.checkpoint, dataset=args.dataset),
    )
    # The library's argument names: a path error quotes the path itself; a shape's names it.
    where = {"path": "FILE", "shape": str(args.file)}
    best, probs = flagged(where, lambda: clf(load_shape(args.file), up=args.up, turns=args.turns))
    print(f"{args.file}: {best}")
    for name, prob in list(probs.items())[: args.top]:
        print(f"  {prob:6.1%}  {name}")
    return 0


def _cache(commands: Commands) -> None:
    top = commands.command(
        "shapes",
        lambda args: 2,
        help="shape-classification data tools (rgbd shapes cache)",
        description="Shape-classification data tools.",
    )
    sub = top.add_subparsers(dest="shapes", metavar="WHAT", required=True, parser_class=Parser)
    p = sub.add_parser(
        "cache",
        help="precompute the ConvNet inputs of a shape dataset",
        description="Compute every shape's depth views, voxel density profiles and (with "
        "--representations ...,curvature) curvature maps into DIR: one memory-mappable float16 "
        ".npy per "
        "representation. Resumable (re-run to continue; done shapes are skipped) and sharded: "
        "--shard i/n computes every n-th shape from i, so n scheduler tasks fill one cache. "
        "A re-run must repeat the first run's settings (--resolution, --representations, "
        "--scale-copies, --scale-range, --scale-seed, ...).",
    )
    p.set_defaults(run=run_cache)
    p.add_argument(
        "--data",
        required=True,
        metavar="SRC",
        help="modelnet10, modelnet40 (the shared point packs), a point pack .npz or a ModelNet "
        "OFF tree folder (CLASS/{train,test}/*.off)",
    )
    p.add_argument("--out", type=folder, required=True, metavar="DIR", help="cache folder")
    p.add_argument(
        "--resolution",
        type=integer(8, 4096),
        default=64,
        metavar="R",
        help="view side (64; thesis 320)",
    )
    p.add_argument(
        "--volume-resolution",
        type=integer(16, 4096),
        metavar="R",
        default=32,
        help="density profile side (32, thesis)",
    )
    p.add_argument(
        "--representations",
        type=_representations,
        metavar="LIST",
        help="comma-separated among depth,volume,curvature (default: depth,volume as available)",
    )
    p.add_argument(
        "--normalisation",
        choices=("lcn", "standardize"),
        default="lcn",
        help="per-map normalisation (lcn: local contrast normalisation, thesis)",
    )
    p.add_argument(
        "--scale-copies",
        type=integer(0, 64),
        default=0,
        metavar="K",
        help="also cache K copies of every training shape with each axis scaled by a factor "
        "drawn from U(LOW, HIGH) of --scale-range (point-cloud augmentation; rows NAME#s1..K; "
        "test shapes never copied; 0 = none)",
    )
    p.add_argument(
        "--scale-range",
        type=real(1e-3, 1e3, low_open=False),
        nargs=2,
        metavar=("LOW", "HIGH"),
        help="range of each axis' factor (default 0.6667 1.5, DGCNN's; only with --scale-copies)",
    )
    p.add_argument(
        "--scale-seed",
        type=integer(0, 2**32 - 1),
        default=0,
        metavar="S",
        help="seed of the copies' scale factors (0; only with --scale-copies)",
    )
    p.add_argument(
        "--copy-turn",
        type=real(0.0, 180.0, low_open=False),
        default=0.0,
        metavar="DEG",
        help="also turn each copy about the up axis z by an angle from U(-DEG, DEG) degrees "
        "(0, off; only with --scale-copies)",
    )
    p.add_argument(
        "--copy-jitter",
        type=real(0.0, 0.5, low_open=False),
        default=0.0,
        metavar="SIGMA",
        help="also move each copy's points (a mesh's vertices) by Gaussian noise of SIGMA times "
        "the shape's radius, clipped at 5 SIGMA (0, off; PointNet's 0.01; only with "
        "--scale-copies)",
    )
    p.add_argument(
        "--copy-drop",
        type=real(0.0, 0.95, low_open=False),
        default=0.0,
        metavar="MAX",
        help="also remove from each copy of a point cloud a fraction of its points drawn from "
        "U(0, MAX) (0, off; PointNet++'s 0.875; meshes keep every vertex; only with "
        "--scale-copies)",
    )
    p.add_argument(
        "--shard", type=shard, default=(0, 1), metavar="i/n", help="compute shard i of n (i/n)"
    )
    p.add_argument(
        "--workers", type=integer(1, 1024), metavar="N", help="threads (default: CPU count)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run_cache(args: argparse.Namespace) -> int:
    from rgbd_rs.errors import InvalidArgumentError
    from rgbd_rs.shapes.dataset import InputSpec, build_cache, open_shapes

    src = named("--data", lambda: open_shapes(args.data))
    # The copies' options mean nothing without copies: (flag, given, as typed).
    copy_options = (
        ("--scale-seed", bool(args.scale_seed), str(args.scale_seed)),
        (
            "--scale-range",
            args.scale_range is not None,
            " ".join(f"{v:g}" for v in args.scale_range or ()),
        ),
        ("--copy-turn", bool(args.copy_turn), f"{args.copy_turn:g}"),
        ("--copy-jitter", bool(args.copy_jitter), f"{args.copy_jitter:g}"),
        ("--copy-drop", bool(args.copy_drop), f"{args.copy_drop:g}"),
    )
    for flag, given, shown in copy_options:
        if given and not args.scale_copies:
            raise InvalidArgumentError(
                f"{flag}: got {shown} without --scale-copies, expected both or neither"
            )
    if args.scale_copies:
        from rgbd_rs.shapes.scaling import SCALE_RANGE, ScaledCopies

        rng = SCALE_RANGE if args.scale_range is None else tuple(args.scale_range)
        src = flagged(
            {
                "scale_range": "--scale-range",
                "turn": "--copy-turn",
                "jitter": "--copy-jitter",
                "drop": "--copy-drop",
            },
            lambda: ScaledCopies(
                src,
                args.scale_copies,
                scale_range=rng,
                seed=args.scale_seed,
                turn=args.copy_turn,
                jitter=args.copy_jitter,
                drop=args.copy_drop,
            ),
        )
    extra = {} if args.representations is None else {"representations": args.representations}
    spec = InputSpec(
        view_resolution=args.resolution,
        volume_resolution=args.volume_resolution,
        normalisation=args.normalisation,
        **extra,
    )
    t0 = time.perf_counter()
    before = 0
    if (args.out / "done.npy").is_file():
        from rgbd_rs.shapes.dataset import ShapeCache

        before = int((named("--out", lambda: ShapeCache(args.out)).done != 0).sum())
    cache = build_cache(
        src, args.out, spec=spec, shard=args.shard, workers=args.workers, quiet=args.quiet
    )
    seconds = time.perf_counter() - t0
    done = cache.done
    made = int((done != 0).sum()) - before
    rate = f", {1000 * seconds / made:.1f} ms per shape" if made > 0 else ""
    print(
        f"{args.out}: {int((done == 1).sum())}/{len(cache)} shapes done, "
        f"{int((done == 2).sum())} failed; this run computed {made} in {seconds:.2f} s{rate}"
    )
    if (done == 2).any() and not (done == 1).any():
        return fail(f"--data: every shape failed (see the warnings); {args.out} holds none")
    return 0


def _train(commands: Commands) -> None:
    p = commands.group_command(
        "train",
        "shapes",
        run_train,
        help="train the 15-branch shape ConvNet",
        description="Train the shape ConvNet of thesis §5.4 on a `rgbd shapes cache` folder "
        "(training split; --val-fraction of it held out for validation). Checkpoints go to "
        "last.pt (every epoch and every --checkpoint-steps steps) and best.pt in the --out folder; "
        "re-running "
        "the same command resumes. Runs under torchrun for DistributedDataParallel training. "
        "--ablation trains one network per Table 5.2 row into <out>/<row>/. --ship writes the best "
        "checkpoint's inference-only float16 copy into the package's weights.",
    )
    p.add_argument(
        "--cache", type=Path, required=True, metavar="DIR", help="`rgbd shapes cache` folder"
    )
    p.add_argument(
        "--out",
        type=folder,
        default=Path("out/train_shapes"),
        metavar="DIR",
        help="output folder (out/train_shapes)",
    )
    p.add_argument(
        "--representations",
        type=_representations,
        metavar="LIST",
        help="comma-separated among depth,volume,curvature (default: all in the cache)",
    )
    p.add_argument(
        "--width", type=integer(1, 4096), default=128, metavar="N", help="descriptor size (128)"
    )
    p.add_argument("--epochs", type=integer(1), default=30, metavar="N", help="epochs (30)")
    p.add_argument(
        "--batch-size", type=integer(1), default=32, metavar="N", help="shapes per step (32)"
    )
    p.add_argument("--lr", type=real(0, 10), default=0.01, metavar="X", help="learning rate (0.01)")
    p.add_argument(
        "--optimizer",
        choices=("sgd", "adamw"),
        default="sgd",
        help="SGD with momentum (the thesis) or AdamW (sgd)",
    )
    p.add_argument(
        "--schedule",
        choices=("step", "cosine"),
        default="step",
        help="step: halve the lr every --lr-step epochs; cosine: anneal it to 0 over --epochs, "
        "per step (--lr-step is then unused) (step)",
    )
    p.add_argument(
        "--momentum", type=real(0, 0.999, low_open=False), default=0.9, metavar="X", help="(0.9)"
    )
    p.add_argument(
        "--weight-decay", type=real(0, 1, low_open=False), default=5e-4, metavar="X", help="(5e-4)"
    )
    p.add_argument(
        "--lr-step", type=integer(0), default=10, metavar="N", help="halve lr every N epochs (10)"
    )
    p.add_argument(
        "--val-fraction",
        type=real(0, 0.9, low_open=False),
        default=0.1,
        metavar="X",
        help="fraction of the training split held out for validation (0.1; 0 = none)",
    )
    p.add_argument(
        "--rotate",
        action="store_true",
        help="random quarter turns about z of the training shapes (for data in arbitrary "
        "orientation; off by default: ModelNet is aligned)",
    )
    p.add_argument(
        "--mirror",
        action="store_true",
        help="replace each training shape by its mirror image (x -> -x) with probability 1/2",
    )
    p.add_argument(
        "--batch-norm",
        action="store_true",
        help="batch normalisation after every convolution (not in the thesis)",
    )
    for flag, what in (
        ("--dropout", "dropout of the descriptor before the classifier"),
        ("--label-smoothing", "mass of the cross-entropy target spread over the classes"),
    ):
        fraction = real(0, 0.99, low_open=False)
        p.add_argument(
            flag, type=fraction, default=0.0, metavar="X", help=f"{what} (0; not in the thesis)"
        )
    p.add_argument(
        "--mixup",
        type=real(0, 100, low_open=False),
        default=0.0,
        metavar="ALPHA",
        help="mix each training shape with another, inputs and targets alike, by a weight "
        "~ Beta(ALPHA, ALPHA) (0 = off; 0.01-100; not in the thesis)",
    )
    p.add_argument(
        "--split-seed",
        type=integer(0, 2**32 - 1),
        default=None,
        metavar="N",
        help="seed of the validation hold-out (default: --seed); give the members of an "
        "ensemble one split",
    )
    p.add_argument(
        "--exclude-names",
        type=Path,
        default=None,
        metavar="FILE",
        help="a text file of training shape names (one a line) neither trained nor validated "
        "on, nor their scaled copies",
    )
    p.add_argument("--ablation", action="store_true", help="one network per Table 5.2 row")
    training_run_options(
        p,
        init_help="start from checkpoint FILE's weights (fine-tuning): FILE must be of this "
        "cache's settings and of the same --representations, --width and --batch-norm; from a "
        "network of other classes (e.g. ModelNet40's) every weight but the classifier's is "
        "taken, the classifier starting afresh from --seed; ignored when resuming --out's "
        "last.pt",
    )


def run_train(args: argparse.Namespace) -> int:
    from rgbd_rs.nn.train import TrainConfig, is_main_process
    from rgbd_rs.shapes.dataset import ShapeCache
    from rgbd_rs.shapes.train import ShapeRecipe, ship, train_ablation, train_shapes

    cache = named("--cache", lambda: ShapeCache(args.cache))
    named("--cache", lambda: cache.require_complete("train"))
    config = TrainConfig(
        epochs=args.epochs,
        batch_size=args.batch_size,
        optimizer=args.optimizer,
        lr=args.lr,
        momentum=args.momentum,
        weight_decay=args.weight_decay,
        lr_step=0 if args.schedule == "cosine" else args.lr_step,
        schedule=args.schedule,
        lr_gamma=0.5,
        seed=args.seed,
        num_workers=args.workers,
        checkpoint_steps=args.checkpoint_steps,
        device=args.device,
    )
    recipe = ShapeRecipe(
        representations=args.representations,
        width=args.width,
        val_fraction=args.val_fraction,
        rotate=args.rotate,
        mirror=args.mirror,
        batch_norm=args.batch_norm,
        dropout=args.dropout,
        label_smoothing=args.label_smoothing,
        mixup=args.mixup,
        split_seed=args.split_seed,
        exclude=() if args.exclude_names is None else _names_file(args.exclude_names),
    )
    t0 = time.perf_counter()
    if args.ablation:
        if args.init is not None or args.ship:
            from rgbd_rs.errors import InvalidArgumentError

            raise InvalidArgumentError("--ablation: expected neither --init nor --ship with it")
        rows = flagged(EXCLUDE, lambda: train_ablation(
            cache, args.out, recipe=recipe, config=config, resume=not args.no_resume,
            quiet=args.quiet,
        ), warnings_too=False)  # fmt: skip
        if is_main_process():
            for row, best in rows.items():
                print(f"{row}: best checkpoint {best}")
        return 0

    def init_named(message: str) -> str:  # the --init checkpoint's errors start with its path
        if args.init is not None and message.startswith(str(args.init)):
            return f"--init: {message}"
        return message

    best = flagged(EXCLUDE, lambda: train_shapes(
        cache, args.out, recipe=recipe, config=config, init=args.init,
        resume=not args.no_resume, quiet=args.quiet,
    ), init_named, warnings_too=False)  # fmt: skip
    if not is_main_process():  # under torchrun, rank 0 reports and ships
        return 0
    print(f"best checkpoint: {best} ({time.perf_counter() - t0:.0f} s)")
    if args.ship:
        print(f"shipped weights: {ship(best)}")
    return 0


def _eval(commands: Commands) -> None:
    p = commands.group_command(
        "eval",
        "shapes",
        run_eval,
        help="evaluate shape ConvNets (accuracy, per class, confusion; Table 5.2 ablation)",
        description="Accuracy of shape-classifier checkpoints on a cache's test split (ModelNet's "
        "official one): overall and per-class accuracy and the confusion matrix (markdown + PNG "
        "heat map in the --out folder). --ablation DIR evaluates every DIR/<row>/best.pt written "
        "by `rgbd train shapes --ablation`; Table 5.2 goes to ablation.md in the --out folder. "
        "Caches must match the network: the shipped weights take --resolution 32 with "
        "--representations depth,volume,curvature.",
    )
    p.add_argument(
        "--cache", type=Path, required=True, metavar="DIR", help="`rgbd shapes cache` folder"
    )
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--checkpoint",
        type=Path,
        nargs="+",
        metavar="FILE",
        help="checkpoint file(s) (default: the shipped weights of the cache's dataset)",
    )
    group.add_argument(
        "--ablation",
        type=Path,
        metavar="DIR",
        help="folder of `rgbd train shapes --ablation` (every row finished)",
    )
    p.add_argument("--split", choices=("test", "train", "all"), default="test", help="(test)")
    p.add_argument(
        "--label", metavar="NAME", help="dataset column name of the ablation table (from the cache)"
    )
    p.add_argument(
        "--out",
        type=folder,
        default=Path("out/eval_shapes"),
        metavar="DIR",
        help="report folder (out/eval_shapes)",
    )
    p.add_argument(
        "--batch-size", type=integer(1), default=64, metavar="N", help="shapes per batch (64)"
    )
    p.add_argument(
        "--turned",
        type=int,
        choices=(0, 90, 180, 270),
        default=0,
        metavar="DEG",
        help="turn every shape by 0, 90, 180 or 270 degrees about z first: how the networks do "
        "on shapes that do not face ModelNet's way (default 0)",
    )
    p.add_argument(
        "--device",
        type=device(auto=False),
        default="cpu",
        metavar="DEV",
        help="cpu, cuda or cuda:N (cpu)",
    )
    p.add_argument(
        "--turns",
        action="store_true",
        help="average the probabilities over the four quarter turns about z of each shape",
    )
    p.add_argument(
        "--mirror",
        action="store_true",
        help="average the probabilities over each shape and its mirror image (x -> -x)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _ablation_checkpoints(folder: Path) -> list[Path]:
    """The checkpoint of every row of ``rgbd train shapes --ablation``'s ``folder``: each row's
    ``best.pt`` (``last.pt`` without validation), once every row's run has finished and no row
    of the table is missing (an ablation interrupted, or still training, is refused: its table
    would hold fewer rows, or half-trained ones, without a word)."""
    from rgbd_rs.errors import RgbdError
    from rgbd_rs.nn.checkpoint import load_checkpoint
    from rgbd_rs.shapes.train import COMBINED, ablation_rows

    rows = sorted(p.parent for p in folder.glob("*/last.pt"))
    if not rows:
        raise RgbdError(
            f"--ablation: {folder}: no <row>/last.pt, expected `rgbd train shapes "
            "--ablation`'s output folder"
        )
    reps: dict[str, tuple[str, ...]] = {}
    for row in rows:
        ck = named("--ablation", partial(load_checkpoint, row / "last.pt"))
        epochs = int(ck.config.get("epochs", 0))
        if ck.epoch < epochs:
            raise RgbdError(
                f"--ablation: {row}: epoch {ck.epoch} of {epochs}, an unfinished run; finish it "
                "(re-run the same `rgbd train shapes ... --ablation`: it resumes) or read it "
                "with --checkpoint"
            )
        reps[row.name] = tuple(ck.normalisation.get("spec", {}).get("representations", ()))
    every = reps.get(COMBINED) or tuple(r for name in reps for r in reps[name])
    want = set(ablation_rows(every)) if every else set()
    missing = sorted(want - set(reps))
    if missing:
        raise RgbdError(
            f"--ablation: {folder}: rows {missing} missing (an interrupted ablation?), expected "
            f"{sorted(want)}"
        )
    return [row / "best.pt" if (row / "best.pt").is_file() else row / "last.pt" for row in rows]


def run_eval(args: argparse.Namespace) -> int:
    from rgbd_rs.errors import RgbdError
    from rgbd_rs.shapes.dataset import ShapeCache
    from rgbd_rs.shapes.evaluate import ShapeEvaluation, ablation_markdown, evaluate, row_name

    if args.label is not None and args.ablation is None:
        raise RgbdError("--label: given without --ablation, expected it only with --ablation")
    cache = named("--cache", lambda: ShapeCache(args.cache))
    named("--cache", lambda: cache.require_complete(args.split))
    if args.ablation is not None:
        checkpoints = _ablation_checkpoints(args.ablation)
    elif args.checkpoint:
        checkpoints = list(args.checkpoint)
    else:
        from rgbd_rs.shapes.classify import shipped_weights

        dataset = f"modelnet{len(cache.classes)}"
        if dataset not in shipped_weights():
            raise RgbdError(
                f"--checkpoint: none given and no shipped {dataset} weights in this installation"
            )
        checkpoints = [shipped_weights()[dataset]]
    results: list[ShapeEvaluation] = []
    for ck in checkpoints:

        def one(ck: Path = ck) -> ShapeEvaluation:
            return evaluate(
                ck,
                cache,
                split=args.split,
                batch_size=args.batch_size,
                device=args.device,
                turns=args.turns,
                mirror=args.mirror,
                quiet=args.quiet,
                turned=args.turned // 90,
            )

        flag = "--ablation" if args.ablation is not None else "--checkpoint"
        res = named(flag, one) if args.ablation is not None or args.checkpoint else one()
        stem = row_name(res.representations)
        if any(row_name(r.representations) == stem for r in results):
            stem = f"{stem}_{len(results)}"  # two checkpoints of one row keep both reports
        res.write(args.out, stem)
        results.append(res)
        print(res.summary())
    if args.ablation is not None:
        label = args.label or str(cache.meta.get("source", "dataset")).split("_")[0]
        table = ablation_markdown({label: results})
        (args.out / "ablation.md").write_text(table + "\n")
        print(table)
    print(f"reports in {args.out}")
    return 0
