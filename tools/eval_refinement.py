"""The segment refinement of §4.7 on real data: which pooling gives each final segment its class?

Runs the full pipeline (shipped semantic ConvNet, ``--segments`` normalized-cuts clusters: 230,
the value ``rgbd eval segmentation`` tunes) once per NYUv2 frame of ../shared/data and scores,
over NYUv2's 13 classes (unlabeled pixels left out), the ConvNet's per-pixel labels and the
refined labels with each pooling of :func:`rgbd_rs.segmentation.segment_classes` on the final
segments and, for comparison, on the over-segmentation. Frame groups: the 25 test frames, the 5
train frames the shipped network's fine-tuning held out for validation (``0016 0017 0035 0036
0038``), and the other 20 train frames (seen in training: the network is much better there, so
this row shows the refinement with a stronger network, not an unbiased score).

    python tools/eval_refinement.py [--segments 230]
"""

from __future__ import annotations

import argparse

import numpy as np
from tqdm import tqdm

from rgbd_rs.data.nyuv2 import LABEL13_NAMES, load_nyuv2_frame, nyuv2_frames
from rgbd_rs.segmentation import segment, segment_classes
from rgbd_rs.segmentation.refine import POOLINGS
from rgbd_rs.segmentation.semantic_stage import _resolve_labeler

#: The train frames the shipped network's fine-tuning validated on (seeded 20 % split).
HELD_OUT_TRAIN = (16, 17, 35, 36, 38)
C = len(LABEL13_NAMES)


def _confusion(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    keep = truth > 0
    idx = truth[keep].astype(np.int64) * C + pred[keep].astype(np.int64)
    return np.bincount(idx, minlength=C * C).reshape(C, C)


def _accuracy(cm: np.ndarray) -> tuple[float, float]:
    support = cm.sum(axis=1)
    present = support > 0
    return float(np.trace(cm) / cm.sum()), float(np.mean(np.diag(cm)[present] / support[present]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segments", type=int, default=230, help="normalized-cuts clusters (230)")
    args = ap.parse_args()
    net = _resolve_labeler("auto")
    groups = {
        "test (25)": list(nyuv2_frames("test")),
        "held-out train (5)": list(HELD_OUT_TRAIN),
        "seen train (20)": [i for i in nyuv2_frames("train") if i not in HELD_OUT_TRAIN],
    }
    rows = ["network (per pixel)"] + [
        f"{p} pooling, {seg}" for seg in ("final segments", "over-segmentation") for p in POOLINGS
    ]
    scores: dict[str, dict[str, np.ndarray]] = {g: {} for g in groups}
    for group, ids in groups.items():
        for i in tqdm(ids, desc=group, leave=False):
            f = load_nyuv2_frame(i)
            r = segment(f.rgb, f.depth, f.camera, labeler=net, n_segments=args.segments)
            assert r.pdfs is not None and r.network_labels is not None
            preds = {rows[0]: r.network_labels}
            for seg_name, seg in (("final segments", r.labels), ("over-segmentation", r.over)):
                for p in POOLINGS:
                    cls = segment_classes(seg, r.pdfs, p)
                    preds[f"{p} pooling, {seg_name}"] = np.where(cls >= 0, cls, r.network_labels)
            for name, pred in preds.items():
                scores[group][name] = scores[group].get(name, 0) + _confusion(pred, f.label13)
    head = " | ".join(groups)
    print(f"| labels | {head} |")
    print("|---|" + "---|" * len(groups))
    for name in rows:
        cells = []
        for g in groups:
            px, cl = _accuracy(scores[g][name])
            cells.append(f"{100 * px:.1f} / {100 * cl:.1f}")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print("(pixel / mean class accuracy, %, 13 classes, unlabeled pixels left out)")


if __name__ == "__main__":
    main()
