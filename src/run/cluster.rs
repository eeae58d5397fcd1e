//! The stages as separate commands, for a scheduler that runs them as array tasks (Slurm job
//! arrays, AWS Batch array jobs, Kubernetes Indexed Jobs): `plan` writes the manifest and the
//! task layout; `bucket` runs bucket tasks; `run-tile` runs one tile task; `status` says which
//! tile tasks are done; `assemble` writes the outputs once every tile is. Each command reads the
//! run from the work directory's manifest (the options as `plan` was given them) and the task
//! layout, so the tasks of a stage run at the same time on any node that sees the directory,
//! without its lock. They call the very stage functions `process` runs, so the outputs are the
//! same bytes.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::config::{ExecOptions, RunParams};
use crate::core::plan::TileKey;
use crate::core::tasks::{
    array_syntax, split_points, ScanRange, TaskLayout, DEFAULT_POINTS_PER_SCAN_TASK,
};
use crate::error::{Error, Result};
use crate::io::source::declared_bounds;
use crate::progress::Reporter;
use crate::run::bucket::{bucket_task, open_buckets};
use crate::run::prepare::{check_output_columns, check_outputs, open_inputs, output_paths};
use crate::run::spec::RunSpec;
use crate::run::tiles::{tiles, TilesDone};
use crate::run::{Exec, Run, Summary};

/// What `plan` made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Planned {
    /// Bucket tasks (one per input file, or per range of points of a large LAS or LAZ file).
    pub bucket_tasks: usize,
    /// Tile tasks.
    pub tile_tasks: u64,
    /// Tiles of the planned grid per tile task.
    pub tiles_per_task: u64,
}

/// The lowest and highest tile keys of the inputs' bounds: a LAS header's (read in no time;
/// when it is wrong, points outside it still go to the nearest task), else from a pass over the
/// points.
fn grid_bounds(spec: &RunSpec) -> Result<(TileKey, TileKey)> {
    let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
    for s in &spec.sources {
        let [min, max] = match declared_bounds(s.as_ref()) {
            Some(b) => b,
            None => s.bounds()?,
        };
        let (a, b) = (spec.grid.key(min[0], min[1]), spec.grid.key(max[0], max[1]));
        lo = (lo.0.min(a.0), lo.1.min(a.1));
        hi = (hi.0.max(b.0), hi.1.max(b.1));
    }
    Ok(if lo.0 > hi.0 {
        ((0, 0), (0, 0))
    } else {
        (lo, hi)
    })
}

/// How `plan` splits a run into tasks: tiles of the grid per tile task (None: as few as keep
/// the tasks within [`crate::core::tasks::DEFAULT_MAX_TASKS`]) and points per bucket task
/// (None: [`DEFAULT_POINTS_PER_SCAN_TASK`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Split {
    /// Tiles of the grid per tile task.
    pub tiles_per_task: Option<u64>,
    /// Points of one input per bucket task, at most (LAZ: to the nearest chunk).
    pub points_per_scan_task: Option<u64>,
}

/// The bucket tasks of `spec`: each input alone, a large one split into ranges of about
/// `per_task` points where its format allows (LAS records anywhere, LAZ at chunk starts).
fn scan_tasks(spec: &RunSpec, per_task: u64) -> Vec<Vec<ScanRange>> {
    let mut tasks = Vec::new();
    for (input, s) in spec.sources.iter().enumerate() {
        for points in split_points(s.len(), per_task, &s.cuts()) {
            tasks.push(vec![ScanRange { input, points }]);
        }
    }
    tasks
}

/// `tilecurv plan`: opens and checks `inputs` (absolute paths: the tasks run elsewhere),
/// creates the work directory `work` if needed and writes its manifest and task layout (bucket
/// tasks of an input or a range of its points; tile tasks of tiles of the grid over the
/// inputs' bounds), as `split` says.
pub fn plan(
    inputs: &[PathBuf],
    params: RunParams,
    work: &Path,
    split: Split,
    reporter: &dyn Reporter,
) -> Result<Planned> {
    if split.tiles_per_task == Some(0) {
        return Err(Error::Usage("--tiles-per-task must be at least 1".into()));
    }
    if split.points_per_scan_task == Some(0) {
        return Err(Error::Usage(
            "--points-per-scan-task must be at least 1 (a number of points, e.g. 50M)".into(),
        ));
    }
    let spec = open_inputs(inputs, params, reporter)?;
    let (lo, hi) = grid_bounds(&spec)?;
    let per_scan = split
        .points_per_scan_task
        .unwrap_or(DEFAULT_POINTS_PER_SCAN_TASK);
    let buckets = scan_tasks(&spec, per_scan);
    let layout = TaskLayout::new(buckets, lo, hi, split.tiles_per_task);
    let run = Run::plan(spec, work, layout, reporter)?;
    Ok(Planned {
        bucket_tasks: run.layout.bucket_tasks.len(),
        tile_tasks: run.layout.tile_tasks(),
        tiles_per_task: run.layout.tiles_per_task,
    })
}

