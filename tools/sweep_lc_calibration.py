"""The LC bin width and the stereo power of the confidence ConvNet on validation scenes.

Usage: python tools/sweep_lc_calibration.py VAL_DIR [BIN_WIDTH ...]

VAL_DIR is a `rgbd synth --vary-tof` folder whose test split the network never saw (README: made
with `rgbd synth --out out/synth_val --seed 1 --train 0 --test 12 --vary-tof`). For each bin
width, prints the table of `rgbd train calibrate-confidence` (fused RMS / better input, worst
damage to a good input) over the powers 1, 2 and 3 of the shipped network's stereo confidence.
"""

from __future__ import annotations

import sys

from rgbd_rs.fusion.calibrate import calibrate_stereo_power
from rgbd_rs.fusion.evaluate import synth_samples
from rgbd_rs.fusion.lc import LcParams
from rgbd_rs.nn.confidence import ConfidenceEstimator


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    est = ConfidenceEstimator.load()
    samples = list(synth_samples(argv[0], "test"))
    for bw in [float(a) for a in argv[1:]] or [0.25, 0.5, 1.0, 2.0]:
        res = calibrate_stereo_power(
            est, samples, powers=(1.0, 2.0, 3.0), params=LcParams(bin_width=bw), quiet=True
        )
        print(f"bin width {bw:g} px\n\n{res.markdown()}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
