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
        _ => ((u[n / 2 - 1].0 + u[n / 2].0) / 2.0 + from).rem_euclid(360.0),
    };
    // An angle of 360 (a file may hold one) is north: 0.
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
mod tests {
    use super::*;

    /// Cells are multiples of the cell size: the edges belong to the cell east and north.
    #[test]
    fn cells_are_aligned_to_multiples_of_the_cell_size() {
        assert_eq!(Cell::of(0.0, 0.0, 0.5), Some(Cell { ix: 0, iy: 0 }));
        assert_eq!(Cell::of(-0.1, 0.49, 0.5), Some(Cell { ix: -1, iy: 0 }));
        assert_eq!(
            Cell::of(500_000.5, 4_100_000.25, 0.5),
            Some(Cell {
                ix: 1_000_001,
                iy: 8_200_000
            })
        );
        assert_eq!(Cell::of(f64::NAN, 0.0, 1.0), None);
        assert_eq!(Cell::of(1e300, 0.0, 1.0), None);
    }

    /// Keys order cells north to south, then west to east, and give the cell back.
    #[test]
    fn keys_order_cells_as_a_north_up_raster_and_round_trip() {
        let cells = [(-3, 5), (7, 5), (-3, 4), (0, 4), (9, -2)];
        let keys: Vec<u64> = cells
            .iter()
            .map(|&(ix, iy)| Cell { ix, iy }.key())
            .collect();
        assert!(keys.windows(2).all(|w| w[0] < w[1]));
        for (&(ix, iy), &k) in cells.iter().zip(&keys) {
            assert_eq!(Cell::from_key(k), Cell { ix, iy });
        }
        let far = Cell {
            ix: -(1 << 31) + 1,
            iy: (1 << 31) - 1,
        };
        assert_eq!(Cell::from_key(far.key()), far);
    }

    /// The grid's corner and positions follow from its cells.
    #[test]
    fn the_grid_places_cells_north_up() {
        let g = CellGrid::covering(2.0, Cell { ix: 10, iy: -5 }, Cell { ix: 12, iy: -3 });
        let g = g.expect("small grid");
        assert_eq!((g.width, g.height), (3, 3));
        assert_eq!(g.corner(), (20.0, -4.0));
        assert_eq!(g.position(Cell { ix: 10, iy: -3 }), Some((0, 0)));
        assert_eq!(g.position(Cell { ix: 12, iy: -5 }), Some((2, 2)));
        assert_eq!(g.position(Cell { ix: 13, iy: -5 }), None);
    }

    /// Tallies of scaled integers give the statistics of the values `r s + o` they stand for,
    /// with a negative scale too (its least value is its greatest integer), undefined ones
    /// left out, and merged partial tallies the tally of all.
    #[test]
    fn tallies_of_integers_are_the_statistics_of_their_values() {
        let raws = [3i64, -5, UNDEFINED, 10, 7];
        for (scale, offset) in [(-0.5, 2.0), (0.25, -1.0), (1e-7, 0.0)] {
            let ints = Integers { scale, offset };
            let values: Vec<f64> = (raws.iter())
                .filter(|&&r| r != UNDEFINED)
                .map(|&r| r as f64 * scale + offset)
                .collect();
            let mean = values.iter().sum::<f64>() / values.len() as f64;
            let least = values.iter().copied().fold(f64::INFINITY, f64::min);
            let most = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            for (stat, want) in [
                (Stat::Mean, mean),
                (Stat::Min, least),
                (Stat::Max, most),
                (Stat::Count, 4.0),
            ] {
                let oriented: Vec<i64> = (raws.iter())
                    .map(|&r| if r == UNDEFINED { r } else { ints.oriented(r) })
                    .collect();
                let mut all = stat.empty();
                for r in &oriented {
                    stat.add_all(std::slice::from_mut(&mut all), std::slice::from_ref(r));
                }
                let (mut a, mut b) = (stat.empty(), stat.empty());
                for (i, r) in oriented.iter().enumerate() {
                    let t = if i % 2 == 0 { &mut a } else { &mut b };
                    stat.add_all(std::slice::from_mut(t), std::slice::from_ref(r));
                }
                stat.merge(&mut a, b);
                assert_eq!(a, all, "{stat} merged");
                let got = stat.tally_value(all, ints) as f64;
                assert!(
                    (got - want).abs() <= 1e-6 * want.abs(),
                    "{stat} {scale}: {got} {want}"
                );
            }
            assert!(Stat::Mean.tally_value(Stat::Mean.empty(), ints).is_nan());
        }
    }

    /// Each statistic on a known set, undefined values left out, whatever the order.
    #[test]
    fn statistics_leave_out_undefined_values_and_ignore_order() {
        let base = [3.0f32, f32::NAN, 1.0, 2.0, 10.0];
        let expect = [
            (Stat::Mean, 4.0),
            (Stat::Median, 2.5),
            (Stat::Min, 1.0),
            (Stat::Max, 10.0),
            (Stat::Count, 4.0),
        ];
        for (stat, want) in expect {
            for rot in 0..base.len() {
                let mut v = base;
                v.rotate_left(rot);
                assert_eq!(stat.reduce(&mut v, false), want, "{stat} rotation {rot}");
            }
        }
        let mut odd = [5.0f32, 1.0, 3.0];
        assert_eq!(Stat::Median.reduce(&mut odd, false), 3.0);
        let mut none = [f32::NAN; 3];
        assert!(Stat::Mean.reduce(&mut none, false).is_nan());
        assert_eq!(Stat::Count.reduce(&mut none, false), 0.0);
    }

