"""Fused RMS and damage to good inputs of a confidence checkpoint, on each evaluation set.

Usage: python tools/score_confidence.py CKPT|shipped SYNTH_TEST_DIR [POWER]

Runs `calibrate_stereo_power` (LC with the checkpoint's P_T and P_S ** POWER; default: the power
stored in the checkpoint, 1 if none) on the synthetic test set (`rgbd synth --out DIR`) and on
the Middlebury pairs of the shared data with simulated ToF, and prints each table: mean fused
RMS (px), mean fused / better input, worst fused / good input (README, confidence recipe).
"""

from __future__ import annotations

import sys

from rgbd_rs.fusion.calibrate import calibrate_stereo_power
from rgbd_rs.fusion.evaluate import middlebury_samples, synth_samples
from rgbd_rs.nn.confidence import ConfidenceEstimator


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3):
        print(__doc__)
        return 2
    est = ConfidenceEstimator.load(None if argv[0] == "shipped" else argv[0])
    power = float(argv[2]) if len(argv) == 3 else est.stereo_power
    sets = {
        "synthetic test": list(synth_samples(argv[1], "test")),
        "Middlebury": middlebury_samples(),
    }
    for name, samples in sets.items():
        cal = calibrate_stereo_power(est, samples, powers=[power], quiet=True)
        print(f"{name}\n\n{cal.markdown()}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
