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

pub mod assemble;
pub mod bucket;
pub mod cluster;
pub mod dry_run;
pub mod limits;
pub mod orientation;
pub mod prepare;
pub mod rerun;
pub mod spec;
pub mod tiles;

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::config::Config;
use crate::core::plan::MemoryPlan;
use crate::core::tasks::TaskLayout;
use crate::error::{Error, Result};
use crate::io::workdir::{write_durably, Resume, WorkDir, TASKS};
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

/// How the stages execute: none of this changes the output.
pub struct Exec<'a> {
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
}

/// Stack of each worker thread, which decodes LAZ chunks (the laz crate's decompressors keep
/// their models on the stack) and runs the estimators: 8x rayon's 2 MiB default, so that a
/// malformed chunk cannot overflow it (an overflow aborts the process instead of failing the
/// run with an error). Address space only: pages are touched as used.
pub(crate) const WORKER_STACK: usize = 16 << 20;

impl<'a> Exec<'a> {
    /// The execution settings of `cfg` for a run of `spec`: its budget fitted to the machine's
    /// memory limits ([`limits::fit_memory`]).
    pub fn new(
        cfg: &Config,
        spec: &RunSpec,
        reporter: &'a dyn Reporter,
        cancel: &'a AtomicBool,
    ) -> Result<Self> {
        let budget = limits::fit_memory(cfg, spec, reporter)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(cfg.threads)
            .stack_size(WORKER_STACK)
            .build()
            .map_err(|e| {
                Error::Resource(format!(
                    "cannot start {} worker threads: {e}; lower --threads, or raise the limits on processes (ulimit -u) or memory (ulimit -v)",
                    cfg.threads
                ))
            })?;
        Ok(Exec {
            pool,
            memory: MemoryPlan::new(
                budget as usize,
                cfg.k,
                cfg.scale.map_or(1, |l| l.rungs()),
                cfg.threads,
            ),
            chunk_points: cfg.chunk_points,
            reporter,
            cancel,
        })
    }
}

/// The work directory of a run: `--work-dir`, or `.<first output name>.tilecurv` beside it.
pub fn work_path(cfg: &Config, spec: &RunSpec) -> PathBuf {
    cfg.work_dir
        .clone()
        .unwrap_or_else(|| crate::io::workdir::default_path(&spec.outputs[0]))
}

/// The plan stage: opens (creating it if needed) and locks the work directory at `path`,
/// writes the manifest of `spec` and the task layout; work left there by another manifest is
/// discarded, and buckets made under another task layout are.
pub fn plan(
    path: &Path,
    spec: &RunSpec,
    layout: &TaskLayout,
    reporter: &dyn Reporter,
) -> Result<WorkDir> {
    let work = WorkDir::open(path, &spec.manifest())?;
    let tasks = work.path().join(TASKS);
    let text = layout.to_text();
    if std::fs::read_to_string(&tasks).ok().as_deref() != Some(text.as_str()) {
        let buckets = work.path().join("buckets");
        if buckets.exists() {
            std::fs::remove_dir_all(&buckets).map_err(|e| Error::write(&buckets, e))?;
        }
        write_durably(&tasks, text.as_bytes())?;
    }
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
    Ok(work)
}

/// Runs `tilecurv process` as configured: every stage, in one process.
pub fn process(cfg: &Config, reporter: &dyn Reporter, cancel: &AtomicBool) -> Result<Summary> {
    let started = Instant::now();
    let spec = prepare::prepare(cfg, reporter)?;
    let exec = Exec::new(cfg, &spec, reporter, cancel)?;
    let path = work_path(cfg, &spec);
    let summary = |tiles: usize, resumed: usize, undefined: u64, retried: u64| Summary {
        points: spec.total_points,
        undefined,
        tiles,
        tiles_resumed: resumed,
        retried,
        seconds: started.elapsed().as_secs_f64(),
        outputs: spec.outputs.clone(),
    };
    if cfg.dry_run {
        dry_run::dry_run(&spec, &exec, &path)?;
        return Ok(summary(0, 0, 0, 0));
    }
    let layout = TaskLayout::single(spec.sources.len());
    let work = plan(&path, &spec, &layout, reporter)?;
    let r = (|| {
        let scan = bucket::bucket_all(&work, &spec, &layout, &exec)?;
        let done = tiles::tiles(&work, &spec, &scan, &layout, None, &exec)?;
        drop(scan);
        crate::io::limits::return_free_memory();
        let undefined = assemble::assemble_outputs(&work, &spec, &done.plan, &exec)?;
        Ok((done, undefined))
    })();
    match &r {
        Ok(_) => work.remove(),
        // Every failure keeps the work (an interruption says so itself): the same command
        // resumes from it once the cause is fixed, whether it was a full disk, a limit, or an
        // input that a rerun finds different (its work is then discarded).
        Err(Error::Interrupted) => drop(work),
        Err(_) => {
            reporter.warn(&format!(
                "the finished work is kept in {}: the same command resumes from it (delete it to start over)",
                work.path().display()
            ));
            drop(work);
        }
    }
    r.map(|(d, undefined)| summary(d.plan.tiles.len(), d.resumed, undefined, d.retried))
}
