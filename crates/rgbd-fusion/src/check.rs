//! Parameter checks shared by the filters' parameter structs.

use rgbd_geom::error::{invalid, Result};

/// Largest window half-size any filter accepts.
pub const MAX_RADIUS: usize = 64;

/// `radius` in `1..=MAX_RADIUS`, then every named value finite and > 0.
pub(crate) fn window_and_positive(radius: usize, named: &[(&'static str, f32)]) -> Result<()> {
    if radius == 0 || radius > MAX_RADIUS {
        return Err(invalid(
            "radius",
            radius,
            format!("1..={MAX_RADIUS} pixels"),
        ));
    }
    for &(name, v) in named {
        if !(v > 0.0) || !v.is_finite() {
            return Err(invalid(name, v, "a finite value > 0"));
        }
    }
    Ok(())
}
