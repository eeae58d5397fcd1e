//! The arguments of each command, in groups shared between commands: the options that change
//! the output ([`RunOptions`], defined once in the option table of `config::options`) and the
//! ones that only change how a run executes ([`ExecArgs`]), and their conversion into the
//! validated run.

use std::path::PathBuf;

use crate::config::{parse_count, ExecOptions, Length, RasterOptions, RunOptions, RunParams};
use crate::core::raster::Stat;
use crate::error::{Error, Result};
use crate::run::Process;

/// The options that change how a run executes, never its output.
#[derive(clap::Args, Debug, Clone)]
pub(super) struct ExecArgs {
    /// Memory budget: 2G, 512M, ... (K, M, G = powers of 1024). It holds the buckets and tiles in
    /// flight, and the raster cells being binned; past it, buckets spill to the work directory
    /// (zstd) and raster cells to sorted runs beside the rasters. Default: half the machine's memory,
    /// at most 4G; lowered (with a message) to what `ulimit -v` leaves beside the mapped inputs
    /// and what the cgroup's memory limit leaves; at least 64M (1M for `tilecurv raster`). The
    /// program itself adds about 60M.
    #[arg(long, value_parser = crate::config::parse_bytes)]
    memory: Option<u64>,

    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,

    /// Points read per chunk when streaming the input. Results do not depend on it.
    #[arg(long = "chunk-size", default_value_t = 1_000_000)]
    chunk_points: usize,

    /// Append one JSON line per tile and per phase to FILE, `-` for standard output (event,
    /// phase, done and total points, points/s, the phase's and the whole run's ETA in seconds),
    /// for a scheduler or a dashboard; the last line is a `summary` event (points, undefined,
    /// tiles, tiles_resumed, retried, outputs, wall_s).
    #[arg(long, value_name = "FILE")]
    progress_json: Option<PathBuf>,

    /// Print only warnings and errors.
    #[arg(short, long)]
    quiet: bool,
}

/// `tilecurv process`.
#[derive(clap::Args, Debug)]
pub(super) struct ProcessArgs {
    /// Input point clouds: LAS or LAZ (LAS 1.0-1.4, point formats 0-10, COPC-LAZ), PLY, XYZ
    /// text (.xyz, .pts, .txt), PCD, or the vertices of OFF and OBJ meshes. Several inputs are
    /// one scene (adjacent tiles of a survey: neighbourhoods cross file borders) and give one
    /// output each. Never modified.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,

    /// Output file, or a directory (end it with /) for several inputs, where each output gets
    /// its input's file name. The extension chooses the format: .las, .laz, .ply (binary) or
    /// .ascii.ply. Holds every input point in the same order with its original fields (LAS/LAZ:
    /// every byte of the records, the VLRs and EVLRs; PLY of a LAS input: every standard field
    /// under laspy's names, the scan angle in degrees, and the scalar extra dimensions), plus
    /// the columns H (mean curvature), K (Gaussian) and CurvatureFlags and, as --columns asks,
    /// NormalX/Y/Z, k1 <= k2 (principal), d1x..d2z (also --directions), SharpFeature and
    /// VcmNormalX/Y/Z (also --features) and the terrain columns. Curvature is positive where
    /// the surface bends away from its normal (hilltops with upward normals), in
    /// 1/(horizontal unit of the file's CRS).
    #[arg(short, long)]
    output: PathBuf,

    #[command(flatten)]
    result: RunOptions,

    #[command(flatten)]
    exec: ExecArgs,

    #[command(flatten)]
    rasters: RasterOut,

    /// Print the plan (tiles, expected peak memory, work-directory disk, estimated run time from
    /// timing the median tile) and stop. Scans the inputs once.
    #[arg(long)]
    dry_run: bool,

    /// Work directory for buckets and per-tile results (default: `.<output name>.tilecurv` beside
    /// the output). Kept when a run is interrupted or fails, so that the same command resumes
    /// from the finished tiles; removed after success. Work from other inputs or parameters is
    /// detected and discarded. A new or empty folder, or one a tilecurv run left: a folder
    /// holding other files is refused, never emptied, and so are outputs inside it.
    #[arg(long)]
    work_dir: Option<PathBuf>,
}

/// Worker threads: `--threads`, else SLURM_CPUS_PER_TASK (set by `sbatch -c N`), else every
/// core.
fn default_threads(threads: Option<usize>) -> usize {
    threads
        .or_else(|| {
            std::env::var("SLURM_CPUS_PER_TASK")
                .ok()
                .and_then(|v| v.trim().parse().ok())
                .filter(|&n: &usize| n > 0)
        })
        .unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
        })
}

impl ExecArgs {
    /// Whether only warnings and errors are printed.
    pub(super) fn quiet(&self) -> bool {
        self.quiet
    }

