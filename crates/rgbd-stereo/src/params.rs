//! The matcher's parameters, validated once ([`SgmParams::validate`]).

use rgbd_error::{invalid, Result};

use crate::census::{bits, CensusReference};

/// The eight path directions of SGM, as the step `(dx, dy)` from the previous pixel of the path
/// to the next (a path "from the left" steps `(1, 0)`).
pub const DIRECTIONS: [(isize, isize); 8] = [
    (1, 0),   // from the left
    (-1, 0),  // from the right
    (1, 1),   // from the top left
    (0, 1),   // from the top
    (-1, 1),  // from the top right
    (1, -1),  // from the bottom left
    (0, -1),  // from the bottom
    (-1, -1), // from the bottom right
];

/// Which of [`DIRECTIONS`] are aggregated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paths {
    /// Left, right, top, bottom.
    Four,
    /// Left, right and the three from above (one top-down sweep, OpenCV's MODE_SGBM set).
    Five,
    /// All eight (Hirschmüller's recommendation).
    Eight,
}

impl Paths {
    /// Whether direction `i` of [`DIRECTIONS`] is used.
    pub fn uses(self, i: usize) -> bool {
        match self {
            Paths::Four => matches!(i, 0 | 1 | 3 | 6),
            Paths::Five => i <= 4,
            Paths::Eight => i < 8,
        }
    }

    /// The number of directions.
    pub fn count(self) -> usize {
        (0..8).filter(|&i| self.uses(i)).count()
    }
}

/// Sub-pixel refinement of the winning integer disparity from its two neighbours' costs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Subpixel {
    /// None: integer disparities.
    Off,
    /// A parabola through the three costs.
    Parabola,
    /// Two lines of opposite slope (equiangular fit; less biased towards integers for costs
    /// that are sums of absolute values).
    Equiangular,
}

/// Largest `p2` accepted: eight paths of cost + P2 must fit a u16 sum.
pub const MAX_P2: u16 = 4000;
/// Largest median window side.
pub const MAX_MEDIAN: usize = 7;
/// Largest [`SgmParams::vertical_tolerance`] (rows above and below).
pub const MAX_VERTICAL: usize = 2;

/// Every parameter of [`crate::sgm`]. Costs are census Hamming distances (0..=bits), the
/// penalties are in the same unit.
#[derive(Debug, Clone, PartialEq)]
pub struct SgmParams {
    /// Smallest disparity searched (pixels).
    pub min_disparity: usize,
    /// Largest disparity searched (pixels, inclusive).
    pub max_disparity: usize,
    /// Census window width and height (odd; at most 64 bits).
    pub census_width: usize,
    pub census_height: usize,
    pub census_reference: CensusReference,
    /// Penalty of a one-pixel disparity step along a path.
    pub p1: u16,
    /// Penalty of a larger step where the image is flat along the path.
    pub p2: u16,
    /// Intensity step (grey levels) that halves P2: `P2(ΔI) = max(P1 + 1, P2 / (1 + ΔI / c))`
    /// with ΔI the reference image's step between the path's two pixels; 0 = constant P2.
    pub p2_contrast: f32,
    pub paths: Paths,
    pub subpixel: Subpixel,
    /// Left-right check: the largest difference (pixels) between this view's winner and the
    /// other view's winner at the matched pixel (read from the same aggregated costs); `None`
    /// switches the check off.
    pub lr_tolerance: Option<u16>,
    /// Uniqueness margin in percent: the winner's cost must be at least this much below every
    /// cost more than one disparity away (0 = off).
    pub uniqueness: u8,
    /// Median filter side on the disparity map (1 = off; odd, at most [`MAX_MEDIAN`]).
    pub median: usize,
    /// Connected regions (4-neighbours within `speckle_range` px) of fewer pixels than this are
    /// removed (0 = off).
    pub speckle_size: usize,
    pub speckle_range: f32,
    /// Rows of the target searched above and below the reference pixel's row: its matching
    /// cost at each disparity is the smallest over target rows `y - v ..= y + v` (clamped at
    /// the image border). 0 = the rectified row only; 1 (the default) tolerates a rig whose
    /// rectification leaves a vertical error of up to about a pixel: on the 20 Middlebury train
    /// and validation scenes with the right image 1 px off, bad-2 21.6 -> 7.0 %, at the price
    /// of 6.3 -> 6.8 % on the perfectly rectified pairs (docs/experiments.md).
    pub vertical_tolerance: usize,
    /// Whether to return the aggregated cost curve's best and second-best costs.
    pub stats: bool,
}

