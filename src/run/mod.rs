//! The run as stages over the work directory:
//!
//! ```text
//! prepare -> plan -> bucket -> tiles -> assemble
//! ```
//!
//! `prepare` opens the inputs and runs every check that can fail; `plan` opens the work
//! directory and writes its manifest (the fingerprint of the inputs and of every parameter that
//! changes the output); `bucket` scans the inputs into per-tile buckets with the scan
//! statistics; `tiles` computes every tile whose result file is not there yet; `assemble`
//! merges the tile results into one output per input. Each stage reads what it needs from the
//! work directory (the manifest, the buckets, the tile results), so that a killed run resumes
//! where it stopped and the stages can run as separate processes. `process` runs them in one:
//! there, buckets that fit the budget are handed from the bucket stage to the tiles stage in
//! memory instead of being written and read back. The work directory is removed only after
//! every output is written: every failure keeps it, so that the same command resumes.

pub(crate) mod assemble;
pub(crate) mod bucket;
pub mod cluster;
pub(crate) mod dry_run;
pub(crate) mod limits;
pub mod memory;
pub(crate) mod one_map;
pub(crate) mod orientation;
pub(crate) mod prepare;
pub mod raster;
pub(crate) mod rerun;
pub(crate) mod spec;
pub(crate) mod tiles;

pub use crate::io::workdir::default_path;
pub use tiles::TilesDone;

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::config::{ExecOptions, RunOptions, RunParams};
use crate::core::plan::{MemoryPlan, TilePlan, TileSpec};
use crate::core::tasks::TaskLayout;
use crate::error::{Error, ExitClass, Result};
use crate::io::workdir::{Resume, WorkDir};
use crate::progress::Reporter;
use crate::run::spec::RunSpec;

/// What a finished run reports.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Points written.
    pub points: u64,
    /// Points written whose curvature is undefined (flag `flags::UNDEFINED`): all of them,
    /// those of tiles resumed from an earlier run too, as counted in the outputs.
    pub undefined: u64,
    /// Tiles in the plan.
    pub tiles: usize,
    /// Tiles found finished from an earlier, interrupted run.
    pub tiles_resumed: usize,
    /// Points recomputed with a wider halo after verification.
    pub retried: u64,
    /// Wall time in seconds.
    pub seconds: f64,
    /// The outputs written.
    pub outputs: Vec<PathBuf>,
}

impl Summary {
    /// The members of the `summary` event of `--progress-json` (JSON values, encoded), for
    /// [`crate::progress::TermReporter::summary`] with [`Summary::seconds`].
    pub fn json_fields(&self) -> Vec<(&'static str, String)> {
        let outputs: Vec<String> = (self.outputs.iter())
            .map(|o| crate::progress::json_str(&o.to_string_lossy()))
            .collect();
        vec![
            ("points", self.points.to_string()),
            ("undefined", self.undefined.to_string()),
            ("tiles", self.tiles.to_string()),
            ("tiles_resumed", self.tiles_resumed.to_string()),
            ("retried", self.retried.to_string()),
            ("outputs", format!("[{}]", outputs.join(","))),
        ]
    }
}

/// How the stages execute: none of this changes the output.
pub(crate) struct Exec<'a> {
    /// The worker threads.
    pub pool: rayon::ThreadPool,
    /// How the memory budget is shared.
    pub memory: MemoryPlan,
    /// Points per read chunk asked for (capped by the memory plan).
    pub chunk_points: usize,
    /// Progress and messages.
    pub reporter: &'a dyn Reporter,
    /// Set by a signal: every stage stops at its next check.
    pub cancel: &'a AtomicBool,
    /// The rasters to make of the outputs as they are written, if any.
    pub rasters: Option<crate::config::RasterOptions>,
}

/// Stack of each worker thread, which decodes LAZ chunks (the laz crate's decompressors keep
/// their models on the stack) and runs the estimators: 8x rayon's 2 MiB default, so that a
/// malformed chunk cannot overflow it (an overflow aborts the process instead of failing the
/// run with an error). Address space only: pages are touched as used.
pub(crate) const WORKER_STACK: usize = 16 << 20;

