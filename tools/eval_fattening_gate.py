"""A measured alternative for the "never damage a good input" target: gate SGM's fattening.

Usage: python tools/eval_fattening_gate.py VAL_DIR TEST_DIR

VAL_DIR: validation scenes (`rgbd synth --out out/synth_val --seed 1 --train 0 --test 12
--vary-tof`), TEST_DIR: the synthetic test set (`rgbd synth --out out/synth`); plus the three
Middlebury pairs of the shared data with simulated ToF. With the shipped confidence ConvNet,
LC is run three ways: the default; with the stereo confidence set to 0 where SGM is more than
1 px nearer than the ToF within 2 px of a ToF depth edge (3 x 3 max - min > 1 px), the place
where window-based stereo fattens foreground objects; and the same only where the ToF
confidence exceeds 0.6. Prints per dataset the mean fused RMS (px), the mean fused / better
input ratio and the worst fused / good input ratio (good: >= 95 % of pixels within 1 px).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from rgbd_rs.fusion._inputs import views
from rgbd_rs.fusion.calibrate import SceneInputs
from rgbd_rs.fusion.evaluate import Sample, evaluate_sample, middlebury_samples, synth_samples
from rgbd_rs.fusion.lc import lc_fuse
from rgbd_rs.nn.confidence import ConfidenceEstimator

Gate = Callable[[dict[str, np.ndarray]], np.ndarray]


def suspects(m: dict[str, np.ndarray]) -> np.ndarray:
    """SGM more than 1 px nearer than the ToF, within 2 px of a ToF depth edge."""
    t = np.nan_to_num(m["tof"], nan=0.0)
    edge = ndimage.maximum_filter(t, 3) - ndimage.minimum_filter(t, 3) > 1.0
    return ndimage.binary_dilation(edge, iterations=2) & (m["sgm"] - m["tof"] > 1.0)


GATES: dict[str, Gate | None] = {
    "default": None,
    "fattening gate": lambda m: np.where(suspects(m), 0.0, m["ps"]),
    "gate where P_T > 0.6": lambda m: np.where(suspects(m) & (m["pt"] > 0.6), 0.0, m["ps"]),
}


def scores(samples: list[Sample], est: ConfidenceEstimator) -> dict[str, list[tuple[float, ...]]]:
    out: dict[str, list[tuple[float, ...]]] = {k: [] for k in GATES}
    for s in samples:
        r = evaluate_sample(s, estimator=est)
        ref, tgt, sign = views(s.left, s.right, s.rig.reference)
        m = {
            "tof": r.maps["Interpolated ToF"],
            "sgm": r.maps["SGM"],
            "pt": r.maps["P_T"],
            "ps": r.maps["P_S"],
        }
        scene = SceneInputs.of((m["tof"], m["sgm"]), r.maps["gt"], r.maps["mask"] > 0)
        for name, gate in GATES.items():
            if gate is None:
                fused = r.maps["LC ConvNet"]
            else:
                ps = gate(m).astype(np.float32)
                fused, _ = lc_fuse(ref, tgt, [m["tof"], m["sgm"]], [m["pt"], ps], target_sign=sign)
            out[name].append(scene.score(fused))
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__)
        return 2
    est = ConfidenceEstimator.load()
    sets = {
        "validation": list(synth_samples(argv[0], "test")),
        "synthetic test": list(synth_samples(argv[1], "test")),
        "Middlebury": middlebury_samples(),
    }
    print("| dataset | LC | mean RMS (px) | mean fused / better input | worst fused / good input |")
    print("|---|---|---:|---:|---:|")
    for name, samples in sets.items():
        for gate, rows in scores(samples, est).items():
            a = np.array(rows)
            print(
                f"| {name} | {gate} | {a[:, 0].mean():.3f} | {a[:, 1].mean():.3f} | "
                f"{a[:, 2].max():.3f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
