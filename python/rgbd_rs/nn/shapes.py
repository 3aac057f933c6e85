"""The 15-branch shape-classification ConvNet of thesis §5.4 (Table 5.1, Fig. 5.4).

Branches (each a stack of conv 3x3 "same" + ReLU + max-pool; the last map is 1 x 1, so each
branch ends in a ``width``-element descriptor, 128 in the thesis):

- depth: six 1-channel views, 4 convolutions of 48, 128, 128, 128 filters;
- curvature: six 2-channel (k1, k2) views, the same 4 convolutions;
- volume: three 1-channel density profiles (X, Y, Z), 5 convolutions of 48, 128, 128, 128, 128
  filters, each pooled by 2.

Weights are shared by the four side views (:data:`SIDE_VIEWS`) and, separately, by the top and
bottom views (:data:`CAP_VIEWS`), for depth and for curvature; the three volume branches are
independent. The descriptors are concatenated (15 x 128 = 1920 with every representation on) and
a linear layer **without bias** gives the class scores (softmax + cross-entropy in training).

**Pool sizes adapt to the resolution** (:func:`_view_pools`, :func:`_volume_pools`): a view of side
R is pooled by p, p, p with p = floor(R^(1/4)) (the largest p with p^4 <= R) and then by the side
that is left, floor(floor(floor(R/p)/p)/p), so the last map is 1 x 1. At the thesis' 320 this is
4, 4, 4, 5 exactly (Table 5.1); at 64 it is 2, 2, 2, 8 and at 32 it is 2, 2, 2, 4. Volume
profiles of side Rv are pooled by 2 four times and then by what is left (2 at the thesis' 32).

Any representation can be switched off (the ablation rows of Table 5.2); only the branches of
the chosen ones are built. The network takes its inputs either as a dict of tensors
(``{"depth": N x 6 x R x R, "volume": N x 3 x Rv x Rv, "curvature": N x 6 x 2 x R x R}``) or
packed into one ``N x D`` tensor by :func:`pack` (what the datasets yield: the shared trainer
moves only tensors of a batch to the device, not dicts).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = [
    "ARCH",
    "REPRESENTATIONS",
    "ShapeNet",
    "pack",
    "unpack",
]

#: Name stored in checkpoints; a checkpoint of another architecture is refused.
ARCH = "shapes-15branch/1"
#: Every representation the network knows, in the order of its feature vector.
REPRESENTATIONS = ("depth", "volume", "curvature")
#: Default representations: curvature maps are not computed by the package yet.
DEFAULT_REPRESENTATIONS = ("depth", "volume")
#: Views per shape (faces of the bounding box, §5.3.1) and the indices of the four side views and
#: of the bottom / top views in the ``6 x R x R`` stack of :func:`rgbd_rs.shapes.views.depth_views`.
N_VIEWS = 6
SIDE_VIEWS = (0, 1, 2, 3)
CAP_VIEWS = (4, 5)
#: Density profiles per shape (along X, Y, Z, §5.3.2).
N_PROFILES = 3
#: Filters of the view branches (Table 5.1, depth and NURBS rows) and of the volume branches.
VIEW_FILTERS = (48, 128, 128, 128)
VOLUME_FILTERS = (48, 128, 128, 128, 128)
#: Channels per view: depth 1, curvature 2 (k1, k2; §5.3.3).
CURVATURE_CHANNELS = 2
#: The thesis' resolutions: 320 x 320 views, 32 x 32 profiles (§5.3.1-5.3.2).
THESIS_VIEW_RESOLUTION = 320
THESIS_VOLUME_RESOLUTION = 32
#: Descriptor length per branch in the thesis (the last layers' filters).
THESIS_WIDTH = 128
#: Smallest sides accepted: a view must survive three pools of 2, a profile four.
MIN_VIEW_RESOLUTION = 8
MIN_VOLUME_RESOLUTION = 16
MAX_RESOLUTION = 4096


def _parse_representations(value: str | Iterable[str]) -> tuple[str, ...]:
    """``"depth,volume"`` or an iterable of names -> the names in :data:`REPRESENTATIONS` order.

    ``"combined"`` / ``"all"`` mean every representation. Unknown, repeated or no names raise
    :class:`InvalidArgumentError` naming ``representations``.
    """
    if isinstance(value, str):
        names = [v.strip() for v in value.split(",") if v.strip()]
        if names in (["combined"], ["all"]):
            names = list(REPRESENTATIONS)
    elif isinstance(value, Iterable) and not isinstance(value, (bytes, Mapping)):
        names = list(value)
    else:
        raise InvalidArgumentError(
            f"representations: got {value!r}, expected names among {list(REPRESENTATIONS)}"
        )
    bad = [n for n in names if not isinstance(n, str) or n not in REPRESENTATIONS]
    if bad:
        raise InvalidArgumentError(
            f"representations: got unknown {bad}, expected names among {list(REPRESENTATIONS)}"
        )
    if not names or len(set(names)) != len(names):
        raise InvalidArgumentError(
            f"representations: got {names}, expected one or more distinct names among "
            f"{list(REPRESENTATIONS)}"
        )
    return tuple(r for r in REPRESENTATIONS if r in names)


def _view_pools(resolution: int) -> tuple[int, int, int, int]:
    """Max-pool sizes of a view branch for ``resolution`` x ``resolution`` views (see the module
    docstring): ``(p, p, p, rest)``, ``(4, 4, 4, 5)`` at the thesis' 320."""
    r = _validate.integer(
        "resolution", resolution, minimum=MIN_VIEW_RESOLUTION, maximum=MAX_RESOLUTION
    )
    p = max(1, math.isqrt(math.isqrt(r)))  # floor(r ** (1/4)), exact for integers
    return p, p, p, r // p // p // p


