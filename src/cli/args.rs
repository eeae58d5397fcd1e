//! The arguments of each command, in groups shared between commands (the options that change
//! the output, the ones that only change how a run executes), and their conversion into one
//! validated [`Config`].

use std::path::PathBuf;

use crate::config::{Config, KArg, Length, OrientMode};
use crate::core::estimate::{EstimatorKind, EstimatorParams};
use crate::core::scale::Ladder;
use crate::error::{Error, Result};
use crate::io::columns::{ColumnChoice, ColumnType, Group};

impl clap::ValueEnum for EstimatorKind {
    fn value_variants<'a>() -> &'a [Self] {
        &EstimatorKind::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()).help(self.summary()))
    }
}

/// The options that change the output (stored in the work directory's manifest).
#[derive(clap::Args, Debug, Clone)]
pub struct ResultArgs {
    /// Tile edge length, with a unit: 50m, 0.1km, 150ft (international foot), 150usft (US
    /// survey foot), or a bare number in file units. Converted with the file's CRS unit (e.g.
    /// 50m is 164.04 in a file in international feet). Results do not depend on it; it trades
    /// memory for halo overhead.
    #[arg(long, default_value = "50m", value_parser = Length::parse)]
    tile: Length,

    /// Neighbours per point, the point itself included (as in the CNC authors' code). 30 suits
    /// aerial LIDAR (the CNC paper finds 15-50 very accurate on clean data; noisy scans want
    /// more). With --radius, the cap on neighbours: the nearest k within the radius (lidR's k
    /// with r, CloudCompare's and PDAL's radius with a maximum count); default 30, or 100 with
    /// --radius.
    ///
    /// `-k auto` chooses K per point among the rungs of --k-range (default 20..320) by the
    /// stability of H across scales (docs/scale.md): for noisy or unevenly noisy scans, where
    /// no single K suits every region. About 9-13x the CPU time of -k 30 (1.5x -k 320); writes
    /// the chosen K (ScaleK) and ScaleFlags (1: the top rung was chosen while the error was
    /// still falling).
    #[arg(short = 'k', long = "neighbours", alias = "neighbors", value_parser = KArg::parse, value_name = "K|auto")]
    k: Option<KArg>,

    /// The ladder of -k auto: MIN..MAX, rungs MIN, 2 MIN, 4 MIN, ... up to MAX (MAX = MIN times
    /// 4 to 64, MIN at least 16). Implies -k auto.
    #[arg(long, value_name = "MIN..MAX", value_parser = Ladder::parse)]
    k_range: Option<Ladder>,

    /// Neighbourhoods by distance instead of count: each point with every point within this
    /// distance, at most -k of them (the nearest; default 100). A length with a unit like
    /// --tile: 1.5m, 5ft, 5usft, or a bare number in file units, converted with the file's CRS
    /// unit (taken as file units, with a warning, when the file has none). Distances are 3D.
    /// Use it when the scale of the measure must not follow the density (curvature at a set
    /// scale across flight lines and overlaps); -k alone adapts to the density instead. Points
    /// with fewer than 3 neighbours within it are flagged FEW_NEIGHBOURS (flag 1).
    #[arg(long, value_parser = Length::parse)]
    radius: Option<Length>,

    /// Curvature estimator (docs/study.md compares their error and time per point).
    #[arg(long, default_value = "cnc-avg-hexagram")]
    estimator: EstimatorKind,

    /// Orientation of PCA normals: `up` (towards +Z, aerial scans), `outward` (away from the
    /// centroid of all points: closed, star-shaped objects), `propagate` (consistent over the
    /// neighbour graph, seeded outward: objects like the Stanford bunny; tile by tile, with
    /// the tiles' signs reconciled through their halos) or `viewpoint:X,Y,Z` (towards a
    /// terrestrial scanner, in file coordinates). Normals stored in the file (NormalX/Y/Z) are
    /// used as they are unless --ignore-file-normals.
    #[arg(long, default_value = "up", value_parser = OrientMode::parse)]
    orient: OrientMode,

