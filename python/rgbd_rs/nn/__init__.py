"""Torch networks of rgbd_rs and the one trainer they share.

:class:`ConfidenceNet` / :class:`ConfidenceEstimator`: the ToF + stereo confidence ConvNet of
thesis §3.6 (``fuse(confidence="convnet")`` runs the shipped weights). :class:`ShapeNet`: the
15-branch shape classifier of thesis Table 5.1 (:class:`ShapeEnsemble`: several averaged).
:class:`SemanticNet`: the semantic-labeling ConvNet of thesis §4.6 (Fig. 4.3).

:func:`train` (single process or under ``torchrun``) with its :class:`TrainConfig`, and the
checkpoints it writes (:func:`load_checkpoint`), which hold the architecture, its configuration
and the input normalisation alongside the weights.
"""

from rgbd_rs.nn.checkpoint import FORMAT, Checkpoint, load_checkpoint, save_checkpoint
from rgbd_rs.nn.confidence import ConfidenceEstimator, ConfidenceNet, predict
from rgbd_rs.nn.semantic import SemanticNet, class_probabilities
from rgbd_rs.nn.shape_ensemble import ShapeEnsemble
from rgbd_rs.nn.shapes import ShapeNet
from rgbd_rs.nn.train import (
    EpochStats,
    TrainConfig,
    TrainResult,
    is_main_process,
    seed_everything,
    split,
    train,
)

__all__ = [
    "FORMAT",
    "Checkpoint",
    "ConfidenceEstimator",
    "ConfidenceNet",
    "EpochStats",
    "SemanticNet",
    "ShapeEnsemble",
    "ShapeNet",
    "TrainConfig",
    "TrainResult",
    "class_probabilities",
    "is_main_process",
    "load_checkpoint",
    "predict",
    "save_checkpoint",
    "seed_everything",
    "split",
    "train",
]
