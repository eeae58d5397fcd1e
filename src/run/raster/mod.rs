//! `tilecurv raster`: GeoTIFFs of the columns of any point files (tilecurv's outputs or
//! anyone's), one streaming pass over the inputs into the out-of-core binning of
//! `io::raster`. The pieces `process --raster` shares with it (the request, the CRS,
//! the quick looks) are here too.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::config::{ExecOptions, Length, RasterOptions};
use crate::core::raster::Stat;
use crate::error::{Error, Result};
use crate::io::columns::output::OutputColumns;
use crate::io::columns::ColumnSet;
use crate::io::crs_summary::VerticalUnit;
use crate::io::durable::{sweep_dead_temps, tmp_name};
use crate::io::las::extra_bytes;
use crate::io::ply::PlyNames;
use crate::io::raster::geokeys::{source_crs, RasterCrs};
pub use crate::io::raster::RasterSummary;
use crate::io::raster::{known_columns, RasterColumn, RasterRequest, Rasterizer};
use crate::io::source::{declared_bounds, PointSource};
use crate::progress::Reporter;
use crate::run::one_map::{check_one_map, Joined};
use crate::run::prepare::check_distinct_files;
use crate::run::spec::RunSpec;
use read::{column_names, reader, reader_of_later, spelled, tally_integers, Binner, Reader};

mod check;
mod read;

/// A `tilecurv raster` run.
#[derive(Debug, Clone)]
pub struct RasterJob {
    /// The point files.
    pub inputs: Vec<PathBuf>,
    /// The cell size.
    pub cell: Length,
    /// The columns by name (None: every curvature column the first input holds).
    pub columns: Option<Vec<String>>,
    /// How a cell's value is formed.
    pub stat: Stat,
    /// The output directory.
    pub dir: PathBuf,
}

/// Share of the memory budget the binning keeps in memory before it spills sorted runs.
pub(crate) fn binning_budget(memory_bytes: u64, share: u64) -> u64 {
    (memory_bytes / share).max(1 << 20)
}

/// The scratch directory of a run's binning beside its rasters: a temporary name of this
/// process (hidden, removed at the end), after removing those that killed runs of this host
/// left there.
pub(crate) fn scratch_dir(dir: &Path) -> PathBuf {
    const RUNS: &str = "raster-runs";
    sweep_dead_temps(dir, Some(RUNS));
    tmp_name(&dir.join(RUNS))
}