    /// The execution settings.
    pub(super) fn options(&self) -> ExecOptions {
        let defaults = ExecOptions::default();
        ExecOptions {
            memory_bytes: self.memory.unwrap_or(defaults.memory_bytes),
            threads: default_threads(self.threads),
            chunk_points: self.chunk_points,
            progress_json: self.progress_json.clone(),
            rasters: None,
        }
    }
}

impl ProcessArgs {
    /// Whether only warnings and errors are printed.
    pub(super) fn quiet(&self) -> bool {
        self.exec.quiet
    }

    /// The execution settings, with the rasters asked for.
    pub(super) fn exec(&self) -> ExecOptions {
        ExecOptions {
            rasters: self.rasters.options(),
            ..self.exec.options()
        }
    }

    /// The run, validated.
    pub(super) fn into_process(self) -> Result<Process> {
        let mut job = Process::new(self.inputs, self.output, self.result)?;
        job.dry_run = self.dry_run;
        job.work_dir = self.work_dir;
        Ok(job)
    }
}

/// `tilecurv plan`.
#[derive(clap::Args, Debug)]
pub(super) struct PlanArgs {
    /// Input point clouds: LAS or LAZ (LAS 1.0-1.4, point formats 0-10, COPC-LAZ), PLY, XYZ
    /// text (.xyz, .pts, .txt), PCD, or the vertices of OFF and OBJ meshes. Several inputs are
    /// one scene (adjacent tiles of a survey: neighbourhoods cross file borders) and give one
    /// output each. Never modified.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,

    /// The work directory (created if needed): on a file system every node sees at the same
    /// path. Work left there from other inputs or options is discarded. A new or empty folder,
    /// or one a tilecurv run left: a folder holding other files is refused, never emptied.
    #[arg(long)]
    pub work: PathBuf,

    #[command(flatten)]
    result: RunOptions,

    /// Tiles of the grid over the inputs' bounds per tile task (1: one task per tile). Default:
    /// as few as keep the tasks within 1000 (Slurm's default MaxArraySize is 1001).
    #[arg(long, value_name = "N")]
    pub tiles_per_task: Option<u64>,

    /// Points of one input per bucket task: 50M, 2e7, 1000000 (k, M, G = powers of ten). A
    /// larger LAS input is scanned by several tasks, split between records; a larger LAZ input
    /// between its compressed chunks (LASzip writes 50,000 points a chunk), so a task holds
    /// about N points, give or take a chunk. PLY, XYZ, PCD, OFF and OBJ inputs are read from
    /// their start and stay one task each, whatever their size. Default: 50M, so that a
    /// 1e10-point file is 200 tasks of about a minute on one core each while a delivered
    /// survey tile stays one. The output does not depend on it.
    #[arg(long, value_name = "N", value_parser = parse_count)]
    pub points_per_scan_task: Option<u64>,

    /// Print only warnings and errors (the task counts are always printed).
    #[arg(short, long)]
    pub quiet: bool,
}

impl PlanArgs {
    /// The inputs as absolute paths, since the tasks run elsewhere (another directory, another
    /// node).
    pub(super) fn inputs(&self) -> Vec<PathBuf> {
        self.inputs
            .iter()
            .map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone()))
            .collect()
    }

    /// The options, validated.
    pub(super) fn params(&self) -> Result<RunParams> {
        RunParams::new(self.result.clone())
    }
}

/// A task index, or `env`: read from the scheduler's environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TaskArg {
    /// This index.
    Index(u64),
    /// TILECURV_TASK, SLURM_ARRAY_TASK_ID, AWS_BATCH_JOB_ARRAY_INDEX or JOB_COMPLETION_INDEX,
    /// the first that is set.
    Env,
}

/// The variables `--task env` reads, in order.
pub(super) const TASK_VARIABLES: [&str; 4] = [
    "TILECURV_TASK",
    "SLURM_ARRAY_TASK_ID",
    "AWS_BATCH_JOB_ARRAY_INDEX",
    "JOB_COMPLETION_INDEX",
];

impl TaskArg {
    /// Parses a task index or `env`.
    pub(super) fn parse(s: &str) -> std::result::Result<Self, String> {
        if s == "env" {
            return Ok(TaskArg::Env);
        }
        s.parse()
            .map(TaskArg::Index)
            .map_err(|_| format!("{s:?}: expected a task index (0, 1, ...) or `env`"))
    }

    /// The index.
    pub(super) fn resolve(self) -> Result<u64> {
        match self {
            TaskArg::Index(i) => Ok(i),
            TaskArg::Env => {
                for v in TASK_VARIABLES {
                    if let Ok(s) = std::env::var(v) {
                        return s.trim().parse().map_err(|_| {
                            Error::Usage(format!("--task env: {v}={s:?} is not a task index"))
                        });
                    }
                }
                Err(Error::Usage(format!(
                    "--task env: none of {} is set; give the index with --task I",
                    TASK_VARIABLES.join(", ")
                )))
            }
        }
    }
}

