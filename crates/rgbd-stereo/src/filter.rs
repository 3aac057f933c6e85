//! Post-filters of a disparity map (NaN = none): a median over the valid pixels of a window and
//! the removal of small connected regions ("speckles", OpenCV's `filterSpeckles`).

pub use crate::median::median;

/// Sets to NaN every 4-connected region (neighbours within `range` px) of fewer than `size`
/// pixels.
pub fn remove_speckles(disp: &mut [f32], w: usize, h: usize, size: usize, range: f32) {
    if size <= 1 {
        return;
    }
    const NONE: u32 = u32::MAX;
    let mut label = vec![NONE; w * h];
    let mut stack: Vec<usize> = Vec::new();
    let mut members: Vec<usize> = Vec::new();
    for seed in 0..w * h {
        if label[seed] != NONE || disp[seed].is_nan() {
            continue;
        }
        label[seed] = seed as u32;
        stack.push(seed);
        members.clear();
        while let Some(i) = stack.pop() {
            members.push(i);
            let (x, y) = (i % w, i / w);
            let v = disp[i];
            let mut visit = |j: usize| {
                if label[j] == NONE && !disp[j].is_nan() && (disp[j] - v).abs() <= range {
                    label[j] = seed as u32;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if members.len() < size {
            for &i in &members {
                disp[i] = f32::NAN;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speckles_go() {
        let mut s = [5.0, 5.0, 5.0, 5.0, 20.0, 5.0, 5.0, 5.0, 5.0];
        remove_speckles(&mut s, 3, 3, 2, 1.0);
        assert!(s[4].is_nan());
        assert_eq!(s.iter().filter(|v| v.is_nan()).count(), 1);
        remove_speckles(&mut s, 3, 3, 9, 1.0);
        assert!(s.iter().all(|v| v.is_nan()));
    }
}
