//! Adapters for region adjacency and merging (rgbd-segment::adjacency, merge);
//! `python/rgbd_rs/segmentation/merge.py` validates and documents.

use std::sync::PoisonError;

use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_error::invalid;
use rgbd_segment::adjacency::{boundaries, BoundaryTest, Cues};
use rgbd_segment::compact::Compact;
use rgbd_segment::merge::{
    majority, majority_of_votes, merge_regions as merge_core, pdf_stats, Descriptors, LabelledFits,
    Priority,
};

use crate::errors::{borrow, run, run_interruptible, shape_err};
use crate::geom::to_numpy;
use crate::spline::PySegmentFits;

type Arr1<'py, T> = Bound<'py, PyArray1<T>>;
type Arr2<'py, T> = Bound<'py, PyArray2<T>>;

fn same(arg: &str, got: &[usize], want: &[usize]) -> PyResult<()> {
    if got != want {
        return Err(shape_err(format!(
            "{arg}: got shape {got:?}, expected {want:?} like labels"
        )));
    }
    Ok(())
}

fn opt3<'a>(
    arg: &str,
    a: &'a Option<PyReadonlyArray3<'_, f32>>,
    h: usize,
    w: usize,
) -> PyResult<Option<&'a [f32]>> {
    a.as_ref()
        .map(|x| {
            same(arg, x.shape(), &[h, w, 3])?;
            borrow(arg, x)
        })
        .transpose()
}

/// Every couple of touching segments: `(pairs (P, 2) labels, length (P,), adjacent (P,))`,
/// `adjacent` = eq. 4.3-4.5 on the cues given.
#[pyfunction]
#[pyo3(signature = (labels, depth, lab, normals, max_depth_step, max_color_distance, max_normal_angle))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn segment_boundaries<'py>(
    py: Python<'py>,
    labels: PyReadonlyArray2<'py, i32>,
    depth: Option<PyReadonlyArray2<'py, f32>>,
    lab: Option<PyReadonlyArray3<'py, f32>>,
    normals: Option<PyReadonlyArray3<'py, f32>>,
    max_depth_step: f32,
    max_color_distance: f32,
    max_normal_angle: f32,
) -> PyResult<(Arr2<'py, i32>, Arr1<'py, u64>, Arr1<'py, bool>)> {
    let &[h, w] = labels.shape() else {
        unreachable!("2-D array")
    };
    let l = borrow("labels", &labels)?;
    let d = depth
        .as_ref()
        .map(|x| {
            same("depth", x.shape(), &[h, w])?;
            borrow("depth", x)
        })
        .transpose()?;
    let (c, n) = (opt3("lab", &lab, h, w)?, opt3("normals", &normals, h, w)?);
    let tested = [d.is_some(), c.is_some(), n.is_some()];
    let test = BoundaryTest {
        depth: max_depth_step,
        color: max_color_distance,
        angle: max_normal_angle,
    };
    let (ids, found) = run(py, || {
        let compact = Compact::new(l);
        let cues = Cues {
            depth: d,
            lab: c,
            normals: n,
        };
        let b = boundaries(&compact.slots, w, h, cues, &test)?;
        Ok((compact.ids, b))
    })?;
    let pairs: Vec<i32> = found.iter().flat_map(|b| [ids[b.a], ids[b.b]]).collect();
    let length: Vec<u64> = found.iter().map(|b| b.length as u64).collect();
    let adjacent: Vec<bool> = found.iter().map(|b| b.adjacent(tested)).collect();
    Ok((
        to_numpy(py, (found.len(), 2), pairs)?,
        length.into_pyarray(py),
        adjacent.into_pyarray(py),
    ))
}

