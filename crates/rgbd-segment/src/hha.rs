//! HHA encoding (Gupta et al. 2014) and the per-pixel geometry it needs: normals by least-squares planes in square windows, gravity estimation, height above the floor, angle with gravity.
