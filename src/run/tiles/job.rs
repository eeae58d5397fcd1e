//! One tile's computation: its parts in order, each computed and its halo verified, the
//! points whose neighbourhoods were not verified complete recomputed with a doubled halo until
//! none is left.

use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::ThreadPool;

use crate::core::compute::{
    compute_tile, ComputeParams, PointResult, Shared, TileBuffers, TileOutcome,
};
use crate::core::plan::{MemoryPlan, TilePlan, TileSpec};
use crate::core::tile::{split_parts, Part, TilePoints};
use crate::error::{Error, Result};
use crate::io::workdir::bucket::{load_tile, Buckets};
use crate::io::workdir::results::TileSidecar;
use crate::run::Exec;

/// A part's results once every neighbourhood was verified.
struct Verified {
    results: Vec<PointResult>,
    retried: u64,
}

/// Everything a tile's computation reads, shared by the drivers.
pub(crate) struct TileJob<'a> {
    /// The buckets.
    pub buckets: &'a Buckets,
    /// The tile plan.
    pub plan: &'a TilePlan,
    /// What to compute per point.
    pub params: &'a ComputeParams<'a>,
    /// How the budget is shared: a tile whose core and halo do not fit its share is computed
    /// in quadtree parts ([`MemoryPlan::core_points_per_part`]).
    pub memory: MemoryPlan,
}

/// One computed tile.
pub(crate) struct ComputedTile {
    /// Its core points' results.
    pub results: Vec<PointResult>,
    /// Its orientation sidecar (`--orient propagate`).
    pub sidecar: TileSidecar,
    /// Points recomputed with a wider halo.
    pub retried: u64,
}

impl TileJob<'_> {
    /// Computes one tile, all its parts in order, on `pool` with the driver's buffers (`exec`
    /// for the signal and the progress).
    pub(crate) fn compute(
        &self,
        spec: &TileSpec,
        exec: &Exec<'_>,
        pool: &ThreadPool,
        bufs: &mut TileBuffers,
    ) -> Result<ComputedTile> {
        let whole = Part::whole(self.plan.grid.rect(spec.key));
        let size = self.plan.grid.size;
        let per_part = self
            .memory
            .core_points_per_part(spec.halo, spec.count as f64 / (size * size));
        let parts = if (spec.count as usize) <= per_part {
            vec![whole]
        } else {
            split_parts(self.buckets.core(spec.key)?.xyz(), whole, per_part)
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
            let mut verified = pool.install(|| {
                self.compute_verified(spec, &part, t, &mut sidecar, bufs, exec.cancel)
            })?;
            retried += verified.retried;
            let mut results = std::mem::take(&mut verified.results);
            exec.reporter.advance(results.len() as u64);
            // A whole tile (one part) hands its results over without a copy.
            if gathered.is_empty() {
                gathered = results;
            } else {
                gathered.append(&mut results);
            }
        }
        Ok(ComputedTile {
            results: gathered,
            sidecar,
            retried,
        })
    }

    /// Computes a part, recomputing with a doubled halo the core points whose neighbourhoods
    /// were not verified complete, until none is left (the loaded region eventually covers the
    /// scene, where every neighbourhood is complete).
    fn compute_verified(
        &self,
        spec: &TileSpec,
        part: &Part,
        tile: TilePoints,
        sidecar: &mut TileSidecar,
        bufs: &mut TileBuffers,
        cancel: &AtomicBool,
    ) -> Result<Verified> {
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
        Ok(Verified { results, retried })
    }
}