/// `tilecurv bucket`.
#[derive(clap::Args, Debug)]
pub(super) struct BucketArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// The bucket task to run (one per input file or range of points of a large one, 0 to
    /// `bucket tasks` - 1 as `plan` printed), or `env` for the scheduler's array index. Without it, every bucket task not done yet.
    #[arg(long, value_parser = TaskArg::parse)]
    pub task: Option<TaskArg>,

    #[command(flatten)]
    pub exec: ExecArgs,
}

/// `tilecurv run-tile`.
#[derive(clap::Args, Debug)]
pub(super) struct RunTileArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// The tile task to run (0 to `tasks` - 1 as `plan` printed), or `env`: TILECURV_TASK,
    /// SLURM_ARRAY_TASK_ID, AWS_BATCH_JOB_ARRAY_INDEX or JOB_COMPLETION_INDEX.
    #[arg(long, value_parser = TaskArg::parse)]
    pub task: TaskArg,

    #[command(flatten)]
    pub exec: ExecArgs,
}

/// `tilecurv status`.
#[derive(clap::Args, Debug)]
pub(super) struct StatusArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// Print only the missing tile task indices in Slurm `--array=` syntax (`3,7-9`), nothing
    /// when every task is done.
    #[arg(long)]
    pub missing: bool,
}

/// `tilecurv assemble`.
#[derive(clap::Args, Debug)]
pub(super) struct AssembleArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// Output file, or a directory (end it with /) for several inputs, where each output gets
    /// its input's file name. The extension chooses the format: .las, .laz, .ply (binary) or
    /// .ascii.ply. Holds every input point in the same order with its original fields (as
    /// `process --output` says), plus the columns the plan's --columns chose (by default H, K
    /// and CurvatureFlags). Curvature is positive where the surface bends away from its normal
    /// (hilltops with upward normals), in 1/(horizontal unit of the file's CRS).
    #[arg(short, long)]
    pub output: PathBuf,

    #[command(flatten)]
    pub exec: ExecArgs,

    #[command(flatten)]
    pub rasters: RasterOut,
}

/// `tilecurv info`.
#[derive(clap::Args, Debug)]
pub(super) struct InfoArgs {
    /// Point cloud files (any format `process` reads).
    #[arg(required = true, num_args = 1..)]
    pub files: Vec<PathBuf>,

    /// Print a JSON array with one object per file instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What `--stat` says.
const STAT_HELP: &str = "How a cell's value is formed from the defined values of its points: \
mean (the default; for Aspect the direction of the mean unit vector), median, min, max (for \
Aspect, of the angles unwrapped to within 180 degrees of that direction), or count. Undefined \
values (no-data, NaN) are left out; a cell without a defined value is no-data (count: 0).";

/// What the raster columns' option says.
const COLUMNS_HELP: &str = "The columns to raster, comma-separated, by their names in the file \
(H, K, k1, k2, ProfileCurvature, TangentialCurvature, PlanCurvature, ShapeIndex, Curvedness, \
Slope, Aspect, NormalZ, or any extra dimension or field such as z or intensity). Default: every \
curvature column the file holds (H, K, k1, k2 and the terrain curvatures; not the flags, slope \
or aspect).";

/// Column names, as the raster columns' option lists them.
#[derive(Debug, Clone)]
pub(super) struct Names(pub(super) Vec<String>);

fn parse_columns(s: &str) -> std::result::Result<Names, String> {
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

    // `--stat` too: `tilecurv raster`'s name for it, which the issue and users carry over.
    #[arg(long = "raster-stat", visible_alias = "stat", value_name = "STAT", help = STAT_HELP, default_value = "mean", requires = "cell", value_parser = Stat::parse)]
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
    pub(super) inputs: Vec<PathBuf>,

    /// Cell size, with a unit like --tile (1m, 0.5m, 3ft, 3usft) or a bare number in file
    /// units. Cells are aligned to whole multiples of it in the CRS, so the rasters of adjacent
    /// surveys line up.
    #[arg(long, value_parser = Length::parse)]
    pub(super) cell: Length,

    #[arg(long, help = COLUMNS_HELP, value_parser = parse_columns)]
    pub(super) columns: Option<Names>,

    #[arg(long, help = STAT_HELP, default_value = "mean", value_parser = Stat::parse)]
    pub(super) stat: Stat,

    /// Output directory (made if missing): one float32 GeoTIFF per column, named after it
    /// (ProfileCurvature.tif, ...), Deflate-compressed, no-data -3.4028235e38, in the input's
    /// CRS, plus PointCount.tif (points per cell), and a PNG quick look beside each (colour
    /// ramp over a hillshade, with a legend). Existing files of those names are replaced.
    #[arg(short, long)]
    pub(super) output: PathBuf,

    #[command(flatten)]
    pub(super) exec: ExecArgs,
}
