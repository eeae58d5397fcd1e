//! Rasters of point columns: points are binned by cell out of core, the integer columns' values
//! tallied per cell ([`sums`]) and the others' kept ([`bins`]), then the cells are reduced
//! ([`crate::core::raster::Stat`]) and written row by row as one GeoTIFF per
//! column ([`geotiff`]), a point-count GeoTIFF, and a quick-look PNG beside each. Fed by the
//! `raster` command (points of any LAS/LAZ holding the columns) and by `process --raster`
//! (each point as its output is written), through one [`Rasterizer`].

mod bins;
pub(crate) mod geokeys;
pub(crate) mod geotiff;
mod rows;
pub(crate) mod sidecar;
mod sums;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::core::raster::{
    max_cells, Cell, CellGrid, Integers, Stat, Tally, MAX_CELL_POINTS, UNDEFINED,
};
use crate::error::{Error, Result};
use crate::io::columns::{ColumnChoice, ColumnSet, Group, TerrainValue, Value};
use bins::{from_words, words_of, Bins, Cells};
use geokeys::RasterCrs;
use geotiff::GeoTiff;
use rows::{quick_looks, Rows};
use sums::{CellSums, SumCells};

/// The name of the point-count raster.
pub(crate) const COUNT_NAME: &str = "PointCount";

/// One column as a raster shows it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RasterColumn {
    /// The column's name, which is the raster's file name.
    pub(crate) name: String,
    /// Its unit ("1/m", "degrees", or empty when unitless or unknown).
    pub(crate) unit: String,
    /// Whether its values have a sign that means something (curvatures): a diverging ramp.
    pub(crate) signed: bool,
    /// Whether it is a direction in degrees (aspect): its mean is circular, its ramp cyclic.
    pub(crate) angle: bool,
    /// The fixed scale (low, high) of its quick look, for values with natural bounds (shape
    /// index); None: the percentiles of the values.
    pub(crate) scale: Option<(f64, f64)>,
    /// Set when the points' values are integers of this scale and offset in every input and
    /// the statistic tallies them ([`Stat::tallies`]): the cells tally the integers
    /// ([`crate::core::raster::Tally`]) instead of keeping every value.
    pub(crate) integers: Option<Integers>,
}

/// How tilecurv's own columns are shown, with `unit` the symbol of the file's unit ("m"):
/// every column it can write but the flags and the scale, and whether `--columns` picks it by
/// default for a raster (the curvatures: H, K, k1, k2, profile, tangential and plan curvature,
/// shape index, curvedness).
pub(crate) fn known_columns(unit: &str) -> Vec<(RasterColumn, bool)> {
    let every = Group::ALL
        .into_iter()
        .fold(ColumnChoice::default(), ColumnChoice::with);
    let set = ColumnSet {
        choice: every,
        extra: Vec::new(),
        unit: unit.into(),
        wide: false,
    };
    let per = format!("1/{unit}");
    set.columns()
        .into_iter()
        .filter_map(|c| {
            use TerrainValue::*;
            let (unit, signed, curvature) = match c.value {
                Value::H | Value::K1 | Value::K2 => (per.clone(), true, true),
                Value::K => (format!("1/{unit}^2"), true, true),
                Value::Terrain(Profile | Tangential | Plan) => (per.clone(), true, true),
                Value::Terrain(ShapeIndex) => (String::new(), true, true),
                Value::Terrain(Curvedness) => (per.clone(), false, true),
                Value::Terrain(Slope | Aspect) => ("degrees".into(), false, false),
                Value::Normal(_) | Value::D1(_) | Value::D2(_) => (String::new(), true, false),
                _ => return None,
            };
            let angle = c.value == Value::Terrain(Aspect);
            let scale = (c.value == Value::Terrain(ShapeIndex)).then_some((-1.0, 1.0));
            let col = RasterColumn {
                name: c.name.into(),
                unit,
                signed,
                angle,
                scale,
                integers: None,
            };
            Some((col, curvature))
        })
        .collect()
}

/// What rasters to make and where.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RasterRequest {
    /// Cell size in file units.
    pub(crate) cell: f64,
    /// The symbol of the file unit ("m", "ft", or "unit"), for messages.
    pub(crate) unit: String,
    /// How a cell's value is formed.
    pub(crate) stat: Stat,
    /// The directory the rasters go to.
    pub(crate) dir: PathBuf,
    /// The columns, one raster each.
    pub(crate) columns: Vec<RasterColumn>,
}