    /// Estimate normals by PCA even when the input has NormalX/Y/Z (a tilecurv output's own
    /// NormalX/Y/Z are never the file's normals: a re-run replaces them).
    #[arg(long)]
    ignore_file_normals: bool,

    /// The new columns, a comma-separated list of: normals (NormalX/Y/Z), H, K, k1, k2,
    /// directions (d1x..d2z), features (with --estimator vcm: SharpFeature, VcmNormalX/Y/Z),
    /// flags (CurvatureFlags). Written in that order whatever the order given. The default,
    /// H,K,flags, keeps a LAZ output within 2x its LAZ input on aerial and forest LIDAR; the
    /// normals and k1 with k2 cost about as much again each (`--columns
    /// normals,H,K,k1,k2,flags`: 3 to 4.2 times the input). Normals already in the input are
    /// kept and not written again.
    #[arg(
        long,
        value_name = "LIST",
        default_value_t = ColumnChoice::default(),
        value_parser = ColumnChoice::parse
    )]
    columns: ColumnChoice,

    /// Also write the principal directions d1 (of k1) and d2 (of k2) as unit vectors (the
    /// column group `directions`).
    #[arg(long)]
    directions: bool,

    /// Also write the VCM's sharp-feature columns (only with --estimator vcm): SharpFeature, the
    /// score lambda2/(lambda1+lambda2+lambda3) of the convolved Voronoi covariance measure
    /// (eigenvalues in decreasing order), and VcmNormalX/Y/Z, the VCM's own unit normal (signed
    /// to agree with the PCA or file normal). The score lies in [0, 1/2]: about 0 on a plane or
    /// smooth surface, about alpha^2/12 on a sharp edge of external (dihedral turning) angle
    /// alpha in radians (about 0.2-0.3 on a right-angled edge), and around 0.2 at a corner;
    /// threshold it to select creases. The column group `features`.
    #[arg(long)]
    features: bool,

    /// Store the new columns of a LAS/LAZ output as 32-bit floats (NaN where undefined), as
    /// tilecurv did before scaled columns. By default they are scaled integers, which readers
    /// turn back into numbers with the extra-bytes descriptors' scale (laspy and PDAL apply it)
    /// and which LAZ compresses far better (with --columns normals,H,K,k1,k2,flags a LAZ
    /// output of forest LIDAR is about 4 times its LAZ input instead of 6.5): unit vectors
    /// (normals, directions, the VCM normal) as i16 at 1/32767 (error at most 1.5e-5); H, K,
    /// and k1 with k2, as i32 at a power-of-two step of at most 1/4096 of the 99th percentile
    /// of |value| over all the points of the run (error at most 1.2e-4 of that percentile;
    /// the RMS quantisation error is 27 to 160 times below the estimator's RMS error on the
    /// CNC authors' torus, 570 to 830 times on generated terrain), coarser only if the largest |value| would exceed 2^30 steps. `tilecurv info`
    /// prints each column's step. An undefined value is the type's minimum (-32768 or
    /// -2147483648), declared as the column's no-data value: laspy returns it scaled, so mask
    /// it with CurvatureFlags & 7 (or the raw value). PLY has no scale field: PLY outputs are
    /// f32 unless --f64.
    #[arg(long = "f32", conflicts_with = "f64_columns")]
    f32_columns: bool,

    /// Store the new columns as 64-bit floats (NaN where undefined) instead of scaled integers.
    #[arg(long = "f64")]
    f64_columns: bool,

    /// Seed of randomised estimators (each point's stream comes from the seed and the point's
    /// coordinates, so that it does not depend on the order of the records).
    #[arg(long, default_value_t = 0)]
    seed: u64,

    /// Triangles per point for cnc-uniform.
    #[arg(long, default_value_t = 100)]
    triangles: usize,

    /// For a mesh (OBJ, OFF, or PLY with a face element): process N points sampled uniformly by
    /// area on its faces instead of its vertices, each with the unit normal of its face (polygons
    /// are fan-triangulated; counter-clockwise vertex order is outward), used as a file normal.
    /// N as for `generate --points`: 200k, 1M. The sample comes from --seed and does not depend
    /// on --threads or --chunk-size. The mesh is held in memory, the samples are streamed.
    #[arg(long, value_name = "N", value_parser = crate::tools::generate::parse_count)]
    sample_faces: Option<u64>,

    /// Write a LAS/LAZ output in its input's LAS version. By default a LAS 1.0-1.3 input gives
    /// a LAS 1.4 output (same point format and records; a 375-byte header with the 64-bit
    /// counts), because PDAL reads the extra-bytes columns of LAS 1.4 files only (without
    /// --readers.las.use_eb_vlr=true it shows none of the new columns in a LAS 1.2 file).
    #[arg(long)]
    keep_version: bool,

    /// Name the new columns of a PLY output as in LAS (NormalX/Y/Z, H, K, k1, k2,
    /// CurvatureFlags). By default they are nx/ny/nz and scalar_H, scalar_K, ...: the names
    /// CloudCompare loads as normals and scalar fields without a dialog (its command line
    /// ignores other names) and shows without the scalar_ prefix.
    #[arg(long)]
    ply_las_names: bool,

    /// Compute only on points of these LAS classes, e.g. 2,9 (ground and water). Neighbourhoods
    /// are formed among the selected points only; every point stays in the output, the others
    /// with NaN values and flag 128 (not computed). Inputs without classes (PLY, XYZ, ...)
    /// cannot be filtered. Default: every class but --skip-classes
    #[arg(long, value_name = "LIST", value_parser = ClassList::parse)]
    classes: Option<ClassList>,

    /// Never compute on points of these LAS classes (they are written with flag 128). The
    /// default skips the noise classes, 7 (low point) and 18 (high noise), whose isolated
    /// points would bend their neighbours' curvature; `none` computes on every class
    #[arg(long, value_name = "LIST", default_value = "7,18", value_parser = ClassList::parse)]
    skip_classes: ClassList,

    /// Never compute on points with the LAS withheld flag (written with flag 128)
    #[arg(long)]
    skip_withheld: bool,
}

