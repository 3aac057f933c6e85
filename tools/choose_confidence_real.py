"""Choose the confidence ConvNet's epoch and stereo power on the real validation cases (issue 29):
every ``OUT/epN.pt`` of ``tools/train_confidence_real.py`` (and the shipped network, on the
census matcher and on the one it was trained on) fuses the val split's scenes under ``--laws``
fixed ToF laws (with ``--dense-protocol``, also each val scene with the dense protocol's ToF,
``rgbd eval fusion --dense``) with ``P_S ** p`` for each power; the choice is the lowest
mean fused / better input among the (epoch, power) pairs that keep every good input within 5 %
(``rgbd_rs.fusion.calibrate.best_score``), else the least damaging pair. The test split is never
read. Writes ``OUT/chosen.pt`` (the power stored in it) and ``OUT/choice.md``.

    python tools/choose_confidence_real.py --out out/conf_real --laws 3
    python tools/choose_confidence_real.py --out out/conf_dense --laws 3 --dense-protocol
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from rgbd_rs.fusion._inputs import FAR_CAMERA_WARNING
from rgbd_rs.fusion.calibrate import best_score, calibrate_stereo_power, write_calibrated
from rgbd_rs.fusion.real_scenes import dense_protocol_samples, real_samples
from rgbd_rs.nn.confidence import WEIGHTS, ConfidenceEstimator


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/conf_real"))
    ap.add_argument("--laws", type=int, default=3, help="fixed ToF laws per val scene (3)")
    ap.add_argument("--powers", type=float, nargs="+", default=[1.0, 1.5, 2.0, 3.0])
    ap.add_argument(
        "--dense-protocol",
        action="store_true",
        help="also the val scenes with the dense protocol's ToF (rgbd eval fusion --dense)",
    )
    ap.add_argument(
        "--far-protocol",
        action="store_true",
        help="also the val scenes fused on the camera far from the ToF (rgbd eval fusion "
        "--view right)",
    )
    ap.add_argument(
        "--epochs",
        type=int,
        help="the training run's --epochs: refuse to choose while epN.pt of any of 1..N is "
        "missing (a run interrupted or still training); without it, epochs 1..max must be there",
    )
    a = ap.parse_args()
    kept = sorted(int(q.stem[2:]) for q in a.out.glob("ep*.pt") if q.stem[2:].isdigit())
    want = list(range(1, (a.epochs if a.epochs is not None else max(kept, default=0)) + 1))
    if missing := sorted(set(want) - set(kept)):
        raise SystemExit(
            f"{a.out}: ep{missing[0]}.pt missing ({len(missing)} of epochs 1..{len(want)}): "
            "finish tools/train_confidence_real.py (it resumes) before choosing"
        )
    samples = list(real_samples("val", a.laws))
    if a.dense_protocol:
        samples += list(dense_protocol_samples("val"))
    if a.far_protocol:
        warnings.filterwarnings("ignore", FAR_CAMERA_WARNING, RuntimeWarning)
        samples += list(real_samples("val", a.laws, view="right"))
    shipped = ConfidenceEstimator.load()
    candidates: dict[str, tuple[Path | None, ConfidenceEstimator]] = {
        f"shipped (trained on {shipped.matcher})": (None, shipped),
    }
    if shipped.matcher != "census":
        candidates["shipped on census"] = (
            None,
            ConfidenceEstimator(shipped.net, shipped.sigmas, str(WEIGHTS), matcher="census"),
        )
    for k in kept:
        p = a.out / f"ep{k}.pt"
        candidates[p.stem] = (p, ConfidenceEstimator.load(p))
    rows = ["| network | power | mean fused RMS px | mean fused / better | worst fused / good |"]
    rows.append("|---|---:|---:|---:|---:|")
    scored = []
    for name, (path, est) in candidates.items():
        cal = calibrate_stereo_power(est, samples, powers=a.powers, quiet=True)
        for s in cal.scores:
            rows.append(
                f"| {name} | {s.power:g} | {s.mean_rms:.3f} | {s.mean_ratio:.3f} | "
                f"{s.worst_damage:.3f} |"
            )
            print(rows[-1], flush=True)
            if path is not None:
                scored.append((s, path))
    if not scored:
        raise SystemExit(f"{a.out}: no epN.pt to choose from")
    best = best_score([s for s, _ in scored])
    path = next(p for s, p in scored if s is best)
    chosen = write_calibrated(path, best.power, a.out / "chosen.pt")
    text = (
        f"Real validation cases: {len(samples)} ({a.laws} ToF laws per val scene"
        + (", and each val scene with the dense protocol's ToF" if a.dense_protocol else "")
        + (", and the val scenes fused on the far camera" if a.far_protocol else "")
        + ")\n\n"
        + "\n".join(rows)
        + f"\n\nChosen: {path.stem}, power {best.power:g} -> {chosen}\n"
    )
    (a.out / "choice.md").write_text(text)
    print(text.splitlines()[-1])


if __name__ == "__main__":
    main()
