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
from pathlib import Path

from rgbd_rs.data.stereo_scenes import SPLITS
from rgbd_rs.fusion.evaluate_real import evaluate_real, markdown
from rgbd_rs.fusion.real_scenes import dense_protocol_samples
from rgbd_rs.nn.confidence import ConfidenceEstimator


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", choices=SPLITS, default="train")
    ap.add_argument("--out", type=Path, default=Path("out/eval_fusion_dense"))
    ap.add_argument(
        "--weights", type=Path, default=None, help="confidence ConvNet (default: the shipped one)"
    )
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()
    title = f"real {a.split} split, dense 512x424 ToF"
    est = None if a.weights is None else ConfidenceEstimator.load(a.weights)
    scores = evaluate_real(
        dense_protocol_samples(a.split), a.out / a.split, title=title, estimator=est, quiet=a.quiet
    )
    print(markdown(scores, title))


if __name__ == "__main__":
    main()
