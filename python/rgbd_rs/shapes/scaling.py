"""Anisotropic scaling augmentation of shape datasets (``rgbd shapes cache --scale-copies K``).

Point-cloud classifiers (DGCNN, SimpleView) train on shapes whose axes are each scaled by a random
factor in [2/3, 3/2]. That changes a shape's proportions, so its six views, density profiles and
curvature maps change with it: unlike the quarter turns and mirror images of
:mod:`rgbd_rs.shapes.augment` it cannot be done on cached tensors. :class:`ScaledCopies` appends
``copies`` scaled copies of every *training* shape to a source (test shapes are never copied);
:func:`rgbd_rs.shapes.dataset.build_cache` stores them as extra rows named ``NAME#s1``,
``NAME#s2``, ... and records the augmentation in the cache's meta.json, and
:func:`rgbd_rs.shapes.train.train_shapes` draws its validation split over the original shapes,
leaves a validation shape's copies out and keeps every other copy with its original.

Each copy's three factors come from ``numpy.random.default_rng([seed, copy, shape])``, so a
sharded cache build computes the same copies in any order. Optionally (``turn``, ``jitter``; off by
default) each copy is also turned about the up axis z by an angle drawn from U(-turn, turn) degrees
and its points (a mesh's vertices) moved by Gaussian noise of ``jitter`` times the shape's radius
(clipped at 5 sigma), the point-cloud classifiers' other augmentations; they come from a second
stream, ``default_rng([seed, copy, shape, 1])``, so the scale factors stay those of a cache
without them. ``drop`` (off by default) removes from each copy of a point cloud a fraction of its
points drawn from U(0, drop), each point leaving with that probability (PointNet++'s random input
dropout; at least one point stays), from a third stream, ``default_rng([seed, copy, shape, 2])``,
so the kept points are moved exactly as in a cache without it. A mesh's copies keep every vertex
(its triangles need them).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes.dataset import TRAIN, Shape, ShapeSource

__all__ = ["COPY_SEP", "SCALE_RANGE", "ScaledCopies", "original_name", "original_rows"]

#: Range of each axis' factor (DGCNN's and SimpleView's point-cloud augmentation).
SCALE_RANGE = (2.0 / 3.0, 1.5)
#: Separates a copy's suffix from its original's name (``chair_0001#s2``).
COPY_SEP = "#"
#: Most copies per training shape.
MAX_COPIES = 64
#: Allowed factors: far beyond them float32 points underflow to 0 or overflow to inf.
SCALE_LIMITS = (1e-3, 1e3)
#: Largest turn about z (degrees) and point jitter (a fraction of the shape's radius).
MAX_TURN = 180.0
MAX_JITTER = 0.5
#: Largest ``drop``: the expected fraction of a copy's points removed is at most half of it.
MAX_DROP = 0.95
#: Jitter is clipped at this many standard deviations (PointNet's 0.05 for sigma 0.01).
JITTER_CLIP = 5.0


def original_name(name: str) -> str:
    """The name of the shape a cache row was copied from (``name`` itself for an original)."""
    return name.split(COPY_SEP, 1)[0]


def original_rows(augmentation: Mapping[str, Any] | None, splits: npt.ArrayLike) -> np.ndarray:
    """For every row of a cache, the row of the original shape it was copied from (its own row
    for an original), from the cache's meta.json ``augmentation`` record (None: no copies) and
    its per-row ``splits``; the rows follow :class:`ScaledCopies`' order."""
    sp = np.asarray(splits)
    rows = np.arange(len(sp), dtype=np.int64)
    if not augmentation:
        return rows
    n = int(augmentation["originals"])
    train = np.flatnonzero(sp[:n] == TRAIN)
    if len(train):
        rows[n:] = train[(rows[n:] - n) % len(train)]
    return rows


