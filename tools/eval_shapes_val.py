"""Shape classifiers on the validation shapes `rgbd train shapes` held out, alone and averaged:
what chooses a recipe, an epoch or an ensemble without reading the test split.

The validation split is the trainer's (``--val-fraction`` of the cache's original training shapes,
seeded by their ``--split-seed``, else their ``--seed``; scaled copies of a validation shape are
never trained on), so it must be given that seed and the fraction of the runs compared. Prints
each checkpoint's accuracy, with ``--mirror`` also mirror-averaged, and that of the average of
all the checkpoints' probabilities. A checkpoint of a larger class list (a ModelNet40 network
on a ModelNet10 cache) is read on the cache's classes: its probabilities of those classes,
renormalised. ``--write-names F`` writes the validation shapes' names, one a line (what
``rgbd train shapes --exclude-names`` reads, so another cache's run never trains on them).

**K-fold validation** (when the held-out 10 % no longer tells candidates apart): ``--folds K
--fold I`` replaces the trainer's split by fold I of K, a seeded partition of every original
training shape. Train fold I's networks with ``--val-fraction 0 --exclude-names FI`` (its
names, from ``--write-names FI``), read them on fold I with ``--save F.npz``, and ``--combine
F0.npz ... FK-1.npz`` gives the accuracy over all the training shapes, each read by networks
that never trained on it (``tools/train_shapes_gpu.sh cv`` runs the whole loop).

    python tools/eval_shapes_val.py --cache C --checkpoint A.pt [B.pt ...] [--seed 1]
        [--val-fraction 0.1 | --folds K --fold I] [--mirror] [--write-names F] [--save F.npz]
    python tools/eval_shapes_val.py --combine F0.npz F1.npz ... [--class-counts N1,N2,...]

``--class-counts`` weighs each class' accuracy by a count: ModelNet10's test split holds its
classes in other proportions than its training split (the thesis' Table 5.4; 39 % of it desks,
dressers, night stands and tables, the classes most confused, against 25 % of the training
shapes), so the fold accuracy weighted that way is the closer estimate of a test figure.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rgbd_rs.shapes.augment import _mirror_pair
from rgbd_rs.shapes.classify import ShapeClassifier
from rgbd_rs.shapes.dataset import ShapeCache
from rgbd_rs.shapes.scaling import original_rows
from rgbd_rs.shapes.train import _split_by_shape


def class_columns(clf: ShapeClassifier, cache: ShapeCache) -> list[int]:
    """The columns of ``clf``'s probabilities that are ``cache``'s classes, in its order."""
    missing = [c for c in cache.classes if c not in clf.classes]
    if missing:
        raise SystemExit(f"the checkpoint has no class {missing[0]!r} of the cache")
    return [clf.classes.index(c) for c in cache.classes]


def fold_positions(data: Any, cache: ShapeCache, folds: int, fold: int, seed: int) -> list[int]:
    """Positions in ``data`` (the cache's training dataset) of fold ``fold`` of ``folds``: the
    original training shapes permuted by ``seed`` (as the trainer's split draws), cut into
    ``folds`` parts of near-equal size. Scaled copies belong to no fold."""
    if not 2 <= folds <= 100 or not 0 <= fold < folds:
        raise SystemExit(f"--folds/--fold: got {folds}/{fold}, expected 2 <= K <= 100, 0 <= I < K")
    rows = np.asarray(data.indices, np.int64)
    origin = original_rows(cache.meta.get("augmentation"), cache.splits)[rows]
    originals = np.flatnonzero(origin == rows)
    order = torch.randperm(len(originals), generator=torch.Generator().manual_seed(seed))
    part = np.array_split(order.numpy(), folds)[fold]
    return sorted(int(originals[j]) for j in part)


def held_out(
    cache: ShapeCache, data: Any, seed: int, fraction: float, fold: tuple[int, int] | None
) -> torch.utils.data.Subset[Any]:
    """The shapes to read: the trainer's validation split, or fold ``(K, I)``."""
    if fold is None:
        return _split_by_shape(cache, data, fraction, seed)[1]
    return torch.utils.data.Subset(data, fold_positions(data, cache, *fold, seed))


def validation_names(
    cache: ShapeCache, seed: int, fraction: float, fold: tuple[int, int] | None = None
) -> list[str]:
    """The names of the trainer's validation shapes (original shapes only), or of a fold's."""
    data = cache.dataset("train", cache.spec.representations)
    val = held_out(cache, data, seed, fraction, fold)
    rows = np.asarray(data.indices)[val.indices]
    return [cache.names[int(r)] for r in rows]


def validation_probabilities(
    clf: ShapeClassifier,
    cache: ShapeCache,
    seed: int,
    fraction: float,
    mirror: bool,
    fold: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(N x K probabilities over the cache's K classes, N labels) of ``clf`` on the trainer's
    validation shapes (or on fold ``(K, I)``)."""
    data = cache.dataset("train", clf.spec.representations)
    val = held_out(cache, data, seed, fraction, fold)
    loader = torch.utils.data.DataLoader(val, batch_size=128, shuffle=False)
    cols = class_columns(clf, cache)
    probs, labels = [], []
    for x, y in loader:
        views = _mirror_pair(x, clf.net.shapes) if mirror else [x]
        p = sum(np.asarray(clf.probabilities_of_inputs(v)) for v in views) / len(views)
        p = p[:, cols]
        probs.append(p / p.sum(1, keepdims=True))
        labels.append(y.numpy())
    return np.concatenate(probs), np.concatenate(labels)


def combine(files: list[Path], counts: list[int] | None = None) -> None:
    """The accuracy over the folds saved by ``--save``: each file one fold's shapes. With
    ``counts`` (one per class), also each class' accuracy and the accuracy a set of those class
    counts would read (each class' accuracy weighted by its count), before the last line."""
    if counts is not None and (min(counts) < 0 or sum(counts) == 0):
        raise SystemExit(
            f"--class-counts: got {','.join(map(str, counts))}, expected non-negative counts "
            "with a positive sum"
        )
    names: list[str] = []
    right = total = 0
    preds, truth = [], []
    seen: dict[int, set[int]] = {}
    for f in files:
        with np.load(f) as z:
            probs, labels = z["probabilities"], z["labels"]
            names += [str(n) for n in z["names"]]
            if "folds" in z.files:
                seen.setdefault(int(z["folds"]), set()).add(int(z["fold"]))
        ok = int((probs.argmax(1) == labels).sum())
        print(f"{f}: {100 * ok / len(labels):.2f} % of {len(labels)} shapes")
        right, total = right + ok, total + len(labels)
        preds.append(probs.argmax(1))
        truth.append(labels)
    if len(set(names)) != len(names):
        raise SystemExit("--combine: a shape is in two of the files (folds of one K and seed?)")
    if len(seen) > 1:
        raise SystemExit(f"--combine: files of {sorted(seen)} folds mixed, expected one K")
    for k, got in seen.items():
        if got != set(range(k)):
            missing = sorted(set(range(k)) - got)
            raise SystemExit(f"--combine: folds {missing} of {k} missing, expected all {k}")
    if counts is not None:
        pred, lab = np.concatenate(preds), np.concatenate(truth)
        k = int(probs.shape[1])
        if len(counts) != k:
            raise SystemExit(f"--class-counts: got {len(counts)} counts, expected {k}, one a class")
        acc = np.array(
            [(pred[lab == c] == c).mean() if (lab == c).any() else np.nan for c in range(k)]
        )
        for c in range(k):
            print(f"class {c}: {100 * acc[c]:.2f} % of {int((lab == c).sum())} shapes")
        w = np.asarray(counts, np.float64)
        empty = [c for c in range(k) if w[c] > 0 and np.isnan(acc[c])]
        if empty:
            raise SystemExit(
                f"--class-counts: class {empty[0]} has a count but no shape in the folds"
            )
        weighted = float((w[w > 0] * acc[w > 0]).sum() / w.sum())
        print(f"weighted by --class-counts: {100 * weighted:.2f} %")
    print(f"all {len(files)} folds: {100 * right / total:.2f} % of {total} shapes")


def _counts(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"got {text!r}, expected N1,N2,... integers") from None


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cache", type=Path)
    p.add_argument("--checkpoint", type=Path, nargs="*", default=[])
    p.add_argument(
        "--seed", type=int, default=1, help="the runs' --split-seed, else their --seed (1)"
    )
    p.add_argument("--val-fraction", type=float, default=0.1, help="the runs' (0.1)")
    p.add_argument("--mirror", action="store_true", help="also mirror-averaged")
    p.add_argument("--write-names", type=Path, help="write the validation shapes' names here")
    p.add_argument("--folds", type=int, help="K: read fold --fold of K instead of the split")
    p.add_argument("--fold", type=int, help="I, 0 <= I < K")
    p.add_argument("--save", type=Path, help="write the averaged probabilities here (.npz)")
    p.add_argument("--combine", type=Path, nargs="+", help="the accuracy over --save files")
    p.add_argument(
        "--class-counts",
        type=_counts,
        metavar="N1,N2,...",
        help="with --combine: per-class accuracy and the accuracy of a set of these class counts "
        "(ModelNet10's test split, the thesis' Table 5.4: 50,100,100,86,86,100,86,100,100,100)",
    )
    a = p.parse_args()
    if a.combine:
        combine(a.combine, a.class_counts)
        return
    if a.class_counts is not None:
        p.error("--class-counts goes with --combine")
    if a.cache is None:
        p.error("expected --cache (or --combine)")
    if not a.checkpoint and a.write_names is None:
        p.error("expected --checkpoint, --write-names or both")
    if (a.folds is None) != (a.fold is None):
        p.error("--folds and --fold go together")
    fold = None if a.folds is None else (a.folds, a.fold)
    cache = ShapeCache(a.cache)
    names = None
    if a.write_names is not None or a.save is not None:
        names = validation_names(cache, a.seed, a.val_fraction, fold)
    if a.write_names is not None and names is not None:
        a.write_names.write_text("".join(f"{n}\n" for n in names), encoding="utf-8")
        print(f"{a.write_names}: {len(names)} validation shape names")
    for mirror in (False, True) if a.mirror else (False,):
        total = None
        for ckpt in a.checkpoint:
            clf = ShapeClassifier.load(ckpt)
            probs, labels = validation_probabilities(
                clf, cache, a.seed, a.val_fraction, mirror, fold
            )
            acc = float((probs.argmax(1) == labels).mean())
            tag = " mirror-averaged" if mirror else ""
            print(f"{ckpt}{tag}: {100 * acc:.2f} % of {len(labels)} validation shapes")
            total = probs if total is None else total + probs
        if len(a.checkpoint) > 1 and total is not None:
            acc = float((total.argmax(1) == labels).mean())
            print(
                f"average of {len(a.checkpoint)}{' mirror-averaged' if mirror else ''}: "
                f"{100 * acc:.2f} %"
            )
        if a.save is not None and total is not None and not mirror:
            where = {} if fold is None else {"folds": fold[0], "fold": fold[1]}
            np.savez(
                a.save,
                probabilities=total / len(a.checkpoint),
                labels=labels,
                names=names,
                **where,
            )
            print(f"{a.save}: the average's probabilities of {len(labels)} shapes")


if __name__ == "__main__":
    main()
