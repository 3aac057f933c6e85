//! Segment adjacency from a label image with the boundary tests of eq. 4.3-4.5.