impl<'a> Exec<'a> {
    /// The execution settings `opts` for a run of `spec`: its budget fitted to the machine's
    /// memory limits (`limits::fit_memory`) and shared as the run's parameters need
    /// (`RunSpec::memory_plan`), whichever command runs it.
    pub(crate) fn new(
        opts: &ExecOptions,
        spec: &RunSpec,
        reporter: &'a dyn Reporter,
        cancel: &'a AtomicBool,
    ) -> Result<Self> {
        opts.validate()?;
        if let Some(r) = &opts.rasters {
            raster::check_output_rasters(r, spec, reporter)?;
        }
        let budget = limits::fit_memory(opts, spec, reporter)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads)
            .stack_size(WORKER_STACK)
            .build()
            .map_err(|e| {
                Error::Resource(format!(
                    "cannot start {} worker threads: {e}; lower --threads, or raise the limits on processes (ulimit -u) or memory (ulimit -v)",
                    opts.threads
                ))
            })?;
        Ok(Exec {
            pool,
            memory: spec.memory_plan(budget as usize, opts.threads),
            chunk_points: opts.chunk_points,
            reporter,
            cancel,
            rasters: opts.rasters.clone(),
        })
    }
}

/// What `tilecurv process` is asked to do.
#[derive(Debug, Clone)]
pub struct Process {
    /// The input files: one scene (halos cross file borders), one output per input.
    pub inputs: Vec<PathBuf>,
    /// The output file for one input, or a directory for several.
    pub output: PathBuf,
    /// The work directory (default: `.<first output name>.tilecurv` beside it).
    pub work_dir: Option<PathBuf>,
    /// Print the plan and estimates, compute nothing.
    pub dry_run: bool,
    /// The options that change the output.
    pub params: RunParams,
}

impl Process {
    /// A run of `inputs` into `output` with `options`, validated.
    pub fn new(inputs: Vec<PathBuf>, output: PathBuf, options: RunOptions) -> Result<Self> {
        if inputs.is_empty() {
            return Err(Error::Usage("no input file given".into()));
        }
        Ok(Process {
            inputs,
            output,
            work_dir: None,
            dry_run: false,
            params: RunParams::new(options)?,
        })
    }
}

/// A run over its work directory: the checked spec, the directory and the task layout. Made
/// by [`Run::plan`] (`process`, `plan`) or [`Run::attach`] (the other cluster stages), so that
/// every command runs the same stages on the same spec.
pub(crate) struct Run {
    /// The checked run.
    pub spec: RunSpec,
    /// Its work directory.
    pub work: WorkDir,
    /// How its stages are split into tasks.
    pub layout: TaskLayout,
}

impl Run {
    /// Opens (creating it if needed) and locks the work directory at `path` for `spec`, writes
    /// its manifest and the task `layout`; work left there by another manifest is discarded,
    /// and buckets made under another task layout are.
    pub(crate) fn plan(
        spec: RunSpec,
        path: &Path,
        layout: TaskLayout,
        reporter: &dyn Reporter,
    ) -> Result<Run> {
        let work = WorkDir::open(path, &spec.manifest())?;
        work.set_task_layout(&layout.to_text())?;
        match work.resume {
            Resume::Fresh => {}
            Resume::Resumed => reporter.info(&format!(
                "resuming the interrupted run in {}",
                work.path().display()
            )),
            Resume::Discarded => reporter.warn(&format!(
                "{}: the work left there came from other inputs or parameters: discarded, starting over",
                work.path().display()
            )),
        }
        Ok(Run { spec, work, layout })
    }

    /// Attaches to the planned work directory at `path`, without its lock: the run's inputs and
    /// options from its manifest, which must still describe the inputs.
    pub(crate) fn attach(path: &Path, reporter: &dyn Reporter) -> Result<Run> {
        let crate::io::workdir::Attached {
            work,
            planned,
            manifest,
        } = WorkDir::attach(path)?;
        let mut options = RunOptions::default();
        for (k, v) in &planned.params {
            options.set(k, v).map_err(|e| {
                Error::damaged_work(
                    path,
                    &format!("its manifest has {e}; run `tilecurv plan` again"),
                )
            })?;
        }
        let params = RunParams::new(options)?;
        let spec = prepare::open_inputs(&planned.inputs, params, reporter)?;
        if spec.manifest() != manifest {
            return Err(Error::Usage(format!(
                "{}: the inputs changed since `tilecurv plan` (size, time or points differ), or another version of tilecurv planned it; run `tilecurv plan` again",
                path.display()
            )));
        }
        // Its ranges index the inputs and their points: a point scanned twice or never (or
        // an input past the last) is damage, not a panic or another output.
        let lens = spec.input_points();
        let layout = work.task_layout(|t| TaskLayout::parse(t).filter(|l| l.covers(&lens)))?;
        Ok(Run { spec, work, layout })
    }

