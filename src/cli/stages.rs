//! The cluster commands: each runs one stage over a work directory (run::cluster) and prints
//! what a scheduler script reads: `plan` the task counts, `status` the tasks done or missing.

use super::args::{AssembleArgs, BucketArgs, PlanArgs, RunTileArgs, StatusArgs};
use super::{exit, fail, fail_run, reporter, CANCEL};
use crate::progress::{out, say};
use crate::run::cluster;

/// `tilecurv plan`: prints `bucket tasks: B`, `tiles per task: K`, then `tasks: N` (the last
/// line of stdout).
pub(super) fn plan(a: PlanArgs) -> Result<i32, i32> {
    let params = a.params().map_err(|e| fail(&e))?;
    let reporter = reporter(a.quiet, None)?;
    let split = cluster::Split {
        tiles_per_task: a.tiles_per_task,
        points_per_scan_task: a.points_per_scan_task,
    };
    let p = cluster::plan(&a.inputs(), params, &a.work, split, &reporter).map_err(|e| fail(&e))?;
    if !a.quiet {
        say!(
            "planned {}: {}, {} of {} of the grid each",
            a.work.display(),
            counted(p.bucket_tasks as u64, "bucket task"),
            counted(p.tile_tasks, "tile task"),
            counted(p.tiles_per_task, "tile")
        );
    }
    out!("bucket tasks: {}", p.bucket_tasks);
    out!("tiles per task: {}", p.tiles_per_task);
    out!("tasks: {}", p.tile_tasks);
    Ok(exit::OK)
}

/// "1 tile", "2 tiles": `n` of `noun` for a message.
fn counted(n: u64, noun: &str) -> String {
    match n {
        1 => format!("1 {noun}"),
        n => format!("{n} {noun}s"),
    }
}

/// `tilecurv bucket`.
pub(super) fn bucket(a: BucketArgs) -> Result<i32, i32> {
    let opts = a.exec.options();
    let reporter = reporter(a.exec.quiet(), opts.progress_json.as_deref())?;
    let task = a
        .task
        .map(|t| t.resolve().map(|i| i as usize))
        .transpose()
        .map_err(|e| fail(&e))?;
    let ran =
        cluster::bucket(&a.work, &opts, task, &reporter, &CANCEL).map_err(|e| fail_run(&e))?;
    if !a.exec.quiet() {
        say!(
            "done: {} run (the others were done)",
            counted(ran as u64, "bucket task")
        );
    }
    Ok(exit::OK)
}

/// `tilecurv run-tile`.
pub(super) fn run_tile(a: RunTileArgs) -> Result<i32, i32> {
    let opts = a.exec.options();
    let reporter = reporter(a.exec.quiet(), opts.progress_json.as_deref())?;
    let task = a.task.resolve().map_err(|e| fail(&e))?;
    let d =
        cluster::run_tile(&a.work, &opts, task, &reporter, &CANCEL).map_err(|e| fail_run(&e))?;
    if !a.exec.quiet() {
        say!(
            "done: task {task}: {} tiles already done, {} undefined points among those computed now, {} points recomputed with a wider halo",
            d.resumed, d.undefined, d.retried
        );
    }
    Ok(exit::OK)
}

/// `tilecurv status`: `done D of N tasks`, or the missing indices with --missing.
pub(super) fn status(a: StatusArgs) -> Result<i32, i32> {
    let reporter = reporter(true, None)?;
    let s = cluster::status(&a.work, &reporter).map_err(|e| fail(&e))?;
    if a.missing {
        if !s.missing.is_empty() {
            out!("{}", crate::core::tasks::array_syntax(&s.missing));
        }
    } else {
        out!("done {} of {} tasks", s.done, s.total);
    }
    Ok(exit::OK)
}

/// `tilecurv assemble`.
pub(super) fn assemble(a: AssembleArgs) -> Result<i32, i32> {
    let opts = crate::config::ExecOptions {
        rasters: a.rasters.options(),
        ..a.exec.options()
    };
    let reporter = reporter(a.exec.quiet(), opts.progress_json.as_deref())?;
    let s = cluster::assemble(&a.work, &a.output, &opts, &reporter, &CANCEL)
        .map_err(|e| fail_run(&e))?;
    reporter.summary(&s.json_fields(), s.seconds);
    if !a.exec.quiet() {
        say!(
            "done: {} points of {} tiles in {:.1} s, {} undefined ({:.2}%) -> {} (the work directory {} is kept; remove it when done)",
            s.points,
            s.tiles,
            s.seconds,
            s.undefined,
            100.0 * s.undefined as f64 / s.points.max(1) as f64,
            a.output.display(),
            a.work.display()
        );
    }
    Ok(exit::OK)
}
