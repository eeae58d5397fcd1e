//! `tilecurv raster`: GeoTIFFs of the columns of any point files (tilecurv's outputs or
//! anyone's), one streaming pass over the inputs into the out-of-core binning of
//! `io::raster`. The pieces `process --raster` shares with it (the request, the CRS,
//! the quick looks) are here too.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::config::{Length, RasterOptions};
use crate::core::raster::Stat;
use crate::error::{Error, Result};
use crate::io::columns::output::OutputColumns;
use crate::io::columns::ColumnSet;
use crate::io::durable::{sweep_dead_temps, tmp_name};
use crate::io::las::extra_bytes::{self, Descriptor, ScalarType};
use crate::io::las::header::POINT_FORMAT_SIZES;
use crate::io::raster::geokeys::{raster_crs, RasterCrs};
pub use crate::io::raster::RasterSummary;
use crate::io::raster::{known_columns, RasterColumn, RasterRequest, Rasterizer};
use crate::io::source::{PointSource, Property, SourceLayout};
use crate::progress::Reporter;

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
    let made = !job.dir.exists();
    make_rasters(job, memory_bytes, chunk, reporter, cancel).inspect_err(|_| {
        if made {
            // A refused run leaves the folder as it was: the directory it made goes if empty.
            let _ = std::fs::remove_dir(&job.dir);
        }
    })
}

