"""Rotation about the vertical axis and mirroring, done exactly on the network inputs (no
re-rendering).

ModelNet's shapes stand upright (z up) but face any direction, so a classifier should not care
about a turn about z. A quarter turn of a shape maps its bounding cube onto itself, so its inputs
are a permutation of the old ones (checked against re-rendered inputs in
``tests/test_shapes_augment.py``): side view ``k`` becomes view ``k + 1`` unchanged, the top view
turns by +90° and the bottom view by -90° in the image (see :mod:`rgbd_rs.shapes.views` for the
view frames), the X and Y density profiles swap (the new Y map is the old X map turned and
transposed) and the Z map turns by +90°. Curvature maps move like the depth views they come from.
Local contrast normalisation and per-map standardisation commute with these moves, so they apply
to cached, normalised inputs.

A mirror image of a shape (x -> -x, the reflection through the plane x = 0 of its bounding cube)
is also a permutation of its inputs (:func:`_mirror_inputs`, checked the same way): the +x and -x
side views swap and every view image is flipped left-right (the +y and -y side views, top and
bottom included: their image's right is +-x or their view direction is x), the X density profile
stays and the Y and Z profiles flip left-right. Curvatures are invariant under a reflection of
the image. Unlike a quarter turn this keeps the front of an aligned ModelNet shape where it was
(a chair's mirror image is still a chair facing the same way).

Training can draw a random number of quarter turns per shape and step (:class:`RotatedShapes`,
``ShapeRecipe(rotate=True)``, ``rgbd train shapes --rotate``) and a random mirror image
(:class:`AugmentedShapes`, ``ShapeRecipe(mirror=True)``, ``--mirror``); evaluation can average
the class probabilities over the four turns (:func:`_quarter_turns`) and over the mirror image
(:func:`_mirror_pair`), cheap test-time augmentations.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from torch.utils.data import Dataset

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn.shapes import pack, unpack

__all__ = [
    "AugmentedShapes",
    "MixedShapes",
    "RotatedShapes",
]

_SIDES = 4


def _rot(t: torch.Tensor, k: int) -> torch.Tensor:
    """Turn the images (last two axes) by ``k`` quarter turns counter-clockwise (``np.rot90``)."""
    return torch.rot90(t, k, dims=(-2, -1))


def _turn_views(v: torch.Tensor) -> torch.Tensor:
    """One +90° turn of ``N x 6 x ...`` view maps (depth or curvature)."""
    return torch.cat(
        [v[:, 3:4], v[:, 0:3], _rot(v[:, 4:5], 1), _rot(v[:, 5:6], 3)], dim=1
    ).contiguous()


def _turn_volume(v: torch.Tensor) -> torch.Tensor:
    """One +90° turn of ``N x 3 x R x R`` density profiles (X, Y, Z maps)."""
    y = _rot(v[:, 0:1], 1).transpose(-2, -1)
    return torch.cat([v[:, 1:2], y, _rot(v[:, 2:3], 1)], dim=1).contiguous()


_TURNS = {"depth": _turn_views, "curvature": _turn_views, "volume": _turn_volume}


def _flip(t: torch.Tensor) -> torch.Tensor:
    """Flip the images (last axis: columns) left-right."""
    return torch.flip(t, dims=(-1,))


def _mirror_views(v: torch.Tensor) -> torch.Tensor:
    """``N x 6 x ...`` view maps (depth or curvature) of the shape mirrored in x."""
    return torch.cat(
        [_flip(v[:, 2:3]), _flip(v[:, 1:2]), _flip(v[:, 0:1]), _flip(v[:, 3:6])], dim=1
    )


def _mirror_volume(v: torch.Tensor) -> torch.Tensor:
    """``N x 3 x R x R`` density profiles (X, Y, Z maps) of the shape mirrored in x."""
    return torch.cat([v[:, 0:1], _flip(v[:, 1:3])], dim=1)


_MIRRORS = {"depth": _mirror_views, "curvature": _mirror_views, "volume": _mirror_volume}


def _check_names(inputs: Mapping[str, torch.Tensor]) -> None:
    for name in inputs:
        if name not in _TURNS:
            raise InvalidArgumentError(
                f"inputs: got representation {name!r}, expected one of {sorted(_TURNS)}"
            )


def _turn_inputs(inputs: Mapping[str, torch.Tensor], turns: int) -> dict[str, torch.Tensor]:
    """The inputs (``{representation: N x ...}``) of the shapes turned by ``turns`` quarter turns
    counter-clockwise about z (seen from above); any integer, taken modulo 4."""
    k = _validate.integer("turns", turns, minimum=-(2**31), maximum=2**31 - 1) % _SIDES
    _check_names(inputs)
    out: dict[str, torch.Tensor] = {}
    for name, value in inputs.items():
        t = value
        for _ in range(k):
            t = _TURNS[name](t)
        out[name] = t
    return out


def _mirror_inputs(inputs: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The inputs (``{representation: N x ...}``) of the shapes mirrored in x (x -> -x)."""
    _check_names(inputs)
    return {name: _MIRRORS[name](value).contiguous() for name, value in inputs.items()}


