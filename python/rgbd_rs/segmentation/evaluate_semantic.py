"""Semantic-labeling scores of the full method (thesis Tables 4.2 and 4.3) for
``rgbd eval segmentation``: pixel and mean class accuracy over NYUv2's 13 classes of the
ConvNet's own per-pixel labels and of the labels after the segment refinement of §4.7 (each
final segment takes one class, :mod:`rgbd_rs.segmentation.refine`), with the per-class accuracies
of both.

Unlabeled ground-truth pixels (label 0) are left out; a prediction is one of the 13 classes.
Pixels without depth get the ConvNet's label in both rows (the merging has no segment there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from rgbd_rs import metrics
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.data.nyuv2 import LABEL13_NAMES, UNLABELED
from rgbd_rs.segmentation.labeling import _weights_path
from rgbd_rs.segmentation.pipeline import Segmentation, segment
from rgbd_rs.segmentation.refine import DEFAULT_POOLING
from rgbd_rs.segmentation.semantic_stage import AUTO, LabelerArg, _resolve_labeler

__all__ = ["LabelingScores", "ours_full"]

#: Classes of the confusion matrices (NYUv2 label13 values, 0 = unlabeled).
N_CLASSES = len(LABEL13_NAMES)

Labels = npt.NDArray[np.integer[Any]]
U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]


@array_eq
@dataclass
class LabelingScores:
    """Confusion matrices (rows truth, columns prediction, NYUv2 label13) accumulated over the
    evaluation frames, for the network and after the segment refinement."""

    network: npt.NDArray[np.int64] = field(
        default_factory=lambda: np.zeros((N_CLASSES, N_CLASSES), np.int64)
    )
    refined: npt.NDArray[np.int64] = field(
        default_factory=lambda: np.zeros((N_CLASSES, N_CLASSES), np.int64)
    )
    frames: int = 0
    source: str = ""

    def add(self, result: Segmentation, truth: npt.ArrayLike) -> None:
        """Count one frame's labels against its ``label13`` ground truth."""
        net, refined = result.network_labels, result.refined_labels
        if net is None or refined is None:
            return
        kw: dict[str, Any] = {"n_classes": N_CLASSES, "ignore": UNLABELED}
        self.network += metrics.confusion_matrix(net, truth, **kw)
        self.refined += metrics.confusion_matrix(refined, truth, **kw)
        self.frames += 1

    @staticmethod
    def _accuracy(cm: npt.NDArray[np.int64]) -> tuple[float, float]:
        total = cm.sum()
        support = cm.sum(axis=1)
        present = support > 0
        pixel = float(np.trace(cm) / total) if total else float("nan")
        cls = (
            float(np.mean(np.diag(cm)[present] / support[present]))
            if present.any()
            else float("nan")
        )
        return pixel, cls

    @property
    def network_accuracy(self) -> tuple[float, float]:
        """(pixel, mean class) accuracy of the ConvNet's per-pixel labels."""
        return self._accuracy(self.network)

    @property
    def refined_accuracy(self) -> tuple[float, float]:
        """(pixel, mean class) accuracy after the segment refinement."""
        return self._accuracy(self.refined)

    def table(self) -> str:
        """Table 4.2: pixel and mean class accuracy, network vs refined."""
        n, r = self.network_accuracy, self.refined_accuracy
        return "\n".join(
            [
                "| labels | pixel accuracy ↑ | mean class accuracy ↑ |",
                "|---|---|---|",
                f"| ConvNet (per pixel) | {100 * n[0]:.1f} % | {100 * n[1]:.1f} % |",
                f"| after segment refinement (§4.7) | {100 * r[0]:.1f} % | {100 * r[1]:.1f} % |",
            ]
        )

    def per_class_table(self) -> str:
        """Table 4.3: accuracy (recall) of each class, network vs refined, and its pixel share."""
        support = self.network.sum(axis=1)
        total = max(int(support.sum()), 1)
        lines = [
            "| class | pixels | ConvNet | refined |",
            "|---|---|---|---|",
        ]
        for c in range(1, N_CLASSES):
            if support[c] == 0:
                lines.append(f"| {LABEL13_NAMES[c]} | 0 % | n/a | n/a |")
                continue
            a = self.network[c, c] / support[c]
            b = self.refined[c, c] / support[c]
            lines.append(
                f"| {LABEL13_NAMES[c]} | {100 * support[c] / total:.1f} % | {100 * a:.1f} % | "
                f"{100 * b:.1f} % |"
            )
        return "\n".join(lines)


class _LastResult:
    """The full method's latest Segmentation, so the evaluation loop scores its labels without
    running it twice."""

    def __init__(self) -> None:
        self.result: Segmentation | None = None

    def take(self) -> Segmentation | None:
        out, self.result = self.result, None
        return out


LAST_FULL = _LastResult()


def ours_full(
    *, n_segments: int, seed: int = 0, labeler: LabelerArg = AUTO, pooling: str = DEFAULT_POOLING
) -> Callable[[U8, F32, PinholeCamera], Labels]:
    """The full method: the pipeline with the semantic ConvNet (``labeler``; the shipped weights
    by default). Raises AttributeError when no ConvNet is available (the evaluation then lists
    the row as not available)."""
    if isinstance(labeler, str) and labeler == AUTO and not _weights_path().is_file():
        raise AttributeError(f"no semantic ConvNet weights installed ({_weights_path().name})")
    net = _resolve_labeler(labeler)
    if net is None:
        raise AttributeError("no semantic ConvNet weights installed or given")

    def run(
        rgb: npt.NDArray[np.uint8], depth: npt.NDArray[np.float32], camera: PinholeCamera
    ) -> Labels:
        result = segment(
            rgb, depth, camera, labeler=net, n_segments=n_segments, pooling=pooling, seed=seed
        )
        LAST_FULL.result = result
        return result.labels

    return run
