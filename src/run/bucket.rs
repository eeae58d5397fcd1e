//! The bucket stage: one streaming pass over the inputs that puts every point in the bucket of
//! its core tile and gathers the scan statistics (bounds, counts per tile, centroid). A run
//! resumed after the scan finished reuses the buckets it left in the work directory.

use std::sync::atomic::Ordering;

use crate::core::plan::ScanStats;
use crate::error::{Error, Result};
use crate::io::bucket::{Buckets, ScanInput};
use crate::io::workdir::{Resume, WorkDir};
use crate::run::spec::RunSpec;
use crate::run::Exec;

/// The scan's product: the buckets and what the scan learned.
pub struct Bucketed {
    /// Every tile's core points (in memory, or spilled to the work directory).
    pub buckets: Buckets,
    /// Bounds, counts per tile, centroid.
    pub stats: ScanStats,
}

/// Points per read chunk for the inputs of `spec`: the user's choice, capped by the budget.
pub fn chunk_points(spec: &RunSpec, exec: &Exec<'_>) -> usize {
    let widest = spec
        .sources
        .iter()
        .map(|s| s.record_length())
        .max()
        .unwrap_or(1);
    exec.memory.chunk_points(exec.chunk_points, widest)
}

/// Runs the scan into `work` (its `buckets/` folder when the buckets do not fit the budget),
/// or reopens the buckets a previous run of the same manifest left complete there.
pub fn bucket(work: &WorkDir, spec: &RunSpec, exec: &Exec<'_>) -> Result<Bucketed> {
    let spill_dir = work.path().join("buckets");
    if work.resume == Resume::Resumed {
        if let Some((buckets, stats)) = Buckets::reopen(&spill_dir, spec.grid) {
            exec.reporter
                .info("reusing the buckets of the interrupted run");
            return Ok(Bucketed { buckets, stats });
        }
    }
    exec.reporter.phase("scan", spec.total_points);
    let inputs: Vec<ScanInput<'_>> = spec
        .sources
        .iter()
        .zip(&spec.first_ids)
        .map(|(s, &first_id)| ScanInput {
            source: s.as_ref(),
            first_id,
        })
        .collect();
    let chunk = chunk_points(spec, exec);
    let (buckets, stats) = exec.pool.install(|| {
        Buckets::scan(&inputs, spec.grid, chunk, &exec.memory, &spill_dir, |n| {
            exec.reporter.advance(n);
            if exec.cancel.load(Ordering::Relaxed) {
                Err(Error::Interrupted)
            } else {
                Ok(())
            }
        })
    })?;
    exec.reporter.finish_phase();
    Ok(Bucketed { buckets, stats })
}
