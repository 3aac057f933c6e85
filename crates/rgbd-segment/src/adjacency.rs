//! Segment adjacency from a label image with the boundary tests of eq. 4.3-4.5.
//!
//! Every 4-neighbour pixel pair with two different segments is one point of their common
//! boundary `C_C`. At each point the depth step, the CIELab distance and the angle between the
//! normals of the two pixels are compared with `T_d`, `T_c`, `T_θ`; two segments are adjacent
//! when each test holds on more than half of their boundary. A point where a cue is missing
//! (NaN on either side) does not vote in that cue's test; a test with no vote fails, so a
//! boundary made only of holes never makes two segments adjacent.

use std::collections::HashMap;

use rayon::prelude::*;
use rgbd_error::{check_interrupt, check_len, image_len, invalid, Result};

/// Eq. 4.3: largest depth step (metres) across a boundary point of adjacent segments.
pub const T_D: f32 = 0.2;
/// Eq. 4.4: largest CIELab distance across a boundary point of adjacent segments.
pub const T_C: f32 = 10.0;
/// Eq. 4.5: largest angle (degrees) between the normals across a boundary point.
pub const T_THETA_DEG: f32 = 4.0;

/// The thresholds of eq. 4.3-4.5.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundaryTest {
    /// `T_d`, metres.
    pub depth: f32,
    /// `T_c`, CIELab units.
    pub color: f32,
    /// `T_θ`, radians.
    pub angle: f32,
}

impl Default for BoundaryTest {
    fn default() -> Self {
        Self {
            depth: T_D,
            color: T_C,
            angle: T_THETA_DEG.to_radians(),
        }
    }
}

impl BoundaryTest {
    /// Checks the thresholds (each finite and >= 0; the angle at most π).
    pub fn check(&self) -> Result<()> {
        for (arg, v, hi) in [
            ("max_depth_step", self.depth, f32::MAX),
            ("max_color_distance", self.color, f32::MAX),
            ("max_normal_angle", self.angle, std::f32::consts::PI),
        ] {
            if !(v >= 0.0 && v <= hi) {
                return Err(invalid(arg, v, format!("a value in [0, {hi}]")));
            }
        }
        Ok(())
    }
}

/// Per-pixel cues of the boundary tests; each is optional (a missing cue is not tested).
#[derive(Debug, Clone, Copy, Default)]
pub struct Cues<'a> {
    /// `H x W` depth (metres, NaN = none): eq. 4.3.
    pub depth: Option<&'a [f32]>,
    /// `H x W x 3` CIELab colour: eq. 4.4.
    pub lab: Option<&'a [f32]>,
    /// `H x W x 3` unit normals (NaN = none): eq. 4.5.
    pub normals: Option<&'a [f32]>,
}

/// The common boundary of two segments (slots `a < b`) and how many of its points passed and
/// voted in each test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Boundary {
    pub a: usize,
    pub b: usize,
    /// Boundary points (4-neighbour pixel pairs).
    pub length: usize,
    /// `[depth, colour, normal]`: points where the cue was present on both sides.
    pub voted: [usize; 3],
    /// `[depth, colour, normal]`: points that passed the test.
    pub passed: [usize; 3],
}

impl Boundary {
    /// Whether the test of cue `k` holds on more than half of its voting points (eq. 4.3-4.5).
    fn holds(&self, k: usize) -> bool {
        2 * self.passed[k] > self.voted[k]
    }

    /// Eq. 4.3-4.5 for the cues that were given (`tested[k]`).
    pub fn adjacent(&self, tested: [bool; 3]) -> bool {
        (0..3).all(|k| !tested[k] || self.holds(k))
    }
}

fn add(stats: &mut HashMap<(u32, u32), Boundary>, a: i32, b: i32, votes: [Option<bool>; 3]) {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let e = stats.entry((lo as u32, hi as u32)).or_default();
    e.length += 1;
    for (k, v) in votes.iter().enumerate() {
        if let Some(pass) = *v {
            e.voted[k] += 1;
            e.passed[k] += usize::from(pass);
        }
    }
}

