"""RGB-D segmentation (thesis ch. 4): 9-D features and HHA, normalized-cuts over-segmentation,
B-spline fits and priority-queue region merging.

The stages are plain functions, exported here::

    from rgbd_rs.segmentation import features, hha, oversegment, merge_regions, segment

The functions ``features``, ``hha`` and ``oversegment`` share their names with the modules
that define them; import a module's other names with ``from rgbd_rs.segmentation.hha import
hha_details`` (``import rgbd_rs.segmentation.hha as m`` would give the function).
"""

from rgbd_rs.holes import fill_depth_holes
from rgbd_rs.segmentation.cues import SemanticCues, cue_maps, semantic_cues
from rgbd_rs.segmentation.features import Features, features, lab_colour
from rgbd_rs.segmentation.hha import HhaResult, hha, hha_details, square_normals
from rgbd_rs.segmentation.labeling import SemanticLabeler
from rgbd_rs.segmentation.merge import (
    T_C,
    T_D,
    T_SIM,
    T_THETA_DEG,
    MergeResult,
    MergeStep,
    adjacency,
    majority_classes,
    merge_regions,
)
from rgbd_rs.segmentation.oversegment import default_channel_weights, oversegment
from rgbd_rs.segmentation.pipeline import Segmentation, segment
from rgbd_rs.segmentation.refine import segment_classes
from rgbd_rs.segmentation.semantic_data import (
    FrameFolder,
    LabeledFrame,
    NyuFrames,
    SemanticCache,
    SyntheticFrames,
    build_semantic_cache,
    downsample_cues,
    downsample_labels,
    open_frames,
)
from rgbd_rs.segmentation.semantic_train import (
    SemanticLoss,
    SemanticRecipe,
    SemanticScores,
    score,
    train_semantic,
)

__all__ = [
    "T_C",
    "T_D",
    "T_SIM",
    "T_THETA_DEG",
    "Features",
    "FrameFolder",
    "HhaResult",
    "LabeledFrame",
    "MergeResult",
    "MergeStep",
    "NyuFrames",
    "Segmentation",
    "SemanticCache",
    "SemanticCues",
    "SemanticLabeler",
    "SemanticLoss",
    "SemanticRecipe",
    "SemanticScores",
    "SyntheticFrames",
    "adjacency",
    "build_semantic_cache",
    "cue_maps",
    "default_channel_weights",
    "downsample_cues",
    "downsample_labels",
    "features",
    "fill_depth_holes",
    "hha",
    "hha_details",
    "lab_colour",
    "majority_classes",
    "merge_regions",
    "open_frames",
    "oversegment",
    "score",
    "segment",
    "segment_classes",
    "semantic_cues",
    "square_normals",
    "train_semantic",
]
