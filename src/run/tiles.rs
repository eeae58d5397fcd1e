//! The tiles stage: plans the tiles from the scan statistics, then computes every tile whose
//! result is not yet in the work directory. Tile drivers (as many as the memory plan has tiles
//! in flight: one per worker thread while the budget allows, at least 2) each take the next
//! tile, load it (part by part when it is too dense for its share of the budget) and compute
//! it: on a worker thread of the driver's own while many tiles are left, so that the threads
//! never wait for each other within a tile (the shared pool's fork-join steps left a core idle
//! a tenth of the time), and on the shared rayon pool for the last tiles and for any tile that
//! holds a large share of the work, so that no core idles at the end. A result writer journals
//! each finished tile. Results and errors travel on one channel: the first error stops the
//! drivers, the tiles finished before it stay journalled, and a signal is honoured between
//! tile parts.

use std::collections::HashSet;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

use crossbeam_channel::bounded;
use rayon::ThreadPool;

use crate::config::OrientMode;
use crate::core::compute::{
    compute_tile, ComputeParams, PointResult, Shared, TileBuffers, TileOutcome,
};
use crate::core::estimate::flags;
use crate::core::normals::Orientation;
use crate::core::plan::{plan, ScanStats, TilePlan, TileSpec};
use crate::core::point::BUCKET_POINT_BYTES;
use crate::core::tasks::TaskLayout;
use crate::core::tile::{split_parts, Part, TilePoints};
use crate::error::{Error, Result};
use crate::io::bucket::{load_tile, Buckets};
use crate::io::columns::ColumnSet;
use crate::io::results::{is_complete, orientation_path, tile_path, Journal, TileSidecar};
use crate::io::workdir::{sweep_dead_temps, WorkDir};
use crate::run::bucket::Bucketed;
use crate::run::spec::RunSpec;
use crate::run::{Exec, WORKER_STACK};

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

/// What to compute per point, once the scan has seen the cloud's centroid.
pub fn compute_params<'s>(spec: &'s RunSpec, stats: &ScanStats) -> ComputeParams<'s> {
    ComputeParams {
        k: spec.k,
        radius: spec.radius,
        // A viewpoint is given in file coordinates: its z converts like the points'.
        orientation: match spec.orientation.resolve(stats.centroid()) {
            Orientation::Viewpoint([x, y, z]) => Orientation::Viewpoint([x, y, z * spec.z_scale]),
            o => o,
        },
        use_file_normals: spec.file_normals,
        estimator: spec.estimator.as_ref(),
        extra: spec.cols.extra.len(),
        propagate: (spec.orientation == OrientMode::Propagate).then_some(stats.centroid()),
        ladder: spec.ladder,
    }
}

/// Whether a tile of the plan is finished: its result file is complete (and, with
/// `--orient propagate`, its orientation sidecar is there: it is renamed first).
pub fn tile_done(dir: &Path, t: &TileSpec, cols: &ColumnSet, propagate: bool) -> bool {
    (!propagate || orientation_path(dir, t.key).exists())
        && is_complete(&tile_path(dir, t.key), t.count, cols)
}

/// Everything a tile's computation reads, shared by the drivers.
pub struct TileJob<'a> {
    /// The buckets.
    pub buckets: &'a Buckets,
    /// The tile plan.
    pub plan: &'a TilePlan,
    /// What to compute per point.
    pub params: &'a ComputeParams<'a>,
    /// Tiles with more core points are computed in quadtree parts.
    pub max_core_points: usize,
}

/// One tile's results, orientation sidecar and retried-point count.
pub type TileResult = (Vec<PointResult>, TileSidecar, u64);