/// What the rasters of a run are: their grid, and what was written.
#[derive(Debug, Clone, PartialEq)]
pub struct RasterSummary {
    /// The grid (its cell size in file units).
    pub grid: CellGrid,
    /// The symbol of the file unit ("m", "ft", or "unit").
    pub unit: String,
    /// Points binned.
    pub points: u64,
    /// Cells holding at least one point.
    pub cells: u64,
    /// The GeoTIFFs and PNGs written.
    pub files: Vec<PathBuf>,
}

/// A length in `unit` (a symbol: "m", "ft", or "unit" without a CRS unit) for messages:
/// "1 m", "6.56167 ftUS", "2 file units".
pub(crate) fn length_text(x: f64, unit: &str) -> String {
    let x = six_digits(x);
    match unit {
        "unit" if x == "1" => "1 file unit".into(),
        "unit" => format!("{x} file units"),
        u => format!("{x} {u}"),
    }
}

/// Refuses a raster over the cells `lo` to `hi` (south-west, north-east) of `cell` file units
/// (`unit`) for `points` points when it has more than [`max_cells`] cells.
pub(crate) fn check_size(lo: Cell, hi: Cell, (cell, unit): (f64, &str), points: u64) -> Result<()> {
    let side = |a: i64, b: i64| b.abs_diff(a).saturating_add(1);
    let (width, height) = (side(lo.ix, hi.ix), side(lo.iy, hi.iy));
    let cells = width.saturating_mul(height);
    if cells <= max_cells(points) {
        return Ok(());
    }
    let span = |n: u64| length_text(n as f64 * cell, unit);
    Err(Error::Usage(format!(
        "a raster of {width} x {height} cells of {} ({cells} cells) for {points} points would be almost all empty (at most {} cells): the points spread over {} by {}. Check that the inputs share a CRS and that no point lies far from the others (`tilecurv info FILE` shows each file's bounds), or use a larger --cell",
        length_text(cell, unit),
        max_cells(points),
        span(width),
        span(height)
    )))
}

impl RasterSummary {
    /// The cell size with its unit, for messages: "1 m", or "2 file units" without a CRS unit.
    pub fn cell_text(&self) -> String {
        length_text(self.grid.cell, &self.unit)
    }

    /// What a user is to be told of the rasters written: a sparse grid, and other runs' rasters
    /// left in the directory.
    pub fn warnings(&self) -> Vec<String> {
        self.sparse_warning()
            .into_iter()
            .chain(self.others_warning())
            .collect()
    }

    /// A warning when the rasters' directory holds GeoTIFFs this run did not write (an earlier
    /// run's columns, which it replaces only where the names meet): they may be of other points
    /// or in another CRS, and a GIS opening the folder shows them beside these.
    fn others_warning(&self) -> Option<String> {
        let dir = self.files.first()?.parent()?;
        let mut others: Vec<String> = (std::fs::read_dir(dir).ok()?)
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "tif") && !self.files.contains(p))
            .filter_map(|p| Some(p.file_name()?.to_string_lossy().into_owned()))
            .collect();
        others.sort();
        (!others.is_empty()).then(|| {
            format!(
                "{} also holds {}, which this run did not write: an earlier run's, perhaps of other points or in another CRS; remove them, or write these rasters to a directory of their own",
                dir.display(),
                others.join(", ")
            )
        })
    }

    /// A warning when fewer than a quarter of the cells hold a point: the cell is finer than
    /// the points' spacing over much of the area, and the rasters are mostly no-data.
    fn sparse_warning(&self) -> Option<String> {
        let all = self.grid.cells();
        (self.cells.saturating_mul(4) < all).then(|| {
            format!(
                "only {} of the {}x{} cells ({}) hold a point: cells of {} are finer than the points' spacing over much of the area, so the rasters are mostly no-data; a larger cell fills more",
                self.cells,
                self.grid.width,
                self.grid.height,
                percent(self.cells as f64 / all as f64),
                self.cell_text()
            )
        })
    }
}

/// The fraction `f` as a percentage for messages: one decimal from 1%, two significant digits
/// below it ("0.0068%"), so that a small share does not read as none.
fn percent(f: f64) -> String {
    let p = 100.0 * f;
    if p >= 1.0 || p <= 0.0 || !p.is_finite() {
        return format!("{p:.1}%");
    }
    let decimals = (1.0 - p.log10().floor()) as usize;
    format!("{p:.decimals$}%")
}

