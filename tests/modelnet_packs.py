"""Small shape sources for the shape tests: point packs cut from the shared ModelNet10 pack, and
two boxes as a mesh source."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rgbd_rs.meshes import Mesh, box
from rgbd_rs.shapes.dataset import PointCloudSet, ShapeSource


def modelnet10_subset(
    shared_data: Path, path: Path, classes: Sequence[int], per_split: Sequence[tuple[int, int]]
) -> Path:
    """Write to ``path`` a pack of the first ``n`` shapes of split ``s`` for each ``(s, n)`` of
    ``per_split`` and each ModelNet10 class index of ``classes`` (renumbered 0.. in that order);
    returns ``path``."""
    src = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz")
    pick = [
        i
        for c in classes
        for s, n in per_split
        for i in np.flatnonzero((src.labels == c) & (src.splits == s))[:n]
    ]
    np.savez(
        path,
        points=src.points[pick],
        label=np.searchsorted(classes, src.labels[pick]).astype(np.int16),
        split=src.splits[pick],
        classes=np.array([src.classes[c] for c in classes]),
        name=np.array([src.names[i] for i in pick]),
    )
    return path


class Boxes(ShapeSource):
    """Two boxes with sides ``sides``, one training and one test shape: a mesh source."""

    kind = "mesh"

    def __init__(self, sides: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> None:
        self.path = Path("boxes")
        self.classes = ("box",)
        self.labels = np.zeros(2, np.int64)
        self.splits = np.array([0, 1], np.uint8)
        self.names = ("a", "b")
        self.sides = sides

    def load(self, index: int) -> Mesh:
        return box(self.sides)