impl TileJob<'_> {
    /// Computes one tile, all its parts in order, on `pool` with the driver's buffers (`exec`
    /// for the signal and the progress).
    pub fn compute(
        &self,
        spec: &TileSpec,
        exec: &Exec<'_>,
        pool: &ThreadPool,
        bufs: &mut TileBuffers,
    ) -> Result<TileResult> {
        let whole = Part::whole(self.plan.grid.rect(spec.key));
        let parts = if (spec.count as usize) <= self.max_core_points {
            vec![whole]
        } else {
            split_parts(
                self.buckets.core(spec.key)?.xyz(),
                whole,
                self.max_core_points,
            )
        };
        let mut gathered = Vec::new();
        let mut sidecar = TileSidecar::default();
        let mut retried = 0;
        for part in parts {
            if exec.cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            let t = load_tile(
                self.buckets,
                spec.key,
                &part,
                spec.halo,
                None,
                &self.plan.per_tile,
            )?;
            let (mut results, again) = pool.install(|| {
                self.compute_verified(spec, &part, t, &mut sidecar, bufs, exec.cancel)
            })?;
            retried += again;
            exec.reporter.advance(results.len() as u64);
            // A whole tile (one part) hands its results over without a copy.
            if gathered.is_empty() {
                gathered = results;
            } else {
                gathered.append(&mut results);
            }
        }
        Ok((gathered, sidecar, retried))
    }

    /// Computes a part, recomputing with a doubled halo the core points whose neighbourhoods
    /// were not verified complete, until none is left (the loaded region eventually covers the
    /// scene, where every neighbourhood is complete). Returns the results and the number of
    /// retried points.
    fn compute_verified(
        &self,
        spec: &TileSpec,
        part: &Part,
        tile: TilePoints,
        sidecar: &mut TileSidecar,
        bufs: &mut TileBuffers,
        cancel: &AtomicBool,
    ) -> Result<(Vec<PointResult>, u64)> {
        // With `--orient propagate` each pass numbers its patches after the tile's earlier ones
        // and reports their anchors and shared normals.
        let keep = |o: &mut TileOutcome, sidecar: &mut TileSidecar| {
            if let Some(or) = o.orientation.take() {
                sidecar.anchors.extend(or.anchors);
                sidecar.shared.extend(or.shared);
            }
        };
        let scene = &self.plan.scene;
        let band = Shared::Band {
            rect: part.rect,
            width: spec.halo,
        };
        let first = sidecar.anchors.len() as u32;
        let mut outcome = compute_tile(&tile, scene, self.params, first, band, bufs, cancel)
            .map_err(|_| Error::Interrupted)?;
        keep(&mut outcome, sidecar);
        drop(tile);
        let mut results = std::mem::take(&mut outcome.done);
        let mut retry = outcome.retry;
        let mut halo = spec.halo;
        let mut retried = 0u64;
        while !retry.is_empty() {
            // Each wider-halo pass loads more of the scene: a signal must not wait for them all.
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            retried += retry.len() as u64;
            halo *= 2.0;
            let only: HashSet<u64> = retry.iter().copied().collect();
            let t = load_tile(
                self.buckets,
                spec.key,
                part,
                halo,
                Some(&only),
                &self.plan.per_tile,
            )?;
            let covers = t.region.covers(scene);
            let first = sidecar.anchors.len() as u32;
            let mut o = compute_tile(&t, scene, self.params, first, Shared::All, bufs, cancel)
                .map_err(|_| Error::Interrupted)?;
            keep(&mut o, sidecar);
            results.append(&mut o.done);
            retry = o.retry;
            if covers && !retry.is_empty() {
                return Err(Error::Internal(format!(
                    "tile {:?}: {} points unverified with the whole scene loaded",
                    spec.key,
                    retry.len()
                )));
            }
        }
        Ok((results, retried))
    }
}

/// The tiles of `tplan` that are not finished in `results_dir`, with the tile task of each.
pub fn missing_tiles<'p>(
    results_dir: &Path,
    spec: &RunSpec,
    tplan: &'p TilePlan,
    layout: &TaskLayout,
) -> Vec<(u64, &'p TileSpec)> {
    let propagate = spec.orientation == OrientMode::Propagate;
    tplan
        .tiles
        .iter()
        .filter(|t| !tile_done(results_dir, t, &spec.cols, propagate))
        .map(|t| (layout.task_of(t.key), t))
        .collect()
}

