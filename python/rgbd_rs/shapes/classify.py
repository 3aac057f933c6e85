"""Classify one shape with a trained 15-branch ConvNet (thesis ch. 5).

``classify(shape)`` runs the weights shipped in the package (``rgbd_rs/nn/weights/
shapes_modelnet40.pt``, else ``shapes_modelnet10.pt``) or any checkpoint written by ``rgbd train
shapes``. The checkpoint records how its inputs were computed (:class:`~rgbd_rs.shapes.dataset.
InputSpec`) and whether it was trained on point clouds: a mesh given to a point-cloud model is
first sampled into as many surface points as its training shapes had (1024 for the ModelNet
packs), so both see the same kind of input.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.meshes import Mesh
from rgbd_rs.nn.shape_ensemble import ShapeEnsemble, _shape_network
from rgbd_rs.nn.shapes import ARCH, ShapeNet, pack
from rgbd_rs.shapes._cloud import check_extent
from rgbd_rs.shapes.augment import _quarter_turns
from rgbd_rs.shapes.dataset import (
    InputSpec,
    Shape,
    _shape_arg,
    batch_inputs,
    load_shape,
    sample_surface,
)

__all__ = [
    "UP_ROTATIONS",
    "WEIGHT_FILES",
    "ShapeClassifier",
    "classify",
    "shipped_weights",
    "to_z_up",
]

#: The checkpoints the package may ship, by dataset.
WEIGHT_FILES = {"modelnet10": "shapes_modelnet10.pt", "modelnet40": "shapes_modelnet40.pt"}
_WEIGHTS_DIR = Path(__file__).resolve().parents[1] / "nn" / "weights"
#: Seed of the surface sampling of meshes (deterministic classification).
SAMPLE_SEED = 0
#: A cloud of at most the network's point count is read without its repeated points when they
#: are over a tenth of it (ModelNet's packs hold one repeat in 67 of 4899 shapes: kept as is).
REPEATS_KEPT = 0.9
#: A cloud with fewer points than this share of the network's training clouds' warns (256 for
#: ModelNet's 1024: a helper measured 86 % at 512 points, 69 % at 200, against 89 % on
#: ModelNet40 test).
SPARSE_FRACTION = 0.25
#: Rotations taking a shape whose ``up`` axis is the key to the z-up frame the networks were
#: trained in (ModelNet's aligned models). Many PLY / OBJ files (the Stanford bunny, ShapeNet)
#: are y-up; a y-up chair given as z-up lies on its back and is classified as something else.
UP_ROTATIONS: dict[str, npt.NDArray[np.float64]] = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
}


def to_z_up(shape: Mesh | npt.ArrayLike, up: str) -> Shape:
    """``shape`` (a Mesh or an ``N x 3`` cloud, validated; a cloud comes back float32) rotated
    so that its ``up`` axis (``"x"``, ``"y"`` or ``"z"``) becomes +z (a proper rotation: the
    y-up frame's +y goes to +z, its +z to -y); ``"z"`` leaves it as it is."""
    r = UP_ROTATIONS[_validate.choice("up", up, tuple(UP_ROTATIONS))]
    x = _shape_arg("shape", shape, centre=False)  # the caller's points, turned in place
    if up == "z":
        return x
    if isinstance(x, Mesh):
        return x.transformed(r)
    return (np.asarray(x, np.float64) @ r.T).astype(np.float32)


def _load_named(name: str, path: str | os.PathLike[str]) -> Shape:
    """:func:`load_shape` of ``path``, its refusals naming the caller's argument ``name``."""
    try:
        return load_shape(path)
    except InvalidArgumentError as exc:
        text = str(exc)
        if text.startswith("path: "):
            raise InvalidArgumentError(f"{name}: {text[len('path: ') :]}") from None
        raise


def _spread(name: str, points: npt.NDArray[np.float32], what: str) -> None:
    """Refuse a shape whose points lie on one point or one line: its views are empty or a
    stroke, and the network would still name a class with confidence."""
    check_extent(name, points)
    p = np.asarray(points, np.float64)
    c = p - p.mean(axis=0) if len(p) else p
    ev = np.sort(np.linalg.eigvalsh(c.T @ c))[::-1] if len(p) else np.zeros(3)
    if not ev[0] > 0 or ev[1] <= 1e-12 * ev[0]:
        where = "one point" if not ev[0] > 0 else "one line"
        got = "a single point" if len(p) == 1 else f"{len(p)} {what} that all lie on {where}"
        raise InvalidArgumentError(
            f"{name}: got {got}, expected a 3-D shape (a surface or a solid)"
        )


def _subset(points: npt.NDArray[np.float32], n: int) -> npt.NDArray[np.float32]:
    """A seeded subset of ``n`` of ``points``, in their order."""
    pick = np.random.default_rng(SAMPLE_SEED).choice(len(points), n, replace=False)
    return points[np.sort(pick)]


def _distinct(points: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """``points`` without their exact repeats, in their order (first occurrences), by a 64-bit
    hash of each point's bits (a sort of integers: 4 s for 10 M points, where comparing rows
    takes 15 s; only run when a subset holds repeats; a collision, about 1 in 2^64 per pair,
    would drop one point)."""
    # + 0 makes -0.0 the same point as 0.0.
    bits = np.ascontiguousarray(points + np.float32(0), np.float32).view(np.uint32)
    bits = bits.astype(np.uint64)
    with np.errstate(over="ignore"):
        h = (
            bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
            ^ bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
            ^ bits[:, 2] * np.uint64(0x165667B19E3779F9)
        )
    _, first = np.unique(h, return_index=True)
    return points if len(first) == len(points) else points[np.sort(first)]


def _weights_path(dataset: str) -> Path:
    """Where the package keeps ``dataset``'s shipped weights (the file may be absent)."""
    name = _validate.choice("dataset", dataset, tuple(WEIGHT_FILES))
    return _WEIGHTS_DIR / WEIGHT_FILES[name]


def shipped_weights() -> dict[str, Path]:
    """The shipped checkpoints present in this installation, by dataset."""
    return {d: _weights_path(d) for d in WEIGHT_FILES if _weights_path(d).is_file()}


class ShapeClassifier:
    """A trained :class:`~rgbd_rs.nn.shapes.ShapeNet` (or a
    :class:`~rgbd_rs.nn.shape_ensemble.ShapeEnsemble` of several, whose class probabilities are
    averaged) with its input spec and class names.

    ``ShapeClassifier.load()`` reads the shipped weights (ModelNet40 when present, else
    ModelNet10; ``dataset=`` picks one), ``load(path)`` any ``rgbd train shapes`` checkpoint. A
    missing file, another architecture or missing metadata raise :class:`RgbdError` naming it.
    """

    def __init__(
        self,
        net: ShapeNet | ShapeEnsemble,
        spec: InputSpec,
        classes: tuple[str, ...],
        *,
        kind: str = "points",
        points_per_shape: int | None = None,
        source: str = "",
    ) -> None:
        if not isinstance(net, (ShapeNet, ShapeEnsemble)):
            raise InvalidArgumentError(
                f"net: got {type(net).__name__}, expected a ShapeNet or a ShapeEnsemble"
            )
        if not isinstance(spec, InputSpec):
            raise InvalidArgumentError(f"spec: got {type(spec).__name__}, expected an InputSpec")
        if (
            not isinstance(classes, (tuple, list))
            or len(classes) != net.n_classes
            or not all(isinstance(c, str) for c in classes)
        ):
            got = (
                f"{len(classes)} names"
                if isinstance(classes, (tuple, list))
                else type(classes).__name__
            )
            raise InvalidArgumentError(f"classes: got {got}, expected {net.n_classes} names (str)")
        if spec.representations != net.representations:
            raise InvalidArgumentError(
                f"spec: representations {list(spec.representations)}, expected the network's "
                f"{list(net.representations)}"
            )
        self.net = net
        self.spec = spec
        self.classes = tuple(classes)
        self.kind = _validate.choice("kind", kind, ("points", "mesh"))
        self.points_per_shape = (
            None
            if points_per_shape is None
            else _validate.integer("points_per_shape", points_per_shape, minimum=1)
        )
        self.source = source

    @classmethod
    def load(
        cls,
        path: str | os.PathLike[str] | None = None,
        *,
        dataset: str | None = None,
        device: str = "cpu",
    ) -> ShapeClassifier:
        """The shipped weights (``path=None``) or the checkpoint at ``path``."""
        from rgbd_rs.nn.checkpoint import load_checkpoint

        _validate.device("device", device)
        if path is None:
            file = _default_weights(dataset)
        elif dataset is not None:
            raise InvalidArgumentError(
                f"path: got {str(path)!r} together with dataset={dataset!r}; expected one of the "
                "two (dataset picks the shipped weights)"
            )
        elif not isinstance(path, (str, os.PathLike)) or not str(path):
            raise InvalidArgumentError(f"path: got {path!r}, expected a checkpoint file")
        else:
            file = Path(path)
        ckpt = load_checkpoint(file, arch=ARCH, normalisation_keys=("spec", "classes"))
        norm = ckpt.normalisation
        try:
            net = _shape_network(ckpt.arch_config)
            spec = InputSpec.from_dict(norm["spec"])
            classes = tuple(str(c) for c in norm["classes"])
            out = cls(
                net,
                spec,
                classes,
                kind=str(norm.get("kind", "points")),
                points_per_shape=norm.get("points_per_shape"),
                source=str(file),
            )
        except RgbdError as exc:
            raise RgbdError(f"{file}: invalid shape-classifier checkpoint ({exc})") from None
        state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt.model_state.items()}
        dataclasses.replace(ckpt, model_state=state).load_weights(net)
        net.to(device)
        net.eval()
        return out

    def _prepare(
        self, shape: Mesh | npt.ArrayLike | str | os.PathLike[str], up: str, name: str = "shape"
    ) -> Shape:
        x: Any = _load_named(name, shape) if isinstance(shape, (str, os.PathLike)) else shape
        x = to_z_up(_shape_arg(name, x), up)  # validated under the caller's name
        n = self.points_per_shape or 1024
        if isinstance(x, Mesh) and self.kind == "points":
            x = sample_surface(x, n, SAMPLE_SEED)
            _spread(name, x, "surface samples of the mesh")
        elif isinstance(x, Mesh):
            check_extent(name, x.vertices, "a mesh")
            _spread(name, x.vertices, "vertices")
        else:
            _spread(name, x, "points")
            if self.kind == "points" and len(x) > n:
                # A dense scan: the network saw n-point clouds (ModelNet's packs), and
                # rendering millions of points took minutes. A seeded subset of n points; if it
                # holds repeated points (they add nothing and crowd others out), the subset of
                # the distinct ones.
                sub = _subset(x, n)
                if len(_distinct(sub)) < n:
                    x = _distinct(x)
                    sub = x if len(x) <= n else _subset(x, n)
                x = sub
            elif self.kind == "points":
                distinct = _distinct(x)
                if len(distinct) < REPEATS_KEPT * len(x):  # mostly repeats: the points they are
                    x = distinct
            if self.kind == "points" and len(x) < SPARSE_FRACTION * n:
                warnings.warn(
                    f"{name}: {len(x)} points, where the network was trained on {n}-point "
                    f"clouds; below ~{SPARSE_FRACTION * n:.0f} it errs far more often "
                    "(ModelNet40 test shapes cut to 200 points: 69 % right against 89 % at 1024)",
                    RuntimeWarning,
                    stacklevel=4,
                )
        return x  # type: ignore[no-any-return]

    def probabilities(
        self,
        shapes: list[Mesh | npt.ArrayLike | str | os.PathLike[str]],
        *,
        workers: int = 1,
        up: str = "z",
        turns: bool = False,
    ) -> npt.NDArray[np.float32]:
        """``N x n_classes`` softmax probabilities of several shapes (meshes, point clouds or
        file paths). The networks were trained on z-up shapes (ModelNet): ``up="y"`` (or
        ``"x"``) rotates shapes whose up axis is y (x) first.

        ``turns``: average the probabilities over the shape's four quarter turns about the up
        axis, for shapes whose heading is not ModelNet's: the answer no longer depends on the
        heading (by quarter turns), at some cost on aligned shapes. The shipped ModelNet10 pair
        on its test split: 92.7 % aligned, 46.6 / 69.4 / 44.5 % turned by 90 / 180 / 270
        degrees, 81.1 % with ``turns`` whichever way the shapes face (``rgbd eval shapes
        --turned DEG [--turns]``)."""
        _validate.flag("turns", turns)
        if not isinstance(shapes, (list, tuple)):
            raise InvalidArgumentError(
                f"shapes: got {type(shapes).__name__}, expected a list of shapes"
            )
        _validate.choice("up", up, tuple(UP_ROTATIONS))
        names = [f"shapes[{i}]" for i in range(len(shapes))]
        return self._probabilities(shapes, names, workers, up, turns)

    def _probabilities(
        self,
        shapes: Sequence[Mesh | npt.ArrayLike | str | os.PathLike[str]],
        names: list[str],
        workers: int,
        up: str,
        turns: bool,
    ) -> npt.NDArray[np.float32]:
        """:meth:`probabilities` with each shape's name for its errors."""
        prepared = [self._prepare(s, up, name) for s, name in zip(shapes, names, strict=True)]
        if not prepared:
            return np.zeros((0, len(self.classes)), np.float32)
        inputs = batch_inputs(prepared, self.spec, workers=workers)
        if not turns:
            return self.probabilities_of_inputs(inputs)
        # A quarter turn permutes the inputs exactly (rgbd_rs.shapes.augment): no re-rendering.
        x = pack(inputs, self.net.shapes)
        views = _quarter_turns(x, self.net.shapes)
        probs = np.mean([self.probabilities_of_inputs(v) for v in views], axis=0)
        return np.asarray(probs, np.float32)

    def probabilities_of_inputs(self, inputs: dict[str, Any] | torch.Tensor) -> np.ndarray:
        """Softmax probabilities of precomputed inputs (a dict of ``N x ...`` arrays, or packed)."""
        x = inputs if isinstance(inputs, torch.Tensor) else pack(inputs, self.net.shapes)
        device = next(self.net.parameters()).device
        self.net.eval()
        with torch.inference_mode():
            logits = self.net(x.to(device, torch.float32))
            return torch.softmax(logits, dim=1).cpu().numpy().astype(np.float32)

    def __call__(
        self,
        shape: Mesh | npt.ArrayLike | str | os.PathLike[str],
        *,
        up: str = "z",
        turns: bool = False,
    ) -> tuple[str, dict[str, float]]:
        """``(class name, {class: probability})``, the dict sorted by decreasing probability;
        ``up``: the shape's up axis, ``turns``: average over its four headings (see
        :meth:`probabilities`)."""
        _validate.flag("turns", turns)
        _validate.choice("up", up, tuple(UP_ROTATIONS))
        p = self._probabilities([shape], ["shape"], 1, up, turns)[0]
        order = np.argsort(-p, kind="stable")
        probs = {self.classes[i]: float(p[i]) for i in order}
        return self.classes[int(order[0])], probs


def _default_weights(dataset: str | None) -> Path:
    have = shipped_weights()
    if dataset is not None:
        file = _weights_path(dataset)
        if not file.is_file():
            raise RgbdError(
                f"{file}: no shipped {dataset} weights in this installation (it ships "
                f"{sorted(have) or 'none'}); train with `rgbd train shapes` and pass the checkpoint"
            )
        return file
    for name in ("modelnet40", "modelnet10"):
        if name in have:
            return have[name]
    raise RgbdError(
        f"{_WEIGHTS_DIR}: no shipped shape-classifier weights in this installation; train with "
        "`rgbd train shapes` and pass the checkpoint"
    )


@functools.lru_cache(maxsize=4)
def _cached(path: str | None, dataset: str | None, stamp: float) -> ShapeClassifier:
    return ShapeClassifier.load(path, dataset=dataset)


def classify(
    shape: Mesh | npt.ArrayLike | str | os.PathLike[str],
    *,
    checkpoint: str | os.PathLike[str] | None = None,
    dataset: str | None = None,
    up: str = "z",
    turns: bool = False,
) -> tuple[str, dict[str, float]]:
    """The class of ``shape`` (a Mesh, an ``N x 3`` point cloud or a mesh / point-cloud file)
    and every class' probability (dict sorted by decreasing probability), with the shipped
    weights (``dataset`` ``"modelnet10"`` / ``"modelnet40"``; default the 40-class ones when
    shipped) or ``checkpoint``. The loaded network is kept for the next calls.

    The networks were trained on ModelNet's aligned shapes, **z up**: give ``up="y"`` (or
    ``"x"``) for a shape whose up axis is y (many PLY / OBJ files): it is rotated first. A
    shape lying on its side is classified as something else, without any error. They also
    read the heading about the up axis (ModelNet's shapes face one way): for a shape that may
    face any way give ``turns=True`` (the four quarter turns averaged; ModelNet10 test: 81.1 %
    whichever way the shapes face, against 92.7 % aligned and 45-69 % turned without it)."""
    if checkpoint is not None:
        checkpoint = _validate.path("checkpoint", checkpoint)
    if dataset is not None:
        _validate.choice("dataset", dataset, tuple(WEIGHT_FILES))
        if checkpoint is not None:
            raise InvalidArgumentError(
                f"checkpoint: got {str(checkpoint)!r} together with dataset={dataset!r}; "
                "expected one of the two (dataset picks the shipped weights)"
            )
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    file = Path(key) if key is not None else None
    stamp = file.stat().st_mtime if file is not None and file.is_file() else 0.0
    # A rewritten checkpoint is read again.
    return _cached(key, dataset, stamp)(shape, up=up, turns=turns)
