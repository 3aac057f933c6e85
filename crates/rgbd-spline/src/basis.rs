//! Uniform B-spline basis functions and their first two derivatives.
//!
//! With knots at the integers, the `p + 1` basis functions that are non-zero on a cell depend
//! only on the local parameter `t ∈ [0, 1)` inside that cell (Piegl & Tiller's BasisFuns with
//! `left[j] = t + j - 1`, `right[j] = j - t`). Function `j` belongs to control point
//! `cell + j`. Derivatives use `N'_{k,p} = N_{k,p-1} - N_{k+1,p-1}` (unit knot spacing).

/// Highest supported degree.
pub const MAX_DEGREE: usize = 5;

/// Error for an unsupported degree or a parameter outside the cell.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BasisError {
    #[error("degree: got {0}, expected 1..={MAX_DEGREE}")]
    Degree(usize),
    #[error("t: got {0}, expected a value in [0, 1]")]
    Parameter(f64),
}

/// Values and derivatives (with respect to the cell coordinate) of the `degree + 1` functions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Basis {
    pub degree: usize,
    pub value: [f64; MAX_DEGREE + 1],
    pub d1: [f64; MAX_DEGREE + 1],
    pub d2: [f64; MAX_DEGREE + 1],
}

/// The `degree + 1` basis values of degree `q` at local parameter `t`.
fn values(q: usize, t: f64) -> [f64; MAX_DEGREE + 1] {
    let mut n = [0.0; MAX_DEGREE + 1];
    n[0] = 1.0;
    for j in 1..=q {
        let mut saved = 0.0;
        for (r, nr) in n.iter_mut().enumerate().take(j) {
            // right[r + 1] = r + 1 - t, left[j - r] = t + j - r - 1; their sum is j.
            let temp = *nr / j as f64;
            *nr = saved + (r as f64 + 1.0 - t) * temp;
            saved = (t + (j - r) as f64 - 1.0) * temp;
        }
        n[j] = saved;
    }
    n
}

/// Derivative of degree-`q` functions from the degree `q - 1` ones: `lo[j-1] - lo[j]`.
fn differentiate(q: usize, lo: &[f64; MAX_DEGREE + 1]) -> [f64; MAX_DEGREE + 1] {
    let mut d = [0.0; MAX_DEGREE + 1];
    for (j, dj) in d.iter_mut().enumerate().take(q + 1) {
        let a = if j >= 1 { lo[j - 1] } else { 0.0 };
        let b = if j < q { lo[j] } else { 0.0 };
        *dj = a - b;
    }
    d
}

/// Basis values and first/second derivatives of a uniform B-spline of `degree` at local `t`.
pub fn uniform_basis(degree: usize, t: f64) -> Result<Basis, BasisError> {
    if !(1..=MAX_DEGREE).contains(&degree) {
        return Err(BasisError::Degree(degree));
    }
    if !(0.0..=1.0).contains(&t) {
        return Err(BasisError::Parameter(t));
    }
    let value = values(degree, t);
    let d1 = differentiate(degree, &values(degree - 1, t));
    let d2 = if degree >= 2 {
        let lo1 = differentiate(degree - 1, &values(degree - 2, t));
        differentiate(degree, &lo1)
    } else {
        [0.0; MAX_DEGREE + 1]
    };
    Ok(Basis {
        degree,
        value,
        d1,
        d2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn cubic_matches_closed_form() {
        let t: f64 = 0.3;
        let b = uniform_basis(3, t).unwrap();
        let s = 1.0 - t;
        let want = [
            s.powi(3) / 6.0,
            (3.0 * t.powi(3) - 6.0 * t * t + 4.0) / 6.0,
            (-3.0 * t.powi(3) + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
            t.powi(3) / 6.0,
        ];
        for (j, w) in want.iter().enumerate() {
            assert!((b.value[j] - w).abs() < 1e-15, "{j}");
        }
        let d1 = [
            -s * s / 2.0,
            (3.0 * t * t - 4.0 * t) / 2.0,
            (-3.0 * t * t + 2.0 * t + 1.0) / 2.0,
            t * t / 2.0,
        ];
        let d2 = [s, 3.0 * t - 2.0, -3.0 * t + 1.0, t];
        for (j, (w1, w2)) in d1.iter().zip(&d2).enumerate() {
            assert!(
                (b.d1[j] - w1).abs() < 1e-14 && (b.d2[j] - w2).abs() < 1e-14,
                "{j}"
            );
        }
    }

    #[test]
    fn rejects_bad_arguments() {
        assert_eq!(uniform_basis(0, 0.5), Err(BasisError::Degree(0)));
        assert_eq!(uniform_basis(6, 0.5), Err(BasisError::Degree(6)));
        assert!(uniform_basis(3, f64::NAN).is_err());
        assert!(uniform_basis(3, 1.5).is_err());
    }

    proptest! {
        #[test]
        fn partition_of_unity_and_finite_differences(degree in 1usize..=MAX_DEGREE, t in 0.01f64..0.99) {
            let b = uniform_basis(degree, t).unwrap();
            let sum: f64 = b.value.iter().sum();
            prop_assert!((sum - 1.0).abs() < 1e-12);
            prop_assert!(b.d1.iter().sum::<f64>().abs() < 1e-12);
            let h = 1e-6;
            let (lo, hi) = (uniform_basis(degree, t - h).unwrap(), uniform_basis(degree, t + h).unwrap());
            for j in 0..=degree {
                prop_assert!(b.value[j] >= 0.0);
                let fd = (hi.value[j] - lo.value[j]) / (2.0 * h);
                prop_assert!((fd - b.d1[j]).abs() < 1e-6, "d1 {} {} {}", j, fd, b.d1[j]);
                if degree >= 3 {
                    let fd2 = (hi.d1[j] - lo.d1[j]) / (2.0 * h);
                    prop_assert!((fd2 - b.d2[j]).abs() < 1e-5, "d2 {} {} {}", j, fd2, b.d2[j]);
                }
            }
        }
    }
}
