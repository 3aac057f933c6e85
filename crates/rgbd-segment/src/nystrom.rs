//! Normalized-cuts embedding with the Nyström approximation (Fowlkes et al. 2004; thesis §4.4).
