"""RGB-D segmentation (thesis ch. 4): 9-D features and HHA, normalized-cuts over-segmentation,
B-spline fits and priority-queue region merging."""
