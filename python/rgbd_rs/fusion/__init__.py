"""ToF-stereo fusion (thesis ch. 2.4.2 and 3): each stage is callable alone.

1. :func:`tof_to_reference` — reproject + upsample ToF onto the reference camera
   (:func:`segment_mean_shift`, :func:`upsample_depth`);
2. :func:`census_match` — our census SGM (what :func:`fuse` runs), or :func:`sgm`, which also
   runs OpenCV's SGBM as in the thesis (``method="opencv"``);
3. the confidence ConvNet (:func:`compute_clues` + :class:`rgbd_rs.nn.ConfidenceEstimator`, the
   default), :func:`tof_confidence`, :func:`stereo_confidence` — deterministic ones, or your own;
4. :func:`lc_fuse` — confidence-weighted locally consistent fusion; :func:`lc_refine` — plain LC.

:func:`fuse` runs them all (and :func:`refine_tof_pose`, which corrects a ToF orientation off by
a fraction of a degree against the stereo map).

Example:
    >>> from rgbd_rs.fusion import fuse  # doctest: +SKIP
    >>> out = fuse(left, right, tof_depth, tof_amplitude, rig)  # doctest: +SKIP
    >>> out.disparity, out.depth  # doctest: +SKIP
"""

from rgbd_rs.fusion.census import CensusMatch, CensusParams, census_match
from rgbd_rs.fusion.clues import compute_clues
from rgbd_rs.fusion.confidence import stereo_confidence, tof_confidence
from rgbd_rs.fusion.fuse import FusionResult, fuse
from rgbd_rs.fusion.lc import LcParams, lc_fuse, lc_refine
from rgbd_rs.fusion.pose_refine import PoseRefinement, refine_tof_pose
from rgbd_rs.fusion.rows import RowAlignment, align_rows, measure_row_alignment
from rgbd_rs.fusion.scale_refine import ScaleRefinement, refine_tof_scale
from rgbd_rs.fusion.stereo import cost_curve_stats, search_range, sgm
from rgbd_rs.fusion.upsample import (
    ToFOnReference,
    segment_mean_shift,
    tof_to_reference,
    upsample_depth,
)

__all__ = [
    "CensusMatch",
    "CensusParams",
    "FusionResult",
    "LcParams",
    "PoseRefinement",
    "RowAlignment",
    "ScaleRefinement",
    "ToFOnReference",
    "align_rows",
    "census_match",
    "compute_clues",
    "cost_curve_stats",
    "fuse",
    "lc_fuse",
    "lc_refine",
    "measure_row_alignment",
    "refine_tof_pose",
    "refine_tof_scale",
    "search_range",
    "segment_mean_shift",
    "sgm",
    "stereo_confidence",
    "tof_confidence",
    "tof_to_reference",
    "upsample_depth",
]
