//! Rasters of point columns: the cell grid and what a cell's value is, from its values or from
//! the tallies of a column of integers ([`Tally`]). Pure: the binning that brings a cell's
//! points together (a table of tallies, an external sort by cell key) and the GeoTIFF writing
//! are in `io::raster`.
//!
//! Cells are aligned to whole multiples of the cell size in CRS coordinates: the cell holding
//! `(x, y)` is `(floor(x / cell), floor(y / cell))`, so the rasters of adjacent surveys at one
//! cell size line up cell for cell. A point exactly on a cell edge belongs to the cell east or
//! north of it. A cell's value depends only on the values of its points, never on their order
//! (a mean is an exact sum or a sum in sorted order, a median sorts, a tally is exact), so it
//! inherits every invariance of the columns.

use std::fmt;

/// Cell indices are kept within +-2^31 of 0 so that a row and a column fit 32 bits of a key.
const INDEX_BIAS: i64 = 1 << 31;

/// The cell of one point: its column (west to east) and row (south to north) index on the
/// grid of multiples of the cell size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cell {
    /// `floor(x / cell)`.
    pub ix: i64,
    /// `floor(y / cell)`.
    pub iy: i64,
}

impl Cell {
    /// The cell of `(x, y)` at cell size `cell`; None when the coordinate is not finite or lies
    /// more than 2^31 cells from 0 (a 1 cm cell reaches 21,000 km).
    pub fn of(x: f64, y: f64, cell: f64) -> Option<Cell> {
        let (fx, fy) = ((x / cell).floor(), (y / cell).floor());
        let ok = |v: f64| v.is_finite() && v.abs() < INDEX_BIAS as f64;
        (ok(fx) && ok(fy)).then_some(Cell {
            ix: fx as i64,
            iy: fy as i64,
        })
    }

    /// The key that orders cells as a north-up raster is written: rows from north to south,
    /// within a row from west to east.
    pub fn key(self) -> u64 {
        let row = (INDEX_BIAS - 1 - self.iy) as u64;
        let col = (self.ix + INDEX_BIAS) as u64;
        (row << 32) | col
    }

    /// The cell of a [`Cell::key`].
    pub fn from_key(key: u64) -> Cell {
        Cell {
            ix: (key & 0xffff_ffff) as i64 - INDEX_BIAS,
            iy: INDEX_BIAS - 1 - (key >> 32) as i64,
        }
    }
}

/// The extent of a raster: the cells from `west` to `east` and `south` to `north`, inclusive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellGrid {
    /// Cell size in CRS units.
    pub cell: f64,
    /// Column index of the westernmost cells.
    pub west: i64,
    /// Row index of the northernmost cells.
    pub north: i64,
    /// Cells per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// The most cells a raster of `points` points may have: 2^32, or 64 a point where that is
/// more. A grid beyond both is all but empty, the sign of a mistake (inputs in different CRSs,
/// a point far from the others, a cell size in the wrong unit) that would otherwise spend hours
/// writing empty cells.
pub fn max_cells(points: u64) -> u64 {
    (1u64 << 32).max(points.saturating_mul(64))
}

impl CellGrid {
    /// Cells in the grid.
    pub fn cells(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// The grid covering the cells `lo` (south-west) to `hi` (north-east); None when it would
    /// have more than 2^31 - 1 cells on a side (what a TIFF holds).
    pub fn covering(cell: f64, lo: Cell, hi: Cell) -> Option<CellGrid> {
        let width = u32::try_from(hi.ix - lo.ix + 1).ok()?;
        let height = u32::try_from(hi.iy - lo.iy + 1).ok()?;
        (width <= i32::MAX as u32 && height <= i32::MAX as u32).then_some(CellGrid {
            cell,
            west: lo.ix,
            north: hi.iy,
            width,
            height,
        })
    }

    /// The CRS coordinates of the grid's north-west corner (a GeoTIFF's tie point with
    /// PixelIsArea).
    pub fn corner(&self) -> (f64, f64) {
        (
            self.west as f64 * self.cell,
            (self.north + 1) as f64 * self.cell,
        )
    }

    /// The raster row and column of `c` (row 0 north), if it is on the grid.
    pub fn position(&self, c: Cell) -> Option<(u32, u32)> {
        let row = u32::try_from(self.north - c.iy).ok()?;
        let col = u32::try_from(c.ix - self.west).ok()?;
        (row < self.height && col < self.width).then_some((row, col))
    }
}

/// How a cell's value is formed from the values of its points (`--stat`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Stat {
    /// The mean of the defined values (the default).
    #[default]
    Mean,
    /// The median: the middle value, or the mean of the two middle ones.
    Median,
    /// The smallest value.
    Min,
    /// The largest value.
    Max,
    /// The number of defined values.
    Count,
}

impl Stat {
    /// Every statistic, as `--stat` lists them.
    pub const ALL: [Stat; 5] = [Stat::Mean, Stat::Median, Stat::Min, Stat::Max, Stat::Count];

