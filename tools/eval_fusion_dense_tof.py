"""The fusion on the real Middlebury split with a *dense, precise* ToF: the dense protocol
(`rgbd_rs.fusion.real_scenes.dense_protocol_samples`: the old three-scene protocol's 512 x 424
ToF of the default `ToFModel`, finer than the ~450 px wide colour images, one fixed seed) instead
of the drawn laws of `rgbd eval fusion --real` (a ToF at 1/4-1/2 of the colour width). It shows
whether the fusion damages a ToF that is much better than the stereo map (the shipped network
saw the dense law family in training, not these cases; the chooser reads the val split's).

    python tools/eval_fusion_dense_tof.py --split train --out out/eval_fusion_dense
    python tools/eval_fusion_dense_tof.py --split val --weights out/conf_dense/chosen.pt

Writes OUT/<split>/table.md and figure.png (the `rgbd eval fusion --real` layout; with
``--weights W``: OUT/<split>_<W's stem>/) and prints the table.
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
        "--weights",
        type=Path,
        default=None,
        help="confidence ConvNet checkpoint (default: the shipped one); its stored stereo power "
        "is used, so pass a chooser's chosen.pt rather than an epN.pt (power 1)",
    )
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()
    title = f"real {a.split} split, dense 512x424 ToF"
    folder = a.out / a.split
    est = None
    if a.weights is not None:
        est = ConfidenceEstimator.load(a.weights)
        title += f", {a.weights.name}"
        folder = a.out / f"{a.split}_{a.weights.stem}"
    scores = evaluate_real(
        dense_protocol_samples(a.split), folder, title=title, estimator=est, quiet=a.quiet
    )
    print(markdown(scores, title))


if __name__ == "__main__":
    main()