    /// The tiles of `tplan` that are not finished, with the tile task of each.
    pub(crate) fn missing_tiles<'p>(
        &self,
        tplan: &'p TilePlan,
    ) -> Result<Vec<(u64, &'p TileSpec)>> {
        let store = self.work.results()?;
        let propagate = self.spec.propagates();
        Ok(store
            .missing(&tplan.tiles, &self.spec.cols, propagate)
            .into_iter()
            .map(|t| (self.layout.task_of(t.key), t))
            .collect())
    }
}

/// Whether `e` refuses the run (a usage error or bad input, exit 2 or 3): such work can never
/// be resumed (a fixed input has another fingerprint, and is discarded anyway), so a refused
/// run leaves the folder as it was.
fn refuses(e: &Error) -> bool {
    matches!(e.exit_class(), ExitClass::Usage | ExitClass::BadInput)
}

/// Runs `tilecurv process`: every stage, in one process. A refused run (a usage error or bad
/// input, exit 2 or 3) and a dry run leave no output, no temporary file, no work directory and
/// no folder they made (the output directory, or the folders above the output); any other
/// failure keeps the work for the same command to resume.
pub fn process(
    job: &Process,
    opts: &ExecOptions,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<Summary> {
    // Deepest first; the output itself among them when it is a directory to be made.
    let missing: Vec<PathBuf> = (job.output.ancestors())
        .filter(|a| !a.as_os_str().is_empty() && !a.exists())
        .map(Path::to_path_buf)
        .collect();
    let r = process_in(job, opts, reporter, cancel);
    if job.dry_run || r.as_ref().is_err_and(refuses) {
        // Each empty once the work directory is gone: remove_dir leaves anything else. The
        // output file's own path, never written by these runs, does not exist.
        for dir in missing.iter().filter(|d| d.exists()) {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
    r
}

/// Refuses outputs (files or the rasters' directory) in the work directory `work` or below
/// it: the work directory is removed once the run is done and refused by the next run while
/// it holds anything of its own (io::workdir), so outputs there would stop every rerun.
fn check_outside_work<'p>(work: &Path, outputs: impl Iterator<Item = &'p PathBuf>) -> Result<()> {
    // Absolute, with `.` and `..` folded as the names read (`a/../w` is `w`).
    let abs = |p: &Path| {
        let mut n = PathBuf::new();
        for c in std::path::absolute(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .components()
        {
            match c {
                std::path::Component::ParentDir => {
                    n.pop();
                }
                std::path::Component::CurDir => {}
                c => n.push(c),
            }
        }
        n
    };
    let inside = abs(work);
    for out in outputs {
        if abs(out).starts_with(&inside) {
            return Err(Error::Usage(format!(
                "{} is in the work directory {}, which is tilecurv's own scratch space; write the outputs elsewhere, or name another --work-dir",
                out.display(),
                work.display()
            )));
        }
    }
    Ok(())
}

/// [`process`] but for the output directory it made.
fn process_in(
    job: &Process,
    opts: &ExecOptions,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<Summary> {
    let started = Instant::now();
    let spec = prepare::prepare(&job.inputs, &job.output, job.params.clone(), reporter)?;
    let exec = Exec::new(opts, &spec, reporter, cancel)?;
    let path = job
        .work_dir
        .clone()
        .unwrap_or_else(|| crate::io::workdir::default_path(&spec.outputs[0]));
    let raster_dir = (exec.rasters.as_ref())
        .map(|r| (r.dir.clone()).unwrap_or_else(|| raster::default_dir(&spec.outputs)));
    check_outside_work(&path, spec.outputs.iter().chain(&raster_dir))?;
    let summary =
        |spec: &RunSpec, tiles: usize, resumed: usize, undefined: u64, retried: u64| Summary {
            points: spec.total_points,
            undefined,
            tiles,
            tiles_resumed: resumed,
            retried,
            seconds: started.elapsed().as_secs_f64(),
            outputs: spec.outputs.clone(),
        };
    if job.dry_run {
        let nothing = summary(&spec, 0, 0, 0, 0);
        dry_run::dry_run(spec, &exec, &path)?;
        return Ok(nothing);
    }
    let layout = TaskLayout::single(&spec.input_points());
    let run = Run::plan(spec, &path, layout, reporter)?;
    let r = (|| {
        let scan = bucket::bucket_all(&run, &exec)?;
        let done = tiles::tiles(&run, &scan, None, &exec)?;
        let spilled = scan.buckets.spilled();
        drop(scan);
        crate::io::limits::return_free_memory();
        // Every tile is done: the bucket files go while the outputs are written, on a thread
        // of their own (deleting thousands of files is the file system's work, not ours), so
        // that their disk is free before the merge's run files need it.
        std::thread::scope(|s| {
            if spilled {
                // A thread that cannot start leaves the files to the directory's removal.
                let release = std::thread::Builder::new().name("release buckets".into());
                let _ = release.spawn_scoped(s, || run.work.release_bucket_files());
            }
            let undefined = assemble::assemble_outputs(&run, &done.plan, &exec)?;
            Ok((done, undefined))
        })
    })();
    let s = r.map(|(d, undefined)| {
        summary(
            &run.spec,
            d.plan.tiles.len(),
            d.resumed,
            undefined,
            d.retried,
        )
    });
    match &s {
        Ok(_) => run.work.remove(),
        // A refusal leaves nothing; every other failure keeps the work (an interruption says
        // so itself): the same command resumes from it once the cause is fixed, a full disk or
        // a limit.
        Err(e) if refuses(e) => run.work.remove(),
        Err(Error::Interrupted) => {}
        Err(_) => reporter.warn(&format!(
            "the finished work is kept in {}: the same command resumes from it (delete it to start over)",
            run.work.path().display()
        )),
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;

    /// `process` and the cluster stages (which rebuild the run from the manifest) share the
    /// memory budget alike for every kind of neighbourhood: the plan follows the run's k and
    /// ladder, not a default.
    #[test]
    fn process_and_run_tile_plan_memory_alike() {
        let dir = tempfile::tempdir().expect("temp dir");
        let input = std::path::absolute("data/Haystack_Rock.las").expect("sample");
        let cancel = AtomicBool::new(false);
        let opts = ExecOptions {
            threads: 2,
            memory_bytes: 128 << 20,
            ..ExecOptions::default()
        };
        let mut seen = Vec::new();
        for (i, pairs) in [&[("k", "30")][..], &[("k", "auto")], &[("radius", "3m")]]
            .iter()
            .enumerate()
        {
            let mut options = RunOptions::default();
            for (k, v) in *pairs {
                options.set(k, v).expect("option");
            }
            let params = RunParams::new(options).expect("valid");
            let out = dir.path().join(format!("o{i}.las"));
            let spec =
                prepare::prepare(std::slice::from_ref(&input), &out, params.clone(), &Silent)
                    .expect("prepared");
            let of_process = Exec::new(&opts, &spec, &Silent, &cancel)
                .expect("exec")
                .memory;
            let work = dir.path().join(format!("w{i}"));
            let spec = prepare::open_inputs(std::slice::from_ref(&input), params, &Silent)
                .expect("opened");
            let layout = TaskLayout::single(&spec.input_points());
            drop(Run::plan(spec, &work, layout, &Silent).expect("planned"));
            let attached = Run::attach(&work, &Silent).expect("attached");
            let of_task = Exec::new(&opts, &attached.spec, &Silent, &cancel)
                .expect("exec")
                .memory;
            assert_eq!(of_process, of_task, "{pairs:?}");
            seen.push(of_task.tile_point_bytes);
        }
        // -k auto's rungs and --radius's cap on neighbours take more memory a point than -k 30.
        assert!(seen[1] > seen[0] && seen[2] > seen[0], "{seen:?}");
    }
}
