//! Connected regions of similar colour: the segmentation of the upsampling filter's
//! segmentation term (run on a mean-shift filtered image, whose regions are flat).

use rgbd_error::{check_len, invalid, Result};

/// Sum of absolute channel differences of two RGB pixels.
fn sum_abs(a: &[u8], b: &[u8]) -> usize {
    (a[0].abs_diff(b[0]) as usize) + (a[1].abs_diff(b[1]) as usize) + (a[2].abs_diff(b[2]) as usize)
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        // Keep the smaller index as root so labels come out in raster order of first pixels.
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

/// Labels 4-connected regions whose neighbouring pixels differ by at most `tolerance` in mean
/// absolute colour (0–255). Returns `(labels, count)`, labels `0..count` in raster order.
pub fn label_regions(
    image: &[u8],
    width: usize,
    height: usize,
    tolerance: f32,
) -> Result<(Vec<i32>, usize)> {
    let n = rgbd_error::image_len("image", width, height)?;
    check_len("image", image, n * 3, "H x W x 3")?;
    if !(tolerance >= 0.0) {
        return Err(invalid("tolerance", tolerance, "a finite value >= 0"));
    }
    let tol = (3.0 * tolerance).floor().min(1e6) as usize;
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let px = |i: usize| &image[3 * i..3 * i + 3];
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if x > 0 && sum_abs(px(i), px(i - 1)) <= tol {
                union(&mut parent, i as u32, (i - 1) as u32);
            }
            if y > 0 && sum_abs(px(i), px(i - width)) <= tol {
                union(&mut parent, i as u32, (i - width) as u32);
            }
        }
    }
    let mut label = vec![-1i32; n];
    let mut count = 0usize;
    for i in 0..n {
        let r = find(&mut parent, i as u32) as usize;
        if label[r] < 0 {
            label[r] = count as i32;
            count += 1;
        }
        label[i] = label[r];
    }
    Ok((label, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_flat_halves_and_an_island() {
        let (w, h) = (6, 4);
        let mut img = vec![0u8; w * h * 3];
        for y in 0..h {
            for x in 3..w {
                img[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[200, 10, 10]);
            }
        }
        img[3 * (w + 1)..3 * (w + 1) + 3].copy_from_slice(&[90, 90, 90]);
        let (lab, n) = label_regions(&img, w, h, 2.0).unwrap();
        assert_eq!(n, 3);
        assert_eq!(lab[0], 0);
        assert_eq!(lab[3], 1);
        assert_eq!(lab[w + 1], 2);
        assert_eq!(
            lab[(h - 1) * w],
            0,
            "the left half is one region around the island"
        );
    }

    #[test]
    fn gradients_chain_within_tolerance() {
        let img: Vec<u8> = (0..10u8).flat_map(|v| [v * 2, v * 2, v * 2]).collect();
        assert_eq!(label_regions(&img, 10, 1, 2.0).unwrap().1, 1);
        assert_eq!(label_regions(&img, 10, 1, 1.0).unwrap().1, 10);
        assert!(label_regions(&img, 9, 1, 1.0).is_err());
        assert!(label_regions(&img, 10, 1, f32::NAN).is_err());
    }
}