/// Runs the tiles stage over `work`: plans the tiles from the scan statistics, skips the
/// finished ones, computes the others (only those of tile task `task` of `layout` when given)
/// and journals them in `results/`.
pub fn tiles(
    work: &WorkDir,
    spec: &RunSpec,
    scan: &Bucketed,
    layout: &TaskLayout,
    task: Option<u64>,
    exec: &Exec<'_>,
) -> Result<TilesDone> {
    let params = compute_params(spec, &scan.stats);
    let tplan = plan(&scan.stats, spec.grid.size, spec.k, spec.radius);
    let results_dir = work.path().join("results");
    std::fs::create_dir_all(&results_dir).map_err(|e| Error::write(&results_dir, e))?;
    // Result files and sidecars that killed runs of this host left half-written.
    sweep_dead_temps(&results_dir);
    let propagate = params.propagate.is_some();
    let mine = |t: &TileSpec| task.is_none_or(|i| layout.task_of(t.key) == i);
    let todo: Vec<TileSpec> = missing_tiles(&results_dir, spec, &tplan, layout)
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
    exec.reporter.advance(done_points);
    let job = TileJob {
        buckets: &scan.buckets,
        plan: &tplan,
        params: &params,
        max_core_points: exec.memory.max_core_points,
    };
    let (undefined, retried) = match drive(&job, &todo, &results_dir, &spec.cols, exec) {
        Ok(v) => v,
        Err(e) => {
            if matches!(e, Error::Interrupted) {
                let done = tplan
                    .tiles
                    .iter()
                    .filter(|t| tile_done(&results_dir, t, &spec.cols, propagate))
                    .count();
                exec.reporter.warn(&format!(
                    "interrupted after {done} of {} tiles; the work is kept in {}",
                    tplan.tiles.len(),
                    work.path().display()
                ));
            }
            return Err(e);
        }
    };
    exec.reporter.finish_phase();
    Ok(TilesDone {
        plan: tplan,
        resumed,
        undefined,
        retried,
    })
}

fn report_plan(spec: &RunSpec, scan: &Bucketed, tplan: &TilePlan, resumed: usize, exec: &Exec<'_>) {
    // The scan leaves out the points the class filter does not select.
    let skipped = spec.total_points.saturating_sub(scan.stats.count);
    if scan.stats.count == 0 {
        exec.reporter.warn(&format!(
            "no point is selected by the class filter ({}); every point is written as not computed (flag 128)",
            spec.select.describe()
        ));
    } else if skipped > 0 {
        exec.reporter.info(&format!(
            "{} of {} points selected ({}); the other {skipped} are written as not computed (flag 128)",
            scan.stats.count,
            spec.total_points,
            spec.select.describe()
        ));
    }
    exec.reporter.info(&format!(
        "plan: {} tiles of {:.3} {}{}; buckets {}",
        tplan.tiles.len(),
        spec.grid.size,
        spec.unit_name,
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

/// A finished tile on its way to the journal.
struct Finished {
    spec: TileSpec,
    results: Vec<PointResult>,
    sidecar: Option<TileSidecar>,
    retried: u64,
}

/// Runs `todo` with the memory plan's number of drivers (each with a worker of its own when
/// there is one per thread, see [`pool_for`]) and one result writer. Tiles finish in any
/// order: each has its own result file, and the parts of a tile stay with one driver, in order
/// (patch numbering). Returns (undefined points, retried points).
fn drive(
    job: &TileJob<'_>,
    todo: &[TileSpec],
    results_dir: &Path,
    cols: &ColumnSet,
    exec: &Exec<'_>,
) -> Result<(u64, u64)> {
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let propagate = job.params.propagate.is_some();
    let drivers = exec.memory.tiles_in_flight.max(1);
    // Workers of their own for the drivers when there is one driver per thread (not with
    // `--threads 1`, whose 2 drivers share its one worker, nor when the budget keeps fewer
    // drivers than threads: `MemoryPlan::tiles_in_flight`).
    let solo = drivers == exec.pool.current_num_threads();
    // Points in the tiles no driver has taken yet.
    let left = AtomicU64::new(todo.iter().map(|t| t.count).sum());
    std::thread::scope(|s| -> Result<(u64, u64)> {
        let (tx, rx) = bounded::<Result<Finished>>(1);
        let (mut started, mut refused) = (0, None);
        for _ in 0..drivers {
            let tx = tx.clone();
            let (next, stop, left) = (&next, &stop, &left);
            let driver = std::thread::Builder::new().name("tile driver".into());
            let spawned = driver.spawn_scoped(s, move || {
                let mut bufs = TileBuffers::default();
                let own = solo.then(solo_pool).flatten();
                while !stop.load(Ordering::Relaxed) {
                    let Some(spec) = todo.get(next.fetch_add(1, Ordering::Relaxed)) else {
                        return;
                    };
                    let before = left.fetch_sub(spec.count, Ordering::Relaxed);
                    let pool = pool_for(own.as_ref(), &exec.pool, spec.count, before, drivers);
                    let msg = if exec.cancel.load(Ordering::Relaxed) {
                        Err(Error::Interrupted)
                    } else {
                        job.compute(spec, exec, pool, &mut bufs).map(
                            |(results, sidecar, retried)| Finished {
                                spec: spec.clone(),
                                results,
                                sidecar: propagate.then_some(sidecar),
                                retried,
                            },
                        )
                    };
                    let failed = msg.is_err();
                    // A failed send means the writer stopped, and it reports why.
                    if tx.send(msg).is_err() || failed {
                        return;
                    }
                }
            });
            match spawned {
                Ok(_) => started += 1,
                Err(e) => {
                    refused = Some(e);
                    break;
                }
            }
        }
        drop(tx);
        // A machine out of threads or address space: fewer drivers, or none and an error.
        if let Some(e) = refused {
            if started == 0 {
                return Err(Error::Resource(format!(
                    "cannot start a thread to compute tiles: {e}; lower --threads, or raise the limits on processes (ulimit -u) or memory (ulimit -v), then run the same command again: it resumes"
                )));
            }
            exec.reporter.warn(&format!(
                "could not start every tile driver ({e}): computing with {started}"
            ));
        }
        let written = write_results(rx, results_dir, cols, &stop);
        let (undefined, retried) = written?;
        if exec.cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        Ok((undefined, retried))
    })
}

/// A pool of one worker thread (with the workers' stack) for a tile driver; None when the
/// thread cannot be started, and the driver then computes on the shared pool.
fn solo_pool() -> Option<ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .stack_size(WORKER_STACK)
        .thread_name(|_| "tile worker".into())
        .build()
        .ok()
}

/// The pool a driver computes a tile of `count` points on when `left` points (the tile's
/// included) were in tiles no driver had taken: its own worker (`own`) while the tile is small
/// against the work left to every driver (at most a quarter of its share), otherwise the shared
/// pool, whose threads share the tile, so that the last tiles of a run, or one tile that holds
/// a large share of it (the dense tile around a terrestrial scanner), do not leave cores idle
/// while one thread computes them. The results do not depend on the pool.
fn pool_for<'p>(
    own: Option<&'p ThreadPool>,
    shared: &'p ThreadPool,
    count: u64,
    left: u64,
    drivers: usize,
) -> &'p ThreadPool {
    match own {
        Some(p) if count.saturating_mul(4 * drivers as u64) <= left => p,
        _ => shared,
    }
}