    /// The name `--stat` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Stat::Mean => "mean",
            Stat::Median => "median",
            Stat::Min => "min",
            Stat::Max => "max",
            Stat::Count => "count",
        }
    }

    /// The statistic named `name`.
    pub fn from_name(name: &str) -> Option<Stat> {
        Stat::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The statistic named `name`, or a message naming the choices (`--stat`, Python's
    /// `stat=`).
    pub fn parse(name: &str) -> Result<Stat, String> {
        Stat::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Stat::ALL.iter().map(|s| s.name()).collect();
            format!(
                "{name:?} is not a statistic: use one of {}",
                names.join(", ")
            )
        })
    }

    /// The cell value of `values` (one cell's values of one column, NaN for undefined ones),
    /// NaN when none is defined. `circular` takes the values as angles in degrees (aspect):
    /// the mean is the direction of the mean unit vector, in [0, 360); the median, min and max
    /// are those of the angles unwrapped about that mean (`circular_order`), so that 359 and
    /// 1 have the median 0, not 180. The result does not depend on the values' order: a mean
    /// whose f64 sum is exact in any order takes it as it comes, other means and the median
    /// sort the values first (NaN last); the min and max compare by total order (-0 below +0).
    pub fn reduce(self, values: &mut [f32], circular: bool) -> f32 {
        let defined = values.iter().copied().filter(|v| !v.is_nan());
        match self {
            Stat::Count => return defined.count() as f32,
            _ if circular => {}
            Stat::Min => return defined.min_by(f32::total_cmp).unwrap_or(f32::NAN),
            Stat::Max => return defined.max_by(f32::total_cmp).unwrap_or(f32::NAN),
            Stat::Mean => {
                if let Some(mean) = exact_mean(values) {
                    return mean;
                }
            }
            Stat::Median => {}
        }
        values.sort_unstable_by(|a, b| a.total_cmp(b));
        let n = values.iter().take_while(|v| !v.is_nan()).count();
        let v = &values[..n];
        if n == 0 {
            return f32::NAN;
        }
        if circular {
            return circular_order(self, v);
        }
        match self {
            Stat::Median => median(v),
            _ => (v.iter().map(|&x| x as f64).sum::<f64>() / n as f64) as f32,
        }
    }
}

/// The middle of the sorted `v` (not empty), or the mean of the two middle ones in f64.
fn median(v: &[f32]) -> f32 {
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        ((v[n / 2 - 1] as f64 + v[n / 2] as f64) / 2.0) as f32
    }
}

/// `stat` of the angles `degrees` (sorted, defined, not empty) as directions: the circular
/// mean; or the median, min or max of the angles ordered as unwrapped into the half-turns
/// either side of that mean (each taken to the mean - 180 to mean + 180): an angle itself, or
/// the middle of two in f64, in [0, 360). NaN where the mean is undefined
/// (directions that cancel), which leaves the others undefined too.
fn circular_order(stat: Stat, degrees: &[f32]) -> f32 {
    let mean = circular_mean(degrees);
    if stat == Stat::Mean || mean.is_nan() {
        return mean;
    }
    let from = mean as f64 - 180.0;
    let mut u: Vec<(f64, f32)> = (degrees.iter())
        .map(|&d| ((d as f64 - from).rem_euclid(360.0), d))
        .collect();
    u.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let n = u.len();
    let picked = match stat {
        Stat::Min => u[0].1 as f64,
        Stat::Max => u[n - 1].1 as f64,
        _ if n % 2 == 1 => u[n / 2].1 as f64,
        _ => (u[n / 2 - 1].0 + u[n / 2].0) / 2.0 + from,
    };
    // Into [0, 360): an angle of 360 (a file may hold one) is north, 0.
    below_360(picked.rem_euclid(360.0))
}

/// `degrees` in [0, 360] as an f32 in [0, 360): 360 (or what rounds to it) is north, 0.
fn below_360(degrees: f64) -> f32 {
    let d = degrees as f32;
    if d >= 360.0 {
        0.0
    } else {
        d
    }
}

/// A column of integers read as `raw * scale + offset` (a scaled LAS extra dimension of an
/// integer type): its cell values are formed from the integers ([`Tally`]), which sum exactly,
/// so that no sort is needed for a mean that ignores the order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integers {
    /// The scale of a raw integer.
    pub scale: f64,
    /// The offset added to the scaled integer.
    pub offset: f64,
}

impl Integers {
    /// `raw` oriented so that its order is the order of the values: negated when the scale is
    /// negative (the minimum of the values is then the maximum of the integers).
    #[inline(always)]
    pub fn oriented(&self, raw: i64) -> i64 {
        if self.scale < 0.0 {
            -raw
        } else {
            raw
        }
    }

    /// The value of `x` oriented integers (a sum divided by a count, or one integer).
    fn value(&self, x: f64) -> f32 {
        (x * self.scale.abs() + self.offset) as f32
    }
}

/// An integer that is not defined (its column's no-data value): no oriented integer of at
/// most 32 bits is this.
pub const UNDEFINED: i64 = i64::MIN;