fn check_cue(arg: &'static str, cue: Option<&[f32]>, n: usize, what: &str) -> Result<()> {
    cue.map_or(Ok(()), |c| check_len(arg, c, n, what))
}

/// Every pair of touching segments of the slot image `slots` (`H x W`, `-1` = none) with its
/// boundary statistics, sorted by `(a, b)`.
pub fn boundaries(
    slots: &[i32],
    width: usize,
    height: usize,
    cues: Cues<'_>,
    test: &BoundaryTest,
) -> Result<Vec<Boundary>> {
    let n = image_len("labels", width, height)?;
    check_len("labels", slots, n, "H x W")?;
    check_cue("depth", cues.depth, n, "H x W")?;
    check_cue("lab", cues.lab, 3 * n, "H x W x 3")?;
    check_cue("normals", cues.normals, 3 * n, "H x W x 3")?;
    test.check()?;
    let cos_max = test.angle.cos();
    let vote = |p: usize, q: usize| -> [Option<bool>; 3] {
        let depth = cues.depth.and_then(|d| {
            let dz = (d[p] - d[q]).abs();
            (!dz.is_nan()).then_some(dz <= test.depth)
        });
        let color = cues.lab.and_then(|c| {
            let (x, y) = (&c[3 * p..3 * p + 3], &c[3 * q..3 * q + 3]);
            let d2: f32 = (0..3).map(|k| (x[k] - y[k]) * (x[k] - y[k])).sum();
            (!d2.is_nan()).then_some(d2 <= test.color * test.color)
        });
        let normal = cues.normals.and_then(|m| {
            let (x, y) = (&m[3 * p..3 * p + 3], &m[3 * q..3 * q + 3]);
            let dot: f32 = (0..3).map(|k| x[k] * y[k]).sum();
            (!dot.is_nan()).then_some(dot >= cos_max)
        });
        [depth, color, normal]
    };
    // Rows in bands, one map per band, merged at the end: boundaries are few next to pixels.
    let band = 16usize;
    let partial: Vec<HashMap<(u32, u32), Boundary>> = (0..height.div_ceil(band))
        .into_par_iter()
        .map(|b| -> Result<_> {
            check_interrupt()?;
            let mut stats = HashMap::new();
            for y in b * band..((b + 1) * band).min(height) {
                for x in 0..width {
                    let p = y * width + x;
                    let sp = slots[p];
                    if sp < 0 {
                        continue;
                    }
                    for q in [
                        (x + 1 < width).then_some(p + 1),
                        (y + 1 < height).then_some(p + width),
                    ]
                    .into_iter()
                    .flatten()
                    {
                        let sq = slots[q];
                        if sq >= 0 && sq != sp {
                            add(&mut stats, sp, sq, vote(p, q));
                        }
                    }
                }
            }
            Ok(stats)
        })
        .collect::<Result<_>>()?;
    let mut all: HashMap<(u32, u32), Boundary> = HashMap::new();
    for stats in partial {
        for (key, s) in stats {
            let e = all.entry(key).or_default();
            e.length += s.length;
            for k in 0..3 {
                e.voted[k] += s.voted[k];
                e.passed[k] += s.passed[k];
            }
        }
    }
    let mut out: Vec<Boundary> = all
        .into_iter()
        .map(|((a, b), s)| Boundary {
            a: a as usize,
            b: b as usize,
            ..s
        })
        .collect();
    out.sort_unstable_by_key(|s| (s.a, s.b));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 4 x 2 image: slots 0 | 1 side by side (two columns each).
    fn halves() -> Vec<i32> {
        vec![0, 0, 1, 1, 0, 0, 1, 1]
    }

    #[test]
    fn touching_pairs_and_lengths() {
        let s = vec![0, 0, 1, -1, 2, 2, 1, 1];
        let b = boundaries(&s, 4, 2, Cues::default(), &BoundaryTest::default()).unwrap();
        let pairs: Vec<_> = b.iter().map(|x| (x.a, x.b, x.length)).collect();
        // (0,1): (0,1)-(0,2); (0,2): two vertical; (1,2): (1,1)-(1,2) only ((0,2)-(1,2) is 1-1).
        assert_eq!(pairs, vec![(0, 1, 1), (0, 2, 2), (1, 2, 1)]);
        assert!(b.iter().all(|x| x.adjacent([false; 3])));
    }

    #[test]
    fn depth_step_decides_by_majority() {
        let s = halves();
        let mut depth = vec![1.0f32, 1.0, 1.1, 1.1, 1.0, 1.0, 1.1, 1.1];
        let cues = Cues {
            depth: Some(&depth),
            ..Cues::default()
        };
        let b = boundaries(&s, 4, 2, cues, &BoundaryTest::default()).unwrap();
        assert!(b[0].adjacent([true, false, false]));
        // One of two boundary points steps 0.5 m: not more than half pass.
        depth[6] = 1.5;
        let cues = Cues {
            depth: Some(&depth),
            ..Cues::default()
        };
        let b = boundaries(&s, 4, 2, cues, &BoundaryTest::default()).unwrap();
        assert_eq!((b[0].passed[0], b[0].voted[0]), (1, 2));
        assert!(!b[0].adjacent([true, false, false]));
        // A hole does not vote; all holes: the test fails.
        depth[6] = f32::NAN;
        let cues = Cues {
            depth: Some(&depth),
            ..Cues::default()
        };
        let b = boundaries(&s, 4, 2, cues, &BoundaryTest::default()).unwrap();
        assert_eq!((b[0].passed[0], b[0].voted[0]), (1, 1));
        assert!(b[0].adjacent([true, false, false]));
        let holes = vec![f32::NAN; 8];
        let cues = Cues {
            depth: Some(&holes),
            ..Cues::default()
        };
        let b = boundaries(&s, 4, 2, cues, &BoundaryTest::default()).unwrap();
        assert!(!b[0].adjacent([true, false, false]));
    }

    #[test]
    fn colour_and_normal_tests() {
        let s = halves();
        let mut lab = vec![50.0f32; 24];
        let mut normals: Vec<f32> = (0..8).flat_map(|_| [0.0, 0.0, 1.0]).collect();
        let a = 3.0f32.to_radians();
        for p in [2, 3, 6, 7] {
            normals[3 * p..3 * p + 3].copy_from_slice(&[a.sin(), 0.0, a.cos()]);
            lab[3 * p] = 59.0;
        }
        let cues = Cues {
            lab: Some(&lab),
            normals: Some(&normals),
            ..Cues::default()
        };
        let b = boundaries(&s, 4, 2, cues, &BoundaryTest::default()).unwrap();
        assert!(b[0].adjacent([false, true, true]), "{:?}", b[0]);
        let strict = BoundaryTest {
            color: 8.0,
            angle: 2.0f32.to_radians(),
            ..BoundaryTest::default()
        };
        let b = boundaries(&s, 4, 2, cues, &strict).unwrap();
        assert!(!b[0].adjacent([false, true, false]));
        assert!(!b[0].adjacent([false, false, true]));
        assert!(b[0].adjacent([false, false, false]));
    }

    #[test]
    fn bad_arguments_name_themselves() {
        let s = halves();
        let t = BoundaryTest::default();
        let e = boundaries(&s, 3, 2, Cues::default(), &t).unwrap_err();
        assert!(e.to_string().starts_with("labels"), "{e}");
        let d = vec![0.0f32; 7];
        let cues = Cues {
            depth: Some(&d),
            ..Cues::default()
        };
        let e = boundaries(&s, 4, 2, cues, &t).unwrap_err();
        assert!(e.to_string().starts_with("depth"), "{e}");
        let bad = BoundaryTest {
            angle: f32::NAN,
            ..t
        };
        let e = boundaries(&s, 4, 2, Cues::default(), &bad).unwrap_err();
        assert!(e.to_string().starts_with("max_normal_angle"), "{e}");
    }
}