class ScaledCopies(ShapeSource):
    """``source``'s shapes, then ``copies`` rounds of its training shapes, each axis of each copy
    scaled by a factor drawn uniformly from ``scale_range`` (about the origin: the inputs are
    computed in the shape's bounding cube, so only the proportions matter)."""

    def __init__(
        self,
        source: ShapeSource,
        copies: int,
        scale_range: tuple[float, float] = SCALE_RANGE,
        seed: int = 0,
        turn: float = 0.0,
        jitter: float = 0.0,
        drop: float = 0.0,
    ) -> None:
        if not isinstance(source, ShapeSource):
            raise InvalidArgumentError(
                f"source: got {type(source).__name__}, expected a rgbd_rs.shapes ShapeSource"
            )
        self.copies = _validate.integer("copies", copies, minimum=1, maximum=MAX_COPIES)
        rng = _validate.array("scale_range", scale_range, shape=(2,), dtype=np.float64)
        low, high = float(rng[0]), float(rng[1])
        if not SCALE_LIMITS[0] <= low <= high <= SCALE_LIMITS[1]:
            raise InvalidArgumentError(
                f"scale_range: got {tuple(scale_range)}, expected {SCALE_LIMITS[0]:g} <= low <= "
                f"high <= {SCALE_LIMITS[1]:g}"
            )
        self.scale_range = (low, high)
        self.seed = _validate.integer("seed", seed, minimum=0, maximum=2**32 - 1)
        self.turn = _validate.real("turn", turn, nonnegative=True)
        if self.turn > MAX_TURN:
            raise InvalidArgumentError(f"turn: got {turn!r}, expected 0 <= turn <= {MAX_TURN:g}")
        self.jitter = _validate.real("jitter", jitter, nonnegative=True)
        if self.jitter > MAX_JITTER:
            raise InvalidArgumentError(
                f"jitter: got {jitter!r}, expected 0 <= jitter <= {MAX_JITTER:g}"
            )
        self.drop = _validate.real("drop", drop, nonnegative=True)
        if self.drop > MAX_DROP:
            raise InvalidArgumentError(f"drop: got {drop!r}, expected 0 <= drop <= {MAX_DROP:g}")
        clash = [n for n in source.names if COPY_SEP in n]
        if clash:
            raise InvalidArgumentError(
                f"source: got shape names with {COPY_SEP!r} (e.g. {clash[0]!r}), expected none: "
                "it marks the scaled copies"
            )
        self.base = source
        self.kind = source.kind
        self.path = source.path
        self.classes = source.classes
        self._train = np.flatnonzero(source.splits == TRAIN).astype(np.int64)
        reps = self.copies
        self.labels = np.concatenate([source.labels, np.tile(source.labels[self._train], reps)])
        self.splits = np.concatenate([source.splits, np.tile(source.splits[self._train], reps)])
        self.names = source.names + tuple(
            f"{source.names[k]}{COPY_SEP}s{c + 1}" for c in range(reps) for k in self._train
        )

    @property
    def augmentation(self) -> dict[str, Any]:
        """What the cache's meta.json records about the copies."""
        record: dict[str, Any] = {
            "scale_copies": self.copies,
            "scale_range": list(self.scale_range),
            "scale_seed": self.seed,
            "originals": len(self.base),
        }
        # Recorded only when on, so caches built before these options still resume.
        if self.turn:
            record["copy_turn"] = self.turn
        if self.jitter:
            record["copy_jitter"] = self.jitter
        if self.drop:
            record["copy_drop"] = self.drop
        return record

    def _content_digest(self, h: Any) -> None:
        self.base._content_digest(h)  # the copies follow from it and the augmentation record

    def _origin(self, index: int) -> tuple[int, int]:
        """(copy round 1.., original index) of row ``index``; round 0 for an original."""
        n = len(self.base)
        if index < n:
            return 0, index
        c, j = divmod(index - n, len(self._train))
        return c + 1, int(self._train[j])

    def scale(self, index: int) -> npt.NDArray[np.float64]:
        """The three axis factors of row ``index`` (ones for an original shape)."""
        c, k = self._origin(self._index(index))
        if c == 0:
            return np.ones(3)
        low, high = self.scale_range
        return np.random.default_rng([self.seed, c, k]).uniform(low, high, 3)

    def turn_angle(self, index: int) -> float:
        """The turn about z (degrees) of row ``index`` (0 for an original or with ``turn`` 0)."""
        c, k = self._origin(self._index(index))
        if c == 0 or not self.turn:
            return 0.0
        return float(self._extra_rng(c, k).uniform(-self.turn, self.turn))

    def _extra_rng(self, c: int, k: int) -> np.random.Generator:
        """The turn's and the jitter's stream (the angle first, then the noise)."""
        return np.random.default_rng([self.seed, c, k, 1])

    def _move(self, xyz: npt.NDArray[Any], c: int, k: int) -> npt.NDArray[np.float32]:
        """Scale, turn and jitter points (N, 3) as copy round ``c`` of original ``k``."""
        low, high = self.scale_range
        p = np.asarray(xyz, np.float64) * np.random.default_rng([self.seed, c, k]).uniform(
            low, high, 3
        )
        if self.turn or self.jitter:
            rng = self._extra_rng(c, k)
            a = np.deg2rad(rng.uniform(-self.turn, self.turn)) if self.turn else 0.0
            if a:
                ca, sa = np.cos(a), np.sin(a)
                p = p @ np.array([[ca, sa, 0.0], [-sa, ca, 0.0], [0.0, 0.0, 1.0]])
            if self.jitter and len(p):
                finite = p[np.isfinite(p).all(axis=1)]
                radius = (
                    float(np.linalg.norm(finite - finite.mean(0), axis=1).max())
                    if len(finite)
                    else 0.0
                )
                sigma = self.jitter * radius
                noise = np.clip(rng.standard_normal(p.shape), -JITTER_CLIP, JITTER_CLIP)
                p = p + sigma * noise
        return p.astype(np.float32)

    def kept(self, index: int, count: int) -> npt.NDArray[np.bool_]:
        """Which of the ``count`` points of row ``index`` its copy keeps (all of them for an
        original or with ``drop`` 0)."""
        c, k = self._origin(self._index(index))
        return self._keep(c, k, _validate.integer("count", count, minimum=0))

    def _keep(self, c: int, k: int, n: int) -> npt.NDArray[np.bool_]:
        """:meth:`kept` of copy round ``c`` of original ``k`` with ``n`` points."""
        if c == 0 or not self.drop or n == 0:
            return np.ones(n, dtype=bool)
        rng = np.random.default_rng([self.seed, c, k, 2])
        ratio = rng.uniform(0.0, self.drop)
        keep = rng.random(n) >= ratio
        if not keep.any():
            keep[int(rng.integers(n))] = True
        return keep

    def load(self, index: int) -> Shape:
        """Row ``index``: an original shape as its source gives it, or a copy of a training shape
        with its axes multiplied by :meth:`scale`, turned by :meth:`turn_angle` and jittered (a
        Mesh's vertices or a cloud's points), and for a cloud only its :meth:`kept` points."""
        i = self._index(index)
        c, k = self._origin(i)
        shape = self.base.load(k)
        if c == 0:
            return shape
        if isinstance(shape, Mesh):
            return Mesh(self._move(shape.vertices, c, k), shape.triangles)
        moved = self._move(shape, c, k)
        return moved[self._keep(c, k, len(moved))] if self.drop else moved
