//! The bucket stage: a streaming pass over the inputs that puts every point in the bucket of
//! its core tile and gathers the scan statistics (bounds, counts per tile, centroid). It runs
//! as bucket tasks (the task layout's ranges of points of the inputs), each writing its own
//! directory `buckets/t<task>/`, so that a cluster scans many files, and parts of one huge
//! file, at once; `process` runs one task over every input and keeps its buckets in memory
//! while they fit. A task whose directory is complete is not run again.

use std::sync::atomic::Ordering;

use crate::error::{Error, Result};
pub(crate) use crate::io::workdir::bucket::Bucketed;
use crate::io::workdir::bucket::{scan, task_stats, Buckets, ScanInput};
use crate::run::spec::RunSpec;
use crate::run::{Exec, Run};

/// Points per read chunk for the inputs of `spec`: the user's choice, capped by the budget.
pub(crate) fn chunk_points(spec: &RunSpec, exec: &Exec<'_>) -> usize {
    let widest = spec
        .sources
        .iter()
        .map(|s| s.record_length())
        .max()
        .unwrap_or(1);
    exec.memory.chunk_points(exec.chunk_points, widest)
}

/// Runs bucket task `task` of `run` unless its directory is already complete (then None).
/// With `keep_in_memory` (`process`), buckets that fit the budget are returned in memory and
/// not written.
pub(crate) fn bucket_task(
    run: &Run,
    task: usize,
    keep_in_memory: bool,
    exec: &Exec<'_>,
) -> Result<Option<Bucketed>> {
    let (spec, layout) = (&run.spec, &run.layout);
    let ranges = layout.bucket_tasks.get(task).ok_or_else(|| {
        Error::Usage(format!(
            "--task {task}: there are {} bucket tasks (0 to {})",
            layout.bucket_tasks.len(),
            layout.bucket_tasks.len().saturating_sub(1)
        ))
    })?;
    let dir = run.work.bucket_task_dir(task);
    if task_stats(&dir).is_some() {
        return Ok(None);
    }
    run.work.prepare_buckets()?;
    let scan_inputs: Vec<ScanInput<'_>> = ranges
        .iter()
        .map(|r| ScanInput {
            source: spec.sources[r.input].as_ref(),
            first_id: spec.first_ids[r.input],
            points: r.points.clone(),
            z_scale: spec.resolved.z_scale,
            select: &spec.params.select,
        })
        .collect();
    let points = scan_inputs
        .iter()
        .map(|s| s.points.end - s.points.start)
        .sum();
    exec.reporter.phase("scan", points);
    let chunk = chunk_points(spec, exec);
    let bucketed = exec.pool.install(|| {
        scan(
            &scan_inputs,
            spec.grid,
            chunk,
            &exec.memory,
            &dir,
            keep_in_memory,
            |n| {
                exec.reporter.advance(n);
                if exec.cancel.load(Ordering::Relaxed) {
                    Err(Error::Interrupted)
                } else {
                    Ok(())
                }
            },
        )
    })?;
    exec.reporter.finish_phase();
    Ok(Some(bucketed))
}

/// The buckets of every bucket task of `run`, from their directories; an error naming the
/// tasks that are not done yet.
pub(crate) fn open_buckets(run: &Run) -> Result<Bucketed> {
    let dirs = run.work.bucket_task_dirs(run.layout.bucket_tasks.len());
    match Buckets::open(run.spec.grid, &dirs) {
        Ok(b) => Ok(b),
        Err(missing) => Err(Error::TasksMissing {
            stage: "bucket",
            tasks: crate::core::tasks::array_syntax(
                &missing.iter().map(|&t| t as u64).collect::<Vec<_>>(),
            ),
            hint: format!(
                "run `tilecurv bucket --work {} --task I` for each (or once without --task)",
                run.work.path().display()
            ),
        }),
    }
}

/// The bucket stage of `process` (its layout has one bucket task over every input): the scan,
/// in memory while the buckets fit, or the buckets an interrupted run of the same manifest left
/// complete.
///
/// Buckets whose files were released once every tile was done (a run stopped while writing
/// its outputs) serve while no tile is missing; if one is (a result file deleted since), they
/// are scanned again.
pub(crate) fn bucket_all(run: &Run, exec: &Exec<'_>) -> Result<Bucketed> {
    if let Some(b) = bucket_task(run, 0, true, exec)? {
        return Ok(b);
    }
    let b = open_buckets(run)?;
    if !run.work.bucket_files_released() {
        exec.reporter
            .info("reusing the buckets of the interrupted run");
        return Ok(b);
    }
    if run.missing_tiles(&run.spec.tile_plan(&b.stats))?.is_empty() {
        exec.reporter
            .info("every tile of the interrupted run is done: writing the outputs");
        return Ok(b);
    }
    exec.reporter
        .info("tiles are missing and the interrupted run's buckets were released: scanning again");
    run.work.discard_buckets()?;
    bucket_task(run, 0, true, exec)?.ok_or_else(|| {
        Error::damaged_work(
            &run.work.bucket_task_dir(0),
            "holds buckets just deleted; delete the work directory and run again",
        )
    })
}
