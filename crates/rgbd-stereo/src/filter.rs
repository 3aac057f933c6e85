//! Post-filters of a disparity map (NaN = none): a median over the valid pixels of a window and
//! the removal of small connected regions ("speckles", OpenCV's `filterSpeckles`).

use rayon::prelude::*;

/// The median of the valid values in the `side x side` window of every valid pixel (the mean
/// of the two middle values for an even count); invalid pixels stay invalid.
pub fn median(disp: &[f32], w: usize, h: usize, side: usize) -> Vec<f32> {
    let r = side / 2;
    let mut out = vec![f32::NAN; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let mut win: Vec<f32> = Vec::with_capacity(side * side);
        for (x, o) in row.iter_mut().enumerate() {
            if disp[y * w + x].is_nan() {
                continue;
            }
            win.clear();
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    let v = disp[yy * w + xx];
                    if !v.is_nan() {
                        win.push(v);
                    }
                }
            }
            let m = win.len();
            // A selection, not a sort: the upper middle, then the largest value below it.
            let (below, &mut mid, _) = win.select_nth_unstable_by(m / 2, f32::total_cmp);
            *o = if m % 2 == 1 {
                mid
            } else {
                let lower = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                0.5 * (lower + mid)
            };
        }
    });
    out
}

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
    fn median_ignores_holes_and_speckles_go() {
        let n = f32::NAN;
        let d = [1.0, 2.0, n, 9.0, 3.0, 4.0, 5.0, 6.0, 7.0];
        let m = median(&d, 3, 3, 3);
        assert!(m[2].is_nan());
        // Centre: the 8 valid values 1..7 and 9 -> (4 + 5) / 2.
        assert_eq!(m[4], 4.5);
        // Top left: 1, 2, 9, 3 -> 2.5.
        assert_eq!(m[0], 2.5);
        let mut s = [5.0, 5.0, 5.0, 5.0, 20.0, 5.0, 5.0, 5.0, 5.0];
        remove_speckles(&mut s, 3, 3, 2, 1.0);
        assert!(s[4].is_nan());
        assert_eq!(s.iter().filter(|v| v.is_nan()).count(), 1);
        remove_speckles(&mut s, 3, 3, 9, 1.0);
        assert!(s.iter().all(|v| v.is_nan()));
    }
}
