//! Label clean-up after clustering: split every label into its 4-connected components and absorb
//! components smaller than `min_size` pixels into the neighbour they share the longest boundary
//! with, so the over-segmentation has no tiny islands.

use rgbd_error::{check_len, image_len, invalid, Result};

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[x as usize];
        parent[x as usize] = parent[p as usize];
        x = p;
    }
    x
}

/// 4-connected components of equal labels (`labels < 0` = excluded, -1 in the output):
/// component ids in raster order of first pixel, and the count.
fn components(labels: &[i32], w: usize, h: usize) -> (Vec<i32>, usize) {
    let mut comp = vec![-1i32; labels.len()];
    let mut stack = Vec::new();
    let mut count = 0usize;
    for start in 0..labels.len() {
        if labels[start] < 0 || comp[start] >= 0 {
            continue;
        }
        let id = count as i32;
        count += 1;
        let l = labels[start];
        comp[start] = id;
        stack.push(start);
        while let Some(p) = stack.pop() {
            let (x, y) = (p % w, p / w);
            let mut visit = |q: usize| {
                if comp[q] < 0 && labels[q] == l {
                    comp[q] = id;
                    stack.push(q);
                }
            };
            if x > 0 {
                visit(p - 1);
            }
            if x + 1 < w {
                visit(p + 1);
            }
            if y > 0 {
                visit(p - w);
            }
            if y + 1 < h {
                visit(p + w);
            }
        }
    }
    (comp, count)
}

/// Splits every label of the `h x w` image into its 4-connected components, then absorbs each
/// component of fewer than `min_size` pixels into the adjacent segment it shares the most
/// 4-neighbour pixel pairs with (ties: the lower id), smallest components first, until every
/// segment that has a neighbour is at least `min_size` pixels (a small component with no valid
/// neighbour, e.g. enclosed by excluded pixels, stays). Negative labels are excluded and come
/// out as -1. Returns labels `0..count` in raster order of first appearance, and `count`.
pub fn split_and_absorb(
    labels: &[i32],
    w: usize,
    h: usize,
    min_size: usize,
) -> Result<(Vec<i32>, usize)> {
    let npx = image_len("labels", w, h)?;
    check_len("labels", labels, npx, "h x w")?;
    if min_size == 0 {
        return Err(invalid("min_size", 0, ">= 1"));
    }
    let (comp, nc) = components(labels, w, h);
    let mut size = vec![0usize; nc];
    for &c in &comp {
        if c >= 0 {
            size[c as usize] += 1;
        }
    }
    // Pixels of each component (CSR).
    let mut start = vec![0usize; nc + 1];
    for c in 0..nc {
        start[c + 1] = start[c] + size[c];
    }
    let mut fill = start.clone();
    let mut pixels = vec![0u32; start[nc]];
    for (p, &c) in comp.iter().enumerate() {
        if c >= 0 {
            pixels[fill[c as usize]] = p as u32;
            fill[c as usize] += 1;
        }
    }
    let mut parent: Vec<u32> = (0..nc as u32).collect();
    // Components merged into each root (the root itself first).
    let mut members: Vec<Vec<u32>> = (0..nc as u32).map(|c| vec![c]).collect();
    let mut order: Vec<u32> = (0..nc as u32)
        .filter(|&c| size[c as usize] < min_size)
        .collect();
    order.sort_by_key(|&c| (size[c as usize], c));
    let mut counts: Vec<u32> = vec![0; nc];
    let mut touched: Vec<u32> = Vec::new();
    loop {
        let mut changed = false;
        for &c in &order {
            let r = find(&mut parent, c);
            if size[r as usize] >= min_size {
                continue;
            }
            for &mc in &members[r as usize] {
                let mc = mc as usize;
                for &p in &pixels[start[mc]..start[mc + 1]] {
                    let p = p as usize;
                    let (x, y) = (p % w, p / w);
                    let mut look = |q: usize| {
                        let cq = comp[q];
                        if cq >= 0 {
                            let rq = find(&mut parent, cq as u32);
                            if rq != r {
                                if counts[rq as usize] == 0 {
                                    touched.push(rq);
                                }
                                counts[rq as usize] += 1;
                            }
                        }
                    };
                    if x > 0 {
                        look(p - 1);
                    }
                    if x + 1 < w {
                        look(p + 1);
                    }
                    if y > 0 {
                        look(p - w);
                    }
                    if y + 1 < h {
                        look(p + w);
                    }
                }
            }
            let best = touched
                .iter()
                .copied()
                .max_by_key(|&q| (counts[q as usize], std::cmp::Reverse(q)));
            for &q in &touched {
                counts[q as usize] = 0;
            }
            touched.clear();
            if let Some(b) = best {
                parent[r as usize] = b;
                size[b as usize] += size[r as usize];
                let moved = std::mem::take(&mut members[r as usize]);
                members[b as usize].extend(moved);
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    // Contiguous ids in raster order of first appearance.
    let mut new_id = vec![-1i32; nc];
    let mut next = 0i32;
    let mut out = vec![-1i32; npx];
    for (o, &c) in out.iter_mut().zip(&comp) {
        if c >= 0 {
            let r = find(&mut parent, c as u32) as usize;
            if new_id[r] < 0 {
                new_id[r] = next;
                next += 1;
            }
            *o = new_id[r];
        }
    }
    Ok((out, next as usize))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disconnected_label_is_split() {
        // Label 0 in two separate columns, label 1 between them.
        let labels = [0, 1, 0, 0, 1, 0];
        let (out, n) = split_and_absorb(&labels, 3, 2, 1).unwrap();
        assert_eq!(n, 3);
        assert_eq!(out, vec![0, 1, 2, 0, 1, 2]);
    }

    #[test]
    fn small_islands_are_absorbed_by_the_longest_boundary() {
        // 6x4: left half 0, right half 1, a 1-pixel island of 2 inside the right half and a
        // 1-pixel island of 3 inside the left half.
        #[rustfmt::skip]
        let labels = [
            0, 0, 0, 1, 1, 1,
            0, 0, 0, 1, 2, 1,
            0, 3, 0, 1, 1, 1,
            0, 0, 0, 1, 1, 1,
        ];
        let (out, n) = split_and_absorb(&labels, 6, 4, 2).unwrap();
        assert_eq!(n, 2);
        assert_eq!(out[6 + 4], out[5], "island of 2 joins 1");
        assert_eq!(out[12 + 1], out[0], "island of 3 joins 0");
        // min_size 1 keeps all four.
        assert_eq!(split_and_absorb(&labels, 6, 4, 1).unwrap().1, 4);
    }

    #[test]
    fn excluded_pixels_and_enclosed_islands() {
        #[rustfmt::skip]
        let labels = [
            0, 0, 0, 0,
            0, -1, -1, 0,
            0, -1, 5, -1,
        ];
        // The lone 5 touches only excluded pixels and the image border: it stays.
        let (out, n) = split_and_absorb(&labels, 4, 3, 3).unwrap();
        assert_eq!(n, 2);
        assert_eq!(out[5], -1);
        assert_eq!(out[10], 1);
        assert!(split_and_absorb(&labels, 4, 3, 0).is_err());
        assert!(split_and_absorb(&labels[1..], 4, 3, 1).is_err());
    }
}