/// `x` to six significant digits, without trailing zeros; in exponent form below 1e-4 and from
/// 1e7 on.
fn six_digits(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    if !(1e-4..1e7).contains(&a) {
        return format!("{x:e}");
    }
    let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
    let text = format!("{x:.decimals$}");
    match text.contains('.') {
        true => text.trim_end_matches('0').trim_end_matches('.').to_string(),
        false => text,
    }
}

/// Points on their way into rasters: each point's cell and column values are binned as they
/// come ([`Rasterizer::push`]); [`Rasterizer::finish`] writes the rasters. The columns of
/// integers ([`RasterColumn::integers`]), the point count and the elevation that shades the
/// quick looks are reduced from tallies ([`crate::core::raster::Tally`]); the others keep
/// every point's value until the cell is reduced ([`Bins`]). Where points are dense (more of
/// them than cells, about), the tallies are made as the points come ([`CellSums`]); where they
/// are sparse, a cell's tallies take more memory than its points, whose integers are then kept
/// with their floats and tallied at the end: the same tallies either way.
pub(crate) struct Rasterizer {
    request: RasterRequest,
    /// Where each column's value of a point is: among its integers or its floats.
    slots: Vec<Slot>,
    /// The cells' tallies as the points come, where points are dense.
    sums: Option<CellSums>,
    /// The points' words: their floats' bits and, without `sums`, their integers (two words
    /// each, z's last); None when there are none.
    bins: Option<Bins>,
    /// One point's words.
    words: Vec<u32>,
    lo: Option<Cell>,
    hi: Option<Cell>,
    points: u64,
}

/// The step of the elevation's integers (shade only): 2^-10 file units, about a millimetre in
/// metres, far below what a hillshade shows whatever the cell (a cell in degrees included),
/// and elevations up to 2^21 units (2,000 km) within the 32 bits a tallied integer has.
const Z_STEP: f64 = 1.0 / 1024.0;

/// Whether tallying the cells as the points come takes less memory than keeping the points'
/// integers: `points` over `area` square units (None: unknown, tallied) in cells of `cell`,
/// with `ints` integer columns (and z) and `floats` others. About 2.3 points a cell for seven
/// integer columns: a cell's tallies take about 150 bytes, a point's integers 64.
fn tallies_fit(points: u64, area: Option<f64>, cell: f64, (ints, floats): (usize, usize)) -> bool {
    let Some(area) = area else {
        return true;
    };
    let cells = (area / (cell * cell)).max(1.0);
    let table = cells * sums::block_bytes(ints + 1) as f64 / sums::BLOCK as f64;
    let kept = bins::record_bytes(floats + 2 * (ints + 1)) - bins::record_bytes(floats);
    table <= points as f64 * kept as f64
}

/// The cells in key order at the end, with their tallies and kept values: from the table of
/// tallies (and the floats' bins, cell for cell), or from the bins alone, the tallies then
/// made from each cell's kept integers.
struct InOrder {
    sums: Option<SumCells>,
    bins: Option<Cells>,
    /// The current cell's records from the bins, word by word.
    words: Vec<Vec<u32>>,
    /// The float columns among the words (the first ones).
    floats: usize,
    /// Each tally's statistic: the integer columns', then the elevation's mean.
    stats: Vec<Stat>,
}

impl InOrder {
    /// The next cell's key and points, its tallies in `tallies` and its float columns' values
    /// in `values`; None after the last cell.
    fn next(
        &mut self,
        tallies: &mut [Tally],
        values: &mut [Vec<f32>],
    ) -> Result<Option<(u64, u32)>> {
        let tallied = match &mut self.sums {
            Some(s) => match s.next_cell(tallies)? {
                None => return Ok(None),
                some => some,
            },
            None => None,
        };
        let Some(bins) = &mut self.bins else {
            return Ok(tallied);
        };
        let key = bins.next_cell(&mut self.words)?;
        let key = match (key, tallied) {
            (Some(k), Some((t, _))) if k == t => k,
            (Some(k), None) => k,
            (None, None) => return Ok(None),
            _ => {
                return Err(Error::Internal(format!(
                    "the cells' tallies and kept values disagree at {key:?}"
                )))
            }
        };
        for (v, w) in values.iter_mut().zip(&self.words) {
            v.clear();
            v.extend(w.iter().map(|&b| f32::from_bits(b)));
        }
        if tallied.is_some() {
            return Ok(tallied);
        }
        let ints = &self.words[self.floats..];
        let points = ints.first().map_or(0, Vec::len);
        if points > MAX_CELL_POINTS as usize {
            return Err(sums::too_many_in(key));
        }
        for ((t, &stat), pair) in tallies
            .iter_mut()
            .zip(&self.stats)
            .zip(ints.chunks_exact(2))
        {
            *t = stat.empty();
            for (&lo, &hi) in pair[0].iter().zip(&pair[1]) {
                stat.add_all(std::slice::from_mut(t), &[from_words(lo, hi)]);
            }
        }
        Ok(Some((key, points as u32)))
    }
}

