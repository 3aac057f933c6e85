"""Several :class:`~rgbd_rs.nn.shapes.ShapeNet` of one architecture as one network: the average
of their class probabilities (model averaging, issue 31).

The members see the same packed input; the output is ``log(mean_k softmax(member_k(x)))``, so a
softmax of it (what :class:`~rgbd_rs.shapes.ShapeClassifier` and the evaluation take) is the
mean probability, and an argmax of it is the ensemble's class. A checkpoint stores the members'
common ``arch_config`` under ``"member"`` and their number under ``"members"``
(:meth:`ShapeEnsemble.arch_config`); ``_shape_network`` rebuilds either kind from a config.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
from torch import nn

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn.shapes import ShapeNet

#: Most members an ensemble may hold (inference time grows with each).
MAX_MEMBERS = 16


class ShapeEnsemble(nn.Module):
    """``members`` (2 to :data:`MAX_MEMBERS` ShapeNets of one ``arch_config``) averaged.

    Exposes what a :class:`~rgbd_rs.nn.shapes.ShapeNet` user reads: ``n_classes``,
    ``representations``, ``shapes`` (the packed input layout), ``view_resolution`` and
    ``volume_resolution``.
    """

    def __init__(self, members: Sequence[ShapeNet]) -> None:
        super().__init__()
        if not isinstance(members, (list, tuple)) or not 2 <= len(members) <= MAX_MEMBERS:
            got = (
                f"{len(members)} members"
                if isinstance(members, (list, tuple))
                else type(members).__name__
            )
            raise InvalidArgumentError(
                f"members: got {got}, expected a list of 2 to {MAX_MEMBERS} ShapeNets"
            )
        for i, m in enumerate(members):
            if not isinstance(m, ShapeNet):
                raise InvalidArgumentError(
                    f"members[{i}]: got {type(m).__name__}, expected a ShapeNet"
                )
            if m.arch_config() != members[0].arch_config():
                raise InvalidArgumentError(
                    f"members[{i}]: got arch_config {m.arch_config()}, expected the first "
                    f"member's {members[0].arch_config()}"
                )
        self.members = nn.ModuleList(members)
        first = members[0]
        self.n_classes = first.n_classes
        self.representations = first.representations
        self.shapes = first.shapes
        self.view_resolution = first.view_resolution
        self.volume_resolution = first.volume_resolution

    def forward(self, x: torch.Tensor | Mapping[str, torch.Tensor]) -> torch.Tensor:
        """``N x n_classes`` log mean probability (a softmax of it is the mean probability)."""
        probs = torch.stack([torch.softmax(m(x), dim=1) for m in self.members]).mean(0)
        return torch.log(probs.clamp_min(torch.finfo(probs.dtype).tiny))

    def arch_config(self) -> dict[str, Any]:
        """``{"members": K, "member": <the members' ShapeNet.arch_config()>}``."""
        first = self.members[0]
        assert isinstance(first, ShapeNet)
        return {"members": len(self.members), "member": first.arch_config()}

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> ShapeEnsemble:
        """Inverse of :meth:`arch_config` (fresh weights); bad keys raise naming them."""
        if not isinstance(config, Mapping) or set(config) != {"members", "member"}:
            got = sorted(config) if isinstance(config, Mapping) else type(config).__name__
            raise InvalidArgumentError(
                f"arch_config: got {got}, expected keys ['member', 'members']"
            )
        k = _validate.integer("members", config["members"], minimum=2, maximum=MAX_MEMBERS)
        return cls([ShapeNet.from_config(config["member"]) for _ in range(k)])


def _shape_network(config: Mapping[str, Any]) -> ShapeNet | ShapeEnsemble:
    """A :class:`ShapeNet` or a :class:`ShapeEnsemble` (config with ``"members"``) from the
    ``arch_config`` a checkpoint stores."""
    if isinstance(config, Mapping) and "members" in config:
        return ShapeEnsemble.from_config(config)
    return ShapeNet.from_config(config)
