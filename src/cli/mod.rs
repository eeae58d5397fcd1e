//! The command line: clap definitions (in `args`), turned once into a validated run
//! (`config::RunParams`, `run::Process`), the commands run, and the exit codes. The binary (`main.rs`) only calls [`main_with_args`].

mod args;
mod generate;
mod info;
mod raster;

pub use info::info_json;

use crate::progress::say;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};

use crate::error::{Error, ExitClass};
use crate::progress::{human_rate, TermReporter};
use args::{AssembleArgs, BucketArgs, InfoArgs, PlanArgs, ProcessArgs, RunTileArgs, StatusArgs};
use generate::GenerateArgs;

/// Exit codes, as documented in `--help` and the README.
pub(crate) mod exit {
    /// Success.
    pub(crate) const OK: i32 = 0;
    /// Internal error (a bug).
    pub(crate) const INTERNAL: i32 = 1;
    /// Usage error: bad option or value.
    pub(crate) const USAGE: i32 = 2;
    /// Bad input: unreadable, malformed or unsupported input file.
    pub(crate) const BAD_INPUT: i32 = 3;
    /// Output failure: the output or the work directory could not be written or read, or a
    /// limit of the machine (disk space, file size, open files, memory) stopped the run.
    pub(crate) const OUTPUT: i32 = 4;
    /// A cluster stage found tasks of an earlier stage not done (`assemble` while tile tasks
    /// are missing); nothing was written.
    pub(crate) const INCOMPLETE: i32 = 5;
    /// Interrupted by SIGINT or SIGTERM; no output was written.
    pub(crate) const INTERRUPTED: i32 = 130;
}

const EXIT_HELP: &str = "\
Exit codes:
  0    success: the output is complete
  1    internal error (a bug: please report it with the command line)
  2    usage error: a bad option or value, or a memory limit (ulimit -v, the cgroup's) too
       small for even the smallest budget (the message says what to raise it to)
  3    bad input: the input is unreadable, malformed or unsupported (the message names the
       file and the byte offset)
  4    output failure: the output or the work directory could not be written or read, or a
       limit of the machine stopped the run (disk space, ulimit -f, ulimit -n, memory, or a
       processor without the AVX2 and FMA instructions the build uses: the message says how to
       rebuild); the work is kept: fix the cause and run the same command again to resume
  5    tasks missing: a cluster stage (run-tile, assemble) found tasks of an earlier stage not
       done; nothing was written (the message names them; `tilecurv status --missing` lists them)
  130  interrupted (SIGINT/SIGTERM): no output was written; `process` and the cluster stages
       resume from their finished tiles when the same command runs again

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
    /// Describe point cloud files: format, version, point count, bounds, CRS with its
    /// horizontal and vertical units, extra dimensions with types and scales, and the tilecurv
    /// provenance of an output. Reads headers only (other formats are scanned for bounds).
    #[command(after_help = EXIT_HELP)]
    Info(InfoArgs),
    /// Rasters of point columns: one GeoTIFF per column (mean of the cell's points by default)
    /// and a point count, aligned to multiples of the cell size, in the input's CRS.
    #[command(after_help = EXIT_HELP)]
    Raster(args::RasterArgs),
    /// Cluster stage 1: check the inputs, write the work directory's manifest and task layout,
    /// and print `bucket tasks: B` and `tasks: N` (the last line). Then run `bucket`, `run-tile`
    /// for every task index, and `assemble` (scripts/slurm/submit.sh chains them on Slurm).
    #[command(after_help = EXIT_HELP)]
    Plan(PlanArgs),
    /// Cluster stage 2: the scan into per-tile buckets, one task per input file or range of its
    /// points (or all).
    #[command(after_help = EXIT_HELP)]
    Bucket(BucketArgs),
    /// Cluster stage 3: the curvature of one tile task's tiles. Idempotent: finished tiles are
    /// skipped, half-written ones redone; a task run twice or on two nodes at once is harmless.
    #[command(after_help = EXIT_HELP)]
    RunTile(RunTileArgs),
    /// Which tile tasks are done: `done D of N tasks` (last line), or with --missing the missing
    /// indices in Slurm --array syntax. Exit 0 either way.
    #[command(after_help = EXIT_HELP)]
    Status(StatusArgs),
    /// Cluster stage 4: write one output per input from the finished tiles; refuses (exit 5,
    /// writing nothing) while tile tasks are missing.
    #[command(after_help = EXIT_HELP)]
    Assemble(AssembleArgs),
}

