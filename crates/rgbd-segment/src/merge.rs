//! Priority-queue region merging (thesis §4.7, Algorithm 1) and the fit-only baseline of the
//! thesis' reference [74].
//!
//! Segments are slots `0..n`. The queue is a binary heap with lazy deletion: each entry carries
//! the version of both segments when it was pushed, and a popped entry whose segment has since
//! merged (dead, or a newer version) is dropped. This is Algorithm 1's "remove all couples
//! including i* or j*" without searching the heap. Ties are broken by the smaller slot pair, so
//! the result is deterministic.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rayon::prelude::*;
use rgbd_error::{check_interrupt, invalid, Result, RgbdError};
use rgbd_spline::SegmentFits;

/// Eq. 4.7: smallest Bhattacharyya similarity of a couple that enters the queue.
pub const T_SIM: f64 = 0.77;

/// The surface fits the merging consults (eq. 4.8). Slots index segments; `merge(a, b)` joins
/// `b` into `a`.
pub trait FitModel: Sync {
    /// Valid pixels of segment `s`.
    fn size(&self, s: usize) -> Result<usize>;
    /// Fitting error of segment `s`.
    fn error(&self, s: usize) -> Result<f64>;
    /// Fitting error of the union of `a` and `b` (nothing changes).
    fn union_error(&self, a: usize, b: usize) -> Result<f64>;
    /// Whether the union fits well enough to merge (eq. 4.8).
    fn accepts(&self, a: usize, b: usize) -> Result<bool>;
    /// Joins `b` into `a`; returns the error of the union.
    fn merge(&mut self, a: usize, b: usize) -> Result<f64>;

    /// Whether eq. 4.8 accepts the union of `a` and `b`, and its relative fit improvement
    /// `1 - e_ab (n_a + n_b) / (e_a n_a + e_b n_b)`. Implementations whose test is eq. 4.8 on
    /// [`Self::error`] and [`Self::union_error`] can answer with one union fit.
    fn assess(&self, a: usize, b: usize) -> Result<(bool, f64)> {
        let accept = self.accepts(a, b)?;
        Ok((accept, gain(self, a, b, self.union_error(a, b)?)?))
    }
}

/// The relative fit improvement of joining `a` and `b` given the union's error (0 when the
/// parts fit exactly, so the ratio is undefined).
fn gain<M: FitModel + ?Sized>(m: &M, a: usize, b: usize, union_error: f64) -> Result<f64> {
    let (na, nb) = (m.size(a)? as f64, m.size(b)? as f64);
    let before = m.error(a)? * na + m.error(b)? * nb;
    let g = 1.0 - union_error * (na + nb) / before;
    Ok(if g.is_finite() { g } else { 0.0 })
}

/// [`SegmentFits`] addressed by slots (`ids[s]` is the label of slot `s`).
pub struct LabelledFits<'a> {
    pub fits: &'a mut SegmentFits,
    pub ids: &'a [i32],
}

impl LabelledFits<'_> {
    fn label(&self, s: usize) -> usize {
        self.ids[s] as usize
    }
}

impl FitModel for LabelledFits<'_> {
    fn size(&self, s: usize) -> Result<usize> {
        self.fits.size(self.label(s))
    }
    fn error(&self, s: usize) -> Result<f64> {
        self.fits.fit_error(self.label(s))
    }
    fn union_error(&self, a: usize, b: usize) -> Result<f64> {
        self.fits.union_error(self.label(a), self.label(b))
    }
    fn accepts(&self, a: usize, b: usize) -> Result<bool> {
        self.fits.should_merge(self.label(a), self.label(b))
    }
    fn merge(&mut self, a: usize, b: usize) -> Result<f64> {
        let (la, lb) = (self.label(a), self.label(b));
        self.fits.merge(la, lb)
    }

    /// One union fit: `SegmentFits::should_merge` is eq. 4.8 on `fit_error` and `union_error`
    /// (checked by the test `assess_matches_should_merge`).
    fn assess(&self, a: usize, b: usize) -> Result<(bool, f64)> {
        let (na, nb) = (self.size(a)? as f64, self.size(b)? as f64);
        let before = self.error(a)? * na + self.error(b)? * nb;
        let after = self.union_error(a, b)? * (na + nb);
        let g = 1.0 - after / before;
        Ok((before > after, if g.is_finite() { g } else { 0.0 }))
    }
}

