//! The 8-wide BVH the ray caster traverses. The binary SAH tree of [`crate::bvh`] is collapsed
//! into nodes of up to eight children whose boxes are stored lane-wise (structure of arrays), so
//! one ray tests all eight boxes with a handful of SIMD operations (one AVX register per bound,
//! or two SSE ones on CPUs without AVX2); leaves are packets of up to four triangles tested
//! together the same way (Moller-Trumbore, lane for lane the scalar arithmetic, so hits are
//! bit-identical to a one-triangle-at-a-time test).
//!
//! Traversal is single-ray, front to back: the hit children are visited nearest first, the
//! others are pushed with their entry distance and skipped on pop once the best hit is nearer.

use std::mem::MaybeUninit;

use crate::bvh::{BinNode, Hit};
use crate::math::{sub, V3};
use crate::simd4::{F4, M4};

/// Marks a child reference as a leaf (the rest is the packet index).
pub(crate) const LEAF: u32 = 1 << 31;
/// Children per node.
pub(crate) const W: usize = 8;
/// Traversal stack entries: at most `W - 1` pushes per level, and the build caps the depth at
/// [`crate::bvh::MAX_DEPTH`] + 32 levels.
pub(crate) const STACK: usize = (W - 1) * (crate::bvh::MAX_DEPTH + 32) + 1;

/// Up to eight child boxes, one lane per child: `b[2k]` / `b[2k + 1]` are the low / high bounds
/// along axis `k`. Unused lanes hold empty boxes and are masked off by `n`.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct Node8 {
    pub(crate) b: [[f32; W]; 6],
    /// A node index, or [`LEAF`] | packet index.
    pub(crate) child: [u32; W],
    /// Lanes in use (2..=8).
    pub(crate) n: u32,
}

/// Up to four triangles, lane-wise: vertex 0, the edges to vertices 1 and 2, and the input
/// index. Unused lanes are zero triangles (determinant 0: never hit).
#[derive(Debug, Clone, Copy)]
#[repr(C, align(16))]
pub(crate) struct Tri4 {
    v0: [[f32; 4]; 3],
    e1: [[f32; 4]; 3],
    e2: [[f32; 4]; 3],
    id: [u32; 4],
}

/// Builds the 8-wide tree from the binary one (`bin[0]` is the root; leaves hold at most four
/// triangles of `tris` in `order`). Returns the nodes, the packets and the root reference.
pub(crate) fn collapse(
    bin: &[BinNode],
    tris: &[[V3; 3]],
    order: &[u32],
) -> (Vec<Node8>, Vec<Tri4>, u32) {
    let mut c = Collapse {
        bin,
        tris,
        order,
        nodes: Vec::with_capacity(bin.len() / 3 + 1),
        packets: Vec::with_capacity(bin.len() / 2 + 1),
    };
    let root = if order.is_empty() { LEAF } else { c.emit(0) };
    (c.nodes, c.packets, root)
}

struct Collapse<'a> {
    bin: &'a [BinNode],
    tris: &'a [[V3; 3]],
    order: &'a [u32],
    nodes: Vec<Node8>,
    packets: Vec<Tri4>,
}

