"""ToF error of a generated dataset's split against its ground truth (the README's figures).

    python tools/eval_synth_tof.py DIR [--split test]

Per scene: fraction of valid ToF pixels, median |error| and RMS error (metres, ToF view); prints
the means over the split.
"""

from __future__ import annotations

import argparse

import numpy as np

from rgbd_rs.data import SynthDataset
from rgbd_rs.metrics import rms_error


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("root")
    ap.add_argument("--split", default="test", choices=["train", "test"])
    args = ap.parse_args()
    valid, med, rms = [], [], []
    for s in SynthDataset(args.root, args.split):
        err = s.tof_depth - s.tof_gt_depth
        valid.append(np.isfinite(s.tof_depth).mean())
        med.append(np.nanmedian(np.abs(err)))
        rms.append(rms_error(s.tof_depth, s.tof_gt_depth))
    print(
        f"{args.split}: {len(valid)} scenes, ToF valid {100 * np.mean(valid):.1f} %, "
        f"median |err| {100 * np.mean(med):.2f} cm, RMS {100 * np.mean(rms):.2f} cm"
    )


if __name__ == "__main__":
    main()
