//! Label compaction: any `i32` labels (negative = no segment) to slots `0..n`, so per-segment
//! arrays are sized by the number of segments, never by the largest label.

use rayon::prelude::*;

/// The distinct labels `>= 0` of a label image (sorted) and each pixel's slot among them
/// (`-1` where the label is negative).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Compact {
    /// `ids[s]` is the label of slot `s`.
    pub ids: Vec<i32>,
    /// Per pixel: the slot of its label, `-1` for no segment.
    pub slots: Vec<i32>,
}

impl Compact {
    /// Compacts `labels` (the distinct labels from `rgbd_spline::distinct_labels`: a presence
    /// scan and a slot table when the labels are at most a few times the pixel count, else a
    /// sort).
    pub fn new(labels: &[i32]) -> Self {
        let (ids, table) = rgbd_spline::distinct_labels(labels);
        let mut slots = rgbd_spline::label_slots(labels, &ids, table.as_deref());
        slots.par_iter_mut().for_each(|s| *s = (*s).max(-1));
        Self { ids, slots }
    }

    /// Number of segments.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether no pixel has a segment.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The slot of `label`, if present.
    pub fn slot(&self, label: i32) -> Option<usize> {
        self.ids.binary_search(&label).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sparse_labels_get_dense_slots() {
        let c = Compact::new(&[7, -3, 2_000_000_000, 7, 0]);
        assert_eq!(c.ids, vec![0, 7, 2_000_000_000]);
        assert_eq!(c.slots, vec![1, -1, 2, 1, 0]);
        assert_eq!(c.slot(7), Some(1));
        assert_eq!(c.slot(8), None);
        assert!(Compact::new(&[-1, -1]).is_empty());
        // Dense labels take the table path: the same ids and slots as the sort.
        let c = Compact::new(&[7, -3, 5, 7, 0, -1]);
        assert_eq!(c.ids, vec![0, 5, 7]);
        assert_eq!(c.slots, vec![2, -1, 1, 2, 0, -1]);
        let many: Vec<i32> = (0..3000).map(|i| (i * 37 % 1001) - 5).collect();
        let c = Compact::new(&many);
        let mut want: Vec<i32> = many.iter().copied().filter(|&l| l >= 0).collect();
        want.sort_unstable();
        want.dedup();
        assert_eq!(c.ids, want);
        for (&l, &s) in many.iter().zip(&c.slots) {
            assert_eq!(
                s,
                if l < 0 {
                    -1
                } else {
                    want.binary_search(&l).unwrap() as i32
                }
            );
        }
    }
}
