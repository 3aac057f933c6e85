//! Seeded k-means (k-means++ initialisation) on embedded pixels.
