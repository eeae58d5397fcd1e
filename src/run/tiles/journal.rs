//! The tiles stage's result writer: journals each finished tile in the result store.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::core::compute::PointResult;
use crate::core::estimate::flags;
use crate::core::plan::TileSpec;
use crate::error::Result;
use crate::io::columns::ColumnSet;
use crate::io::workdir::results::{Journal, TileSidecar};

/// What the journalled tiles hold.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Tally {
    /// Points whose curvature is undefined.
    pub undefined: u64,
    /// Points recomputed with a wider halo.
    pub retried: u64,
}

/// A finished tile on its way to the journal.
pub(super) struct Finished {
    /// The tile.
    pub spec: TileSpec,
    /// Its core points' results.
    pub results: Vec<PointResult>,
    /// Its orientation sidecar (`--orient propagate`).
    pub sidecar: Option<TileSidecar>,
    /// Points recomputed with a wider halo.
    pub retried: u64,
}

/// The result writer: journals each finished tile. The first error (a driver's, or the
/// journal's) sets `stop`, so no driver starts another tile; tiles that were already being
/// computed are still journalled, and everything journalled is committed, so the same command
/// resumes after them.
pub(super) fn write_results(
    rx: crossbeam_channel::Receiver<Result<Finished>>,
    mut journal: Journal,
    cols: &ColumnSet,
    stop: &AtomicBool,
) -> Result<Tally> {
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
        None => committed.map(|_| Tally { undefined, retried }),
    }
}