/// A list of LAS classes on the command line (`2,9` or `none`).
#[derive(Debug, Clone)]
pub struct ClassList(Vec<u8>);

impl ClassList {
    fn parse(s: &str) -> std::result::Result<Self, String> {
        crate::core::select::parse_classes(s).map(ClassList)
    }
}

/// The options that change how a run executes, never its output.
#[derive(clap::Args, Debug, Clone)]
pub struct ExecArgs {
    /// Memory budget for buckets and tiles in flight: 2G, 512M, ... (K, M, G = powers of 1024).
    /// Past it, buckets spill to the work directory (zstd). Default: half the machine's memory,
    /// at most 4G; lowered (with a message) to what `ulimit -v` leaves beside the mapped inputs
    /// and what the cgroup's memory limit leaves. The program itself adds about 60M.
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
pub struct ProcessArgs {
    /// Input point clouds: LAS or LAZ (LAS 1.0-1.4, point formats 0-10, COPC-LAZ), PLY, XYZ
    /// text (.xyz, .pts, .txt), PCD, or the vertices of OFF and OBJ meshes. Several inputs are
    /// one scene (adjacent tiles of a survey: neighbourhoods cross file borders) and give one
    /// output each. Never modified.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,

    /// Output file, or a directory (end it with /) for several inputs, where each output gets
    /// its input's file name. The extension chooses the format: .las, .laz, .ply (binary) or
    /// .ascii.ply. Holds every input
    /// point in the same order with all original fields, VLRs and EVLRs, plus the columns
    /// H (mean curvature), K (Gaussian) and CurvatureFlags and, as --columns asks, NormalX/Y/Z,
    /// k1 <= k2 (principal), d1x..d2z (also --directions) and SharpFeature and VcmNormalX/Y/Z
    /// (also --features). Curvature is positive where the surface bends away from its
    /// normal (hilltops with upward normals), in 1/(horizontal unit of the file's CRS).
    #[arg(short, long)]
    output: PathBuf,