/// Per-segment class descriptors of eq. 4.6, kept as sums so a union is one addition.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptors {
    /// `n x classes` sums of the pixel PDFs.
    pub sums: Vec<f64>,
    /// Pixels summed per segment.
    pub counts: Vec<f64>,
    /// `n x classes`: per segment, how many pixels have each class as their argmax (the first
    /// maximum), for [`majority`]'s labelling.
    pub votes: Vec<u32>,
    pub classes: usize,
}

/// The argmax of `p` (the first maximum).
#[inline]
fn argmax<T: PartialOrd + Copy>(p: &[T]) -> usize {
    let mut best = 0;
    for c in 1..p.len() {
        if p[c] > p[best] {
            best = c;
        }
    }
    best
}

/// The [`argmax`] of each of the (at most [`PDF_GROUP`]) pixels of `ps` (`classes` values
/// each) into `best`, the pixels side by side so that their dependency chains overlap.
#[inline]
fn argmax_group(ps: &[f32], classes: usize, best: &mut [usize; PDF_GROUP]) {
    if ps.len() < PDF_GROUP * classes {
        for (b, p) in best.iter_mut().zip(ps.chunks_exact(classes)) {
            *b = argmax(p);
        }
        return;
    }
    let mut top = [0.0f32; PDF_GROUP];
    for g in 0..PDF_GROUP {
        (best[g], top[g]) = (0, ps[g * classes]);
    }
    for c in 1..classes {
        for g in 0..PDF_GROUP {
            let v = ps[g * classes + c];
            // As `argmax`: a NaN never wins, and a NaN first value is never beaten.
            if v > top[g] {
                (best[g], top[g]) = (c, v);
            }
        }
    }
}

/// Per segment of `votes` (`n x classes`; counts, or any non-negative scores such as the PDF
/// sums of [`Descriptors`]), the class with the most (the smaller on ties), `-1` for a segment
/// whose scores are all zero (no pixels).
pub fn majority_of_votes<T: PartialOrd + Copy + Default>(votes: &[T], classes: usize) -> Vec<i32> {
    votes
        .chunks_exact(classes)
        .map(|v| {
            let best = argmax(v);
            if v[best] == T::default() {
                -1
            } else {
                best as i32
            }
        })
        .collect()
}

/// Parts the PDF sums of [`Descriptors::new`] are split into (fixed, so the sums do not depend
/// on the thread count).
const DESCRIPTOR_PARTS: usize = 16;

impl Descriptors {
    /// Sums the `H x W x classes` PDFs `pdfs` over the segments of `slots` (`-1` = none).
    pub fn new(slots: &[i32], n: usize, pdfs: &[f32], classes: usize) -> Result<Self> {
        if classes == 0 {
            return Err(invalid("pdfs", "0 classes", "at least one class"));
        }
        rgbd_error::check_len("pdfs", pdfs, slots.len() * classes, "H x W x classes")?;
        // A fixed number of parts, summed in order: the same sums (bits) whatever the threads.
        let chunk = slots.len().div_ceil(DESCRIPTOR_PARTS).max(4096);
        let zero = || {
            (
                vec![0.0f64; n * classes],
                vec![0.0f64; n],
                vec![0u32; n * classes],
            )
        };
        let parts: Vec<_> = slots
            .par_chunks(chunk)
            .zip(pdfs.par_chunks(chunk * classes))
            .map(|(ls, ps)| {
                let (mut sums, mut counts, mut votes) = zero();
                let mut best = [0usize; PDF_GROUP];
                for (ls, ps) in ls.chunks(PDF_GROUP).zip(ps.chunks(PDF_GROUP * classes)) {
                    argmax_group(ps, classes, &mut best);
                    for ((&s, p), &c) in ls.iter().zip(ps.chunks_exact(classes)).zip(&best) {
                        if s >= 0 {
                            let row = &mut sums[s as usize * classes..][..classes];
                            row.iter_mut().zip(p).for_each(|(a, &b)| *a += f64::from(b));
                            counts[s as usize] += 1.0;
                            votes[s as usize * classes + c] += 1;
                        }
                    }
                }
                (sums, counts, votes)
            })
            .collect();
        let (mut sums, mut counts, mut votes) = zero();
        for (s2, c2, v2) in &parts {
            sums.iter_mut().zip(s2).for_each(|(a, b)| *a += b);
            counts.iter_mut().zip(c2).for_each(|(a, b)| *a += b);
            votes.iter_mut().zip(v2).for_each(|(a, b)| *a += b);
        }
        Ok(Self {
            sums,
            counts,
            votes,
            classes,
        })
    }