/// [`raster`]'s work.
fn make_rasters(
    job: &RasterJob,
    memory_bytes: u64,
    chunk: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<RasterSummary> {
    let sources = job
        .inputs
        .iter()
        .map(|p| crate::io::source::open(p))
        .collect::<Result<Vec<_>>>()?;
    let Some(first) = sources.first().map(|s| s.as_ref()) else {
        return Err(Error::Usage("raster: name at least one input file".into()));
    };
    let unit = first.unit();
    let cell = job.cell.in_file_units(unit.unit());
    if job.cell.has_unit() && unit.unit().is_none() {
        reporter.warn(&format!(
            "{} has no CRS unit: --cell {} is taken in file units",
            first.path().display(),
            job.cell
        ));
    }
    let symbol = unit.unit().map_or("unit".into(), |u| u.symbol());
    let columns = choose_columns(first, job.columns.as_deref(), &symbol)?;
    let request = RasterRequest {
        cell,
        stat: job.stat,
        dir: job.dir.clone(),
        columns,
    };
    let scratch = scratch_dir(&job.dir);
    let total = sources.iter().map(|s| s.len()).sum();
    let budget = binning_budget(memory_bytes, 2);
    let mut rasterizer = Rasterizer::new(request, &scratch, budget, total);
    reporter.phase("bin", total);
    for s in &sources {
        bin_source(s.as_ref(), &mut rasterizer, chunk, reporter, cancel)?;
    }
    reporter.finish_phase();
    let crs = source_crs(first);
    if let Some(w) = &crs.warning {
        reporter.warn(w);
    }
    warn_other_crs(&sources, &crs, reporter);
    reporter.info(&format!("raster CRS: {}", crs.described));
    rasterizer.finish(&crs, cancel)
}

/// Warns about each input whose CRS is not the first's: one raster takes the first's.
fn warn_other_crs(sources: &[Box<dyn PointSource>], crs: &RasterCrs, reporter: &dyn Reporter) {
    for s in sources.iter().skip(1) {
        let other = source_crs(s.as_ref());
        if other.directory != crs.directory {
            reporter.warn(&format!(
                "{} has another CRS ({}) than the first input ({}): the rasters are in the first's, and this file's points are placed by their coordinates as they are",
                s.path().display(),
                other.described,
                crs.described
            ));
        }
    }
}

/// The raster CRS of a source: its LAS CRS ([`raster_crs`]); none for other formats.
pub(crate) fn source_crs(s: &dyn PointSource) -> RasterCrs {
    match s.layout() {
        SourceLayout::Las(p) => {
            let h = p.header;
            let records = p.vlrs.iter().chain(p.evlrs.iter().map(|(_, v)| v));
            raster_crs(records, h.version.1 >= 4 && h.global_encoding & 0x10 != 0)
        }
        SourceLayout::Converted => raster_crs(std::iter::empty(), false),
    }
}

/// Where a column's value is in a record.
enum Reader {
    /// A LAS extra dimension (its no-data value gives NaN).
    Extra { at: usize, d: Descriptor },
    /// Any other property.
    Property(Property),
}

impl Reader {
    /// The value of each record of `records` (`row` bytes each) into column `c` of `values`
    /// (rows of `width`), NaN where it is missing or no-data.
    fn column(&self, records: &[u8], row: usize, values: &mut [f32], (c, width): (usize, usize)) {
        fn each(
            records: &[u8],
            row: usize,
            values: &mut [f32],
            (c, width): (usize, usize),
            read: impl Fn(&[u8]) -> f64,
        ) {
            for (rec, v) in records
                .chunks_exact(row)
                .zip(values.chunks_exact_mut(width))
            {
                v[c] = read(rec) as f32;
            }
        }
        let place = (c, width);
        let (at, d) = match self {
            Reader::Property(p) => return each(records, row, values, place, |r| p.value(r)),
            Reader::Extra { at, d } => (*at, d),
        };
        let extra = |r: &[u8], t| {
            r.get(at..)
                .and_then(|e| d.read_as(t, e))
                .unwrap_or(f64::NAN)
        };
        // The type fixed in each loop (the types tilecurv writes, and f64); any other as read.
        match d.scalar() {
            Some(ScalarType::I32) => {
                each(records, row, values, place, |r| extra(r, ScalarType::I32))
            }
            Some(ScalarType::I16) => {
                each(records, row, values, place, |r| extra(r, ScalarType::I16))
            }
            Some(ScalarType::F32) => {
                each(records, row, values, place, |r| extra(r, ScalarType::F32))
            }
            Some(ScalarType::F64) => {
                each(records, row, values, place, |r| extra(r, ScalarType::F64))
            }
            Some(t) => each(records, row, values, place, |r| extra(r, t)),
            None => each(records, row, values, place, |_| f64::NAN),
        }
    }
}

/// The reader of the column `name` in `s` (names compare without case).
fn reader(s: &dyn PointSource, name: &str) -> Option<Reader> {
    if let SourceLayout::Las(p) = s.layout() {
        let base = POINT_FORMAT_SIZES[p.header.point_format as usize] as usize;
        if let Some(d) = p.extra.iter().find(|d| d.name.eq_ignore_ascii_case(name)) {
            return d.scalar().map(|_| Reader::Extra {
                at: base,
                d: d.clone(),
            });
        }
    }
    s.properties()
        .into_iter()
        .find(|p| p.name.eq_ignore_ascii_case(name))
        .map(Reader::Property)
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
        Some(names) => names.iter().map(|n| describe(&known, n)).collect(),
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
    Ok(chosen)
}

/// How the column `name` is shown: as tilecurv's own column of that name (`known`), else as a
/// signed quantity without a unit.
fn describe(known: &[(RasterColumn, bool)], name: &str) -> RasterColumn {
    known
        .iter()
        .find(|(k, _)| k.name.eq_ignore_ascii_case(name))
        .map(|(k, _)| k.clone())
        .unwrap_or_else(|| RasterColumn {
            name: name.to_string(),
            unit: String::new(),
            signed: true,
            angle: false,
        })
}

/// The reader of the column `name` of a later input `s`, or the error that it lacks one the
/// first input has.
fn reader_of_later(s: &dyn PointSource, name: &str) -> Result<Reader> {
    reader(s, name).ok_or_else(|| {
        Error::Usage(format!(
            "{} has no column {name:?} (the first input has it); it has: {}",
            s.path().display(),
            column_names(s).join(", ")
        ))
    })
}

/// The names of the columns of `s`.
fn column_names(s: &dyn PointSource) -> Vec<String> {
    s.properties().into_iter().map(|p| p.name).collect()
}

/// Bins every point of `s`.
fn bin_source(
    s: &dyn PointSource,
    r: &mut Rasterizer,
    chunk: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let readers = r
        .request()
        .columns
        .iter()
        .map(|c| reader_of_later(s, &c.name))
        .collect::<Result<Vec<_>>>()?;
    let mut binner = Binner::new(readers);
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

/// Reads points' raster values from their records and bins them: the one path of `raster`'s
/// inputs and of `process --raster`'s output records.
struct Binner {
    /// Per raster column, where its value is in a record and how it is stored.
    readers: Vec<Reader>,
    /// The values of the points being binned, a row each: one a column, then z (for the
    /// hillshade).
    values: Vec<f32>,
    /// Their coordinates.
    xyz: Vec<[f64; 3]>,
}

impl Binner {
    fn new(readers: Vec<Reader>) -> Self {
        Binner {
            readers,
            values: Vec::new(),
            xyz: Vec::new(),
        }
    }

    /// Bins the points of `s` whose records, `row` bytes each (the source's record first, then
    /// any columns an output added), are `records`; the first is point `first`. Column by
    /// column over [`Binner::BATCH`] points at a time, each column in a loop made for its
    /// stored type: point by point, choosing the type of every value again cost more than
    /// binning it. `what` names a point in an error.
    fn bin_all(
        &mut self,
        s: &dyn PointSource,
        (first, records, row): (u64, &[u8], usize),
        r: &mut Rasterizer,
        what: &dyn Fn(u64) -> String,
    ) -> Result<()> {
        let width = self.readers.len() + 1;
        for (b, batch) in records.chunks(Self::BATCH * row).enumerate() {
            let first = first + (b * Self::BATCH) as u64;
            let n = batch.len() / row;
            self.values.resize(n * width, 0.0);
            self.xyz.clear();
            s.coordinates(first, batch, row, &mut self.xyz);
            for (p, v) in self.xyz.iter().zip(self.values.chunks_exact_mut(width)) {
                v[width - 1] = p[2] as f32;
            }
            for (c, rd) in self.readers.iter().enumerate() {
                rd.column(batch, row, &mut self.values, (c, width));
            }
            let points = self.xyz.iter().zip(self.values.chunks_exact(width));
            for (i, (p, v)) in points.enumerate() {
                r.push(p[0], p[1], v, &|| what(first + i as u64))?;
            }
        }
        Ok(())
    }

    /// Points decoded at a time: their records (about 100 bytes each with the terrain columns)
    /// and values stay in the first-level cache between the columns (4096 did not: a miss for
    /// every record in every column's loop, 12 a point more than a run without rasters).
    const BATCH: usize = 256;
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

/// The rasters of a run's outputs (`process --raster`, `assemble --raster`), binned from each
/// output record as it is written.
pub(crate) struct OutputRasters {
    rasterizer: Rasterizer,
    crs: RasterCrs,
}

impl OutputRasters {
    /// The rasters `opts` asks for of outputs with the columns `cols` (the run's), from the
    /// inputs `sources`, into `dir`; `memory_bytes` bounds the points binned in memory.
    pub(crate) fn new(
        opts: &RasterOptions,
        cols: &ColumnSet,
        sources: &[Box<dyn PointSource>],
        dir: PathBuf,
        memory_bytes: u64,
    ) -> Result<OutputRasters> {
        let Some(first) = sources.first().map(|s| s.as_ref()) else {
            return Err(Error::Usage("raster: name at least one input file".into()));
        };
        let cell = opts.cell.in_file_units(first.unit().unit());
        let known = known_columns(&cols.unit);
        let written: Vec<&str> = cols.columns().iter().map(|c| c.name).collect();
        let columns: Vec<RasterColumn> = match &opts.columns {
            Some(names) => names
                .iter()
                .map(|n| {
                    let known_here = known.iter().find(|(k, _)| k.name.eq_ignore_ascii_case(n));
                    match known_here {
                        Some((k, _)) if written.contains(&k.name.as_str()) => Ok(k.clone()),
                        _ if reader(first, n).is_some() => Ok(describe(&known, n)),
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
                "--raster: the outputs hold no curvature column ({}); add some with --columns or name them with --raster-columns",
                written.join(", ")
            )));
        }
        let request = RasterRequest {
            cell,
            stat: opts.stat,
            dir: dir.clone(),
            columns,
        };
        let scratch = scratch_dir(&dir);
        let points = sources.iter().map(|s| s.len()).sum();
        let budget = binning_budget(memory_bytes, 4);
        Ok(OutputRasters {
            rasterizer: Rasterizer::new(request, &scratch, budget, points),
            crs: source_crs(first),
        })
    }

    /// The tap of one output: its records are `source`'s followed by `out`'s columns. A
    /// raster column is read from the new columns, else from the input's record (a field or
    /// an extra dimension of the input, such as z or intensity).
    pub(crate) fn tap<'a>(
        &'a mut self,
        source: &'a dyn PointSource,
        out: &OutputColumns,
    ) -> Result<Tap<'a>> {
        let names: Vec<String> = (self.rasterizer.request().columns.iter())
            .map(|c| c.name.clone())
            .collect();
        // The new columns as a reader of the output file sees them: their descriptors encoded
        // as the writer encodes them and parsed as any LAS input's are.
        let encoded: Vec<u8> = out
            .descriptors()
            .iter()
            .flat_map(extra_bytes::encode)
            .collect();
        let new_columns = extra_bytes::parse(&encoded)
            .map_err(|why| Error::Internal(format!("the output's own descriptors: {why}")))?;
        let rl = source.record_length();
        let readers = names
            .iter()
            .map(|n| match new_columns.iter().find(|d| d.name == *n) {
                Some(d) => Ok(Reader::Extra {
                    at: rl,
                    d: d.clone(),
                }),
                None => reader_of_later(source, n),
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Tap {
            binner: Binner::new(readers),
            row: rl + out.record_size(),
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
        self.rasterizer.finish(&self.crs, cancel)
    }
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