    #[command(flatten)]
    result: ResultArgs,

    #[command(flatten)]
    exec: ExecArgs,

    /// Print the plan (tiles, expected peak memory, work-directory disk, estimated run time from
    /// timing the median tile) and stop. Scans the inputs once.
    #[arg(long)]
    dry_run: bool,

    /// Work directory for buckets and per-tile results (default: .<output name>.tilecurv beside
    /// the output). Kept when a run is interrupted or fails, so that the same command resumes
    /// from the finished tiles; removed after success. Work from other inputs or parameters is
    /// detected and discarded.
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
    pub fn quiet(&self) -> bool {
        self.quiet
    }

    /// A configuration with these execution settings and the defaults for the rest.
    pub fn config(&self) -> Config {
        Config {
            memory_bytes: self.memory.unwrap_or_else(crate::config::default_memory),
            threads: default_threads(self.threads),
            chunk_points: self.chunk_points,
            progress_json: self.progress_json.clone(),
            ..Config::default()
        }
    }
}

/// The cap on neighbours with --radius when -k is not given.
const RADIUS_CAP: usize = 100;

impl ResultArgs {
    /// Sets these options in `cfg`.
    fn apply(&self, cfg: &mut Config) {
        cfg.tile = self.tile;
        cfg.radius = self.radius;
        cfg.scale = match self.k {
            Some(KArg::Auto) => Some(self.k_range.unwrap_or_default()),
            _ => self.k_range,
        };
        cfg.k = match (self.k, cfg.scale) {
            (Some(KArg::Count(k)), _) => k,
            (_, Some(ladder)) => ladder.max,
            _ if self.radius.is_some() => RADIUS_CAP,
            _ => 30,
        };
        cfg.estimator = self.estimator;
        cfg.params = EstimatorParams {
            seed: self.seed,
            triangles: self.triangles,
            ..EstimatorParams::default()
        };
        cfg.orientation = self.orient;
        cfg.ignore_file_normals = self.ignore_file_normals;
        cfg.columns = [
            (self.directions, Group::Directions),
            (self.features, Group::Features),
        ]
        .into_iter()
        .filter(|(on, _)| *on)
        .fold(self.columns, |c, (_, g)| c.with(g));
        cfg.column_type = match (self.f32_columns, self.f64_columns) {
            (_, true) => ColumnType::F64,
            (true, false) => ColumnType::F32,
            (false, false) => ColumnType::Scaled,
        };
        cfg.sample_faces = self.sample_faces;
        cfg.keep_version = self.keep_version;
        cfg.ply_las_names = self.ply_las_names;
        cfg.select = crate::core::select::ClassFilter {
            only: self.classes.as_ref().map(|c| c.0.clone()),
            skip: self.skip_classes.0.clone(),
            skip_withheld: self.skip_withheld,
        };
    }
}

impl ProcessArgs {
    /// Whether only warnings and errors are printed.
    pub fn quiet(&self) -> bool {
        self.exec.quiet
    }

    /// The run's configuration.
    pub fn into_config(self) -> Config {
        let mut cfg = Config {
            inputs: self.inputs,
            output: self.output,
            dry_run: self.dry_run,
            work_dir: self.work_dir,
            ..self.exec.config()
        };
        self.result.apply(&mut cfg);
        cfg
    }
}

/// `tilecurv plan`.
#[derive(clap::Args, Debug)]
pub struct PlanArgs {
    /// Input point clouds: LAS or LAZ (LAS 1.0-1.4, point formats 0-10, COPC-LAZ), PLY, XYZ
    /// text (.xyz, .pts, .txt), PCD, or the vertices of OFF and OBJ meshes. Several inputs are
    /// one scene (adjacent tiles of a survey: neighbourhoods cross file borders) and give one
    /// output each. Never modified.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,

