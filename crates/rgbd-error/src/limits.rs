//! Upper bounds checked before a kernel allocates, so an absurd size is an error instead of an
//! aborted interpreter ("memory allocation of N bytes failed" cannot be caught).
//!
//! The bounds are generous for any camera or shape view (a 16384 x 16384 image passes) and small
//! enough that the largest per-pixel output (the render g-buffer, 32 bytes a pixel) stays under
//! 10 GiB.

use crate::{invalid, Result};

/// Largest image side (width or height) any kernel accepts, in pixels.
pub const MAX_SIDE: usize = 1 << 16;
/// Largest pixel count (width x height) any kernel accepts: 16384 x 16384.
pub const MAX_PIXELS: usize = 1 << 28;
/// Largest element count of any other buffer a kernel allocates from its arguments.
pub const MAX_ELEMENTS: usize = 1 << 31;

/// `width * height`, after checking each side is in `1..=MAX_SIDE` and the product is at most
/// [`MAX_PIXELS`]. `what` names the image in the error (e.g. `"view"`).
pub fn image_len(what: &'static str, width: usize, height: usize) -> Result<usize> {
    for (side, v) in [("width", width), ("height", height)] {
        if v == 0 || v > MAX_SIDE {
            return Err(invalid(
                what,
                format!("{side} {v}"),
                format!("a {side} in 1..={MAX_SIDE} pixels"),
            ));
        }
    }
    let n = width * height; // both <= 2^16: cannot overflow
    if n > MAX_PIXELS {
        return Err(invalid(
            what,
            format!("{width} x {height} = {n} pixels"),
            format!("at most {MAX_PIXELS} pixels"),
        ));
    }
    Ok(n)
}

/// The product of `factors` (element count of a buffer), or an error naming `what` when it
/// overflows or exceeds [`MAX_ELEMENTS`].
pub fn checked_len(what: &'static str, factors: &[usize]) -> Result<usize> {
    let n = factors
        .iter()
        .try_fold(1usize, |acc, &f| acc.checked_mul(f))
        .filter(|&n| n <= MAX_ELEMENTS);
    n.ok_or_else(|| {
        let shown: Vec<String> = factors.iter().map(|f| f.to_string()).collect();
        invalid(
            what,
            format!("a buffer of {} elements", shown.join(" x ")),
            format!("at most {MAX_ELEMENTS} elements"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_bounded_before_allocation() {
        assert_eq!(image_len("view", 640, 480), Ok(640 * 480));
        assert_eq!(
            image_len("view", MAX_SIDE, MAX_PIXELS / MAX_SIDE),
            Ok(MAX_PIXELS)
        );
        let e = image_len("view", 1 << 20, 1 << 20).unwrap_err().to_string();
        assert!(e.starts_with("view: got width 1048576"), "{e}");
        assert!(image_len("view", 0, 4).is_err());
        assert!(image_len("view", MAX_SIDE, MAX_SIDE).is_err());
        assert_eq!(checked_len("bins", &[3, 4]), Ok(12));
        assert!(checked_len("bins", &[usize::MAX, 2]).is_err());
        assert!(checked_len("bins", &[MAX_ELEMENTS, 2]).is_err());
    }
}
