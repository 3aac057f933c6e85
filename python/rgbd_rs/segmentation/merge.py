"""Region merging (thesis §4.7, Algorithm 1) and its fit-only baseline."""
