//! The command line: clap definitions, turned once into a validated [`Config`], and the exit
//! codes. The binary (`main.rs`) only calls [`main_with_args`].

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};

use crate::config::OrientMode;
use crate::config::{ColumnType, Config, Length};
use crate::core::estimate::{EstimatorKind, EstimatorParams};
use crate::error::{Error, ExitClass};
use crate::progress::TermReporter;

/// Exit codes, as documented in `--help` and the README.
pub mod exit {
    /// Success.
    pub const OK: i32 = 0;
    /// Internal error (a bug).
    pub const INTERNAL: i32 = 1;
    /// Usage error: bad option or value.
    pub const USAGE: i32 = 2;
    /// Bad input: unreadable, malformed or unsupported input file.
    pub const BAD_INPUT: i32 = 3;
    /// Output failure: the output or work directory could not be written.
    pub const OUTPUT: i32 = 4;
    /// Interrupted by SIGINT or SIGTERM; no output was written.
    pub const INTERRUPTED: i32 = 130;
}

const EXIT_HELP: &str = "\
Exit codes:
  0    success: the output is complete
  1    internal error (a bug: please report it with the command line)
  2    usage error: a bad option or value
  3    bad input: the input is unreadable, malformed or unsupported (the message names the file and byte offset)
  4    output failure: the output or the work directory could not be written
  130  interrupted (SIGINT/SIGTERM): no output was written; run the same command again to resume

The output is written to a temporary file beside it and renamed only on success: it is complete or absent.";

#[derive(Parser, Debug)]
#[command(name = "tilecurv", version, about = "Per-point normals and mean, Gaussian and principal curvature for LIDAR point clouds (LAS/LAZ in, LAS/LAZ out)", after_help = EXIT_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Compute normals and curvature for every point and write them as new extra-bytes columns.
    #[command(after_help = EXIT_HELP)]
    Process(ProcessArgs),
    /// Write a synthetic point cloud with its exact curvature, for testing and benchmarking.
    Generate(GenerateArgs),
}

#[derive(clap::Args, Debug)]
struct GenerateArgs {
    #[command(subcommand)]
    kind: GenerateKind,
}

#[derive(Subcommand, Debug)]
enum GenerateKind {
    /// Aerial-LIDAR-like terrain (hills and hollows on a gentle slope) of any size, with the
    /// closed-form curvature of every point. Streams: memory does not grow with --points.
    ///
    /// Units: coordinates in metres (WGS 84 / UTM zone 10N, EPSG:32610, declared by GeoTIFF
    /// keys with metre units; scale 0.001 m) around easting 500000, northing 4100000. Points
    /// are LAS 1.2 point format 1 (GPS time), ordered by flight strip (north-south, 250 m wide)
    /// and scan row, classified as ground. Extra-bytes columns (f64): TrueH (mean curvature,
    /// 1/m), TrueK (Gaussian curvature, 1/m^2), Truek1 <= Truek2 (principal curvatures, 1/m),
    /// with the upward normal: positive on hilltops, the sign of `process`'s H, K, k1, k2.
    #[command(after_help = EXIT_HELP)]
    Terrain(TerrainArgs),
}

#[derive(clap::Args, Debug)]
struct TerrainArgs {
    /// Output file; the extension chooses the format: .las or .laz. Written to a temporary file
    /// and renamed when complete.
    #[arg(short, long)]
    output: PathBuf,

    /// Number of points: 2000000, 2M, 500k, 1e6 (k, M, G = powers of ten). At most 4294967295
    /// (LAS 1.2).
    #[arg(long, value_parser = crate::tools::generate::parse_count)]
    points: u64,

    /// Points per square metre; the terrain covers a square of points/density square metres.
    #[arg(long, default_value_t = 10.0)]
    density: f64,

    /// Seed of the terrain and of the sampling: the same options give the same file.
    #[arg(long, default_value_t = 0)]
    seed: u64,

    /// Standard deviation of Gaussian noise added to z, in metres. The truth columns stay those
    /// of the noise-free surface at the point's x, y.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,

    /// Print nothing on success.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
struct ProcessArgs {
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
    /// NormalX/Y/Z, H (mean curvature), K (Gaussian), k1 <= k2 (principal), CurvatureFlags and,
    /// with --directions, d1x..d2z and, with --features, SharpFeature and VcmNormalX/Y/Z. Curvature is positive where the surface bends away from its
    /// normal (hilltops with upward normals), in 1/(horizontal unit of the file's CRS).
    #[arg(short, long)]
    output: PathBuf,

    /// Memory budget for buckets and tiles in flight: 2G, 512M, ... (K, M, G = powers of 1024).
    /// Past it, buckets spill to the work directory (zstd). Default: half the machine's memory,
    /// at most 4G. The program itself adds about 60M.
    #[arg(long, value_parser = crate::config::parse_bytes)]
    memory: Option<u64>,

