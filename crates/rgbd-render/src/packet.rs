//! Packets of eight coherent rays (the primary rays of neighbouring pixels) walking the 8-wide
//! BVH together under AVX2. A node's children are tested one by one against all eight rays at
//! once (one lane per ray): eight independent box tests per instruction instead of one ray's
//! dependent chain, so the walk is bound by throughput rather than latency. Leaves are tested
//! ray by ray with the single-ray packet test, and every ray keeps its own nearest distance, so
//! each ray gets the hit distance [`crate::wide::traverse`] finds, bit for bit (where two
//! triangles are hit at exactly the same distance either may be reported).

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use crate::bvh::Hit;
use crate::math::V3;
use crate::simd4::F4;
use crate::wide::{leaf, Node8, Ray4, Tri4, LEAF, STACK, W};

/// Rays per packet (one AVX lane each).
pub(crate) const P: usize = 8;

/// # Safety
/// AVX (as for [`closest8`], into which it is inlined).
#[inline(always)]
unsafe fn ld(a: &[f32; P]) -> __m256 {
    // SAFETY: reads exactly the 8 floats of `a`; AVX per this function's contract.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

/// Entry and exit distances of the eight rays through the slab `[l, h]` of one axis: per lane
/// the single-ray test (the bound met first chosen by the sign of the reciprocal `i`, which
/// blendv reads from its sign bit).
///
/// # Safety
/// AVX (as for [`closest8`], into which it is inlined).
#[inline(always)]
unsafe fn slab(l: f32, h: f32, o: __m256, i: __m256) -> (__m256, __m256) {
    // SAFETY: AVX per this function's contract.
    unsafe {
        let (l, h) = (_mm256_set1_ps(l), _mm256_set1_ps(h));
        let near = _mm256_mul_ps(_mm256_sub_ps(_mm256_blendv_ps(l, h, i), o), i);
        let far = _mm256_mul_ps(_mm256_sub_ps(_mm256_blendv_ps(h, l, i), o), i);
        (near, far)
    }
}

/// The nearest hit with `t_min < t < t_max` of each of the eight rays `(o[i], d[i])`.
///
/// # Safety
/// The running CPU supports AVX2 (the caller is the AVX2 build of the traversal).
#[inline(always)]
pub(crate) unsafe fn closest8(
    nodes: &[Node8],
    packets: &[Tri4],
    root: u32,
    o: &[V3; P],
    d: &[V3; P],
    t_min: f32,
    t_max: f32,
) -> [Option<Hit>; P] {
    let axis = |v: &[V3; P], k: usize| -> [f32; P] { std::array::from_fn(|i| v[i][k]) };
    let mut inv = [[0.0f32; P]; 3];
    let t_lo = F4::splat(t_min);
    let mut t_best = [t_max; P];
    let mut out = [None; P];
    let mut stack = [MaybeUninit::<(u32, u32, f32)>::uninit(); STACK];
    let mut sp = 0usize;
    let (mut cur, mut active) = (root, (1u32 << P) - 1);
    // SAFETY: the caller guarantees AVX2; every load reads exactly an 8-float array.
    unsafe {
        let (ox, oy, oz) = (ld(&axis(o, 0)), ld(&axis(o, 1)), ld(&axis(o, 2)));
        // Eight IEEE divisions at once: the same reciprocals as the single-ray setup.
        let one = _mm256_set1_ps(1.0);
        let ix = _mm256_div_ps(one, ld(&axis(d, 0)));
        let iy = _mm256_div_ps(one, ld(&axis(d, 1)));
        let iz = _mm256_div_ps(one, ld(&axis(d, 2)));
        for (a, v) in inv.iter_mut().zip([ix, iy, iz]) {
            _mm256_storeu_ps(a.as_mut_ptr(), v);
        }
        let lo = _mm256_set1_ps(t_min);
        let mut hi = ld(&t_best);
        loop {
            if cur & LEAF == 0 {
                let n = &nodes[cur as usize];
                let mut kids = [(0.0f32, 0u32, 0u32); W];
                let mut c = 0;
                for j in 0..n.n as usize {
                    let (nx, fx) = slab(n.b[0][j], n.b[1][j], ox, ix);
                    let (ny, fy) = slab(n.b[2][j], n.b[3][j], oy, iy);
                    let (nz, fz) = slab(n.b[4][j], n.b[5][j], oz, iz);
                    // The same tree of max / min as the single-ray test, same NaN handling.
                    let t0 = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, lo));
                    let t1 = _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, hi));
                    let inside = _mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1);
                    let m = _mm256_movemask_ps(inside) as u32 & active;
                    if m != 0 {
                        // The nearest entry of the rays that enter: the visiting order and,
                        // on pop, a bound no ray of the packet can beat inside the child.
                        let e = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), t0, inside);
                        let e = _mm256_min_ps(e, _mm256_permute2f128_ps::<1>(e, e));
                        let e = _mm256_min_ps(e, _mm256_permute_ps::<0b01_00_11_10>(e));
                        let e = _mm256_min_ps(e, _mm256_permute_ps::<0b10_11_00_01>(e));
                        kids[c] = (_mm256_cvtss_f32(e), n.child[j], m);
                        c += 1;
                    }
                }
                if c > 0 {
                    // Farthest first onto the stack, the nearest visited now.
                    for i in 1..c {
                        let mut j = i;
                        while j > 0 && kids[j - 1].0 < kids[j].0 {
                            kids.swap(j - 1, j);
                            j -= 1;
                        }
                    }
                    for &(dist, child, m) in &kids[..c - 1] {
                        stack[sp].write((child, m, dist));
                        sp += 1;
                    }
                    (cur, active) = (kids[c - 1].1, kids[c - 1].2);
                    continue;
                }
            } else {
                let p = &packets[(cur & !LEAF) as usize];
                let mut m = active;
                while m != 0 {
                    let r = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let ray = Ray4::with_inverse(o[r], d[r], [inv[0][r], inv[1][r], inv[2][r]]);
                    if let Some(h) = leaf(p, &ray, t_lo, t_best[r]) {
                        t_best[r] = h.t;
                        out[r] = Some(h);
                    }
                }
                hi = ld(&t_best);
            }
            // Pop the next node with the rays whose nearest hit may still lie inside it.
            loop {
                if sp == 0 {
                    return out;
                }
                sp -= 1;
                let (c, m, dist) = stack[sp].assume_init();
                let open = _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_set1_ps(dist), hi);
                let m = m & _mm256_movemask_ps(open) as u32;
                if m != 0 {
                    (cur, active) = (c, m);
                    break;
                }
            }
        }
    }
}