impl SgmParams {
    /// The defaults for a search up to `max_disparity`, chosen on the 20 Middlebury train and
    /// validation scenes by the worse of bad-2 and edge-band bad-1 relative to OpenCV SGBM-HH
    /// 7x7 (`tools/sweep_census.py`, coordinate descent over every field; a missing output
    /// counts as bad there, so the checks that only remove pixels, left-right and uniqueness,
    /// came out off: switch them on where holes are better than guesses).
    pub fn new(max_disparity: usize) -> Self {
        SgmParams {
            min_disparity: 0,
            max_disparity,
            census_width: 5,
            census_height: 5,
            census_reference: CensusReference::Center,
            p1: 15,
            p2: 80,
            p2_contrast: 8.0,
            paths: Paths::Four,
            subpixel: Subpixel::Equiangular,
            lr_tolerance: None,
            uniqueness: 0,
            median: 5,
            speckle_size: 0,
            speckle_range: 1.0,
            vertical_tolerance: 1,
            stats: false,
        }
    }

    /// The number of disparities searched.
    pub fn disparities(&self) -> usize {
        self.max_disparity - self.min_disparity + 1
    }

    /// The census strings' bit count, the largest matching cost.
    pub fn max_cost(&self) -> u16 {
        bits(self.census_width, self.census_height, self.census_reference) as u16
    }

    /// Checks every value against the image width.
    pub fn validate(&self, width: usize) -> Result<()> {
        if self.max_disparity <= self.min_disparity {
            return Err(invalid(
                "max_disparity",
                self.max_disparity,
                format!("more than min_disparity ({})", self.min_disparity),
            ));
        }
        if self.max_disparity >= width {
            return Err(invalid(
                "max_disparity",
                self.max_disparity,
                format!("less than the image width {width}"),
            ));
        }
        for (name, v) in [
            ("census_width", self.census_width),
            ("census_height", self.census_height),
        ] {
            if v % 2 == 0 || v > 15 {
                return Err(invalid(name, v, "an odd number of pixels in 1..=15"));
            }
        }
        let b = bits(self.census_width, self.census_height, self.census_reference);
        if !(1..=64).contains(&b) {
            return Err(invalid(
                "census_width",
                format!(
                    "a {}x{} window ({b} bits)",
                    self.census_width, self.census_height
                ),
                "a window of 1..=64 bits (e.g. 9x7)",
            ));
        }
        if self.p1 == 0 {
            return Err(invalid("p1", self.p1, "at least 1"));
        }
        if self.p2 <= self.p1 || self.p2 > MAX_P2 {
            return Err(invalid(
                "p2",
                self.p2,
                format!("more than p1 ({}) and at most {MAX_P2}", self.p1),
            ));
        }
        if !(self.p2_contrast >= 0.0) || !self.p2_contrast.is_finite() {
            return Err(invalid(
                "p2_contrast",
                self.p2_contrast,
                "a finite value >= 0 (0 = constant P2)",
            ));
        }
        if self.uniqueness >= 100 {
            return Err(invalid(
                "uniqueness",
                self.uniqueness,
                "a percentage in 0..=99",
            ));
        }
        if self.median.is_multiple_of(2) || self.median > MAX_MEDIAN {
            return Err(invalid(
                "median",
                self.median,
                format!("an odd side in 1..={MAX_MEDIAN} (1 = off)"),
            ));
        }
        if self.vertical_tolerance > MAX_VERTICAL {
            return Err(invalid(
                "vertical_tolerance",
                self.vertical_tolerance,
                format!("0..={MAX_VERTICAL} rows"),
            ));
        }
        if !(self.speckle_range >= 0.0) || !self.speckle_range.is_finite() {
            return Err(invalid(
                "speckle_range",
                self.speckle_range,
                "a finite number of pixels >= 0",
            ));
        }
        Ok(())
    }

    /// `P2` for each grey-level step 0..=255 along a path.
    pub(crate) fn p2_table(&self) -> [u16; 256] {
        let mut t = [self.p2; 256];
        if self.p2_contrast > 0.0 {
            for (di, v) in t.iter_mut().enumerate() {
                let p = f32::from(self.p2) / (1.0 + di as f32 / self.p2_contrast);
                *v = (p.round() as u16).max(self.p1 + 1);
            }
        }
        t
    }
}