/// `tilecurv bucket`: bucket task `task`, or every bucket task not done yet. Returns the number
/// of tasks run (done ones are skipped).
pub fn bucket(
    path: &Path,
    opts: &ExecOptions,
    task: Option<usize>,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<usize> {
    let run = Run::attach(path, reporter)?;
    let exec = Exec::new(opts, &run.spec, reporter, cancel)?;
    let tasks: Vec<usize> = match task {
        Some(t) => vec![t],
        None => (0..run.layout.bucket_tasks.len()).collect(),
    };
    let mut ran = 0;
    for t in tasks {
        ran += bucket_task(&run, t, false, &exec)?.is_some() as usize;
    }
    Ok(ran)
}

/// `tilecurv run-tile`: the tiles of tile task `task` that are not done yet.
pub fn run_tile(
    path: &Path,
    opts: &ExecOptions,
    task: u64,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<TilesDone> {
    let run = Run::attach(path, reporter)?;
    let n = run.layout.tile_tasks();
    if task >= n {
        return Err(Error::Usage(format!(
            "--task {task}: there are {n} tile tasks (0 to {})",
            n - 1
        )));
    }
    let exec = Exec::new(opts, &run.spec, reporter, cancel)?;
    let scan = open_buckets(&run)?;
    tiles(&run, &scan, Some(task), &exec)
}

/// Which tile tasks are done.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Status {
    /// Tile tasks whose every tile is finished.
    pub done: u64,
    /// Tile tasks in the layout.
    pub total: u64,
    /// The others, ascending.
    pub missing: Vec<u64>,
}

/// `tilecurv status`: the tile tasks done and missing (all missing until the buckets are).
pub fn status(path: &Path, reporter: &dyn Reporter) -> Result<Status> {
    let run = Run::attach(path, reporter)?;
    let total = run.layout.tile_tasks();
    let missing: Vec<u64> = match open_buckets(&run) {
        Ok(scan) => {
            let tplan = run.spec.tile_plan(&scan.stats);
            let mut m: Vec<u64> = run
                .missing_tiles(&tplan)?
                .into_iter()
                .map(|(task, _)| task)
                .collect();
            m.sort_unstable();
            m.dedup();
            m
        }
        Err(Error::TasksMissing { .. }) => (0..total).collect(),
        Err(e) => return Err(e),
    };
    Ok(Status {
        done: total - missing.len() as u64,
        total,
        missing,
    })
}

/// `tilecurv assemble`: one output per input from the finished tiles (`output` names them as
/// `process -o` does); refuses, writing nothing, while tile tasks are missing.
pub fn assemble(
    path: &Path,
    output: &Path,
    opts: &ExecOptions,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<Summary> {
    let started = Instant::now();
    let mut run = Run::attach(path, reporter)?;
    let exec = Exec::new(opts, &run.spec, reporter, cancel)?;
    let scan = open_buckets(&run)?;
    let tplan = run.spec.tile_plan(&scan.stats);
    let missing = run.missing_tiles(&tplan)?;
    if !missing.is_empty() {
        let tasks: Vec<u64> = missing.iter().map(|(t, _)| *t).collect();
        return Err(Error::TasksMissing {
            stage: "run-tile",
            tasks: array_syntax(&tasks),
            hint: format!(
                "{} tiles have no result; resubmit `tilecurv status --work {} --missing` and assemble again; nothing was written",
                missing.len(),
                path.display()
            ),
        });
    }
    set_outputs(&mut run.spec, output, reporter)?;
    let undefined = super::assemble::assemble_outputs(&run, &tplan, &exec)?;
    Ok(Summary {
        points: run.spec.total_points,
        undefined,
        tiles: tplan.tiles.len(),
        tiles_resumed: tplan.tiles.len(),
        retried: 0,
        seconds: started.elapsed().as_secs_f64(),
        outputs: run.spec.outputs.clone(),
    })
}

/// Gives `spec` the outputs `output` names, after the checks `process` makes of them.
fn set_outputs(spec: &mut RunSpec, output: &Path, reporter: &dyn Reporter) -> Result<()> {
    let outputs = output_paths(&spec.inputs, output)?;
    check_outputs(&spec.inputs, &outputs)?;
    let ply = spec.output_options.ply_names;
    for note in check_output_columns(&spec.params, &spec.sources, &outputs, &spec.cols, ply)? {
        reporter.warn(&note);
    }
    // The output's folder, made as `process` makes it (there, with the work directory beside).
    for parent in outputs.iter().filter_map(|o| o.parent()) {
        if !parent.as_os_str().is_empty() {
            std::fs::create_dir_all(parent).map_err(|e| Error::write(parent, e))?;
        }
    }
    spec.outputs = outputs;
    Ok(())
}
