"""Shape classifiers on ModelNet test shapes whose proportions changed: every axis of every test
shape of the shared point pack scaled by U(2/3, 3/2) (the scaled-copies range), a stand-in for
users' shapes that are not proportioned like ModelNet's.

Writes the scaled pack and its input cache under ``--work`` (the cache settings come from the
first checkpoint), then prints each checkpoint's accuracy on it (``rgbd eval shapes`` gives the
unscaled test split's).

    python tools/eval_shapes_scaled.py --checkpoint A.pt [B.pt ...] [--data modelnet10]
        [--seed 7] [--work out/shapes_scaled_test]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rgbd_rs.shapes.classify import ShapeClassifier
from rgbd_rs.shapes.dataset import PACKS, TEST, PointCloudSet, build_cache, open_shapes
from rgbd_rs.shapes.evaluate import evaluate
from rgbd_rs.shapes.scaling import SCALE_RANGE


def scaled_test_pack(data: str, out: Path, seed: int) -> Path:
    """Write ``data``'s test shapes with each axis scaled by U(SCALE_RANGE) to ``out``."""
    src = open_shapes(data)
    if not isinstance(src, PointCloudSet):
        raise SystemExit(f"{data}: expected a point pack (modelnet10, modelnet40 or a .npz)")
    test = np.flatnonzero(src.splits == TEST)
    rng = np.random.default_rng(seed)
    factors = rng.uniform(*SCALE_RANGE, (len(test), 1, 3))
    points = (src.points[test].astype(np.float32) * factors).astype(np.float16)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(
        out,
        points=points,
        label=src.labels[test].astype(np.int16),
        split=src.splits[test],
        classes=np.array(src.classes),
        name=np.array([src.names[i] for i in test]),
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", nargs="+", required=True, help="rgbd train shapes checkpoints")
    ap.add_argument("--data", default="modelnet10", help=f"{sorted(PACKS)} or a point pack .npz")
    ap.add_argument("--seed", type=int, default=7, help="seed of the scale factors (7)")
    ap.add_argument("--work", type=Path, default=Path("out/shapes_scaled_test"), help="folder")
    args = ap.parse_args()
    first = ShapeClassifier.load(args.checkpoint[0])
    pack = scaled_test_pack(args.data, args.work / f"test_scaled_s{args.seed}.npz", args.seed)
    cache = build_cache(pack, args.work / f"cache_s{args.seed}", spec=first.spec, quiet=True)
    for ck in args.checkpoint:
        r = evaluate(ck, cache)
        print(
            f"{ck}: {100 * r.accuracy:.1f} % (mean class {100 * r.mean_class_accuracy:.1f} %) "
            f"on {r.count} test shapes with rescaled axes"
        )


if __name__ == "__main__":
    main()
