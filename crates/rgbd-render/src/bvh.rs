//! Bounding-volume hierarchy over triangles: binned SAH build (16 bins per axis), a flat node
//! array (32-byte nodes, children adjacent), and closest-hit / any-hit traversal with the nearer
//! child visited first. Triangles are stored in BVH order with precomputed edges
//! (Moller-Trumbore), so a leaf test touches contiguous memory.

use crate::math::{add, cross, dot, scale, sub, vmax, vmin, V3};

/// Bins per axis of the SAH sweep; 16 is within a few % of a full sweep at a fraction of the cost.
const BINS: usize = 16;
/// Leaves never hold more triangles than this (the SAH may stop earlier).
const MAX_LEAF: usize = 4;
/// Cost of one node traversal relative to one triangle test (SAH constant).
const TRAVERSAL_COST: f32 = 0.5;
/// Traversal stack depth; a SAH tree over < 2^32 triangles stays far below it.
const STACK: usize = 64;

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: V3,
    /// Leaf: first triangle; interior: index of the left child (right = left + 1).
    first: u32,
    hi: V3,
    /// Number of triangles; 0 marks an interior node.
    count: u32,
}

/// A triangle in BVH order: vertex 0, the two edges from it, and its index in the input.
#[derive(Debug, Clone, Copy)]
struct Tri {
    v0: V3,
    e1: V3,
    e2: V3,
    id: u32,
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
    nodes: Vec<Node>,
    tris: Vec<Tri>,
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
        nodes.push(Node {
            lo: [0.0; 3],
            first: 0,
            hi: [0.0; 3],
            count: n as u32,
        });
        let mut todo = vec![0usize];
        while let Some(ni) = todo.pop() {
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
            let Some(mid) = split(idx, &boxes, &centroids, &cb, bounds.area()) else {
                continue;
            };
            let left = nodes.len();
            nodes[ni].first = left as u32;
            nodes[ni].count = 0;
            for (f, c) in [(first, mid), (first + mid, count - mid)] {
                nodes.push(Node {
                    lo: [0.0; 3],
                    first: f as u32,
                    hi: [0.0; 3],
                    count: c as u32,
                });
            }
            todo.push(left);
            todo.push(left + 1);
        }
        let tris = order
            .iter()
            .map(|&i| {
                let [a, b, c] = triangles[i as usize];
                Tri {
                    v0: a,
                    e1: sub(b, a),
                    e2: sub(c, a),
                    id: i,
                }
            })
            .collect();
        Self { nodes, tris }
    }

    /// Number of triangles in the tree.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when the tree holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The nearest hit with `t_min < t < t_max`.
    pub fn closest(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        self.traverse(o, d, t_min, &mut t_best, |tri, t, u, v| {
            best = Some(Hit {
                t,
                prim: tri.id,
                u,
                v,
            });
            false
        });
        best
    }

    /// True when anything lies strictly between `t_min` and `t_max` (shadow rays).
    pub fn occluded(&self, o: V3, d: V3, t_min: f32, t_max: f32) -> bool {
        let mut hit = false;
        let mut t_best = t_max;
        self.traverse(o, d, t_min, &mut t_best, |_, _, _, _| {
            hit = true;
            true
        });
        hit
    }

    /// Visits nodes front to back; `on_hit` is called for every hit closer than `t_best`
    /// (which then shrinks) and returns true to stop.
    #[inline]
    fn traverse(
        &self,
        o: V3,
        d: V3,
        t_min: f32,
        t_best: &mut f32,
        mut on_hit: impl FnMut(&Tri, f32, f32, f32) -> bool,
    ) {
        if self.tris.is_empty() {
            return;
        }
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node = &self.nodes[0];
        if slab(node, o, inv, t_min, *t_best).is_none() {
            return;
        }
        loop {
            if node.count > 0 {
                let first = node.first as usize;
                for tri in &self.tris[first..first + node.count as usize] {
                    if let Some((t, u, v)) = intersect(tri, o, d, t_min, *t_best) {
                        *t_best = t;
                        if on_hit(tri, t, u, v) {
                            return;
                        }
                    }
                }
            } else {
                let l = node.first as usize;
                let (a, b) = (&self.nodes[l], &self.nodes[l + 1]);
                let ta = slab(a, o, inv, t_min, *t_best);
                let tb = slab(b, o, inv, t_min, *t_best);
                match (ta, tb) {
                    (Some(x), Some(y)) => {
                        let (near, far) = if x <= y { (l, l + 1) } else { (l + 1, l) };
                        stack[sp] = far as u32;
                        sp += 1;
                        node = &self.nodes[near];
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node, skipping those the shrunken t_best already excludes.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let cand = &self.nodes[stack[sp] as usize];
                if slab(cand, o, inv, t_min, *t_best).is_some() {
                    node = cand;
                    break;
                }
            }
        }
    }
}

/// Entry distance of the ray into the node's box, if it enters within `(t_min, t_max)`.
#[inline(always)]
fn slab(n: &Node, o: V3, inv: V3, t_min: f32, t_max: f32) -> Option<f32> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    for k in 0..3 {
        let a = (n.lo[k] - o[k]) * inv[k];
        let b = (n.hi[k] - o[k]) * inv[k];
        // Plain comparisons (cheaper than f32::min/max); a NaN from 0 * inf (ray inside a slab
        // plane) fails every comparison and leaves the bounds unchanged.
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        t0 = if near > t0 { near } else { t0 };
        t1 = if far < t1 { far } else { t1 };
    }
    (t0 <= t1).then_some(t0)
}

/// Moller-Trumbore; returns `(t, u, v)` for hits with `t_min < t < t_max`.
#[inline(always)]
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
            let cost = acc.area() * n as f32 + ra * rn as f32;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, lo + (i + 1) as f32 / k));
            }
        }
    }
    let leaf_cost = count as f32;
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
            (mid > 0 && mid < count).then_some(mid)
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
    use crate::rng::Rng;

    fn brute(tris: &[[V3; 3]], o: V3, d: V3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (i, t) in tris.iter().enumerate() {
            let tri = Tri {
                v0: t[0],
                e1: sub(t[1], t[0]),
                e2: sub(t[2], t[0]),
                id: i as u32,
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
