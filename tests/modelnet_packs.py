"""Small point packs cut from the shared ModelNet10 pack, for the shape tests."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rgbd_rs.shapes.dataset import PointCloudSet


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
