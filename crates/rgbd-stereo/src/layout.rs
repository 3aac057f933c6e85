//! Where each pixel's disparities lie in the cost-sum volume `S`. A reference pixel `x` can only
//! match target pixels `x - d >= 0`, so it has `min(x - dmin + 1, D)` searchable disparities
//! (none left of `dmin`), and `S` stores just those: each row is the pixels' runs back to back.
//! At 960 x 540 x 128 that is 6.6 % less memory than the full `W x H x D` box; the paths still
//! run over all `D` disparities (the unsearchable ones cost the census maximum), only their
//! sums are not kept.

use std::ops::Range;

/// The run of every pixel of a row (the same for every row).
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    /// `offsets[x]..offsets[x + 1]` is pixel `x`'s run; `offsets[w]` the row's length.
    offsets: Vec<usize>,
}

impl Layout {
    /// The layout of rows `w` wide searching disparities `dmin..dmin + nd`.
    pub fn new(w: usize, dmin: usize, nd: usize) -> Self {
        let mut offsets = Vec::with_capacity(w + 1);
        let mut at = 0;
        offsets.push(0);
        for x in 0..w {
            at += valid(x, dmin, nd);
            offsets.push(at);
        }
        Layout { offsets }
    }

    /// The length of one row of `S`.
    pub fn row_len(&self) -> usize {
        self.offsets[self.offsets.len() - 1]
    }

    /// Pixel `x`'s run within its row.
    #[inline(always)]
    pub fn run(&self, x: usize) -> Range<usize> {
        self.offsets[x]..self.offsets[x + 1]
    }

    /// Pixels `x0..x1`'s runs within their row.
    pub fn span(&self, x0: usize, x1: usize) -> Range<usize> {
        self.offsets[x0]..self.offsets[x1]
    }

    /// A row of `S` cut into the runs of consecutive blocks of `block` pixels.
    pub fn blocks<'a>(&self, mut row: &'a mut [u16], block: usize) -> Vec<&'a mut [u16]> {
        let w = self.offsets.len() - 1;
        let mut out = Vec::with_capacity(w.div_ceil(block));
        for x0 in (0..w).step_by(block) {
            let r = self.span(x0, (x0 + block).min(w));
            let (head, tail) = std::mem::take(&mut row).split_at_mut(r.len());
            out.push(head);
            row = tail;
        }
        out
    }
}

/// The number of searchable disparities of reference pixel `x`.
#[inline(always)]
pub(crate) fn valid(x: usize, dmin: usize, nd: usize) -> usize {
    if x < dmin {
        0
    } else {
        (x - dmin + 1).min(nd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_the_searchable_disparities() {
        let l = Layout::new(6, 1, 3);
        // Pixel 0 searches nothing, 1 one disparity, 2 two, then all three.
        assert_eq!(l.row_len(), 1 + 2 + 3 + 3 + 3);
        assert_eq!(l.run(0), 0..0);
        assert_eq!(l.run(3), 3..6);
        let mut row = vec![0u16; l.row_len()];
        let lens: Vec<usize> = l.blocks(&mut row, 4).iter().map(|b| b.len()).collect();
        assert_eq!(lens, vec![6, 6]);
    }
}
