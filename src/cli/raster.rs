//! `tilecurv raster`, and the raster options `process` and `assemble` share with it (one
//! definition each: the statistic, the columns).

use std::path::PathBuf;

use super::args::ExecArgs;
use super::{fail, reporter, CANCEL};
use crate::config::{Length, RasterOptions};
use crate::core::raster::Stat;
use crate::progress::say;
use crate::run::raster::{raster, RasterJob};

/// What `--stat` says.
const STAT_HELP: &str = "How a cell's value is formed from the defined values of its points: \
mean (the default; for Aspect the direction of the mean unit vector), median, min, max, or \
count. Undefined values (no-data, NaN) are left out.";

/// What the raster columns' option says.
const COLUMNS_HELP: &str = "The columns to raster, comma-separated, by their names in the file \
(H, K, k1, k2, ProfileCurvature, TangentialCurvature, PlanCurvature, ShapeIndex, Curvedness, \
Slope, Aspect, NormalZ, or any extra dimension or field such as z or intensity). Default: every \
curvature column the file holds (H, K, k1, k2 and the terrain curvatures; not the flags, slope \
or aspect).";

fn parse_stat(s: &str) -> Result<Stat, String> {
    Stat::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Stat::ALL.iter().map(|s| s.name()).collect();
        format!("{s:?} is not a statistic: use one of {}", names.join(", "))
    })
}

/// Column names, as the raster columns' option lists them.
#[derive(Debug, Clone)]
pub(super) struct Names(pub(super) Vec<String>);

fn parse_columns(s: &str) -> Result<Names, String> {
    let v: Vec<String> = s
        .split(',')
        .map(|c| c.trim().to_string())
        .filter(|c| !c.is_empty())
        .collect();
    match v.is_empty() {
        true => Err("name at least one column".into()),
        false => Ok(Names(v)),
    }
}

/// The rasters `process` and `assemble` make of their outputs' columns as they write them.
#[derive(clap::Args, Debug, Clone)]
pub(super) struct RasterOut {
    /// Also write rasters of the outputs' columns with cells of this size (a length with a unit
    /// like --tile: 1m, 0.5m, 3ft, or file units), binned while the outputs are written (no
    /// second read): one float32 GeoTIFF per column and PointCount.tif, as `tilecurv raster`
    /// makes them, with a PNG quick look beside each. Cells are aligned to multiples of the
    /// cell size in the CRS.
    #[arg(long = "raster", value_name = "CELL", value_parser = Length::parse)]
    cell: Option<Length>,

    /// Directory of the rasters (made if missing). Default: beside the output, named after it
    /// with `.rasters` (out.laz -> out.rasters/; an output directory gets rasters/ inside).
    #[arg(long, value_name = "DIR", requires = "cell")]
    raster_dir: Option<PathBuf>,

    #[arg(long = "raster-columns", value_name = "LIST", help = COLUMNS_HELP, requires = "cell", value_parser = parse_columns)]
    raster_columns: Option<Names>,

    #[arg(long = "raster-stat", value_name = "STAT", help = STAT_HELP, default_value = "mean", value_parser = parse_stat)]
    raster_stat: Stat,
}

impl RasterOut {
    /// The rasters asked for, if any.
    pub(super) fn options(&self) -> Option<RasterOptions> {
        Some(RasterOptions {
            cell: self.cell?,
            stat: self.raster_stat,
            columns: self.raster_columns.clone().map(|c| c.0),
            dir: self.raster_dir.clone(),
        })
    }
}

/// `tilecurv raster`.
#[derive(clap::Args, Debug)]
pub(super) struct RasterArgs {
    /// Point files holding the columns: LAS or LAZ (a `tilecurv process` output or any other),
    /// or the other formats `process` reads. Several files are one scene: one raster covers
    /// them all. Never modified.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,

    /// Cell size, with a unit like --tile (1m, 0.5m, 3ft, 3usft) or a bare number in file
    /// units. Cells are aligned to whole multiples of it in the CRS, so the rasters of adjacent
    /// surveys line up.
    #[arg(long, value_parser = Length::parse)]
    cell: Length,

    #[arg(long, help = COLUMNS_HELP, value_parser = parse_columns)]
    columns: Option<Names>,

    #[arg(long, help = STAT_HELP, default_value = "mean", value_parser = parse_stat)]
    stat: Stat,

    /// Output directory (made if missing): one float32 GeoTIFF per column, named after it
    /// (ProfileCurvature.tif, ...), Deflate-compressed, no-data -3.4028235e38, in the input's
    /// CRS, plus PointCount.tif (points per cell). Existing files of those names are replaced.
    #[arg(short, long)]
    output: PathBuf,

    #[command(flatten)]
    exec: ExecArgs,
}

/// Runs `tilecurv raster`.
pub(super) fn run(a: RasterArgs) -> Result<i32, i32> {
    let exec = a.exec.options();
    let reporter = reporter(a.exec.quiet(), exec.progress_json.as_deref())?;
    let job = RasterJob {
        inputs: a.inputs,
        cell: a.cell,
        columns: a.columns.map(|c| c.0),
        stat: a.stat,
        dir: a.output,
    };
    let made = !job.dir.exists();
    let started = std::time::Instant::now();
    let s = raster(
        &job,
        exec.memory_bytes,
        exec.chunk_points,
        &reporter,
        &CANCEL,
    )
    .map_err(|e| {
        if made {
            // A refused run leaves the folder as it was: the directory it made goes if empty.
            let _ = std::fs::remove_dir(&job.dir);
        }
        fail(&e)
    })?;
    if !a.exec.quiet() {
        say!(
            "done: {} points in {} of {}x{} cells of {} ({} rasters) in {:.1} s -> {}",
            s.points,
            s.cells,
            s.grid.width,
            s.grid.height,
            s.grid.cell,
            s.files.len(),
            started.elapsed().as_secs_f64(),
            job.dir.display()
        );
    }
    Ok(super::exit::OK)
}