def _volume_pools(resolution: int) -> tuple[int, int, int, int, int]:
    """Max-pool sizes of a volume branch: 2, 2, 2, 2 and what is left (2 at the thesis' 32)."""
    r = _validate.integer(
        "volume_resolution", resolution, minimum=MIN_VOLUME_RESOLUTION, maximum=MAX_RESOLUTION
    )
    return 2, 2, 2, 2, r // 16


def _input_shapes(
    representations: Iterable[str], view_resolution: int, volume_resolution: int
) -> dict[str, tuple[int, ...]]:
    """The per-shape array shape of each representation (no batch axis)."""
    reps = _parse_representations(representations)
    r = _validate.integer("view_resolution", view_resolution, minimum=1)
    rv = _validate.integer("volume_resolution", volume_resolution, minimum=1)
    full = {
        "depth": (N_VIEWS, r, r),
        "volume": (N_PROFILES, rv, rv),
        "curvature": (N_VIEWS, CURVATURE_CHANNELS, r, r),
    }
    return {name: full[name] for name in reps}


def _branch(
    in_channels: int, filters: Sequence[int], pools: Sequence[int], batch_norm: bool = False
) -> nn.Sequential:
    layers: list[nn.Module] = []
    c = in_channels
    for f, p in zip(filters, pools, strict=True):
        layers.append(nn.Conv2d(c, f, 3, padding=1))
        if batch_norm:
            layers.append(nn.BatchNorm2d(f))
        layers += [nn.ReLU(inplace=True), nn.MaxPool2d(p)]
        c = f
    return nn.Sequential(*layers)


def _scaled(filters: Sequence[int], width: int) -> tuple[int, ...]:
    """Table 5.1's filters scaled so the last layers have ``width`` (48 -> 48 * width / 128)."""
    return tuple(max(1, round(f * width / THESIS_WIDTH)) for f in filters)