    /// The work directory (created if needed): on a file system every node sees at the same
    /// path. Work left there from other inputs or options is discarded.
    #[arg(long)]
    pub work: PathBuf,

    #[command(flatten)]
    result: ResultArgs,

    /// Tiles of the grid over the inputs' bounds per tile task (1: one task per tile). Default:
    /// as few as keep the tasks within 1000 (Slurm's default MaxArraySize is 1001).
    #[arg(long, value_name = "N")]
    pub tiles_per_task: Option<u64>,

    /// Print only warnings and errors (the task counts are always printed).
    #[arg(short, long)]
    pub quiet: bool,
}

impl PlanArgs {
    /// The run's configuration; the inputs as absolute paths, since the tasks run elsewhere
    /// (another directory, another node).
    pub fn config(&self) -> Config {
        let mut cfg = Config {
            inputs: self
                .inputs
                .iter()
                .map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone()))
                .collect(),
            ..Config::default()
        };
        self.result.apply(&mut cfg);
        cfg
    }
}

/// A task index, or `env`: read from the scheduler's environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskArg {
    /// This index.
    Index(u64),
    /// TILECURV_TASK, SLURM_ARRAY_TASK_ID, AWS_BATCH_JOB_ARRAY_INDEX or JOB_COMPLETION_INDEX,
    /// the first that is set.
    Env,
}

/// The variables `--task env` reads, in order.
pub const TASK_VARIABLES: [&str; 4] = [
    "TILECURV_TASK",
    "SLURM_ARRAY_TASK_ID",
    "AWS_BATCH_JOB_ARRAY_INDEX",
    "JOB_COMPLETION_INDEX",
];

impl TaskArg {
    /// Parses a task index or `env`.
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        if s == "env" {
            return Ok(TaskArg::Env);
        }
        s.parse()
            .map(TaskArg::Index)
            .map_err(|_| format!("{s:?}: expected a task index (0, 1, ...) or `env`"))
    }

    /// The index.
    pub fn resolve(self) -> Result<u64> {
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
pub struct BucketArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// The bucket task to run (one per input file, 0 to `bucket tasks` - 1 as `plan` printed),
    /// or `env` for the scheduler's array index. Without it, every bucket task not done yet.
    #[arg(long, value_parser = TaskArg::parse)]
    pub task: Option<TaskArg>,

    #[command(flatten)]
    pub exec: ExecArgs,
}

/// `tilecurv run-tile`.
#[derive(clap::Args, Debug)]
pub struct RunTileArgs {
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
pub struct StatusArgs {
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
pub struct AssembleArgs {
    /// The work directory `tilecurv plan` made.
    #[arg(long)]
    pub work: PathBuf,

    /// Output file, or a directory (end it with /) for several inputs, where each output gets
    /// its input's file name. The extension chooses the format: .las, .laz, .ply (binary) or
    /// .ascii.ply. Holds every input
    /// point in the same order with all original fields, VLRs and EVLRs, plus the columns
    /// the plan's --columns chose (by default H, K and CurvatureFlags). Curvature is positive
    /// where the surface bends away from its normal (hilltops with upward normals), in
    /// 1/(horizontal unit of the file's CRS).
    #[arg(short, long)]
    pub output: PathBuf,

    #[command(flatten)]
    pub exec: ExecArgs,
}

/// `tilecurv info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// Point cloud files (any format `process` reads).
    #[arg(required = true, num_args = 1..)]
    pub files: Vec<PathBuf>,

    /// Print a JSON array with one object per file instead of text.
    #[arg(long)]
    pub json: bool,
}
