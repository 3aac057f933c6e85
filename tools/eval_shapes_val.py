"""Shape classifiers on the validation shapes `rgbd train shapes` held out, alone and averaged:
what chooses a recipe, an epoch or an ensemble without reading the test split.

The validation split is the trainer's (``--val-fraction`` of the cache's original training shapes,
seeded by their ``--split-seed``, else their ``--seed``; scaled copies of a validation shape are
never trained on), so it must be given that seed and the fraction of the runs compared. Prints
each checkpoint's accuracy, with ``--mirror`` also mirror-averaged, and that of the average of
all the checkpoints' probabilities.

    python tools/eval_shapes_val.py --cache C --checkpoint A.pt [B.pt ...] [--seed 1]
        [--val-fraction 0.1] [--mirror]
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


def validation_probabilities(
    clf: ShapeClassifier, cache: ShapeCache, seed: int, fraction: float, mirror: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(N x K probabilities, N labels) of ``clf`` on the trainer's validation shapes."""
    data = cache.dataset("train", clf.spec.representations)
    _, val = _split_by_shape(cache, data, fraction, seed)
    loader = torch.utils.data.DataLoader(val, batch_size=128, shuffle=False)
    probs, labels = [], []
    for x, y in loader:
        views = _mirror_pair(x, clf.net.shapes) if mirror else [x]
        probs.append(sum(np.asarray(clf.probabilities_of_inputs(v)) for v in views) / len(views))
        labels.append(y.numpy())
    return np.concatenate(probs), np.concatenate(labels)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cache", type=Path, required=True)
    p.add_argument("--checkpoint", type=Path, nargs="+", required=True)
    p.add_argument(
        "--seed", type=int, default=1, help="the runs' --split-seed, else their --seed (1)"
    )
    p.add_argument("--val-fraction", type=float, default=0.1, help="the runs' (0.1)")
    p.add_argument("--mirror", action="store_true", help="also mirror-averaged")
    a = p.parse_args()
    cache = ShapeCache(a.cache)
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