    /// Eq. 4.7: the Bhattacharyya coefficient of the mean PDFs of `a` and `b` (eq. 4.6).
    pub fn similarity(&self, a: usize, b: usize) -> f64 {
        let (ca, cb) = (self.counts[a], self.counts[b]);
        if ca == 0.0 || cb == 0.0 {
            return 0.0;
        }
        let k = self.classes;
        let (sa, sb) = (&self.sums[a * k..][..k], &self.sums[b * k..][..k]);
        sa.iter()
            .zip(sb)
            .map(|(x, y)| ((x / ca) * (y / cb)).max(0.0).sqrt())
            .sum()
    }

    fn join(&mut self, a: usize, b: usize) {
        let k = self.classes;
        for t in 0..k {
            self.sums[a * k + t] += self.sums[b * k + t];
        }
        self.counts[a] += self.counts[b];
        for t in 0..k {
            self.votes[a * k + t] += self.votes[b * k + t];
        }
    }
}

/// What the checks of per-pixel class PDFs need, from one parallel pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdfStats {
    /// Values that are NaN or infinite.
    pub non_finite: usize,
    /// The smallest finite value (`+inf` when there is none).
    pub min: f64,
    /// The largest `|Σ_c p_c - 1|` over the pixels whose values are all finite (f64 sums).
    pub worst_sum: f64,
}

/// Pixels whose PDF sums [`pdf_stats`] takes side by side.
const PDF_GROUP: usize = 8;

/// [`PdfStats`] of `H x W x classes` PDFs.
pub fn pdf_stats(pdfs: &[f32], classes: usize) -> Result<PdfStats> {
    if classes == 0 || !pdfs.len().is_multiple_of(classes) {
        return Err(invalid(
            "pdfs",
            format!("{} values in rows of {classes}", pdfs.len()),
            "H x W x classes values, classes >= 1",
        ));
    }
    let chunk = 4096 * classes;
    let zero = || PdfStats {
        non_finite: 0,
        min: f64::INFINITY,
        worst_sum: 0.0,
    };
    Ok(pdfs
        .par_chunks(chunk)
        .map(|block| {
            // Non-finite count and minimum: elementwise, LANES values side by side.
            const LANES: usize = 16;
            let (mut low, mut bad) = ([f32::INFINITY; LANES], [0usize; LANES]);
            let mut lanes = block.chunks_exact(LANES);
            for vs in &mut lanes {
                for l in 0..LANES {
                    let (v, fin) = (vs[l], vs[l].is_finite());
                    low[l] = if fin && v < low[l] { v } else { low[l] };
                    bad[l] += usize::from(!fin);
                }
            }
            for (l, &v) in lanes.remainder().iter().enumerate() {
                let fin = v.is_finite();
                low[l] = if fin && v < low[l] { v } else { low[l] };
                bad[l] += usize::from(!fin);
            }
            // Per-pixel sums in class order (f64: finite exactly when all its values are),
            // PDF_GROUP pixels side by side so that their dependency chains overlap.
            let mut worst = 0.0f64;
            let mut check = |sum: f64| {
                if sum.is_finite() {
                    worst = worst.max((sum - 1.0).abs());
                }
            };
            let mut groups = block.chunks_exact(PDF_GROUP * classes);
            for group in &mut groups {
                let mut sum = [0.0f64; PDF_GROUP];
                for c in 0..classes {
                    for (g, s) in sum.iter_mut().enumerate() {
                        *s += f64::from(group[g * classes + c]);
                    }
                }
                sum.into_iter().for_each(&mut check);
            }
            for px in groups.remainder().chunks_exact(classes) {
                check(px.iter().fold(0.0f64, |s, &v| s + f64::from(v)));
            }
            PdfStats {
                non_finite: bad.iter().sum(),
                min: low.iter().fold(f64::INFINITY, |m, &v| m.min(f64::from(v))),
                worst_sum: worst,
            }
        })
        .reduce(zero, |a, b| PdfStats {
            non_finite: a.non_finite + b.non_finite,
            min: a.min.min(b.min),
            worst_sum: a.worst_sum.max(b.worst_sum),
        }))
}

