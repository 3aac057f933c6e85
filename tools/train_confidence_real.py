"""Train the confidence ConvNet on real scenes (issue 29): clue caches of the Middlebury train
split (``../shared/data/stereo``) under ``--laws`` simulated ToF laws per scene and
``--dense-laws`` of the dense family (a ToF as fine as the colour camera; a fixed pool, the same
every epoch) with the ``--matcher``'s stereo disparities, the val split's fixed laws for the
validation loss (for monitoring only: the epoch is chosen by ``tools/choose_confidence_real.py``
on what the fusion gives), one checkpoint per epoch kept.

    python tools/train_confidence_real.py --out out/conf_real --laws 4 --epochs 6
    python tools/train_confidence_real.py --out out/conf_dense --laws 4 --dense-laws 2 \
        --epochs 4 --target-t 1 --lr 5e-4 --init python/rgbd_rs/nn/weights/confidence.pt

Resumable: caches are skipped when present and ``train`` resumes from the last checkpoint.
"""

from __future__ import annotations

import argparse
import itertools
import shutil
import warnings
from pathlib import Path

from rgbd_rs.fusion._inputs import FAR_CAMERA_WARNING
from rgbd_rs.fusion.real_scenes import real_samples
from rgbd_rs.nn.confidence_data import prepare
from rgbd_rs.nn.confidence_train import Recipe, recipe_config, train_on_caches


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/conf_real"))
    ap.add_argument("--laws", type=int, default=4, help="ToF laws per training scene (4)")
    ap.add_argument("--val-laws", type=int, default=2, help="ToF laws per val scene (2)")
    ap.add_argument(
        "--dense-laws",
        type=int,
        default=0,
        help="laws of the dense family (a ToF as fine as the colour camera) per training "
        "scene, added to the pool (0; rgbd_rs.fusion.real_scenes.DENSE_TOF_SCALE)",
    )
    ap.add_argument(
        "--far-laws",
        type=int,
        default=0,
        help="laws per training scene fused on the camera far from the ToF (the right one, "
        "real_samples(view='right')), added to the pool (0)",
    )
    ap.add_argument("--matcher", default="census", choices=("census", "opencv"))
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--per-scene", type=int, default=100, help="crops per case and epoch")
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--batch-size", type=int, default=16)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--target-t",
        type=float,
        default=None,
        help=f"error (px) at which the target confidence reaches 0 (default: the recipe's "
        f"{Recipe().target_t:g}; the shipped network: 1)",
    )
    ap.add_argument("--init", type=Path, default=None, help="start from these weights")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()
    cache = a.out / f"cache_{a.matcher}"
    # The far-camera cases are fused there on purpose.
    warnings.filterwarnings("ignore", FAR_CAMERA_WARNING, RuntimeWarning)
    pool = real_samples("train", a.laws, dense_laws=a.dense_laws)
    if a.far_laws:
        pool = itertools.chain(pool, real_samples("train", a.far_laws, view="right"))
    train = prepare(
        pool,
        cache / "train",  # one file per case name: a dense or far law's name differs
        matcher=a.matcher,
        quiet=a.quiet,
    )
    val = prepare(real_samples("val", a.val_laws), cache / "val", matcher=a.matcher, quiet=a.quiet)
    recipe = Recipe(width=a.width, per_scene=a.per_scene)
    if a.target_t is not None:
        recipe = Recipe(width=a.width, per_scene=a.per_scene, target_t=a.target_t)
    best = None
    # One epoch per call (the trainer resumes bit for bit), so every epoch's weights are kept
    # as epN.pt for the choice on what the fusion gives.
    for epoch in range(1, a.epochs + 1):
        kept = a.out / f"ep{epoch}.pt"
        if kept.is_file():
            continue
        config = recipe_config(epoch, a.batch_size, a.lr, a.seed)
        best = train_on_caches(
            train,
            val,
            a.out,
            recipe=recipe,
            config=config,
            init=a.init,
            quiet=a.quiet,
            matcher=a.matcher,
        )
        shutil.copyfile(a.out / "last.pt", kept)
        print(f"epoch {epoch}: {kept}", flush=True)
    if best is not None:
        print(f"lowest validation loss: {best}")


if __name__ == "__main__":
    main()