/// Makes the rasters of `job` (`tilecurv raster`). `memory_bytes` bounds the points binned in
/// memory; `chunk` points are read at a time; a set `cancel` stops the run. On an error nothing
/// is written, and the output directory is removed if the run made it and it is empty.
pub fn raster(
    job: &RasterJob,
    memory_bytes: u64,
    chunk: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<RasterSummary> {
    // The check of --chunk-size of every command; a budget of its own (binning spills cells
    // to sorted runs past any budget, where a run of process needs room for its tiles).
    let exec = ExecOptions {
        chunk_points: chunk,
        ..ExecOptions::default()
    };
    exec.validate()?;
    if memory_bytes < MIN_RASTER_BYTES {
        return Err(Error::Usage(format!(
            "--memory {memory_bytes} bytes is too small for rasters: at least 1M"
        )));
    }
    let made = !job.dir.exists();
    let made = made.then_some(job.dir.as_path());
    make_rasters(job, memory_bytes, chunk, reporter, cancel).inspect_err(|_| remove_made(made))
}

/// Removes `made`, a directory a run made, if it is empty: a refused or interrupted run leaves
/// the folder as it was.
fn remove_made(made: Option<&Path>) {
    if let Some(dir) = made {
        let _ = std::fs::remove_dir(dir);
    }
}

/// [`raster`]'s work.
fn make_rasters(
    job: &RasterJob,
    memory_bytes: u64,
    chunk: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<RasterSummary> {
    check_distinct_files(&job.inputs)?;
    let sources = job
        .inputs
        .iter()
        .map(|p| crate::io::source::open(p))
        .collect::<Result<Vec<_>>>()?;
    let Some(first) = sources.first().map(|s| s.as_ref()) else {
        return Err(Error::Usage("raster: name at least one input file".into()));
    };
    let cell = job.cell.in_file_units(first.unit().unit());
    if let Some(w) = cell_in_file_units(first, &job.cell, "--cell") {
        reporter.warn(&w);
    }
    let symbol = unit_symbol(first);
    let mut columns = choose_columns(first, job.columns.as_deref(), &symbol)?;
    check::check_dir(&job.dir, "-o")?;
    let (crs, crs_notes) = check_one_map(&sources, Joined::Rasters)?;
    // Before the grid's check: inputs that may not share a CRS explain an all but empty grid.
    for note in &crs_notes {
        reporter.warn(note);
    }
    check::check_grid(&sources, (cell, &symbol))?;
    let readers = sources
        .iter()
        .map(|s| {
            (columns.iter())
                .map(|c| reader_of_later(s.as_ref(), &c.name))
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    tally_integers(&mut columns, &readers, job.stat);
    let request = RasterRequest {
        cell,
        unit: symbol,
        stat: job.stat,
        dir: job.dir.clone(),
        columns,
    };
    let scratch = scratch_dir(&job.dir);
    let total = sources.iter().map(|s| s.len()).sum();
    let budget = binning_budget(memory_bytes, 2);
    let extent = (total, declared_area(&sources));
    let mut rasterizer = Rasterizer::new(request, &scratch, budget, extent);
    reporter.phase("bin", total);
    for (s, readers) in sources.iter().zip(readers) {
        let binner = Binner::new(readers, &rasterizer);
        bin_source(s.as_ref(), binner, &mut rasterizer, chunk, reporter, cancel)?;
    }
    reporter.finish_phase();
    if let Some(w) = &crs.warning {
        reporter.warn(w);
    }
    reporter.info(&format!("raster CRS: {}", crs.carried()));
    rasterizer.finish(&crs, cancel)
}

/// The area the inputs' points cover by their declared bounds (LAS headers), summed over the
/// inputs; None when one has none. Only the binning's memory depends on it, not the rasters.
fn declared_area(sources: &[Box<dyn PointSource>]) -> Option<f64> {
    sources
        .iter()
        .map(|s| declared_bounds(s.as_ref()).map(|[lo, hi]| (hi[0] - lo[0]) * (hi[1] - lo[1])))
        .sum()
}

/// The symbol of the CRS unit of `s` ("m", "ftUS"), "unit" when it has none.
fn unit_symbol(s: &dyn PointSource) -> String {
    s.unit().unit().map_or("unit".into(), |u| u.symbol())
}

/// The columns to raster: those named (each must be in `s`), or every curvature column `s`
/// holds.
fn choose_columns(
    s: &dyn PointSource,
    names: Option<&[String]>,
    unit: &str,
) -> Result<Vec<RasterColumn>> {
    let known = known_columns(unit);
    let chosen: Vec<RasterColumn> = match names {
        Some(names) => names.iter().map(|n| describe(&known, n, s)).collect(),
        None => known
            .iter()
            .filter(|(k, curvature)| *curvature && reader(s, &k.name).is_some())
            .map(|(k, _)| k.clone())
            .collect(),
    };
    let have = |n: &str| reader(s, n).is_some();
    if let Some(missing) = chosen.iter().find(|c| !have(&c.name)) {
        return Err(Error::Usage(format!(
            "{} has no column {:?}; it has: {}",
            s.path().display(),
            missing.name,
            column_names(s).join(", ")
        )));
    }
    if chosen.is_empty() {
        return Err(Error::Usage(format!(
            "{} holds no curvature column (H, K, k1, k2, ProfileCurvature, ...): run `tilecurv process` on it first, or name the columns with --columns (it has: {})",
            s.path().display(),
            column_names(s).join(", ")
        )));
    }
    check::check_names(&chosen, s.path())?;
    Ok(chosen)
}

/// How the column `name` is shown: as tilecurv's own column of that name (`known`), else on a
/// sequential ramp (a sign means nothing known of another's column, nor of an elevation), in
/// the unit of the file `s` for x and y, its vertical unit for z (the horizontal one where it
/// declares none) and without a unit for the others.
fn describe(known: &[(RasterColumn, bool)], name: &str, s: &dyn PointSource) -> RasterColumn {
    let unit = match name.to_ascii_lowercase().as_str() {
        "x" | "y" => unit_symbol(s),
        "z" => match s.vertical_unit() {
            VerticalUnit::Declared(u) => u.symbol(),
            _ => unit_symbol(s),
        },
        _ => String::new(),
    };
    // Named as the file names it (`Z` as `z`), as tilecurv's own columns are, even as a PLY
    // output names them (`scalar_H`, read as `H`).
    let spelling = spelled(s, name);
    let name = spelling.as_deref().unwrap_or(name);
    known
        .iter()
        .find(|(k, _)| k.name == name || PlyNames::CloudCompare.name(&k.name) == name)
        .map(|(k, _)| k.clone())
        .unwrap_or_else(|| RasterColumn {
            name: name.to_string(),
            unit,
            signed: false,
            angle: false,
            scale: None,
            integers: None,
        })
}

/// Bins every point of `s`.
fn bin_source(
    s: &dyn PointSource,
    mut binner: Binner,
    r: &mut Rasterizer,
    chunk: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let rl = s.record_length();
    let what = |id: u64| format!("{} point {id}", s.path().display());
    s.for_each_chunk(chunk, &mut |first, records| {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        binner.bin_all(s, (first, records, rl), r, &what)?;
        reporter.advance((records.len() / rl) as u64);
        Ok(())
    })
}

/// The default directory of the rasters of `outputs`: beside a single output, named after it
/// with `.rasters` (out.laz -> out.rasters/), else `rasters/` beside the outputs.
pub(crate) fn default_dir(outputs: &[PathBuf]) -> PathBuf {
    match outputs {
        [one] => one.with_extension("rasters"),
        _ => outputs
            .first()
            .map_or_else(|| PathBuf::from("rasters"), |o| o.with_file_name("rasters")),
    }
}

/// The columns `process --raster` rasters of outputs with the columns `cols` of the input
/// `first`: those `opts` names (the new columns, or the input's own), else every curvature
/// column among the new ones.
fn output_raster_columns(
    opts: &RasterOptions,
    cols: &ColumnSet,
    first: &dyn PointSource,
) -> Result<Vec<RasterColumn>> {
    let known = known_columns(&cols.unit);
    let written: Vec<&str> = cols.columns().iter().map(|c| c.name).collect();
    let columns: Vec<RasterColumn> = match &opts.columns {
        Some(names) => names
            .iter()
            .map(|n| {
                let known_here = known.iter().find(|(k, _)| k.name.eq_ignore_ascii_case(n));
                match known_here {
                    Some((k, _)) if written.contains(&k.name.as_str()) => Ok(k.clone()),
                    _ if reader(first, n).is_some() => Ok(describe(&known, n, first)),
                    _ => Err(Error::Usage(format!(
                        "--raster-columns {n}: the outputs have no such column; they have {}, and the input's {}",
                        written.join(", "),
                        column_names(first).join(", ")
                    ))),
                }
            })
            .collect::<Result<_>>()?,
        None => known
            .into_iter()
            .filter(|(k, curvature)| *curvature && written.contains(&k.name.as_str()))
            .map(|(k, _)| k)
            .collect(),
    };
    if columns.is_empty() {
        return Err(Error::Usage(format!(
            "--raster: none of the outputs' new columns ({}) is a curvature column; add some with --columns (H, K, terrain, ...) or name the columns to raster with --raster-columns",
            written.join(", ")
        )));
    }
    check::check_names(&columns, first.path())?;
    Ok(columns)
}

/// The least memory budget of `tilecurv raster`: cells past it go to sorted runs on disk, and a
/// smaller budget would make a run of a handful of cells.
const MIN_RASTER_BYTES: u64 = 1 << 20;

/// The warning that the cell `cell` (given by `option`), which has a unit, is taken in the file
/// units of `first`, which has no CRS unit.
fn cell_in_file_units(first: &dyn PointSource, cell: &Length, option: &str) -> Option<String> {
    (cell.has_unit() && first.unit().unit().is_none()).then(|| {
        format!(
            "{} has no CRS unit: {option} {cell} is taken in file units",
            first.path().display()
        )
    })
}

/// Checks the rasters `opts` asks of the run `spec` before any work (run by every command that
/// runs a stage, so that a dry run checks them too): their columns, their directory and the
/// grid's size by the declared bounds (the inputs' CRSs were checked when the run was
/// resolved: `run::one_map`). The same failures found only once the outputs are written would
/// have cost the whole run. Warns through `reporter` of a cell taken in file units.
pub(crate) fn check_output_rasters(
    opts: &RasterOptions,
    spec: &RunSpec,
    reporter: &dyn Reporter,
) -> Result<()> {
    let Some(first) = spec.sources.first().map(|s| s.as_ref()) else {
        return Err(Error::Usage("raster: name at least one input file".into()));
    };
    if let Some(w) = cell_in_file_units(first, &opts.cell, "--raster") {
        reporter.warn(&w);
    }
    output_raster_columns(opts, &spec.cols, first)?;
    let dir = opts
        .dir
        .clone()
        .unwrap_or_else(|| default_dir(&spec.outputs));
    check::check_dir(&dir, "--raster-dir")?;
    let cell = opts.cell.in_file_units(first.unit().unit());
    check::check_grid(&spec.sources, (cell, &spec.cols.unit))
}

/// The rasters of a run's outputs (`process --raster`, `assemble --raster`), binned from each
/// output record as it is written.
pub(crate) struct OutputRasters {
    rasterizer: Rasterizer,
    crs: RasterCrs,
    /// Per output, the readers of its records' raster columns (taken by its tap).
    readers: Vec<Vec<Reader>>,
    /// The directory the rasters go to, if the run makes it.
    made: Option<PathBuf>,
}

impl OutputRasters {
    /// The rasters `opts` asks for of outputs with the columns `cols` (the run's), from the
    /// inputs `sources`, whose outputs store the new columns as `outs` say (one each), into
    /// `dir`; `memory_bytes` bounds the points binned in memory.
    pub(crate) fn new(
        opts: &RasterOptions,
        cols: &ColumnSet,
        (sources, outs): (&[Box<dyn PointSource>], &[OutputColumns]),
        dir: PathBuf,
        memory_bytes: u64,
    ) -> Result<OutputRasters> {
        let Some(first) = sources.first().map(|s| s.as_ref()) else {
            return Err(Error::Usage("raster: name at least one input file".into()));
        };
        let cell = opts.cell.in_file_units(first.unit().unit());
        let mut columns = output_raster_columns(opts, cols, first)?;
        let readers = (sources.iter().zip(outs))
            .map(|(s, out)| output_readers(&columns, s.as_ref(), out))
            .collect::<Result<Vec<_>>>()?;
        tally_integers(&mut columns, &readers, opts.stat);
        let request = RasterRequest {
            cell,
            unit: cols.unit.clone(),
            stat: opts.stat,
            dir: dir.clone(),
            columns,
        };
        let scratch = scratch_dir(&dir);
        let points = sources.iter().map(|s| s.len()).sum();
        let budget = binning_budget(memory_bytes, 4);
        let extent = (points, declared_area(sources));
        Ok(OutputRasters {
            rasterizer: Rasterizer::new(request, &scratch, budget, extent),
            crs: source_crs(first),
            readers,
            made: (!dir.exists()).then_some(dir),
        })
    }

    /// The tap of output `i`, of the input `source`: its records are the input's followed by
    /// its new columns.
    pub(crate) fn tap<'a>(
        &'a mut self,
        i: usize,
        source: &'a dyn PointSource,
        out: &OutputColumns,
    ) -> Result<Tap<'a>> {
        let readers = (self.readers.get_mut(i).map(std::mem::take))
            .ok_or_else(|| Error::Internal(format!("no raster readers for output {i}")))?;
        Ok(Tap {
            binner: Binner::new(readers, &self.rasterizer),
            row: source.record_length() + out.record_size(),
            source,
            rasterizer: &mut self.rasterizer,
        })
    }

    /// Writes the rasters and their quick looks; a set `cancel` stops it.
    pub(crate) fn finish(
        self,
        reporter: &dyn Reporter,
        cancel: &AtomicBool,
    ) -> Result<RasterSummary> {
        if let Some(w) = &self.crs.warning {
            reporter.warn(w);
        }
        (self.rasterizer.finish(&self.crs, cancel))
            .inspect_err(|_| remove_made(self.made.as_deref()))
    }
}

/// The readers of `columns` in the records of an output of `source` with the new columns
/// `out`: a column is read from the new columns, else from the input's record (a field or an
/// extra dimension of the input, such as z or intensity).
fn output_readers(
    columns: &[RasterColumn],
    source: &dyn PointSource,
    out: &OutputColumns,
) -> Result<Vec<Reader>> {
    // The new columns as a reader of the output file sees them: their descriptors encoded as
    // the writer encodes them and parsed as any LAS input's are.
    let encoded: Vec<u8> = out
        .descriptors()
        .iter()
        .flat_map(extra_bytes::encode)
        .collect();
    let new_columns = extra_bytes::parse(&encoded)
        .map_err(|why| Error::Internal(format!("the output's own descriptors: {why}")))?;
    let rl = source.record_length();
    (columns.iter())
        .map(|c| match new_columns.iter().find(|d| d.name == c.name) {
            Some(d) => Ok(Reader::Extra {
                at: rl,
                d: d.clone(),
            }),
            None => reader_of_later(source, &c.name),
        })
        .collect()
}

/// Bins the records of one output as they are written.
pub(crate) struct Tap<'a> {
    rasterizer: &'a mut Rasterizer,
    source: &'a dyn PointSource,
    /// The raster columns' readers of an output record.
    binner: Binner,
    /// Bytes of an output record (the input's record and the new columns).
    row: usize,
}

impl Tap<'_> {
    /// Bins every output record in `records` (whole records, in order).
    pub(crate) fn feed(&mut self, records: &[u8]) -> Result<()> {
        let what = |_| format!("a point of {}", self.source.path().display());
        let records = (0, records, self.row);
        (self.binner).bin_all(self.source, records, self.rasterizer, &what)
    }
}
