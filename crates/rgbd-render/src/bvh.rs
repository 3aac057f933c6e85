//! Bounding-volume hierarchy over triangles: a binary binned-SAH build (16 bins per axis),
//! collapsed into the 8-wide tree of [`crate::wide`] that closest-hit / any-hit queries traverse
//! (SIMD box and triangle tests, nearest child first). Triangles are stored in BVH order in
//! packets of four with precomputed edges (Moller-Trumbore), so a leaf test touches one
//! contiguous block.

use crate::math::{add, scale, sub, vmax, vmin, V3};
use crate::wide::{self, Node8, Tri4};

/// Bins per axis of the SAH sweep; 16 is within a few % of a full sweep at a fraction of the cost.
const BINS: usize = 16;
/// Leaves never hold more triangles than this (the SAH may stop earlier).
const MAX_LEAF: usize = 4;
/// Cost of one node traversal relative to one packet test of four triangles (SAH constant).
const TRAVERSAL_COST: f32 = 0.5;
/// SAH cost of intersecting `n` triangles: leaves are tested four triangles at a time.
fn packets(n: usize) -> f32 {
    n.div_ceil(4) as f32
}
/// Below this depth of the binary tree, nodes are split in half by count instead of by SAH, so
/// the depth stays under `MAX_DEPTH + 32` whatever the input (the traversal stack relies on it).
pub(crate) const MAX_DEPTH: usize = 48;

/// A node of the binary build tree.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BinNode {
    pub(crate) lo: V3,
    /// Leaf: first triangle (in build order); interior: index of the left child (right = left + 1).
    pub(crate) first: u32,
    pub(crate) hi: V3,
    /// Number of triangles (at most [`MAX_LEAF`]); 0 marks an interior node.
    pub(crate) count: u32,
}

impl BinNode {
    pub(crate) fn area(&self) -> f32 {
        Aabb {
            lo: self.lo,
            hi: self.hi,
        }
        .area()
    }
}

/// A ray-triangle hit: parameter `t` along the (not necessarily unit) direction, the input
/// triangle index and the barycentric coordinates of vertices 1 and 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// The acceleration structure. Build once per scene, cast from many threads.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node8>,
    packets: Vec<Tri4>,
    /// Reference of the root (a node, or a single packet).
    root: u32,
    len: usize,
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: V3,
    hi: V3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };
    fn grow(&mut self, p: V3) {
        self.lo = vmin(self.lo, p);
        self.hi = vmax(self.hi, p);
    }
    fn join(&mut self, o: &Aabb) {
        self.lo = vmin(self.lo, o.lo);
        self.hi = vmax(self.hi, o.hi);
    }
    fn area(&self) -> f32 {
        let d = sub(self.hi, self.lo);
        if d[0] < 0.0 {
            return 0.0;
        }
        2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
    }
}