def _mirror_pair(x: torch.Tensor, shapes: Mapping[str, tuple[int, ...]]) -> list[torch.Tensor]:
    """The packed batch ``x`` and its mirror image (see :func:`_mirror_inputs`)."""
    return [x, pack(_mirror_inputs(unpack(x, shapes)), shapes)]


def _quarter_turns(x: torch.Tensor, shapes: Mapping[str, tuple[int, ...]]) -> list[torch.Tensor]:
    """The packed batch ``x`` (see :func:`rgbd_rs.nn.shapes.pack`) under 0, 1, 2 and 3 turns."""
    parts = unpack(x, shapes)
    return [pack(_turn_inputs(parts, k), shapes) for k in range(_SIDES)]


class AugmentedShapes(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """``dataset`` (items ``(packed inputs, label)``) with each item turned by a random number
    of quarter turns (``turns``) and/or mirrored with probability 1/2 (``mirror``), drawn from
    torch's generator (seeded by the trainer: deterministic)."""

    def __init__(
        self,
        dataset: Any,
        shapes: Mapping[str, tuple[int, ...]],
        *,
        turns: bool = True,
        mirror: bool = False,
    ) -> None:
        for name, flag in (("turns", turns), ("mirror", mirror)):
            if not isinstance(flag, bool):
                raise InvalidArgumentError(f"{name}: got {flag!r}, expected True or False")
        self.dataset = dataset
        self.shapes = dict(shapes)
        self.turns = turns
        self.mirror = mirror

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        x, y = self.dataset[i]
        k = int(torch.randint(0, _SIDES, ()).item()) if self.turns else 0
        m = bool(torch.randint(0, 2, ()).item()) if self.mirror else False
        if k == 0 and not m:
            return x, y
        parts = unpack(x[None], self.shapes)
        if m:
            parts = _mirror_inputs(parts)
        if k:
            parts = _turn_inputs(parts, k)
        return pack(parts, self.shapes)[0], y


class RotatedShapes(AugmentedShapes):
    """``dataset`` with each item turned by a random number of quarter turns drawn from torch's
    generator (seeded by the trainer: deterministic); :class:`AugmentedShapes` with turns only."""

    def __init__(self, dataset: Any, shapes: Mapping[str, tuple[int, ...]]) -> None:
        super().__init__(dataset, shapes, turns=True, mirror=False)


#: The mixup ``alpha`` accepted: past the largest Beta(alpha, alpha) is nearly 1/2 everywhere;
#: below the smallest torch's Beta sampler degenerates (it returns 1/2 for alpha ~ 1e-10).
MIN_MIXUP_ALPHA = 0.01
MAX_MIXUP_ALPHA = 100.0


class MixedShapes(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """mixup (Zhang et al. 2018; not in the thesis) of ``dataset`` (items ``(packed inputs,
    label)`` over ``classes`` classes): item ``i`` becomes ``lam * item_i + (1 - lam) * item_j``
    for a random other item ``j`` of the dataset and ``lam ~ Beta(alpha, alpha)`` folded onto
    [1/2, 1] (so item ``i``'s own class keeps the larger weight), its label the same mix of the
    two one-hot targets (a float vector of ``classes`` entries, which
    :func:`~rgbd_rs.shapes.train.cross_entropy` and :func:`~rgbd_rs.shapes.train.accuracy`
    take). The mix is of the cached, normalised inputs (as image mixup mixes normalised
    images; a mix of two shapes' raw maps, normalised, would differ). The draws come from
    torch's global generator (seeded by the trainer: deterministic)."""

    def __init__(self, dataset: Any, classes: int, alpha: float) -> None:
        self.dataset = dataset
        self.classes = _validate.integer("classes", classes, minimum=2)
        a = _validate.real("alpha", alpha)
        if not MIN_MIXUP_ALPHA <= a <= MAX_MIXUP_ALPHA:
            raise InvalidArgumentError(
                f"alpha: got {alpha}, expected {MIN_MIXUP_ALPHA:g} <= alpha <= {MAX_MIXUP_ALPHA:g}"
            )
        self.alpha = a
        self._beta = torch.distributions.Beta(
            torch.tensor(a, dtype=torch.float64), torch.tensor(a, dtype=torch.float64)
        )

    def __len__(self) -> int:
        return len(self.dataset)

    def _onehot(self, y: torch.Tensor) -> torch.Tensor:
        return torch.nn.functional.one_hot(y.reshape(()).long(), self.classes).to(torch.float32)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        x, y = self.dataset[i]
        j = int(torch.randint(0, len(self.dataset), ()).item())
        lam = float(self._beta.sample().item())
        lam = max(lam, 1.0 - lam)
        xj, yj = self.dataset[j]
        mixed = lam * x + (1.0 - lam) * xj
        target = lam * self._onehot(y) + (1.0 - lam) * self._onehot(yj)
        return mixed.to(x.dtype), target