/// The result writer: journals each finished tile. The first error (a driver's, or the
/// journal's) sets `stop`, so no driver starts another tile; tiles that were already being
/// computed are still journalled, and everything journalled is committed, so the same command
/// resumes after them. Returns (undefined points, retried points).
fn write_results(
    rx: crossbeam_channel::Receiver<Result<Finished>>,
    results_dir: &Path,
    cols: &ColumnSet,
    stop: &AtomicBool,
) -> Result<(u64, u64)> {
    let mut journal = Journal::new(results_dir);
    let (mut undefined, mut retried) = (0u64, 0u64);
    let mut first_error = None;
    for msg in rx.iter() {
        let added = msg.and_then(|f| {
            undefined += f
                .results
                .iter()
                .filter(|r| r.curvature.flags & flags::UNDEFINED != 0)
                .count() as u64;
            retried += f.retried;
            journal.add(
                f.spec.key,
                f.spec.index,
                &f.results,
                f.sidecar.as_ref(),
                cols,
            )
        });
        if let Err(e) = added {
            stop.store(true, Ordering::Relaxed);
            first_error.get_or_insert(e);
        }
    }
    let committed = journal.commit();
    match first_error {
        Some(e) => Err(e),
        None => committed.map(|_| (undefined, retried)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A driver keeps a tile on its own worker while the tile is at most a quarter of its share
    /// of the work left, and hands the last tiles, and a tile holding much of the run, to the
    /// shared pool.
    #[test]
    fn the_last_and_the_largest_tiles_go_to_the_shared_pool() {
        let pool = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .expect("a test pool")
        };
        let (own, shared) = (pool(1), pool(2));
        let on_own =
            |count, left| std::ptr::eq(pool_for(Some(&own), &shared, count, left, 2), &own);
        assert!(on_own(25_000, 20_000_000));
        // 2 drivers: a quarter of each one's share is left / 8.
        assert!(on_own(25_000, 200_000));
        assert!(!on_own(25_000, 199_999));
        assert!(!on_own(5_000_000, 20_000_000));
        // Without a worker of its own (one thread, or none could be started): the shared pool.
        assert!(std::ptr::eq(
            pool_for(None, &shared, 1, u64::MAX, 2),
            &shared
        ));
    }
}