impl Collapse<'_> {
    /// Emits binary node `i` (and its subtree) and returns its reference.
    fn emit(&mut self, i: usize) -> u32 {
        let b = self.bin[i];
        if b.count > 0 {
            return LEAF | self.packet(b.first as usize, b.count as usize);
        }
        // Open the interior child of largest surface area until there are eight children: the
        // children most rays enter are the ones worth testing together.
        let mut kids = [0usize; W];
        kids[..2].copy_from_slice(&[b.first as usize, b.first as usize + 1]);
        let mut len = 2;
        while len < W {
            let Some(j) = (0..len)
                .filter(|&j| self.bin[kids[j]].count == 0)
                .max_by(|&x, &y| {
                    self.bin[kids[x]]
                        .area()
                        .total_cmp(&self.bin[kids[y]].area())
                })
            else {
                break;
            };
            let l = self.bin[kids[j]].first as usize;
            kids[j] = l;
            kids[len] = l + 1;
            len += 1;
        }
        let slot = self.nodes.len();
        self.nodes.push(Node8 {
            b: [
                [f32::INFINITY; W],
                [f32::NEG_INFINITY; W],
                [f32::INFINITY; W],
                [f32::NEG_INFINITY; W],
                [f32::INFINITY; W],
                [f32::NEG_INFINITY; W],
            ],
            child: [0; W],
            n: len as u32,
        });
        for (lane, &k) in kids[..len].iter().enumerate() {
            let r = self.emit(k);
            let (lo, hi) = (self.bin[k].lo, self.bin[k].hi);
            let node = &mut self.nodes[slot];
            for a in 0..3 {
                node.b[2 * a][lane] = lo[a];
                node.b[2 * a + 1][lane] = hi[a];
            }
            node.child[lane] = r;
        }
        slot as u32
    }

    /// Packs `order[first..first + count]` (at most 4) into a packet; returns its index.
    fn packet(&mut self, first: usize, count: usize) -> u32 {
        debug_assert!(count <= 4);
        let mut p = Tri4 {
            v0: [[0.0; 4]; 3],
            e1: [[0.0; 4]; 3],
            e2: [[0.0; 4]; 3],
            id: [u32::MAX; 4],
        };
        for (lane, &id) in self.order[first..first + count].iter().enumerate() {
            let [a, b, c] = self.tris[id as usize];
            let (e1, e2) = (sub(b, a), sub(c, a));
            for k in 0..3 {
                p.v0[k][lane] = a[k];
                p.e1[k][lane] = e1[k];
                p.e2[k][lane] = e2[k];
            }
            p.id[lane] = id;
        }
        self.packets.push(p);
        (self.packets.len() - 1) as u32
    }
}

/// A ray broadcast to four lanes, with its reciprocal direction and, per axis, which bound
/// (low or high) it meets first.
pub(crate) struct Ray4 {
    o: [F4; 3],
    d: [F4; 3],
    so: V3,
    sinv: V3,
    near: [usize; 3],
}

impl Ray4 {
    #[inline(always)]
    pub(crate) fn new(o: V3, d: V3) -> Self {
        Self::with_inverse(o, d, [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]])
    }

    /// The ray with its reciprocal direction `inv` already computed.
    #[inline(always)]
    pub(crate) fn with_inverse(o: V3, d: V3, inv: V3) -> Self {
        Self {
            o: o.map(F4::splat),
            d: d.map(F4::splat),
            so: o,
            sinv: inv,
            near: [0, 1, 2].map(|k| 2 * k + inv[k].is_sign_negative() as usize),
        }
    }
}

/// The eight-box slab test, compiled per instruction set.
///
/// # Safety
/// Implementations may use instructions beyond the x86-64 baseline: [`BoxTest::boxes`] must
/// only run on a CPU that has them (see each implementation).
pub(crate) unsafe trait BoxTest {
    /// The mask of children entered within `[t_min, t_max]` and the entry distances.
    ///
    /// # Safety
    /// The running CPU supports the implementation's instruction set.
    unsafe fn boxes(n: &Node8, r: &Ray4, t_min: f32, t_max: f32) -> (u32, [f32; W]);
}

/// Two 4-lane halves: the x86-64 baseline (SSE) or plain lanes elsewhere.
pub(crate) struct Narrow;

// SAFETY: uses only F4, which needs nothing beyond the baseline.
unsafe impl BoxTest for Narrow {
    #[inline(always)]
    unsafe fn boxes(n: &Node8, r: &Ray4, t_min: f32, t_max: f32) -> (u32, [f32; W]) {
        #[inline(always)]
        fn slab(n: &Node8, r: &Ray4, k: usize, h: usize) -> (F4, F4) {
            let (o, inv) = (F4::splat(r.so[k]), F4::splat(r.sinv[k]));
            let half = |b: &[f32; W]| F4::load(b[4 * h..4 * h + 4].try_into().unwrap());
            let near = half(&n.b[r.near[k]]).sub(o).mul(inv);
            let far = half(&n.b[r.near[k] ^ 1]).sub(o).mul(inv);
            (near, far)
        }
        let mut mask = 0;
        let mut dist = [0.0; W];
        for h in 0..2 {
            let ((nx, fx), (ny, fy), (nz, fz)) =
                (slab(n, r, 0, h), slab(n, r, 1, h), slab(n, r, 2, h));
            // A tree, not a chain (shorter latency). A NaN from 0 * inf (ray in a slab plane)
            // drops out: max/min return their second operand when either is NaN, and the
            // second operand of the outer and right inner operations is NaN-free.
            let t0 = nx.max(ny).max(nz.max(F4::splat(t_min)));
            let t1 = fx.min(fy).min(fz.min(F4::splat(t_max)));
            mask |= t0.le(t1).bits() << (4 * h);
            dist[4 * h..4 * h + 4].copy_from_slice(&t0.to_array());
        }
        (mask & ((1 << n.n) - 1), dist)
    }
}