/// Where a column's values are kept: the index of its integers or of its floats.
#[derive(Debug, Clone, Copy)]
enum Slot {
    Integers(usize, Integers),
    Floats(usize),
}

impl Rasterizer {
    /// A rasterizer for `request` whose temporary run files go to `scratch`, keeping at most
    /// `budget` bytes of cells and points in memory, for about `points` points over about
    /// `area` square file units (None: unknown).
    pub(crate) fn new(
        request: RasterRequest,
        scratch: &Path,
        budget: u64,
        (points, area): (u64, Option<f64>),
    ) -> Rasterizer {
        let (mut ints, mut floats) = (0, 0);
        let slots = (request.columns.iter())
            .map(|c| match c.integers {
                Some(i) => {
                    ints += 1;
                    Slot::Integers(ints - 1, i)
                }
                None => {
                    floats += 1;
                    Slot::Floats(floats - 1)
                }
            })
            .collect();
        // The integer columns, then the elevation, whose mean shades the quick looks.
        let dense = tallies_fit(points, area, request.cell, (ints, floats));
        let words = floats + if dense { 0 } else { 2 * (ints + 1) };
        let share = if dense && words > 0 {
            budget / 2
        } else {
            budget
        };
        let sums = dense.then(|| CellSums::new(scratch, request.stat, ints + 1, share));
        let bins = (words > 0).then(|| Bins::new(scratch, "points", words, share, points));
        Rasterizer {
            request,
            slots,
            sums,
            bins,
            words: Vec::with_capacity(words),
            lo: None,
            hi: None,
            points: 0,
        }
    }

    /// The request.
    pub(crate) fn request(&self) -> &RasterRequest {
        &self.request
    }

    /// The integer that stands for the elevation `z` in the shading of the quick looks: z in
    /// steps of [`Z_STEP`] file units, tallied exactly like the columns' integers.
    pub(crate) fn z_integer(z: f64) -> i64 {
        const LIMIT: f64 = i32::MAX as f64;
        match z.is_finite() {
            true => (z / Z_STEP).round().clamp(-LIMIT, LIMIT) as i64,
            false => UNDEFINED,
        }
    }

    /// Bins one point at `(x, y)`: `floats` holds its values of the columns that are not of
    /// integers (NaN: undefined), `ints` its oriented integers of the others
    /// ([`Integers::oriented`]; [`UNDEFINED`]: undefined) followed by [`Self::z_integer`] of
    /// its z. `what` names the point for the error when its coordinates have no cell (not
    /// finite, or 2^31 cells away).
    pub(crate) fn push(
        &mut self,
        x: f64,
        y: f64,
        (floats, ints): (&[f32], &[i64]),
        what: &dyn Fn() -> String,
    ) -> Result<()> {
        let Some(c) = Cell::of(x, y, self.request.cell) else {
            return Err(Error::Usage(format!(
                "{}: ({x}, {y}) lies more than 2^31 cells of {} from the origin; use a larger --cell",
                what(),
                length_text(self.request.cell, &self.request.unit)
            )));
        };
        self.lo = Some(self.lo.map_or(c, |l| Cell {
            ix: l.ix.min(c.ix),
            iy: l.iy.min(c.iy),
        }));
        self.hi = Some(self.hi.map_or(c, |h| Cell {
            ix: h.ix.max(c.ix),
            iy: h.iy.max(c.iy),
        }));
        self.points += 1;
        if let Some(s) = &mut self.sums {
            s.add(c.key(), ints, what)?;
        }
        let Some(b) = &mut self.bins else {
            return Ok(());
        };
        self.words.clear();
        self.words.extend(floats.iter().map(|v| v.to_bits()));
        if self.sums.is_none() {
            self.words.extend(ints.iter().flat_map(|&i| words_of(i)));
        }
        b.push(c.key(), &self.words)
    }

