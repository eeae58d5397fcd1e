//! The tiles stage's scheduler: tile drivers (as many as the memory plan has tiles in flight)
//! each take the next tile and compute it, on a worker thread of the driver's own while many
//! tiles are left and on the shared pool for the last ones and for any tile holding a large
//! share of the work; one result writer journals what they finish.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

use crossbeam_channel::bounded;
use rayon::ThreadPool;

use super::job::TileJob;
use super::journal::{write_results, Finished, Tally};
use crate::core::compute::TileBuffers;
use crate::core::plan::TileSpec;
use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::workdir::results::Journal;
use crate::run::{Exec, WORKER_STACK};

/// Runs `todo` with the memory plan's number of drivers (each with a worker of its own when
/// there is one per thread, see [`pool_for`]) and one result writer. Tiles finish in any
/// order: each has its own result file, and the parts of a tile stay with one driver, in order
/// (patch numbering).
pub(super) fn drive(
    job: &TileJob<'_>,
    todo: &[TileSpec],
    journal: Journal,
    cols: &ColumnSet,
    exec: &Exec<'_>,
) -> Result<Tally> {
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
    std::thread::scope(|s| -> Result<Tally> {
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
                        job.compute(spec, exec, pool, &mut bufs).map(|t| Finished {
                            spec: spec.clone(),
                            results: t.results,
                            sidecar: propagate.then_some(t.sidecar),
                            retried: t.retried,
                        })
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
        let tally = write_results(rx, journal, cols, &stop)?;
        if exec.cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        Ok(tally)
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
