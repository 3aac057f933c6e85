"""The segmentation pipeline: features -> over-segmentation -> fits -> merging."""