    /// Print the plan (tiles, expected peak memory, work-directory disk, estimated run time from
    /// timing the median tile) and stop. Scans the inputs once.
    #[arg(long)]
    dry_run: bool,

    /// Append one JSON line per tile and per phase to FILE (phase, done and total points,
    /// points/s, ETA in seconds), for a scheduler or a dashboard.
    #[arg(long, value_name = "FILE")]
    progress_json: Option<PathBuf>,

    /// Tile edge length, with a unit: 50m, 0.1km, 150ft (international foot), 150usft (US
    /// survey foot), or a bare number in file units. Converted with the file's CRS unit (e.g.
    /// 50m is 164.04 in a file in international feet). Results do not depend on it; it trades
    /// memory for halo overhead.
    #[arg(long, default_value = "50m", value_parser = Length::parse)]
    tile: Length,

    /// Neighbours per point, the point itself included (as in the CNC authors' code). 30 suits
    /// aerial LIDAR (the CNC paper finds 15-50 very accurate on clean data; noisy scans want more).
    #[arg(
        short = 'k',
        long = "neighbours",
        alias = "neighbors",
        default_value_t = 30
    )]
    k: usize,

    /// Curvature estimator (docs/study.md compares their error and time per point).
    #[arg(long, default_value = "cnc-avg-hexagram")]
    estimator: EstimatorKind,

    /// Orientation of PCA normals: `up` (towards +Z, aerial scans), `outward` (away from the
    /// centroid of all points: closed, star-shaped objects), `propagate` (consistent over the
    /// neighbour graph, seeded outward: objects like the Stanford bunny; tile by tile, with
    /// the tiles' signs reconciled through their halos) or `viewpoint:X,Y,Z` (towards a
    /// terrestrial scanner, in file coordinates). Normals stored in the file (NormalX/Y/Z) are
    /// used as they are unless --ignore-file-normals.
    #[arg(long, default_value = "up", value_parser = parse_orientation)]
    orient: OrientMode,

    /// Estimate normals by PCA even when the input has NormalX/Y/Z.
    #[arg(long)]
    ignore_file_normals: bool,

    /// Also write the principal directions d1 (of k1) and d2 (of k2) as unit vectors.
    #[arg(long)]
    directions: bool,

    /// Also write the VCM's sharp-feature columns (only with --estimator vcm): SharpFeature, the
    /// score lambda2/(lambda1+lambda2+lambda3) of the convolved Voronoi covariance measure
    /// (eigenvalues in decreasing order), and VcmNormalX/Y/Z, the VCM's own unit normal (signed
    /// to agree with the PCA or file normal). The score lies in [0, 1/2]: about 0 on a plane or
    /// smooth surface, about alpha^2/12 on a sharp edge of external (dihedral turning) angle
    /// alpha in radians (about 0.2-0.3 on a right-angled edge), and around 0.2 at a corner;
    /// threshold it to select creases.
    #[arg(long)]
    features: bool,

    /// Store the new columns as 64-bit floats (default: 32-bit).
    #[arg(long = "f64")]
    f64_columns: bool,

    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,

    /// Points read per chunk when streaming the input. Results do not depend on it.
    #[arg(long = "chunk-size", default_value_t = 1_000_000)]
    chunk_points: usize,

    /// Seed of randomised estimators (each point's stream comes from the seed and its index).
    #[arg(long, default_value_t = 0)]
    seed: u64,

    /// Triangles per point for cnc-uniform.
    #[arg(long, default_value_t = 100)]
    triangles: usize,

    /// Work directory for buckets and per-tile results (default: .<output name>.tilecurv beside
    /// the output). Kept when a run is interrupted or fails, so that the same command resumes
    /// from the finished tiles; removed after success. Work from other inputs or parameters is
    /// detected and discarded.
    #[arg(long)]
    work_dir: Option<PathBuf>,

    /// For a mesh (OBJ, OFF, or PLY with a face element): process N points sampled uniformly by
    /// area on its faces instead of its vertices, each with the unit normal of its face (polygons
    /// are fan-triangulated; counter-clockwise vertex order is outward), used as a file normal.
    /// N as for `generate --points`: 200k, 1M. The sample comes from --seed and does not depend
    /// on --threads or --chunk-size. The mesh is held in memory, the samples are streamed.
    #[arg(long, value_name = "N", value_parser = crate::tools::generate::parse_count)]
    sample_faces: Option<u64>,

    /// Print only warnings and errors.
    #[arg(short, long)]
    quiet: bool,
}

impl clap::ValueEnum for EstimatorKind {
    fn value_variants<'a>() -> &'a [Self] {
        &EstimatorKind::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()).help(self.summary()))
    }
}