/// §4.7's final labelling: per slot of `slots` (`0..n`, `-1` = none), the most common per-pixel
/// class (argmax of its PDF, the first on ties) among its pixels, the smaller class on ties;
/// `-1` for a slot without pixels.
pub fn majority(slots: &[i32], n: usize, pdfs: &[f32], classes: usize) -> Result<Vec<i32>> {
    if classes == 0 {
        return Err(invalid("pdfs", "0 classes", "at least one class"));
    }
    rgbd_error::check_len("pdfs", pdfs, slots.len() * classes, "H x W x classes")?;
    let chunk = 4096;
    let votes = slots
        .par_chunks(chunk)
        .zip(pdfs.par_chunks(chunk * classes))
        .fold(
            || vec![0u32; n * classes],
            |mut votes, (ls, ps)| {
                for (&s, p) in ls.iter().zip(ps.chunks_exact(classes)) {
                    if s >= 0 && (s as usize) < n {
                        votes[s as usize * classes + argmax(p)] += 1;
                    }
                }
                votes
            },
        )
        .reduce(
            || vec![0u32; n * classes],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    Ok(majority_of_votes(&votes, classes))
}

/// How couples are chosen and ordered.
#[derive(Debug, Clone)]
pub enum Priority {
    /// Algorithm 1: couples with similarity `>= t_sim` in order of similarity; eq. 4.8 decides.
    Similarity {
        descriptors: Descriptors,
        t_sim: f64,
    },
    /// Reference [74]: couples that pass eq. 4.8 in order of relative fit improvement
    /// `1 - e_ij (n_i + n_j) / (e_i n_i + e_j n_j)` (unit-free).
    FitGain,
}

/// One merge: `absorbed` joined `kept`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeStep {
    pub kept: usize,
    pub absorbed: usize,
    /// The couple's priority: similarity (eq. 4.7) or relative fit improvement.
    pub score: f64,
    pub error_kept: f64,
    pub error_absorbed: f64,
    pub error_union: f64,
}

/// The outcome: merges in order and, per slot, the slot it ended in.
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    pub history: Vec<MergeStep>,
    pub root: Vec<usize>,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    score: f64,
    a: usize,
    b: usize,
    va: u32,
    vb: u32,
}

impl PartialEq for Entry {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    /// Higher score first, then the smaller `(a, b)`.
    fn cmp(&self, o: &Self) -> Ordering {
        self.score
            .total_cmp(&o.score)
            .then_with(|| (o.a, o.b).cmp(&(self.a, self.b)))
    }
}

/// A fit failure (too few pixels, singular system) rejects the couple; only an interrupt
/// stops the merging.
fn soft<T>(r: Result<T>) -> Result<Option<T>> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(RgbdError::Interrupted) => Err(RgbdError::Interrupted),
        Err(_) => Ok(None),
    }
}

/// The relative fit improvement of joining `a` and `b`, if eq. 4.8 accepts it.
fn fit_gain<M: FitModel>(m: &M, a: usize, b: usize) -> Result<Option<f64>> {
    Ok(match soft(m.assess(a, b))? {
        Some((true, g)) => Some(g),
        _ => None,
    })
}

