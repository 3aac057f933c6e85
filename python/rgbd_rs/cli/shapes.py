"""``rgbd classify``, ``rgbd shapes cache``, ``rgbd train shapes``, ``rgbd eval shapes``: the
shape-classification pipeline's commands (thesis ch. 5)."""

from __future__ import annotations

from rgbd_rs.cli._args import Commands


def register(commands: Commands) -> None:
    """Add the shape commands (none yet)."""