/// One AVX register per bound.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx;

// SAFETY: needs AVX, which the contract of `boxes` requires of the caller.
#[cfg(target_arch = "x86_64")]
unsafe impl BoxTest for Avx {
    #[inline(always)]
    unsafe fn boxes(n: &Node8, r: &Ray4, t_min: f32, t_max: f32) -> (u32, [f32; W]) {
        use std::arch::x86_64::*;
        // SAFETY: the caller guarantees AVX; loads and stores touch exactly 8-float arrays.
        unsafe {
            #[inline(always)]
            unsafe fn slab(n: &Node8, r: &Ray4, k: usize) -> (__m256, __m256) {
                // SAFETY: as in `boxes` (inlined there).
                unsafe {
                    let (o, inv) = (_mm256_set1_ps(r.so[k]), _mm256_set1_ps(r.sinv[k]));
                    let lo = _mm256_loadu_ps(n.b[r.near[k]].as_ptr());
                    let hi = _mm256_loadu_ps(n.b[r.near[k] ^ 1].as_ptr());
                    let near = _mm256_mul_ps(_mm256_sub_ps(lo, o), inv);
                    let far = _mm256_mul_ps(_mm256_sub_ps(hi, o), inv);
                    (near, far)
                }
            }
            let ((nx, fx), (ny, fy), (nz, fz)) = (slab(n, r, 0), slab(n, r, 1), slab(n, r, 2));
            // The same tree as `Narrow`, with the same NaN handling.
            let t0 = _mm256_max_ps(
                _mm256_max_ps(nx, ny),
                _mm256_max_ps(nz, _mm256_set1_ps(t_min)),
            );
            let t1 = _mm256_min_ps(
                _mm256_min_ps(fx, fy),
                _mm256_min_ps(fz, _mm256_set1_ps(t_max)),
            );
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32;
            let mut dist = [0.0; W];
            _mm256_storeu_ps(dist.as_mut_ptr(), t0);
            (hit & ((1 << n.n) - 1), dist)
        }
    }
}

/// Moller-Trumbore on four triangles: the mask of hits with `t_min < t < t_max` and their
/// `(t, u, v)`. Same operations in the same order as the scalar test.
#[inline(always)]
fn triangles(p: &Tri4, r: &Ray4, t_min: F4, t_max: F4) -> (u32, F4, F4, F4) {
    let [ox, oy, oz] = r.o;
    let [dx, dy, dz] = r.d;
    let [e1x, e1y, e1z] = p.e1.each_ref().map(F4::load);
    let [e2x, e2y, e2z] = p.e2.each_ref().map(F4::load);
    let px = dy.mul(e2z).sub(dz.mul(e2y));
    let py = dz.mul(e2x).sub(dx.mul(e2z));
    let pz = dx.mul(e2y).sub(dy.mul(e2x));
    let det = e1x.mul(px).add(e1y.mul(py)).add(e1z.mul(pz));
    let zero = F4::splat(0.0);
    let one = F4::splat(1.0);
    let inv = one.div(det);
    let sx = ox.sub(F4::load(&p.v0[0]));
    let sy = oy.sub(F4::load(&p.v0[1]));
    let sz = oz.sub(F4::load(&p.v0[2]));
    let u = sx.mul(px).add(sy.mul(py)).add(sz.mul(pz)).mul(inv);
    // A NaN determinant fails the u test, as in the scalar code.
    let mut ok: M4 = u
        .ge(zero)
        .and(u.le(one))
        .and_not(det.abs().lt(F4::splat(1e-20)));
    let qx = sy.mul(e1z).sub(sz.mul(e1y));
    let qy = sz.mul(e1x).sub(sx.mul(e1z));
    let qz = sx.mul(e1y).sub(sy.mul(e1x));
    let v = dx.mul(qx).add(dy.mul(qy)).add(dz.mul(qz)).mul(inv);
    ok = ok.and_not(v.lt(zero).or(u.add(v).gt(one)));
    let t = e2x.mul(qx).add(e2y.mul(qy)).add(e2z.mul(qz)).mul(inv);
    ok = ok.and(t.gt(t_min)).and(t.lt(t_max));
    (ok.bits(), t, u, v)
}