/// The score of a couple under `priority`, or None when it does not enter the queue.
fn score<M: FitModel>(p: &Priority, m: &M, a: usize, b: usize) -> Result<Option<f64>> {
    match p {
        Priority::Similarity { descriptors, t_sim } => {
            let s = descriptors.similarity(a, b);
            Ok((s >= *t_sim).then_some(s))
        }
        Priority::FitGain => fit_gain(m, a, b),
    }
}

/// Checks `pairs` against `n` segments and returns the sorted, deduplicated neighbour lists.
fn neighbours(n: usize, pairs: &[(usize, usize)]) -> Result<Vec<Vec<usize>>> {
    let mut nb = vec![Vec::new(); n];
    for &(a, b) in pairs {
        if a >= n || b >= n || a == b {
            return Err(invalid(
                "pairs",
                format!("({a}, {b})"),
                format!("two different segments < {n}"),
            ));
        }
        nb[a].push(b);
        nb[b].push(a);
    }
    for v in &mut nb {
        v.sort_unstable();
        v.dedup();
    }
    Ok(nb)
}

/// The queue's bookkeeping: per slot whether it is live and its version.
struct Live {
    alive: Vec<bool>,
    version: Vec<u32>,
}

impl Live {
    fn valid(&self, e: &Entry) -> bool {
        self.alive[e.a] && self.alive[e.b] && self.version[e.a] == e.va && self.version[e.b] == e.vb
    }
}

/// Runs Algorithm 1 (or the fit-only baseline) on `n` segments with the adjacent couples
/// `pairs`. `model` ends holding the merged fits.
pub fn merge_regions<M: FitModel + Send>(
    n: usize,
    pairs: &[(usize, usize)],
    priority: Priority,
    model: &mut M,
) -> Result<Merged> {
    // On a thread of the pool: the loop's parallel scorings then start without waking a pool
    // from outside (tested: testing upcoming couples on the second thread beside each merge
    // cost more CPU than it saved wall time, and is not done).
    rayon::scope(|_| merge_loop(n, pairs, priority, model))
}

