//! The heap with lazy deletion merges exactly like Algorithm 1 read literally: keep a list of
//! couples, re-sort it every step, pop the front, and on a merge delete every couple of the two
//! segments and add the union's couples.

use proptest::prelude::*;
use rgbd_error::Result;
use rgbd_segment::merge::{merge_regions, Descriptors, FitModel, MergeStep, Priority};

/// Errors are a pseudo-random function of a segment's member set, so every union is a new
/// surface and both implementations see the same numbers for the same history.
#[derive(Clone)]
struct Hashed {
    base: Vec<usize>,
    members: Vec<Vec<usize>>,
    salt: u64,
}

impl Hashed {
    fn err(&self, set: &[usize]) -> f64 {
        let mut s = set.to_vec();
        s.sort_unstable();
        let mut h = self.salt ^ 0x9e37_79b9_7f4a_7c15;
        for x in s {
            h = (h ^ x as u64).wrapping_mul(0x1000_0000_01b3);
            h ^= h >> 29;
        }
        0.01 + (h % 1000) as f64 / 100.0
    }
    fn n(&self, set: &[usize]) -> usize {
        set.iter().map(|&s| self.base[s]).sum()
    }
}

impl FitModel for Hashed {
    fn size(&self, s: usize) -> Result<usize> {
        Ok(self.n(&self.members[s]))
    }
    fn error(&self, s: usize) -> Result<f64> {
        Ok(self.err(&self.members[s]))
    }
    fn union_error(&self, a: usize, b: usize) -> Result<f64> {
        let u: Vec<usize> = self.members[a]
            .iter()
            .chain(&self.members[b])
            .copied()
            .collect();
        Ok(self.err(&u))
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

fn gain(m: &Hashed, a: usize, b: usize) -> Option<f64> {
    if !m.accepts(a, b).unwrap() {
        return None;
    }
    let (na, nb) = (m.size(a).unwrap() as f64, m.size(b).unwrap() as f64);
    let before = m.error(a).unwrap() * na + m.error(b).unwrap() * nb;
    let g = 1.0 - m.union_error(a, b).unwrap() * (na + nb) / before;
    Some(if g.is_finite() { g } else { 0.0 })
}

/// Algorithm 1 with a plain list re-sorted every step.
fn naive(
    n: usize,
    pairs: &[(usize, usize)],
    mut desc: Option<(Descriptors, f64)>,
    m: &mut Hashed,
) -> (Vec<MergeStep>, Vec<usize>) {
    let mut nb: Vec<Vec<usize>> = vec![Vec::new(); n];
    for &(a, b) in pairs {
        nb[a].push(b);
        nb[b].push(a);
    }
    for v in &mut nb {
        v.sort_unstable();
        v.dedup();
    }
    let score = |desc: &Option<(Descriptors, f64)>, m: &Hashed, a: usize, b: usize| match desc {
        Some((d, t)) => {
            let s = d.similarity(a, b);
            (s >= *t).then_some(s)
        }
        None => gain(m, a, b),
    };
    let mut list: Vec<(f64, usize, usize)> = Vec::new();
    for (a, near) in nb.iter().enumerate() {
        for &b in near {
            if b > a {
                if let Some(s) = score(&desc, m, a, b) {
                    list.push((s, a, b));
                }
            }
        }
    }
    let mut parent: Vec<usize> = (0..n).collect();
    let mut history = Vec::new();
    loop {
        list.sort_by(|x, y| y.0.total_cmp(&x.0).then((x.1, x.2).cmp(&(y.1, y.2))));
        if list.is_empty() {
            break;
        }
        let (s, a, b) = list.remove(0);
        if desc.is_some() && !m.accepts(a, b).unwrap() {
            continue;
        }
        let (ea, eb) = (m.error(a).unwrap(), m.error(b).unwrap());
        let eu = m.merge(a, b).unwrap();
        history.push(MergeStep {
            kept: a,
            absorbed: b,
            score: s,
            error_kept: ea,
            error_absorbed: eb,
            error_union: eu,
        });
        parent[b] = a;
        if let Some((d, _)) = &mut desc {
            for t in 0..d.classes {
                d.sums[a * d.classes + t] += d.sums[b * d.classes + t];
            }
            d.counts[a] += d.counts[b];
        }
        list.retain(|&(_, x, y)| x != a && x != b && y != a && y != b);
        let nb_b = std::mem::take(&mut nb[b]);
        for &k in &nb_b {
            nb[k].retain(|&x| x != b);
            if k != a && !nb[k].contains(&a) {
                nb[k].push(a);
            }
        }
        let mut u: Vec<usize> = nb[a].iter().chain(&nb_b).copied().collect();
        u.sort_unstable();
        u.dedup();
        u.retain(|&k| k != a && k != b);
        nb[a] = u;
        for &k in &nb[a].clone() {
            let (x, y) = (a.min(k), a.max(k));
            if let Some(s) = score(&desc, m, x, y) {
                list.push((s, x, y));
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
    (history, root)
}

/// Segments, couples, base sizes, PDF values, error salt, with PDFs or fit-only.
type Case = (usize, Vec<(usize, usize)>, Vec<usize>, Vec<f32>, u64, bool);

fn case() -> impl Strategy<Value = Case> {
    (2usize..24).prop_flat_map(|n| {
        (
            Just(n),
            prop::collection::vec((0..n, 0..n), 1..3 * n),
            prop::collection::vec(1usize..50, n),
            prop::collection::vec(0.0f32..1.0, 3 * n),
            any::<u64>(),
            any::<bool>(),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn heap_equals_naive_resort((n, raw, base, pdf, salt, by_similarity) in case()) {
        let pairs: Vec<(usize, usize)> = raw.into_iter().filter(|(a, b)| a != b).collect();
        prop_assume!(!pairs.is_empty());
        let model = Hashed { base, members: (0..n).map(|s| vec![s]).collect(), salt };
        // Few classes, so similarities spread around the threshold.
        let slots: Vec<i32> = (0..n as i32).collect();
        let desc = Descriptors::new(&slots, n, &pdf, 3).unwrap();
        let t = 0.9;
        let (mut fast, mut slow) = (model.clone(), model);
        let priority = if by_similarity {
            Priority::Similarity { descriptors: desc.clone(), t_sim: t }
        } else {
            Priority::FitGain
        };
        let out = merge_regions(n, &pairs, priority, &mut fast).unwrap();
        let (history, root) = naive(n, &pairs, by_similarity.then_some((desc, t)), &mut slow);
        prop_assert_eq!(out.history, history);
        prop_assert_eq!(out.root, root);
    }
}
