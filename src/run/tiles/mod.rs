//! The tiles stage: plans the tiles from the scan statistics, then computes every tile whose
//! result is not yet in the work directory. Tile drivers (as many as the memory plan has tiles
//! in flight: one per worker thread while the budget allows, at least 2) each take the next
//! tile, load it (part by part when it is too dense for its share of the budget) and compute
//! it: on a worker thread of the driver's own while many tiles are left, so that the threads
//! never wait for each other within a tile, and on the shared rayon pool for the last tiles and for any tile that
//! holds a large share of the work, so that no core idles at the end. A result writer journals
//! each finished tile. Results and errors travel on one channel: the first error stops the
//! drivers, the tiles finished before it stay journalled, and a signal is honoured between
//! tile parts.

mod drive;
mod job;
mod journal;

use crate::core::plan::{TilePlan, TileSpec};
use crate::core::point::BUCKET_POINT_BYTES;
use crate::error::{Error, Result};
use crate::run::bucket::Bucketed;
use crate::run::spec::RunSpec;
use crate::run::{Exec, Run};
use drive::drive;
pub(crate) use job::TileJob;

/// What the tiles stage did.
#[derive(Debug, Clone)]
pub struct TilesDone {
    /// The tile plan (the assemble stage merges its tiles' results).
    pub plan: TilePlan,
    /// Tiles found finished from an earlier run.
    pub resumed: usize,
    /// Points computed in this run whose curvature is undefined.
    pub undefined: u64,
    /// Points recomputed with a wider halo after verification.
    pub retried: u64,
}

/// Runs the tiles stage of `run`: plans the tiles from the scan statistics, skips the
/// finished ones, computes the others (only those of tile task `task` when given) and
/// journals them in the result store.
pub(crate) fn tiles(
    run: &Run,
    scan: &Bucketed,
    task: Option<u64>,
    exec: &Exec<'_>,
) -> Result<TilesDone> {
    let spec = &run.spec;
    let params = spec.compute_params(&scan.stats);
    let tplan = spec.tile_plan(&scan.stats);
    let store = run.work.results()?;
    let propagate = params.propagate.is_some();
    let mine = |t: &TileSpec| task.is_none_or(|i| run.layout.task_of(t.key) == i);
    let todo: Vec<TileSpec> = run
        .missing_tiles(&tplan)?
        .into_iter()
        .map(|(_, t)| t)
        .filter(|t| mine(t))
        .cloned()
        .collect();
    let resumed = tplan.tiles.iter().filter(|t| mine(t)).count() - todo.len();
    report_plan(spec, scan, &tplan, resumed, exec);
    if scan.buckets.spilled() {
        scan.buckets
            .set_cache_budget(exec.memory.bucket_cache_bytes);
    }
    if let Some(t) = todo
        .iter()
        .find(|t| t.count as usize * BUCKET_POINT_BYTES > exec.memory.per_tile_bytes)
    {
        exec.reporter.warn(&format!(
            "tile {:?} holds {} points, whose raw bucket alone exceeds the {} MiB the budget leaves per tile; memory may exceed --memory: use a smaller --tile or a larger --memory",
            t.key,
            t.count,
            exec.memory.per_tile_bytes >> 20
        ));
    }
    let points: u64 = tplan
        .tiles
        .iter()
        .filter(|t| mine(t))
        .map(|t| t.count)
        .sum();
    let done_points: u64 = points - todo.iter().map(|t| t.count).sum::<u64>();
    exec.reporter.phase("curvature", points);
    exec.reporter.resumed(done_points);
    let job = TileJob {
        buckets: &scan.buckets,
        plan: &tplan,
        params: &params,
        memory: exec.memory,
    };
    let tally = match drive(&job, &todo, store.journal(), &spec.cols, exec) {
        Ok(v) => v,
        Err(e) => {
            if matches!(e, Error::Interrupted) {
                let done = tplan
                    .tiles
                    .iter()
                    .filter(|t| store.tile_done(t, &spec.cols, propagate))
                    .count();
                exec.reporter.warn(&format!(
                    "interrupted after {done} of {} tiles; the work is kept in {}",
                    tplan.tiles.len(),
                    run.work.path().display()
                ));
            }
            return Err(e);
        }
    };
    exec.reporter.finish_phase();
    Ok(TilesDone {
        plan: tplan,
        resumed,
        undefined: tally.undefined,
        retried: tally.retried,
    })
}

fn report_plan(spec: &RunSpec, scan: &Bucketed, tplan: &TilePlan, resumed: usize, exec: &Exec<'_>) {
    // The scan leaves out the points the class filter does not select.
    let skipped = spec.total_points.saturating_sub(scan.stats.count);
    if scan.stats.count == 0 {
        exec.reporter.warn(&format!(
            "no point is selected by the class filter ({}); every point is written as not computed (flag 128)",
            spec.params.select.describe()
        ));
    } else if skipped > 0 {
        exec.reporter.info(&format!(
            "{} of {} points selected ({}); the other {skipped} are written as not computed (flag 128)",
            scan.stats.count,
            spec.total_points,
            spec.params.select.describe()
        ));
    }
    exec.reporter.info(&format!(
        "plan: {} tiles of {}{}; buckets {}",
        tplan.tiles.len(),
        crate::io::raster::length_text(spec.grid.size, &spec.cols.unit),
        if resumed > 0 {
            format!(", {resumed} already done")
        } else {
            String::new()
        },
        if scan.buckets.spilled() {
            "spilled to the work directory"
        } else {
            "in memory"
        }
    ));
}
