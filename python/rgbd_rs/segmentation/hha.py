"""HHA encoding of a depth map (Gupta et al. 2014)."""