class ShapeNet(nn.Module):
    """Table 5.1's multi-branch ConvNet over the chosen ``representations``.

    ``width`` is the number of filters of the 128-filter layers (the first layer scales with it:
    48 at 128), so each branch's descriptor has ``width`` elements. Inputs: see the module
    docstring. Output: ``N x n_classes`` class scores (logits).

    Not in the thesis, both off by default (the architecture of Table 5.1): ``batch_norm`` puts
    a batch normalisation between every convolution and its ReLU (its statistics shared where
    the branch's weights are), and ``dropout`` drops that fraction of the concatenated
    descriptor's elements before the classifier in training.
    """

    def __init__(
        self,
        n_classes: int,
        *,
        representations: Iterable[str] | str = DEFAULT_REPRESENTATIONS,
        view_resolution: int = THESIS_VIEW_RESOLUTION,
        volume_resolution: int = THESIS_VOLUME_RESOLUTION,
        width: int = THESIS_WIDTH,
        batch_norm: bool = False,
        dropout: float = 0.0,
    ) -> None:
        super().__init__()
        self.batch_norm = _validate.flag("batch_norm", batch_norm)
        self.dropout = _validate.real("dropout", dropout, nonnegative=True)
        if self.dropout >= 1:
            raise InvalidArgumentError(f"dropout: got {dropout}, expected 0 <= dropout < 1")
        self.n_classes = _validate.integer("n_classes", n_classes, minimum=2, maximum=100_000)
        self.representations = _parse_representations(representations)
        self.view_resolution = _validate.integer(
            "view_resolution", view_resolution, minimum=MIN_VIEW_RESOLUTION, maximum=MAX_RESOLUTION
        )
        self.volume_resolution = _validate.integer(
            "volume_resolution",
            volume_resolution,
            minimum=MIN_VOLUME_RESOLUTION,
            maximum=MAX_RESOLUTION,
        )
        self.width = _validate.integer("width", width, minimum=1, maximum=4096)
        self.shapes = _input_shapes(self.representations, self.view_resolution, volume_resolution)
        vf, pf = _scaled(VIEW_FILTERS, self.width), _scaled(VOLUME_FILTERS, self.width)
        vp, pp = _view_pools(self.view_resolution), _volume_pools(self.volume_resolution)
        self.branches = nn.ModuleDict()
        n_branches = 0
        for name in self.representations:
            if name == "volume":
                for axis in "xyz":  # independent weights per axis (§5.4)
                    self.branches[f"volume_{axis}"] = _branch(1, pf, pp, self.batch_norm)
                n_branches += N_PROFILES
            else:
                c = 1 if name == "depth" else CURVATURE_CHANNELS
                bn = self.batch_norm
                self.branches[f"{name}_side"] = _branch(c, vf, vp, bn)  # shared by 4 side views
                self.branches[f"{name}_caps"] = _branch(c, vf, vp, bn)  # shared by bottom and top
                n_branches += N_VIEWS
        self.n_features = n_branches * self.width
        self.drop = nn.Dropout(self.dropout)  # no weights: old checkpoints load unchanged
        self.classifier = nn.Linear(self.n_features, self.n_classes, bias=False)
        for m in self.branches.modules():
            if isinstance(m, nn.Conv2d):  # He initialisation for ReLU stacks (not in the thesis)
                nn.init.kaiming_normal_(m.weight, nonlinearity="relu")
                assert m.bias is not None
                nn.init.zeros_(m.bias)

    def arch_config(self) -> dict[str, Any]:
        """The constructor arguments (what checkpoints store to rebuild the network);
        ``batch_norm`` and ``dropout`` only when on, so a Table 5.1 network's config is the
        one checkpoints stored before they existed."""
        out: dict[str, Any] = {
            "n_classes": self.n_classes,
            "representations": list(self.representations),
            "view_resolution": self.view_resolution,
            "volume_resolution": self.volume_resolution,
            "width": self.width,
        }
        if self.batch_norm:
            out["batch_norm"] = True
        if self.dropout:
            out["dropout"] = self.dropout
        return out

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> ShapeNet:
        """Inverse of :meth:`arch_config`; missing or unknown keys raise naming them."""
        keys = {"n_classes", "representations", "view_resolution", "volume_resolution", "width"}
        optional = {"batch_norm", "dropout"}
        if not isinstance(config, Mapping) or not keys <= set(config) <= keys | optional:
            got = sorted(config) if isinstance(config, Mapping) else type(config).__name__
            raise InvalidArgumentError(
                f"arch_config: got {got}, expected keys {sorted(keys)} (and optionally "
                f"{sorted(optional)})"
            )
        return cls(
            config["n_classes"],
            representations=config["representations"],
            view_resolution=config["view_resolution"],
            volume_resolution=config["volume_resolution"],
            width=config["width"],
            batch_norm=config.get("batch_norm", False),
            dropout=config.get("dropout", 0.0),
        )

    def features(self, x: torch.Tensor | Mapping[str, torch.Tensor]) -> torch.Tensor:
        """The concatenated branch descriptors, ``N x n_features``."""
        inputs = unpack(x, self.shapes) if isinstance(x, torch.Tensor) else self._checked(x)
        out: list[torch.Tensor] = []
        for name in self.representations:
            t = inputs[name]
            n = t.shape[0]
            if name == "volume":
                for k, axis in enumerate("xyz"):
                    out.append(self.branches[f"volume_{axis}"](t[:, k : k + 1]).reshape(n, -1))
                continue
            views = t if name == "curvature" else t[:, :, None]  # N x 6 x C x R x R
            for group, idx in (("side", SIDE_VIEWS), ("caps", CAP_VIEWS)):
                sel = views[:, list(idx)]
                flat = sel.reshape(n * len(idx), *sel.shape[2:])
                out.append(self.branches[f"{name}_{group}"](flat).reshape(n, -1))
        feats = torch.cat(out, dim=1)
        if feats.shape[1] != self.n_features:  # a pool rule bug would leave maps above 1 x 1
            raise ShapeMismatchError(
                f"features: got {feats.shape[1]} values, expected {self.n_features}"
            )
        return feats

    def forward(self, x: torch.Tensor | Mapping[str, torch.Tensor]) -> torch.Tensor:
        """Class scores ``N x n_classes`` (logits) of packed or dict inputs."""
        return self.classifier(self.drop(self.features(x)))  # type: ignore[no-any-return]

    def _checked(self, x: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        if not isinstance(x, Mapping):
            raise InvalidArgumentError(
                f"x: got {type(x).__name__}, expected a packed tensor or a dict of tensors"
            )
        missing = [r for r in self.representations if r not in x]
        if missing:
            raise InvalidArgumentError(
                f"x: got representations {sorted(x)}, expected {list(self.representations)} "
                f"(missing {missing})"
            )
        out: dict[str, torch.Tensor] = {}
        n: int | None = None
        for name, shape in self.shapes.items():
            t = x[name]
            if not isinstance(t, torch.Tensor) or tuple(t.shape[1:]) != shape or t.ndim < 2:
                got = tuple(t.shape) if isinstance(t, torch.Tensor) else type(t).__name__
                raise ShapeMismatchError(f"x[{name!r}]: got shape {got}, expected (N, *{shape})")
            if n is not None and t.shape[0] != n:
                raise ShapeMismatchError(
                    f"x[{name!r}]: got {t.shape[0]} shapes, expected {n} like the others"
                )
            n = int(t.shape[0])
            out[name] = t
        return out


def pack(
    inputs: Mapping[str, torch.Tensor | np.ndarray], shapes: Mapping[str, tuple[int, ...]]
) -> torch.Tensor:
    """``N x D`` float32 tensor holding ``inputs[name]`` (``N x *shapes[name]``) flattened, in
    ``shapes``' order. A single shape (no batch axis) is accepted and packed as ``1 x D``."""
    if not isinstance(inputs, Mapping):
        raise InvalidArgumentError(f"inputs: got {type(inputs).__name__}, expected a dict")
    parts: list[torch.Tensor] = []
    n: int | None = None
    for name, shape in shapes.items():
        if name not in inputs:
            raise InvalidArgumentError(
                f"inputs: got representations {sorted(inputs)}, expected {list(shapes)}"
            )
        v = inputs[name]
        if not isinstance(v, torch.Tensor):
            v = _validate.asarray(f"inputs[{name!r}]", v)
            if v.dtype.kind not in "iuf":
                raise InvalidArgumentError(
                    f"inputs[{name!r}]: got dtype {v.dtype}, expected real numbers"
                )
        elif v.is_complex() or v.dtype == torch.bool:
            raise InvalidArgumentError(f"inputs[{name!r}]: got dtype {v.dtype}, expected real")
        t = torch.as_tensor(v)
        if tuple(t.shape) == tuple(shape):
            t = t[None]
        if tuple(t.shape[1:]) != tuple(shape):
            raise ShapeMismatchError(
                f"inputs[{name!r}]: got shape {tuple(t.shape)}, expected (N, *{tuple(shape)}) "
                f"or {tuple(shape)}"
            )
        if n is not None and t.shape[0] != n:
            raise ShapeMismatchError(
                f"inputs[{name!r}]: got {t.shape[0]} shapes, expected {n} like the others"
            )
        n = int(t.shape[0])
        parts.append(t.reshape(n, -1).to(torch.float32))
    if not parts:
        raise InvalidArgumentError("shapes: got no representations, expected at least one")
    return torch.cat(parts, dim=1)


def unpack(x: torch.Tensor, shapes: Mapping[str, tuple[int, ...]]) -> dict[str, torch.Tensor]:
    """Inverse of :func:`pack` (views into ``x``)."""
    sizes = [math.prod(s) for s in shapes.values()]
    if not isinstance(x, torch.Tensor) or x.ndim != 2 or x.shape[1] != sum(sizes):
        got = tuple(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
        raise ShapeMismatchError(
            f"x: got shape {got}, expected (N, {sum(sizes)}): packed {dict(shapes)}"
        )
    out: dict[str, torch.Tensor] = {}
    start = 0
    for (name, shape), size in zip(shapes.items(), sizes, strict=True):
        out[name] = x[:, start : start + size].reshape(x.shape[0], *shape)
        start += size
    return out