/// The most points a cell may hold for integer tallies: the sum of this many integers of
/// 32 bits stays within an i64.
pub const MAX_CELL_POINTS: u32 = i32::MAX as u32;

/// One column's statistic over some of a cell's oriented integers ([`Integers::oriented`]): a
/// sum, a minimum or a maximum, and how many were defined. Exact, so that a cell's tally does
/// not depend on the order of its points or on how they were split into partial tallies that
/// were merged ([`Stat::merge`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tally {
    /// The sum (mean, count), the least (min) or the greatest (max) integer.
    pub acc: i64,
    /// Defined integers.
    pub count: u32,
}

impl Stat {
    /// Whether this statistic is a [`Tally`] of integers: all but the median, which needs every
    /// value.
    pub fn tallies(self) -> bool {
        self != Stat::Median
    }

    /// The tally of no integer.
    pub fn empty(self) -> Tally {
        let acc = match self {
            Stat::Min => i64::MAX,
            Stat::Max => i64::MIN,
            _ => 0,
        };
        Tally { acc, count: 0 }
    }

    /// Adds each oriented integer of `raws` to its tally in `tallies` but the [`UNDEFINED`]
    /// ones (fewer than [`MAX_CELL_POINTS`] in a tally). The statistic chosen once for the
    /// columns, each a loop without branches.
    #[inline(always)]
    pub fn add_all(self, tallies: &mut [Tally], raws: &[i64]) {
        #[inline(always)]
        fn each(tallies: &mut [Tally], raws: &[i64], f: impl Fn(i64, i64) -> i64) {
            for (t, &raw) in tallies.iter_mut().zip(raws) {
                let defined = raw != UNDEFINED;
                t.acc = if defined { f(t.acc, raw) } else { t.acc };
                t.count += u32::from(defined);
            }
        }
        match self {
            Stat::Min => each(tallies, raws, i64::min),
            Stat::Max => each(tallies, raws, i64::max),
            _ => each(tallies, raws, |a, b| a + b),
        }
    }

    /// Merges the tally `other` of other points of the cell into `t`.
    pub fn merge(self, t: &mut Tally, other: Tally) {
        t.acc = match self {
            Stat::Min => t.acc.min(other.acc),
            Stat::Max => t.acc.max(other.acc),
            _ => t.acc + other.acc,
        };
        t.count += other.count;
    }

    /// The cell value of the tally `t` of a column of `ints`; NaN when no integer was defined
    /// (a count of 0 for [`Stat::Count`]). The mean is the sum over the count, scaled and
    /// offset in f64: the mean of the values the integers stand for, not of their f32 values.
    pub fn tally_value(self, t: Tally, ints: Integers) -> f32 {
        match self {
            Stat::Count => t.count as f32,
            _ if t.count == 0 => f32::NAN,
            Stat::Min | Stat::Max => ints.value(t.acc as f64),
            _ => ints.value(t.acc as f64 / t.count as f64),
        }
    }
}

impl fmt::Display for Stat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The mean of the defined values when their f64 sum is exact in any order (NaN when none is
/// defined), so that no sort is needed for a mean independent of the order; `None` otherwise.
/// Every f32 is a multiple of its unit in the last place, at most 2^24 of them: n values whose
/// largest binary exponent is at most `spread` above the smallest are all multiples of the
/// smallest ulp and their partial sums stay below 2^(24 + spread + log2 n) of it, which f64's
/// 53-bit significand holds exactly when 24 + spread + ceil(log2 n) <= 53. A cell's values
/// almost always span far less than the 2^26 this allows for 8 points; the rest are sorted.
fn exact_mean(values: &[f32]) -> Option<f32> {
    let (mut n, mut sum) = (0u64, 0.0f64);
    let (mut lo, mut hi) = (u32::MAX, 0u32);
    for &v in values.iter().filter(|v| !v.is_nan()) {
        n += 1;
        sum += f64::from(v);
        if v != 0.0 {
            // The biased exponent; subnormals share the unit of exponent 1.
            let e = ((v.to_bits() >> 23) & 0xff).max(1);
            (lo, hi) = (lo.min(e), hi.max(e));
        }
    }
    if n == 0 {
        return Some(f32::NAN);
    }
    let spread = hi.saturating_sub(lo);
    let room = 64 - (n - 1).leading_zeros(); // ceil(log2 n)
    (24 + spread + room <= 53 && sum.is_finite()).then(|| (sum / n as f64) as f32)
}

/// The direction of the mean unit vector of `degrees`, in [0, 360); NaN when they cancel
/// (the mean vector shorter than 1e-9).
fn circular_mean(degrees: &[f32]) -> f32 {
    let (s, c) = degrees.iter().fold((0.0, 0.0), |(s, c), &d| {
        let r = (d as f64).to_radians();
        (s + r.sin(), c + r.cos())
    });
    if s.hypot(c) < 1e-9 * degrees.len() as f64 {
        return f32::NAN;
    }
    below_360(s.atan2(c).to_degrees().rem_euclid(360.0))
}

#[cfg(test)]
#[path = "raster_tests.rs"]
mod tests;