/// The nearest hit in a packet with `t_min < t < t_best` (the first lane among equals).
#[inline(always)]
pub(crate) fn leaf(p: &Tri4, r: &Ray4, t_min: F4, t_best: f32) -> Option<Hit> {
    let (mask, t, u, v) = triangles(p, r, t_min, F4::splat(t_best));
    if mask == 0 {
        return None;
    }
    let ts = t.to_array();
    let mut lane = mask.trailing_zeros() as usize;
    let mut m = mask & (mask - 1);
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        if ts[i] < ts[lane] {
            lane = i;
        }
    }
    Some(Hit {
        t: ts[lane],
        prim: p.id[lane],
        u: u.to_array()[lane],
        v: v.to_array()[lane],
    })
}

/// Closest hit with `t_min < t < t_max` (`ANY = false`), or the first hit found (`ANY = true`,
/// shadow rays). `root` is the reference [`collapse`] returned; the tree must not be empty.
///
/// # Safety
/// The running CPU supports `B`'s instruction set.
#[inline(always)]
pub(crate) unsafe fn traverse<B: BoxTest, const ANY: bool>(
    nodes: &[Node8],
    packets: &[Tri4],
    root: u32,
    o: V3,
    d: V3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    let r = Ray4::new(o, d);
    let t_lo = F4::splat(t_min);
    let mut t_best = t_max;
    let mut best: Option<Hit> = None;
    let mut stack = [MaybeUninit::<(u32, f32)>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = root;
    loop {
        if cur & LEAF == 0 {
            let n = &nodes[cur as usize];
            // SAFETY: passed on from this function's contract.
            let (mut mask, dist) = unsafe { B::boxes(n, &r, t_min, t_best) };
            if mask != 0 {
                let a = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if mask == 0 {
                    cur = n.child[a];
                    continue;
                }
                let b = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if mask == 0 {
                    let (near, far) = if dist[a] <= dist[b] { (a, b) } else { (b, a) };
                    stack[sp].write((n.child[far], dist[far]));
                    sp += 1;
                    cur = n.child[near];
                    continue;
                }
                // More children: push all but the nearest, farthest first.
                let mut k = [(0.0, 0); W];
                k[0] = (dist[a], a);
                k[1] = (dist[b], b);
                let mut c = 2;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    k[c] = (dist[i], i);
                    c += 1;
                }
                for i in 1..c {
                    let mut j = i;
                    while j > 0 && k[j - 1].0 < k[j].0 {
                        k.swap(j - 1, j);
                        j -= 1;
                    }
                }
                for &(dd, i) in &k[..c - 1] {
                    stack[sp].write((n.child[i], dd));
                    sp += 1;
                }
                cur = n.child[k[c - 1].1];
                continue;
            }
        } else {
            let p = &packets[(cur & !LEAF) as usize];
            if let Some(h) = leaf(p, &r, t_lo, t_best) {
                t_best = h.t;
                best = Some(h);
                if ANY {
                    return best;
                }
            }
        }
        // Pop the next node, skipping those the shrunken t_best already excludes.
        loop {
            if sp == 0 {
                return best;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written by a push above.
            let (c, dist) = unsafe { stack[sp].assume_init() };
            if dist <= t_best {
                cur = c;
                break;
            }
        }
    }
}
