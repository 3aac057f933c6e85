"""Normalized-cuts over-segmentation with the Nyström approximation (thesis §4.4)."""
