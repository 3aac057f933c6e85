"""The default fusion on the real Middlebury split with a *dense, precise* ToF: the old
three-scene protocol's simulation (`rgbd_rs.fusion.evaluate.middlebury_sample`: a 512 x 424 ToF
of the default `ToFModel`, finer than the ~450 px wide colour images, one fixed seed) instead of
the drawn laws of `rgbd eval fusion --real` (a ToF at 1/4-1/2 of the colour width). A regime the
confidence ConvNet was not trained on: it shows whether the fusion damages a ToF that is much
better than the stereo map.

    python tools/eval_fusion_dense_tof.py --split train --out out/eval_fusion_dense

Writes OUT/<split>/table.md and figure.png (the `rgbd eval fusion --real` layout) and prints the
table.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path

from rgbd_rs.data.stereo_scenes import SPLITS, load_stereo_scene, scene_names
from rgbd_rs.fusion.evaluate import Sample, simulate_tof
from rgbd_rs.fusion.evaluate_real import evaluate_real, markdown
from rgbd_rs.render import ToFModel

#: The old protocol's ToF camera (columns, rows) and seed.
TOF_SIZE = (512, 424)
SEED = 0


def dense_samples(split: str) -> Iterator[Sample]:
    """Every scene of ``split`` with the dense default-model ToF frame."""
    for name in scene_names(split):
        scene = load_stereo_scene(name)
        gt = scene.disparity_left
        depth, amplitude, rig = simulate_tof(gt, TOF_SIZE, ToFModel(), SEED)
        yield Sample(f"{name}_dense", scene.left, scene.right, depth, amplitude, rig, gt)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", choices=SPLITS, default="train")
    ap.add_argument("--out", type=Path, default=Path("out/eval_fusion_dense"))
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()
    title = f"real {a.split} split, dense 512x424 ToF"
    scores = evaluate_real(dense_samples(a.split), a.out / a.split, title=title, quiet=a.quiet)
    print(markdown(scores, title))


if __name__ == "__main__":
    main()