    /// The mean without a sort equals the mean of the sorted values, and values too far apart
    /// in magnitude for an exact sum still give the same mean in every order.
    #[test]
    fn the_mean_is_the_sorted_sum_and_ignores_order_when_magnitudes_differ() {
        let mut rng = crate::core::rng::Rng::new(7);
        for case in 0..2000_i32 {
            let n = 1 + (rng.next_u64() % 12) as usize;
            // Exponent spreads from none to far beyond what an f64 sum holds exactly.
            let reach = case % 40;
            let mut v: Vec<f32> = (0..n)
                .map(|_| {
                    let m = rng.uniform() * 2.0 - 1.0;
                    let e = (rng.next_u64() % (reach as u64 + 1)) as i32 - reach / 2;
                    (m * 2f64.powi(e)) as f32
                })
                .collect();
            let mut sorted = v.clone();
            sorted.sort_unstable_by(f32::total_cmp);
            let want = (sorted.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64) as f32;
            let exact = exact_mean(&v);
            if let Some(m) = exact {
                assert_eq!(m.to_bits(), want.to_bits(), "{v:?}");
            }
            // Values within a factor of 2^24 of each other (12 of them need at most 4 bits
            // more) always sum exactly: the sort-free path must answer for them.
            let big = v.iter().fold(0.0f32, |m, x| m.max(x.abs()));
            let small = v
                .iter()
                .filter(|x| **x != 0.0)
                .fold(f32::MAX, |m, x| m.min(x.abs()));
            if big <= small * 2f32.powi(24) {
                assert!(exact.is_some(), "an exact sum left to the sort: {v:?}");
            }
            for rot in 0..n {
                v.rotate_left(1);
                let got = Stat::Mean.reduce(&mut v.clone(), false);
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "case {case} rotation {rot}: {v:?}"
                );
            }
        }
        // A spread of 2^40 between values is past an exact sum: the sorted path answers.
        let far = [1.0f32, 1e-12, -1.0];
        assert_eq!(exact_mean(&far), None);
        let first = Stat::Mean.reduce(&mut far.clone(), false);
        for order in [[1e-12f32, -1.0, 1.0], [-1.0, 1.0, 1e-12]] {
            assert_eq!(Stat::Mean.reduce(&mut order.clone(), false), first);
        }
    }

    /// The circular mean of aspects across north is north, not south.
    #[test]
    fn the_mean_of_aspects_is_circular() {
        let mut v = [350.0f32, 10.0];
        let m = Stat::Mean.reduce(&mut v, true);
        assert!(!(1e-3..=359.999).contains(&m), "{m}");
        let mut v = [80.0f32, 100.0, 90.0];
        assert!((Stat::Mean.reduce(&mut v, true) - 90.0).abs() < 1e-4);
        let mut v = [0.0f32, 180.0];
        assert!(Stat::Mean.reduce(&mut v, true).is_nan());
        assert_eq!(Stat::Mean.reduce(&mut [350.0f32, 10.0], false), 180.0);
    }

    /// The median, min and max of aspects are those of the angles about their circular mean:
    /// the trial's cell of 6.5 and 358.8 degrees has the median 2.65 (it had 182.65), its min
    /// 358.8 and max 6.5 (the arc from one to the other clockwise through north); away from
    /// north they are the plain ones; where directions cancel they are undefined.
    #[test]
    fn the_median_min_and_max_of_aspects_are_circular() {
        let cell = [6.5f32, 358.8];
        let r = |s: Stat, v: &[f32]| s.reduce(&mut v.to_vec(), true);
        assert!(
            (r(Stat::Median, &cell) - 2.65).abs() < 1e-4,
            "{}",
            r(Stat::Median, &cell)
        );
        assert_eq!(r(Stat::Min, &cell), 358.8);
        assert_eq!(r(Stat::Max, &cell), 6.5);
        let across = [355.0f32, 359.0, 3.0, 20.0, 350.0];
        assert!((r(Stat::Median, &across) - 359.0).abs() < 1e-4);
        assert_eq!(r(Stat::Min, &across), 350.0);
        assert_eq!(r(Stat::Max, &across), 20.0);
        let east = [80.0f32, 95.0, 91.0, 120.0];
        assert_eq!(
            r(Stat::Median, &east),
            Stat::Median.reduce(&mut east.to_vec(), false)
        );
        assert_eq!(r(Stat::Min, &east), 80.0);
        assert_eq!(r(Stat::Max, &east), 120.0);
        for s in [Stat::Median, Stat::Min, Stat::Max] {
            assert!(r(s, &[0.0, 180.0]).is_nan(), "{s:?}");
            assert!(r(s, &[f32::NAN]).is_nan(), "{s:?}");
            assert_eq!(r(s, &[f32::NAN, 42.0]), 42.0, "{s:?}");
        }
        // Across north the values stay in [0, 360).
        for k in 0..200 {
            let a = 359.999f32 + k as f32 * 1e-5;
            for s in [Stat::Mean, Stat::Median, Stat::Min, Stat::Max] {
                let v = r(s, &[a, 360.0 - a, 1e-6]);
                assert!((0.0..360.0).contains(&v), "{s:?} of {a}: {v}");
            }
        }
    }
}