fn merge_loop<M: FitModel>(
    n: usize,
    pairs: &[(usize, usize)],
    mut priority: Priority,
    model: &mut M,
) -> Result<Merged> {
    if let Priority::Similarity { descriptors, t_sim } = &priority {
        if descriptors.counts.len() != n {
            return Err(invalid(
                "pdfs",
                format!("descriptors of {} segments", descriptors.counts.len()),
                format!("{n} segments"),
            ));
        }
        if !(0.0..=1.0).contains(t_sim) {
            return Err(invalid("t_sim", t_sim, "a value in [0, 1]"));
        }
    }
    let similarity = matches!(priority, Priority::Similarity { .. });
    let mut nb = neighbours(n, pairs)?;
    let couples: Vec<(usize, usize)> = (0..n)
        .flat_map(|a| nb[a].iter().filter(move |&&b| b > a).map(move |&b| (a, b)))
        .collect();
    let scores: Vec<Option<f64>> = {
        let (p, m) = (&priority, &*model);
        couples
            .par_iter()
            .map(|&(a, b)| score(p, m, a, b))
            .collect::<Result<_>>()?
    };
    let mut heap: BinaryHeap<Entry> = couples
        .iter()
        .zip(scores)
        .filter_map(|(&(a, b), s)| {
            s.map(|score| Entry {
                score,
                a,
                b,
                va: 0,
                vb: 0,
            })
        })
        .collect();
    let mut live = Live {
        alive: vec![true; n],
        version: vec![0u32; n],
    };
    let mut parent: Vec<usize> = (0..n).collect();
    let mut history = Vec::new();
    while let Some(e) = heap.pop() {
        let (a, b) = (e.a, e.b);
        if !live.valid(&e) {
            continue;
        }
        check_interrupt()?;
        if similarity && soft(model.accepts(a, b))? != Some(true) {
            continue;
        }
        let (Some(ea), Some(eb)) = (soft(model.error(a))?, soft(model.error(b))?) else {
            continue;
        };
        let Some(eu) = soft(model.merge(a, b))? else {
            continue;
        };
        history.push(MergeStep {
            kept: a,
            absorbed: b,
            score: e.score,
            error_kept: ea,
            error_absorbed: eb,
            error_union: eu,
        });
        live.alive[b] = false;
        parent[b] = a;
        live.version[a] += 1;
        if let Priority::Similarity { descriptors, .. } = &mut priority {
            descriptors.join(a, b);
        }
        // The union is adjacent to every former neighbour of a or b.
        let nb_b = std::mem::take(&mut nb[b]);
        for &k in &nb_b {
            let list = &mut nb[k];
            if let Ok(i) = list.binary_search(&b) {
                list.remove(i);
            }
            if k != a {
                if let Err(i) = list.binary_search(&a) {
                    list.insert(i, a);
                }
            }
        }
        let mut union: Vec<usize> = nb[a].iter().chain(&nb_b).copied().collect();
        union.sort_unstable();
        union.dedup();
        union.retain(|&k| k != a && k != b);
        nb[a] = union;
        let (p, m) = (&priority, &*model);
        let rescore = |&k: &usize| Ok((k, score(p, m, a.min(k), a.max(k))?));
        // Similarities are a few multiply-adds each: not worth a parallel job.
        let fresh: Vec<(usize, Option<f64>)> = if similarity {
            nb[a].iter().map(rescore).collect::<Result<_>>()?
        } else {
            nb[a].par_iter().map(rescore).collect::<Result<_>>()?
        };
        for (k, s) in fresh {
            if let Some(score) = s {
                let (x, y) = (a.min(k), a.max(k));
                heap.push(Entry {
                    score,
                    a: x,
                    b: y,
                    va: live.version[x],
                    vb: live.version[y],
                });
            }
        }
    }
    let root = (0..n)
        .map(|s| {
            let mut r = s;
            while parent[r] != r {
                r = parent[r];
            }
            r
        })
        .collect();
    Ok(Merged { history, root })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PDF sums are added in a fixed order: the same bits in a pool of 1 or 4 threads.
    #[test]
    fn descriptors_are_the_same_bits_for_any_thread_count() {
        let (pixels, n, classes) = (300 * 400, 37usize, 13usize);
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as u32
        };
        let slots: Vec<i32> = (0..pixels).map(|_| (next() % 40) as i32 - 3).collect();
        // Scores of many magnitudes (down to 1e-40): their f64 sums depend on the order.
        let pdfs: Vec<f32> = (0..pixels * classes)
            .map(|_| (next() as f32 / 16_777_216.0).powi(6))
            .collect();
        let sums = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let d = pool.install(|| Descriptors::new(&slots, n, &pdfs, classes).unwrap());
            d.sums.iter().map(|v| v.to_bits()).collect::<Vec<u64>>()
        };
        let one = sums(1);
        for _ in 0..5 {
            assert_eq!(sums(4), one);
        }
    }

    /// Segments on a line, each with a "surface" id: unions of one surface fit (error 1),
    /// mixed unions do not (error 10).
    struct Line {
        surface: Vec<usize>,
        members: Vec<Vec<usize>>,
    }

    impl Line {
        fn new(surface: Vec<usize>) -> Self {
            let members = (0..surface.len()).map(|s| vec![s]).collect();
            Self { surface, members }
        }
        fn pure(&self, set: &[usize]) -> bool {
            set.iter().all(|&s| self.surface[s] == self.surface[set[0]])
        }
    }

    impl FitModel for Line {
        fn size(&self, s: usize) -> Result<usize> {
            Ok(self.members[s].len() * 10)
        }
        fn error(&self, s: usize) -> Result<f64> {
            Ok(if self.pure(&self.members[s]) {
                1.0
            } else {
                10.0
            })
        }
        fn union_error(&self, a: usize, b: usize) -> Result<f64> {
            let u: Vec<usize> = self.members[a]
                .iter()
                .chain(&self.members[b])
                .copied()
                .collect();
            Ok(if self.pure(&u) { 0.9 } else { 10.0 })
        }
        fn accepts(&self, a: usize, b: usize) -> Result<bool> {
            let (na, nb) = (self.size(a)? as f64, self.size(b)? as f64);
            Ok(self.error(a)? * na + self.error(b)? * nb > self.union_error(a, b)? * (na + nb))
        }
        fn merge(&mut self, a: usize, b: usize) -> Result<f64> {
            let e = self.union_error(a, b)?;
            let mb = std::mem::take(&mut self.members[b]);
            self.members[a].extend(mb);
            Ok(e)
        }
    }

    fn chain(n: usize) -> Vec<(usize, usize)> {
        (1..n).map(|i| (i - 1, i)).collect()
    }

    #[test]
    fn fit_only_merges_each_surface() {
        let mut m = Line::new(vec![0, 0, 0, 1, 1, 2]);
        let out = merge_regions(6, &chain(6), Priority::FitGain, &mut m).unwrap();
        assert_eq!(out.root, vec![0, 0, 0, 3, 3, 5]);
        assert_eq!(out.history.len(), 3);
        assert!(out.history.iter().all(|s| s.error_union < 1.0));
    }

    #[test]
    fn similarity_gates_and_orders() {
        // PDFs: segments 0,1 alike (class 0), 2 alike to 1 but its surface differs, 3 alone.
        let slots = vec![0, 1, 2, 3];
        let pdfs = vec![
            1.0, 0.0, //
            0.9, 0.1, //
            0.9, 0.1, //
            0.0, 1.0,
        ];
        let d = Descriptors::new(&slots, 4, &pdfs, 2).unwrap();
        assert!((d.similarity(0, 1) - 0.9f64.sqrt()).abs() < 1e-6);
        let mut m = Line::new(vec![0, 0, 1, 1]);
        let p = Priority::Similarity {
            descriptors: d,
            t_sim: T_SIM,
        };
        let out = merge_regions(4, &chain(4), p, &mut m).unwrap();
        // (1,2) is the most similar couple (1.0) but its union mixes surfaces: rejected;
        // (0,1) merges; (2,3) never enters the queue (similarity 0.32).
        assert_eq!(out.root, vec![0, 0, 2, 3]);
        assert_eq!(out.history.len(), 1);
    }

    #[test]
    fn assess_matches_should_merge() {
        // Three noisy planes side by side on a 48 x 16 grid: two coplanar, one tilted.
        let (w, h) = (48usize, 16usize);
        let mut pts = Vec::new();
        let mut labels = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let noise = (((x * 7919 + y * 104_729) % 97) as f32 / 97.0 - 0.5) * 1e-3;
                let z = if x < 32 {
                    2.0
                } else {
                    2.0 + 0.05 * (x as f32 - 32.0)
                } + noise;
                pts.extend([(x as f32 - 24.0) * z / 50.0, (y as f32 - 8.0) * z / 50.0, z]);
                labels.push((x / 16) as i32);
            }
        }
        let grid = rgbd_spline::KnotGrid::new(w, h, 8.0, 3).unwrap();
        let mut fits = SegmentFits::new(
            &pts,
            w,
            h,
            3,
            &labels,
            &grid,
            rgbd_spline::DEFAULT_LAMBDA,
            rgbd_spline::Criterion::Gcv,
        )
        .unwrap();
        let ids = [0, 1, 2];
        let expected: Vec<bool> = [(0, 1), (1, 2), (0, 2)]
            .iter()
            .map(|&(a, b)| fits.should_merge(a, b).unwrap())
            .collect();
        assert_eq!(
            &expected[..2],
            &[true, false],
            "coplanar merge, the crease does not"
        );
        let m = LabelledFits {
            fits: &mut fits,
            ids: &ids,
        };
        for (k, &(a, b)) in [(0, 1), (1, 2), (0, 2)].iter().enumerate() {
            let (accept, g) = m.assess(a, b).unwrap();
            assert_eq!(accept, expected[k], "couple ({a}, {b})");
            assert_eq!(accept, g > 0.0);
        }
    }

    #[test]
    fn pdf_stats_of_grouped_pixels_match_one_by_one() {
        // 37 pixels of 3 classes (four groups of 8 and 5 more), a NaN, an inf and a negative.
        let mut pdfs: Vec<f32> = (0..37 * 3)
            .map(|i| ((i * 7919) % 101) as f32 / 150.0)
            .collect();
        pdfs[20] = f32::NAN;
        pdfs[58] = f32::INFINITY;
        pdfs[90] = -0.25;
        let (mut non_finite, mut min, mut worst) = (0, f64::INFINITY, 0.0f64);
        for px in pdfs.chunks_exact(3) {
            if px.iter().all(|v| v.is_finite()) {
                let sum: f64 = px.iter().map(|&v| f64::from(v)).sum();
                worst = worst.max((sum - 1.0).abs());
            }
            for &v in px {
                if v.is_finite() {
                    min = min.min(f64::from(v));
                } else {
                    non_finite += 1;
                }
            }
        }
        let st = pdf_stats(&pdfs, 3).unwrap();
        assert_eq!(st.non_finite, non_finite);
        assert_eq!(st.min, min);
        assert_eq!(st.worst_sum, worst);
        // Grouped argmax = argmax, ties (first wins) and NaN included; a whole group and a
        // short one.
        pdfs[3..6].copy_from_slice(&[0.4, 0.4, 0.2]);
        pdfs[6..9].copy_from_slice(&[f32::NAN, 0.9, 0.1]);
        for part in [
            &pdfs[..PDF_GROUP * 3],
            &pdfs[PDF_GROUP * 3..PDF_GROUP * 3 + 15],
        ] {
            let mut best = [usize::MAX; PDF_GROUP];
            argmax_group(part, 3, &mut best);
            for (g, p) in part.chunks_exact(3).enumerate() {
                assert_eq!(best[g], argmax(p), "pixel {g}");
            }
        }
        // The descriptors' votes are the majority's.
        let slots: Vec<i32> = (0..37).map(|i| i % 4 - 1).collect();
        let d = Descriptors::new(&slots, 3, &pdfs, 3).unwrap();
        assert_eq!(
            majority_of_votes(&d.votes, 3),
            majority(&slots, 3, &pdfs, 3).unwrap()
        );
    }

    #[test]
    fn pdf_stats_and_majority() {
        let pdfs = [
            0.2,
            0.8, //
            f32::NAN,
            1.0, //
            0.7,
            0.4, //
            0.5,
            0.5, //
            -0.1,
            1.1,
        ];
        let st = pdf_stats(&pdfs, 2).unwrap();
        assert_eq!(st.non_finite, 1);
        assert_eq!(st.min, f64::from(-0.1f32));
        assert!((st.worst_sum - 0.1).abs() < 1e-6, "{}", st.worst_sum);
        assert!(pdf_stats(&pdfs, 3).is_err());
        // Slot 0: pixels of class 1 and 1; slot 1: class 0, then a tie (the first class wins: 0);
        // slot 2 has no pixel.
        let m = majority(&[0, -1, 1, 1, 0], 3, &pdfs, 2).unwrap();
        assert_eq!(m, vec![1, 0, -1]);
        // One vote each for classes 1 and 0: the smaller class wins.
        let m = majority(&[0, -1, 0, -1, -1], 1, &pdfs, 2).unwrap();
        assert_eq!(m, vec![0]);
        // The descriptors count the same votes; joined segments add them.
        let mut d = Descriptors::new(&[0, -1, 1, 1, 0], 3, &pdfs, 2).unwrap();
        assert_eq!(majority_of_votes(&d.votes, 2), vec![1, 0, -1]);
        d.join(1, 0);
        assert_eq!(d.votes[2..4], [2, 2]);
    }

    #[test]
    fn bad_pairs_are_named() {
        let mut m = Line::new(vec![0, 0]);
        let e = merge_regions(2, &[(0, 2)], Priority::FitGain, &mut m).unwrap_err();
        assert!(e.to_string().starts_with("pairs"), "{e}");
        let e = merge_regions(2, &[(1, 1)], Priority::FitGain, &mut m).unwrap_err();
        assert!(e.to_string().starts_with("pairs"), "{e}");
    }
}
