"""Per-pixel 9-D colour/position/normal vectors of eq. 4.1."""