static CANCEL: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    CANCEL.store(true, Ordering::SeqCst);
}

fn install_signal_handlers() {
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe. SIGXFSZ is
    // ignored so that a write past the file-size limit (`ulimit -f`) fails with EFBIG, an
    // output failure with its message, instead of killing the run with a temporary file left.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

fn exit_code(e: &Error) -> i32 {
    match e.exit_class() {
        ExitClass::Usage => exit::USAGE,
        ExitClass::BadInput => exit::BAD_INPUT,
        ExitClass::Output => exit::OUTPUT,
        ExitClass::Incomplete => exit::INCOMPLETE,
        ExitClass::Interrupted => exit::INTERRUPTED,
        ExitClass::Internal => exit::INTERNAL,
    }
}

/// A terminal reporter (`progress_json`: `--progress-json`), or the exit code of the error
/// that prevented it.
fn reporter(quiet: bool, progress_json: Option<&std::path::Path>) -> Result<TermReporter, i32> {
    TermReporter::new(quiet, progress_json).map_err(|e| fail(&e))
}

/// Prints an error and returns its exit code.
fn fail(e: &Error) -> i32 {
    say!("tilecurv: error: {e}");
    exit_code(e)
}

/// [`fail`] for the commands that keep their finished tiles (`process` and the cluster
/// stages), saying after an interruption that the same command resumes; `raster` and
/// `generate` start over.
fn fail_run(e: &Error) -> i32 {
    let code = fail(e);
    if e.exit_class() == ExitClass::Interrupted {
        say!("tilecurv: run the same command again to resume from the finished tiles");
    }
    code
}

/// Parses `args` (the program name first, as `std::env::args_os` gives them), runs the
/// command, prints the outcome, and returns the exit code: the binary and the Python package's
/// `tilecurv` command run this one parser.
pub fn main_with_args<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
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
    install_signal_handlers();
    crate::io::limits::raise_open_files();
    crate::io::limits::fit_allocator();
    let r = match cli.command {
        Command::Generate(args) => generate::generate(args),
        Command::Process(args) => process(args),
        Command::Info(a) => info::info(a),
        Command::Raster(a) => raster::run(a),
        Command::Plan(a) => stages::plan(a),
        Command::Bucket(a) => stages::bucket(a),
        Command::RunTile(a) => stages::run_tile(a),
        Command::Status(a) => stages::status(a),
        Command::Assemble(a) => stages::assemble(a),
    };
    r.unwrap_or_else(|code| code)
}

/// `tilecurv process`.
fn process(args: ProcessArgs) -> Result<i32, i32> {
    let quiet = args.quiet();
    let exec = args.exec();
    let job = args.into_process().map_err(|e| fail(&e))?;
    let reporter = reporter(quiet, exec.progress_json.as_deref())?;
    let s = crate::run::process(&job, &exec, &reporter, &CANCEL).map_err(|e| fail_run(&e))?;
    if !job.dry_run {
        reporter.summary(&s.json_fields(), s.seconds);
    }
    if !quiet && !job.dry_run {
        // A rate over every point would count the resumed tiles' points, computed by an
        // earlier run, as this one's: given only when none were resumed.
        let rate = match s.tiles_resumed {
            0 => format!(" ({})", human_rate(s.points as f64 / s.seconds.max(1e-9))),
            _ => String::new(),
        };
        say!(
            "done: {} points in {:.1} s{rate}, {} tiles ({} resumed), {} undefined ({:.2}%), {} points recomputed with a wider halo -> {}",
            s.points,
            s.seconds,
            s.tiles,
            s.tiles_resumed,
            s.undefined,
            100.0 * s.undefined as f64 / s.points.max(1) as f64,
            s.retried,
            job.output.display()
        );
    }
    Ok(exit::OK)
}

mod stages;