fn parse_orientation(s: &str) -> Result<OrientMode, String> {
    if s == "up" {
        return Ok(OrientMode::Up);
    }
    if s == "outward" {
        return Ok(OrientMode::Outward);
    }
    if s == "propagate" {
        return Ok(OrientMode::Propagate);
    }
    if let Some(rest) = s.strip_prefix("viewpoint:") {
        let v: Vec<f64> = rest
            .split(',')
            .map(|c| c.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("{s:?}: expected viewpoint:X,Y,Z with three numbers"))?;
        if let [x, y, z] = v[..] {
            if [x, y, z].iter().all(|c| c.is_finite()) {
                return Ok(OrientMode::Viewpoint([x, y, z]));
            }
        }
        return Err(format!(
            "{s:?}: expected viewpoint:X,Y,Z with three finite numbers"
        ));
    }
    Err(format!(
        "{s:?}: expected `up`, `outward`, `propagate` or `viewpoint:X,Y,Z`"
    ))
}

impl ProcessArgs {
    fn into_config(self) -> Config {
        let threads = self.threads.unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
        });
        Config {
            inputs: self.inputs,
            output: self.output,
            memory_bytes: self.memory.unwrap_or_else(crate::config::default_memory),
            dry_run: self.dry_run,
            progress_json: self.progress_json,
            tile: self.tile,
            k: self.k,
            estimator: self.estimator,
            params: EstimatorParams {
                seed: self.seed,
                triangles: self.triangles,
                ..EstimatorParams::default()
            },
            orientation: self.orient,
            ignore_file_normals: self.ignore_file_normals,
            directions: self.directions,
            features: self.features,
            column_type: if self.f64_columns {
                ColumnType::F64
            } else {
                ColumnType::F32
            },
            threads,
            chunk_points: self.chunk_points,
            work_dir: self.work_dir,
            sample_faces: self.sample_faces,
        }
    }
}

static CANCEL: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    CANCEL.store(true, Ordering::SeqCst);
}

fn install_signal_handlers() {
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
}

fn exit_code(e: &Error) -> i32 {
    match e.exit_class() {
        ExitClass::Usage => exit::USAGE,
        ExitClass::BadInput => exit::BAD_INPUT,
        ExitClass::Output => exit::OUTPUT,
        ExitClass::Interrupted => exit::INTERRUPTED,
        ExitClass::Internal => exit::INTERNAL,
    }
}

/// Parses the process arguments, runs the command, prints the outcome, and returns the exit code.
pub fn main_with_args() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                exit::USAGE
            } else {
                exit::OK
            };
        }
    };
    match cli.command {
        Command::Generate(GenerateArgs {
            kind: GenerateKind::Terrain(args),
        }) => {
            let opts = crate::tools::generate::TerrainOptions {
                points: args.points,
                density_per_m2: args.density,
                seed: args.seed,
                noise_m: args.noise,
            };
            install_signal_handlers();
            match crate::tools::generate::generate_terrain(&opts, &args.output, &CANCEL) {
                Ok(s) => {
                    if !args.quiet {
                        eprintln!(
                            "done: {} points over {:.0} m x {:.0} m ({} strips, {} bumps, z {:.1}..{:.1} m) in {:.1} s ({:.0} points/s) -> {}",
                            s.points,
                            s.side_m,
                            s.side_m,
                            s.strips,
                            s.bumps,
                            s.z_range_m[0],
                            s.z_range_m[1],
                            s.seconds,
                            s.points as f64 / s.seconds.max(1e-9),
                            args.output.display()
                        );
                    }
                    exit::OK
                }
                Err(e) => {
                    eprintln!("tilecurv: error: {e}");
                    exit_code(&e)
                }
            }
        }
        Command::Process(args) => {
            let quiet = args.quiet;
            let cfg = args.into_config();
            install_signal_handlers();
            let reporter = match TermReporter::new(quiet, cfg.progress_json.as_deref()) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("tilecurv: error: {e}");
                    return exit_code(&e);
                }
            };
            match crate::run::process(&cfg, &reporter, &CANCEL) {
                Ok(s) => {
                    if !quiet && !cfg.dry_run {
                        {
                            eprintln!(
                                "done: {} points in {:.1} s ({:.0} points/s), {} tiles ({} resumed), {} undefined ({:.2}%), {} recomputed with a wider halo -> {}",
                                s.points,
                                s.seconds,
                                s.points as f64 / s.seconds.max(1e-9),
                                s.tiles,
                                s.tiles_resumed,
                                s.undefined,
                                100.0 * s.undefined as f64 / s.points.max(1) as f64,
                                s.retried,
                                cfg.output.display()
                            );
                        }
                    }
                    exit::OK
                }
                Err(e) => {
                    eprintln!("tilecurv: error: {e}");
                    if e.exit_class() == ExitClass::Interrupted {
                        eprintln!("tilecurv: run the same command again to resume from the finished tiles");
                    }
                    exit_code(&e)
                }
            }
        }
    }
}
