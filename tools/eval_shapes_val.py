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

    python tools/eval_shapes_val.py --cache C --checkpoint A.pt [B.pt ...] [--seed 1]
        [--val-fraction 0.1] [--mirror] [--write-names F]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from rgbd_rs.shapes.augment import _mirror_pair
from rgbd_rs.shapes.classify import ShapeClassifier
from rgbd_rs.shapes.dataset import ShapeCache
from rgbd_rs.shapes.train import _split_by_shape


def class_columns(clf: ShapeClassifier, cache: ShapeCache) -> list[int]:
    """The columns of ``clf``'s probabilities that are ``cache``'s classes, in its order."""
    missing = [c for c in cache.classes if c not in clf.classes]
    if missing:
        raise SystemExit(f"the checkpoint has no class {missing[0]!r} of the cache")
    return [clf.classes.index(c) for c in cache.classes]


def validation_names(cache: ShapeCache, seed: int, fraction: float) -> list[str]:
    """The names of the trainer's validation shapes (original shapes only)."""
    data = cache.dataset("train", cache.spec.representations)
    _, val = _split_by_shape(cache, data, fraction, seed)
    rows = np.asarray(data.indices)[val.indices]
    return [cache.names[int(r)] for r in rows]


def validation_probabilities(
    clf: ShapeClassifier, cache: ShapeCache, seed: int, fraction: float, mirror: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(N x K probabilities over the cache's K classes, N labels) of ``clf`` on the trainer's
    validation shapes."""
    data = cache.dataset("train", clf.spec.representations)
    _, val = _split_by_shape(cache, data, fraction, seed)
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cache", type=Path, required=True)
    p.add_argument("--checkpoint", type=Path, nargs="*", default=[])
    p.add_argument(
        "--seed", type=int, default=1, help="the runs' --split-seed, else their --seed (1)"
    )
    p.add_argument("--val-fraction", type=float, default=0.1, help="the runs' (0.1)")
    p.add_argument("--mirror", action="store_true", help="also mirror-averaged")
    p.add_argument("--write-names", type=Path, help="write the validation shapes' names here")
    a = p.parse_args()
    if not a.checkpoint and a.write_names is None:
        p.error("expected --checkpoint, --write-names or both")
    cache = ShapeCache(a.cache)
    if a.write_names is not None:
        names = validation_names(cache, a.seed, a.val_fraction)
        a.write_names.write_text("".join(f"{n}\n" for n in names), encoding="utf-8")
        print(f"{a.write_names}: {len(names)} validation shape names")
    for mirror in (False, True) if a.mirror else (False,):
        total = None
        for ckpt in a.checkpoint:
            clf = ShapeClassifier.load(ckpt)
            probs, labels = validation_probabilities(clf, cache, a.seed, a.val_fraction, mirror)
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


if __name__ == "__main__":
    main()