    /// Writes one GeoTIFF per column and the point count into the request's directory (made if
    /// missing), each complete or absent, with GDAL's sidecar of each when the keys cannot hold
    /// the CRS ([`sidecar`]). Returns what was written; an error when no point came.
    /// A set `cancel` stops the writing (nothing appears).
    pub(crate) fn finish(self, crs: &RasterCrs, cancel: &AtomicBool) -> Result<RasterSummary> {
        let (Some(lo), Some(hi)) = (self.lo, self.hi) else {
            return Err(Error::Usage("no point to make a raster of".into()));
        };
        let req = self.request;
        check_size(lo, hi, (req.cell, &req.unit), self.points)?;
        let grid = CellGrid::covering(req.cell, lo, hi).ok_or_else(|| {
            Error::Usage(format!(
                "a raster of cells of {} over the points would have more than 2^31 cells on a side; use a larger --cell",
                length_text(req.cell, &req.unit)
            ))
        })?;
        std::fs::create_dir_all(&req.dir).map_err(|e| Error::write(&req.dir, e))?;
        let mut files: Vec<PathBuf> = req
            .columns
            .iter()
            .map(|c| req.dir.join(format!("{}.tif", c.name)))
            .collect();
        files.push(req.dir.join(format!("{COUNT_NAME}.tif")));
        let bands = (req.columns.iter())
            .map(|c| (c.name.as_str(), c.unit.as_str()))
            .chain([(COUNT_NAME, "points")]);
        let writers = (files.iter().zip(bands))
            .map(|(p, band)| GeoTiff::create(p, &grid, crs, band))
            .collect::<Result<Vec<_>>>()?;
        let mut rows = Rows::new(&grid, (writers, self.points), cancel);
        let n = req.columns.len();
        let floats = self.slots.iter().filter(|s| matches!(s, Slot::Floats(_)));
        let mut values: Vec<Vec<f32>> = vec![Vec::new(); floats.count()];
        let mut tallies = vec![Stat::Mean.empty(); n - values.len() + 1];
        let mut cells = InOrder {
            sums: self.sums.map(CellSums::into_cells).transpose()?,
            bins: self.bins.map(Bins::into_cells).transpose()?,
            words: Vec::new(),
            floats: values.len(),
            stats: sums::tally_stats(req.stat, tallies.len()),
        };
        let z = Integers {
            scale: Z_STEP,
            offset: 0.0,
        };
        // The columns' cell values, the point count, then the mean z (shade only).
        let mut cell_values = vec![0.0f32; n + 2];
        let mut count = 0u64;
        while let Some((key, points)) = cells.next(&mut tallies, &mut values)? {
            if count.is_multiple_of(4096) && cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            let cell = Cell::from_key(key);
            let Some((row, col)) = grid.position(cell) else {
                return Err(Error::Internal(format!(
                    "cell {cell:?} outside the raster {grid:?}"
                )));
            };
            let columns = self.slots.iter().zip(&req.columns);
            for ((slot, column), out) in columns.zip(&mut cell_values) {
                *out = match *slot {
                    Slot::Integers(j, ints) => req.stat.tally_value(tallies[j], ints),
                    Slot::Floats(j) => req.stat.reduce(&mut values[j], column.angle),
                };
            }
            cell_values[n] = points as f32;
            cell_values[n + 1] = Stat::Mean.tally_value(tallies[tallies.len() - 1], z);
            rows.put(row, col, &cell_values)?;
            count += 1;
        }
        let (looks, factor) = rows.finish()?;
        files.extend(sidecar::write_all(&files, crs.wkt.as_deref())?);
        let counts = |name: &str| RasterColumn {
            name: name.into(),
            unit: "points".into(),
            signed: false,
            angle: false,
            scale: None,
            integers: None,
        };
        // A count is of points whatever the column: shown as one, on a sequential ramp.
        let mut shown: Vec<(RasterColumn, String)> = match req.stat {
            Stat::Count => (req.columns.iter())
                .map(|c| (counts(&c.name), "points with a value, per cell".into()))
                .collect(),
            stat => (req.columns.iter())
                .map(|c| (c.clone(), format!("cell {stat} of the points")))
                .collect(),
        };
        shown.push((counts(COUNT_NAME), "points per cell".into()));
        files.extend(quick_looks(
            &req.dir,
            &shown,
            looks,
            grid.cell * factor as f64,
        )?);
        Ok(RasterSummary {
            grid,
            unit: req.unit.clone(),
            points: self.points,
            cells: count,
            files,
        })
    }
}

#[cfg(test)]
mod tests;
