//! Priority-queue region merging (thesis §4.7, Algorithm 1).