impl Bvh {
    /// Builds the tree over `triangles` (each three vertices). Degenerate triangles are kept
    /// (they are never hit). An empty list gives a tree that every ray misses.
    pub fn build(triangles: &[[V3; 3]]) -> Self {
        let n = triangles.len();
        let mut boxes = Vec::with_capacity(n);
        let mut centroids = Vec::with_capacity(n);
        for t in triangles {
            let mut b = Aabb::EMPTY;
            t.iter().for_each(|&p| b.grow(p));
            centroids.push(scale(add(b.lo, b.hi), 0.5));
            boxes.push(b);
        }
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n.max(1));
        nodes.push(BinNode {
            lo: [0.0; 3],
            first: 0,
            hi: [0.0; 3],
            count: n as u32,
        });
        let mut todo = vec![(0usize, 0usize)];
        while let Some((ni, depth)) = todo.pop() {
            let (first, count) = (nodes[ni].first as usize, nodes[ni].count as usize);
            let idx = &mut order[first..first + count];
            let mut bounds = Aabb::EMPTY;
            let mut cb = Aabb::EMPTY;
            for &i in idx.iter() {
                bounds.join(&boxes[i as usize]);
                cb.grow(centroids[i as usize]);
            }
            nodes[ni].lo = bounds.lo;
            nodes[ni].hi = bounds.hi;
            if count <= 2 {
                continue;
            }
            let mid = if depth < MAX_DEPTH {
                split(idx, &boxes, &centroids, &cb, bounds.area())
            } else {
                (count > MAX_LEAF).then_some(count / 2)
            };
            let Some(mid) = mid else {
                continue;
            };
            let left = nodes.len();
            nodes[ni].first = left as u32;
            nodes[ni].count = 0;
            for (f, c) in [(first, mid), (first + mid, count - mid)] {
                nodes.push(BinNode {
                    lo: [0.0; 3],
                    first: f as u32,
                    hi: [0.0; 3],
                    count: c as u32,
                });
            }
            todo.push((left, depth + 1));
            todo.push((left + 1, depth + 1));
        }
        let (nodes, packets, root) = wide::collapse(&nodes, triangles, &order);
        Self {
            nodes,
            packets,
            root,
            len: n,
        }
    }

    /// Number of triangles in the tree.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when the tree holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest hit with `t_min < t < t_max`.
    pub fn closest(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<Hit> {
        self.query::<false>(o, d, t_min, t_max)
    }

    /// True when anything lies strictly between `t_min` and `t_max` (shadow rays).
    pub fn occluded(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> bool {
        self.query::<true>(o, d, t_min, t_max).is_some()
    }

    /// The nearest hits of eight rays, for coherent rays (neighbouring pixels) faster than eight
    /// [`Bvh::closest`] calls, with the same hit distances.
    pub fn closest8(&self, o: &[V3; 8], d: &[V3; 8], t_min: f32, t_max: f32) -> [Option<Hit>; 8] {
        if self.len == 0 {
            return [None; 8];
        }
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the running CPU supports AVX2 and FMA, checked just above.
            return unsafe { self.closest8_avx2(o, d, t_min, t_max) };
        }
        std::array::from_fn(|i| self.closest(o[i], d[i], t_min, t_max))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn closest8_avx2(&self, o: &[V3; 8], d: &[V3; 8], t_min: f32, t_max: f32) -> [Option<Hit>; 8] {
        let (nodes, packets) = (&self.nodes, &self.packets);
        // SAFETY: this function only runs where AVX2 is available.
        unsafe { crate::packet::closest8(nodes, packets, self.root, o, d, t_min, t_max) }
    }

    /// Runs the traversal compiled for AVX2 + FMA when the CPU has them (eight boxes per
    /// register; the same lane arithmetic, so results are identical), else the baseline build.
    #[inline]
    fn query<const ANY: bool>(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<Hit> {
        if self.len == 0 {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the running CPU supports AVX2 and FMA, checked just above.
            return unsafe { self.query_avx2::<ANY>(o, d, t_min, t_max) };
        }
        let (nodes, packets) = (&self.nodes, &self.packets);
        // SAFETY: `Narrow` needs nothing beyond the baseline instruction set.
        unsafe {
            wide::traverse::<wide::Narrow, ANY>(nodes, packets, self.root, o, d, t_min, t_max)
        }
    }

    /// The baseline build of the traversal whatever the CPU (tests compare it to the AVX2 one).
    #[cfg(test)]
    fn closest_baseline(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<Hit> {
        let (nodes, packets) = (&self.nodes, &self.packets);
        // SAFETY: `Narrow` needs nothing beyond the baseline instruction set.
        unsafe {
            wide::traverse::<wide::Narrow, false>(nodes, packets, self.root, o, d, t_min, t_max)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn query_avx2<const ANY: bool>(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<Hit> {
        let (nodes, packets) = (&self.nodes, &self.packets);
        // SAFETY: this function only runs where AVX2 (and so AVX) is available.
        unsafe { wide::traverse::<wide::Avx, ANY>(nodes, packets, self.root, o, d, t_min, t_max) }
    }
}

#[cfg(target_arch = "x86_64")]
#[inline]
fn has_avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// Chooses the binned-SAH split of `idx` (partitioned in place) and returns the left count, or
/// `None` when a leaf is cheaper and small enough.
fn split(
    idx: &mut [u32],
    boxes: &[Aabb],
    centroids: &[V3],
    cb: &Aabb,
    parent_area: f32,
) -> Option<usize> {
    let count = idx.len();
    let mut best: Option<(f32, usize, f32)> = None; // (cost, axis, split coordinate)
    for axis in 0..3 {
        let (lo, hi) = (cb.lo[axis], cb.hi[axis]);
        if !(hi > lo) {
            continue;
        }
        let k = BINS as f32 / (hi - lo);
        let bin_of = |c: f32| (((c - lo) * k) as usize).min(BINS - 1);
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        for &i in idx.iter() {
            let b = &mut bins[bin_of(centroids[i as usize][axis])];
            b.0.join(&boxes[i as usize]);
            b.1 += 1;
        }
        // Sweep from the right to get suffix areas/counts, then from the left.
        let mut right = [(0.0f32, 0usize); BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc.join(&bins[i].0);
            n += bins[i].1;
            right[i] = (acc.area(), n);
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for i in 0..BINS - 1 {
            acc.join(&bins[i].0);
            n += bins[i].1;
            let (ra, rn) = right[i + 1];
            if n == 0 || rn == 0 {
                continue;
            }
            let cost = acc.area() * packets(n) + ra * packets(rn);
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, lo + (i + 1) as f32 / k));
            }
        }
    }
    let leaf_cost = packets(count);
    match best {
        Some((cost, axis, at))
            if count > MAX_LEAF
                || TRAVERSAL_COST + cost / parent_area.max(f32::MIN_POSITIVE) < leaf_cost =>
        {
            let k = BINS as f32 / (cb.hi[axis] - cb.lo[axis]);
            let lo = cb.lo[axis];
            let bin_at = ((at - lo) * k).round() as usize;
            let mid = partition(idx, |i| {
                (((centroids[i as usize][axis] - lo) * k) as usize).min(BINS - 1) < bin_at
            });
            if mid > 0 && mid < count {
                Some(mid)
            } else {
                // Rounding put every centroid on one side: leaves must stay <= MAX_LEAF.
                (count > MAX_LEAF).then_some(count / 2)
            }
        }
        // All centroids coincide: split the list in half so leaves stay small.
        None if count > MAX_LEAF => Some(count / 2),
        _ => None,
    }
}

fn partition(idx: &mut [u32], pred: impl Fn(u32) -> bool) -> usize {
    let mut m = 0;
    for j in 0..idx.len() {
        if pred(idx[j]) {
            idx.swap(m, j);
            m += 1;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{cross, dot};
    use crate::rng::Rng;

    /// A triangle: vertex 0 and the two edges from it.
    struct Tri {
        v0: V3,
        e1: V3,
        e2: V3,
    }

    /// The scalar Moller-Trumbore test the packets reproduce lane for lane.
    fn intersect(tri: &Tri, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let p = cross(d, tri.e2);
        let det = dot(tri.e1, p);
        if det.abs() < 1e-20 {
            return None;
        }
        let inv = 1.0 / det;
        let s = sub(o, tri.v0);
        let u = dot(s, p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = cross(s, tri.e1);
        let v = dot(d, q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = dot(tri.e2, q) * inv;
        (t > t_min && t < t_max).then_some((t, u, v))
    }

    fn brute(tris: &[[V3; 3]], o: V3, d: V3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (i, t) in tris.iter().enumerate() {
            let tri = Tri {
                v0: t[0],
                e1: sub(t[1], t[0]),
                e2: sub(t[2], t[0]),
            };
            if let Some((tt, _, _)) = intersect(&tri, o, d, 0.0, f32::INFINITY) {
                if best.is_none_or(|b| tt < b.0) {
                    best = Some((tt, i as u32));
                }
            }
        }
        best
    }

    fn soup(n: usize, seed: u64) -> Vec<[V3; 3]> {
        let mut r = Rng::new(seed, 0, 0);
        (0..n)
            .map(|_| {
                let c = [
                    r.uniform() * 4.0 - 2.0,
                    r.uniform() * 4.0 - 2.0,
                    r.uniform() * 4.0 + 1.0,
                ];
                let mut v = || {
                    add(
                        c,
                        [
                            r.uniform() * 0.4 - 0.2,
                            r.uniform() * 0.4 - 0.2,
                            r.uniform() * 0.4 - 0.2,
                        ],
                    )
                };
                [v(), v(), v()]
            })
            .collect()
    }

    #[test]
    fn matches_brute_force() {
        let tris = soup(2000, 3);
        let bvh = Bvh::build(&tris);
        let mut r = Rng::new(9, 0, 0);
        for _ in 0..2000 {
            let d = [r.uniform() - 0.5, r.uniform() - 0.5, 1.0];
            let got = bvh
                .closest([0.0; 3], d, 0.0, f32::INFINITY)
                .map(|h| (h.t, h.prim));
            let want = brute(&tris, [0.0; 3], d);
            assert_eq!(got.is_some(), want.is_some());
            if let (Some(g), Some(w)) = (got, want) {
                assert!((g.0 - w.0).abs() <= 1e-6 * w.0, "{g:?} {w:?}");
            }
            assert_eq!(
                bvh.occluded([0.0; 3], d, 0.0, f32::INFINITY),
                want.is_some()
            );
            // Both instruction-set builds give the same hit, bit for bit.
            assert_eq!(
                bvh.closest_baseline([0.0; 3], d, 0.0, f32::INFINITY),
                bvh.closest([0.0; 3], d, 0.0, f32::INFINITY)
            );
        }
    }

    #[test]
    fn packets_of_eight_find_the_single_ray_hits() {
        let tris = soup(1500, 13);
        let bvh = Bvh::build(&tris);
        let mut r = Rng::new(17, 0, 0);
        for bundle in 0..400 {
            // Coherent bundles (one origin, neighbouring directions), incoherent ones, and
            // axis-aligned ones with zero direction components.
            let o: [V3; 8] = if bundle % 3 == 1 {
                std::array::from_fn(|_| [r.uniform() - 0.5, r.uniform() - 0.5, r.uniform()])
            } else {
                [[0.0; 3]; 8]
            };
            let (cx, cy) = (r.uniform() - 0.5, r.uniform() - 0.5);
            let d: [V3; 8] = std::array::from_fn(|i| match bundle % 3 {
                0 => [cx + 0.002 * i as f32, cy, 1.0],
                1 => [r.uniform() - 0.5, r.uniform() - 0.5, 1.0],
                _ => [0.0, 0.0, 1.0],
            });
            let o = if bundle % 3 == 2 {
                std::array::from_fn(|i| [cx * 4.0 + 0.01 * i as f32, cy * 4.0, 0.0])
            } else {
                o
            };
            let got = bvh.closest8(&o, &d, 0.5, 50.0);
            for i in 0..8 {
                let want = bvh.closest(o[i], d[i], 0.5, 50.0);
                assert_eq!(got[i].map(|h| h.t), want.map(|h| h.t), "{bundle} {i}");
            }
        }
        assert_eq!(
            Bvh::build(&[]).closest8(&[[0.0; 3]; 8], &[[0.0, 0.0, 1.0]; 8], 0.0, 1.0),
            [None; 8]
        );
    }

    #[test]
    fn matches_brute_force_on_axis_aligned_rays() {
        // Zero direction components (infinite reciprocals) and origins on the boxes' planes, as
        // the orthographic depth views cast them; any-hit within a bounded segment too.
        let tris = soup(500, 5);
        let bvh = Bvh::build(&tris);
        for (i, t) in tris.iter().enumerate().take(200) {
            let c = scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0);
            let corner = t[i % 3];
            for (o, d) in [
                ([c[0], c[1], -1.0], [0.0, 0.0, 1.0]),
                ([c[0], -5.0, c[2]], [0.0, 1.0, 0.0]),
                ([9.0, c[1], c[2]], [-1.0, 0.0, -0.0]),
                ([corner[0], corner[1], 0.0], [0.0, 0.0, 1.0]),
            ] {
                let got = bvh.closest(o, d, 0.0, f32::INFINITY).map(|h| h.t);
                let want = brute(&tris, o, d).map(|w| w.0);
                assert_eq!(got, want, "{o:?} {d:?}");
                let half = want.map_or(1.0, |w| w * 0.5);
                assert!(!bvh.occluded(o, d, 0.0, half) || want.is_none_or(|w| w < half));
            }
        }
    }

    #[test]
    fn hits_report_the_input_triangle_and_barycentrics() {
        let tris = soup(300, 7);
        let bvh = Bvh::build(&tris);
        let mut r = Rng::new(11, 0, 0);
        let mut hits = 0;
        for _ in 0..500 {
            let d = [r.uniform() - 0.5, r.uniform() - 0.5, 1.0];
            let Some(h) = bvh.closest([0.0; 3], d, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let t = tris[h.prim as usize];
            let p = add(
                t[0],
                add(scale(sub(t[1], t[0]), h.u), scale(sub(t[2], t[0]), h.v)),
            );
            let q = scale(d, h.t);
            assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-4), "{p:?} {q:?}");
        }
        assert!(hits > 50);
    }

    #[test]
    fn nearest_of_many_stacked_triangles() {
        // 300 parallel triangles at z = 1.25^i, every box on the ray: the far children pile up
        // on the stack and the hit must still be the first triangle past the origin.
        let tris: Vec<[V3; 3]> = (0..300)
            .map(|i| {
                let z = 1.25f32.powi(i);
                [[-1.0, -1.0, z], [2.0, -1.0, z], [-1.0, 2.0, z]]
            })
            .collect();
        let bvh = Bvh::build(&tris);
        for (i, t) in tris.iter().enumerate() {
            let o = [0.0, 0.0, t[0][2] * 0.99];
            let h = bvh.closest(o, [0.0, 0.0, 1.0], 0.0, f32::INFINITY);
            assert_eq!(h.map(|h| h.prim), Some(i as u32));
        }
    }

    #[test]
    fn empty_and_degenerate() {
        let bvh = Bvh::build(&[]);
        assert!(bvh.closest([0.0; 3], [0.0, 0.0, 1.0], 0.0, 1e9).is_none());
        let flat = vec![[[0.0, 0.0, 1.0]; 3]; 20];
        let bvh = Bvh::build(&flat);
        assert!(bvh.closest([0.0; 3], [0.0, 0.0, 1.0], 0.0, 1e9).is_none());
        assert_eq!(bvh.len(), 20);
    }
}