/// Algorithm 1 on the live segments of `fits` (merged in place): `(labels, kept, absorbed,
/// score, errors (M, 3) = kept, absorbed, union, semantic)`, `semantic` the class of each final
/// segment from the descriptors' pass: the majority of its pixels' argmax votes, or with `mean`
/// the argmax of its PDF sums (eq. 4.6's descriptor; first maximum on ties); `None` without
/// `pdfs` (the fit-only baseline).
#[pyfunction]
#[pyo3(signature = (fits, pairs, pdfs, t_sim, mean=false))]
#[allow(clippy::type_complexity)]
pub fn merge_regions<'py>(
    py: Python<'py>,
    fits: &PySegmentFits,
    pairs: PyReadonlyArray2<'py, i32>,
    pdfs: Option<PyReadonlyArray3<'py, f32>>,
    t_sim: f64,
    mean: bool,
) -> PyResult<(
    Arr2<'py, i32>,
    Arr1<'py, i32>,
    Arr1<'py, i32>,
    Arr1<'py, f64>,
    Arr2<'py, f64>,
    Option<Arr2<'py, i32>>,
)> {
    let p = pairs.shape();
    if p[1] != 2 {
        return Err(shape_err(format!(
            "pairs: got shape {p:?}, expected (P, 2) label pairs"
        )));
    }
    let pr = borrow("pairs", &pairs)?;
    let pdf = pdfs
        .as_ref()
        .map(|x| Ok::<_, PyErr>((borrow("pdfs", x)?, x.shape().to_vec())))
        .transpose()?;
    let out = run_interruptible(py, || {
        let mut guard = fits.inner.write().unwrap_or_else(PoisonError::into_inner);
        let (w, h) = (guard.width, guard.height);
        let compact = Compact::new(&guard.current_labels());
        let slot = |l: i32| {
            compact
                .slot(l)
                .ok_or_else(|| invalid("pairs", l, "labels of live segments of fits"))
        };
        let couples = pr
            .chunks_exact(2)
            .map(|c| Ok((slot(c[0])?, slot(c[1])?)))
            .collect::<Result<Vec<_>, rgbd_error::RgbdError>>()?;
        let priority = match &pdf {
            Some((x, shape)) => {
                if shape[..2] != [h, w] {
                    return Err(rgbd_error::mismatch(
                        "pdfs",
                        format!("{shape:?}"),
                        format!("({h}, {w}, classes) like the fits"),
                    ));
                }
                Priority::Similarity {
                    descriptors: Descriptors::new(&compact.slots, compact.len(), x, shape[2])?,
                    t_sim,
                }
            }
            None => Priority::FitGain,
        };
        // Per initial segment and class, what the final segment's class is chosen from.
        let scores = match &priority {
            Priority::Similarity { descriptors, .. } => Some(if mean {
                (
                    Vec::new(),
                    Some(descriptors.sums.clone()),
                    descriptors.classes,
                )
            } else {
                (descriptors.votes.clone(), None, descriptors.classes)
            }),
            Priority::FitGain => None,
        };
        let mut model = LabelledFits {
            fits: &mut guard,
            ids: &compact.ids,
        };
        let merged = merge_core(compact.len(), &couples, priority, &mut model)?;
        let labels: Vec<i32> = compact
            .slots
            .iter()
            .map(|&s| {
                if s < 0 {
                    -1
                } else {
                    compact.ids[merged.root[s as usize]]
                }
            })
            .collect();
        // Each final segment's votes (or PDF sums) are the sum of its initial segments'.
        let semantic = scores.map(|(votes, sums, classes)| {
            let cls = match sums {
                Some(sums) => final_classes(&sums, &merged.root, classes),
                None => final_classes(&votes, &merged.root, classes),
            };
            compact
                .slots
                .iter()
                .map(|&s| {
                    if s < 0 {
                        -1
                    } else {
                        cls[merged.root[s as usize]]
                    }
                })
                .collect::<Vec<i32>>()
        });
        Ok((w, h, compact.ids, merged, labels, semantic))
    })?;
    let (w, h, ids, merged, labels, semantic) = out;
    let steps = &merged.history;
    let kept: Vec<i32> = steps.iter().map(|s| ids[s.kept]).collect();
    let absorbed: Vec<i32> = steps.iter().map(|s| ids[s.absorbed]).collect();
    let score: Vec<f64> = steps.iter().map(|s| s.score).collect();
    let errors: Vec<f64> = steps
        .iter()
        .flat_map(|s| [s.error_kept, s.error_absorbed, s.error_union])
        .collect();
    Ok((
        to_numpy(py, (h, w), labels)?,
        kept.into_pyarray(py),
        absorbed.into_pyarray(py),
        score.into_pyarray(py),
        to_numpy(py, (steps.len(), 3), errors)?,
        semantic.map(|v| to_numpy(py, (h, w), v)).transpose()?,
    ))
}

/// Each final segment's class: the per-class `initial` scores (votes or PDF sums, `n x
/// classes`) of its initial segments summed over `root`, then their [`majority_of_votes`].
fn final_classes<T>(initial: &[T], root: &[usize], classes: usize) -> Vec<i32>
where
    T: Copy + Default + PartialOrd + std::ops::AddAssign,
{
    let mut total = vec![T::default(); initial.len()];
    for (s, &r) in root.iter().enumerate() {
        for c in 0..classes {
            total[r * classes + c] += initial[s * classes + c];
        }
    }
    majority_of_votes(&total, classes)
}

/// Checks of `H x W x C` class PDFs in one pass: `(non-finite values, smallest finite value,
/// largest |sum - 1| over the pixels whose values are finite)`.
#[pyfunction]
#[pyo3(name = "pdf_stats")]
pub fn pdf_stats_native(
    py: Python<'_>,
    pdfs: PyReadonlyArray3<'_, f32>,
) -> PyResult<(u64, f64, f64)> {
    let classes = pdfs.shape()[2];
    let p = borrow("pdfs", &pdfs)?;
    let st = run(py, || pdf_stats(p, classes))?;
    Ok((st.non_finite as u64, st.min, st.worst_sum))
}

/// Majority class (argmax of `pdfs`, `H x W x C`) of each segment of `labels` (`H x W`, -1 =
/// none), painted on its pixels; -1 outside segments.
#[pyfunction]
pub fn majority_classes<'py>(
    py: Python<'py>,
    labels: PyReadonlyArray2<'py, i32>,
    pdfs: PyReadonlyArray3<'py, f32>,
) -> PyResult<Arr2<'py, i32>> {
    let &[h, w] = labels.shape() else {
        unreachable!("2-D array")
    };
    same("pdfs", &pdfs.shape()[..2], &[h, w])?;
    let classes = pdfs.shape()[2];
    let (l, p) = (borrow("labels", &labels)?, borrow("pdfs", &pdfs)?);
    let out = run(py, || {
        let compact = Compact::new(l);
        let cls = majority(&compact.slots, compact.len(), p, classes)?;
        Ok(compact
            .slots
            .iter()
            .map(|&s| if s < 0 { -1 } else { cls[s as usize] })
            .collect::<Vec<i32>>())
    })?;
    to_numpy(py, (h, w), out)
}

/// Adds this module's functions and constants to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(segment_boundaries, m)?)?;
    m.add_function(wrap_pyfunction!(merge_regions, m)?)?;
    m.add_function(wrap_pyfunction!(pdf_stats_native, m)?)?;
    m.add_function(wrap_pyfunction!(majority_classes, m)?)?;
    m.add("T_SIM", rgbd_segment::merge::T_SIM)?;
    m.add("T_D", rgbd_segment::adjacency::T_D)?;
    m.add("T_C", rgbd_segment::adjacency::T_C)?;
    m.add("T_THETA_DEG", rgbd_segment::adjacency::T_THETA_DEG)?;
    Ok(())
}
