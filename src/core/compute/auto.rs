//! `-k auto` over one loaded tile (algorithms.md 9, 11.3): one k-NN list per point at the top
//! rung's K, each rung a prefix of it (the lists are sorted by the tie rule, so a prefix is the
//! k-NN of its size); per rung, PCA normals from the first K_s / 2 and the estimator from the
//! first K_s; then per core point the criterion from the rungs' H at its 64 nearest, and every
//! value from the chosen rung (core::scale).
//!
//! A core point is computed when its list, the lists of its 64 nearest (their rung estimates
//! are compared) and the normal prefixes of their neighbours are all provably complete; the
//! others are retried with a wider halo like any point, so the result does not depend on the
//! tiling.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::{
    estimate_one, mark, neighbour_lists, stopped, tile_normals, Cancelled, ComputeParams, Estimate,
    ListQuery, NeighbourhoodBuf, PointResult, Reach, TileBuffers, TileOutcome, NO_PATCH,
};
use crate::core::estimate::{flags, Curvature};
use crate::core::geometry::V3;
use crate::core::neighbors::NeighbourIndex;
use crate::core::plan::Rect;
use crate::core::scale::{choose, Ladder, SMOOTH};
use crate::core::tile::TilePoints;

/// Computes the core points of `t` with the scale chosen per point from `ladder`
/// (`p.k` is its top rung; no radius, no propagation: refused by the configuration).
pub(super) fn compute_auto(
    t: &TilePoints,
    scene: &Rect,
    p: &ComputeParams<'_>,
    ladder: Ladder,
    index: &NeighbourIndex<'_>,
    bufs: &mut TileBuffers,
    cancel: &AtomicBool,
) -> Result<TileOutcome, Cancelled> {
    let stop = || stopped(cancel);
    let (n, k, n_core) = (t.xyz.len(), ladder.max, t.n_core);
    let reach = Reach {
        k,
        radius: None,
        prefix: ladder.normal_k(ladder.rungs() - 1),
    };
    // The core lists, those of their 64 nearest, and of those points' neighbours (normals).
    let q = ListQuery {
        t,
        index,
        scene,
        reach,
    };
    neighbour_lists(&q, &[SMOOTH, k], bufs, None, cancel);
    stop()?;
    let bufs = &*bufs;
    let normals = rung_normals(t, p, ladder, bufs, cancel);
    stop()?;
    // A point whose rung estimates are exact: its whole list, and each neighbour's normal
    // prefix, provably complete.
    let exact: Vec<bool> = (0..n).into_par_iter().map(|q| bufs.exact(q, k)).collect();
    let verified: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| i < n_core && smooth(bufs, k, i).iter().all(|&q| exact[q as usize]))
        .collect();
    let retry: Vec<u64> = (0..n_core)
        .filter(|&i| !verified[i])
        .map(|i| t.ids[i])
        .collect();
    // The rungs at every point some verified core point compares.
    let compared = mark(bufs, k, &verified, SMOOTH);
    let rungs = rung_results(t, p, ladder, bufs, &normals, &compared, cancel);
    stop()?;
    let todo: Vec<usize> = (0..n_core).filter(|&i| verified[i]).collect();
    let mut done = Vec::with_capacity(todo.len());
    todo.par_iter()
        .map(|&i| {
            let c: Vec<f64> = (0..ladder.rungs() - 1)
                .map(|s| criterion(&rungs, smooth(bufs, k, i), s))
                .collect();
            let own = rungs.of(i);
            if own.is_empty() {
                // Not reached: a verified point is among its own 64 nearest, so compared.
                return PointResult::not_computed(t.ids[i]);
            }
            let defined: Vec<bool> = own.iter().map(|e| is_defined(&e.curvature)).collect();
            let choice = choose(&c, &defined);
            let Estimate { curvature, extra } = own[choice.rung];
            PointResult {
                id: t.ids[i],
                normal: normals[choice.rung][i].unwrap_or([f64::NAN; 3]),
                curvature,
                extra,
                patch: NO_PATCH,
                scale: ladder.k(choice.rung) as u16,
                scale_flags: choice.flags,
                terrain: p.terrain_of(normals[choice.rung][i], &curvature),
            }
        })
        .collect_into_vec(&mut done);
    stop()?;
    Ok(TileOutcome {
        done,
        retry,
        orientation: None,
    })
}

/// The first [`SMOOTH`] entries of point `i`'s list: the points its criterion averages over
/// (itself first).
fn smooth(bufs: &TileBuffers, k: usize, i: usize) -> &[u32] {
    let l = bufs.list(i, k);
    &l[..l.len().min(SMOOTH)]
}

/// Whether a rung's curvature is defined (H a number, no undefined flag).
fn is_defined(c: &Curvature) -> bool {
    c.h.is_finite() && c.flags & flags::UNDEFINED == 0
}

/// Per rung, the normal of every point with a list: the file's, or PCA from the first
/// K_s / 2 of its list, oriented as usual. `normals[s][i]`.
fn rung_normals(
    t: &TilePoints,
    p: &ComputeParams<'_>,
    ladder: Ladder,
    bufs: &TileBuffers,
    cancel: &AtomicBool,
) -> Vec<Vec<Option<V3>>> {
    (0..ladder.rungs())
        .map(|s| tile_normals(t, p, bufs, ladder.normal_k(s), cancel))
        .collect()
}

/// Every rung's result at the points `which` marks.
struct Rungs {
    /// Per point, its slot in `results` (u32::MAX: none).
    slot: Vec<u32>,
    /// Rungs per point.
    rungs: usize,
    /// `rungs` results per slot.
    results: Vec<Estimate>,
}

impl Rungs {
    /// The rungs of point `i` (empty if not computed).
    fn of(&self, i: usize) -> &[Estimate] {
        match self.slot[i] {
            u32::MAX => &[],
            s => &self.results[s as usize * self.rungs..][..self.rungs],
        }
    }
}

/// The estimator at every rung of the points `which` marks: rung s from the first K_s of the
/// point's list with the rung's normals.
fn rung_results(
    t: &TilePoints,
    p: &ComputeParams<'_>,
    ladder: Ladder,
    bufs: &TileBuffers,
    normals: &[Vec<Option<V3>>],
    which: &[bool],
    cancel: &AtomicBool,
) -> Rungs {
    let rungs = ladder.rungs();
    let points: Vec<usize> = (0..which.len()).filter(|&i| which[i]).collect();
    let mut slot = vec![u32::MAX; which.len()];
    for (s, &i) in points.iter().enumerate() {
        slot[i] = s as u32;
    }
    let mut results = vec![Estimate::undefined(0); points.len() * rungs];
    results
        .par_chunks_mut(rungs)
        .zip(points.par_iter())
        .for_each_init(
            || NeighbourhoodBuf::with_capacity(ladder.max),
            |buf, (out, &i)| {
                if cancel.load(Ordering::Relaxed) {
                    return;
                }
                let l = bufs.list(i, ladder.max);
                for (s, r) in out.iter_mut().enumerate() {
                    let list = &l[..l.len().min(ladder.k(s))];
                    *r = estimate_one(t, p, &normals[s], i, list, buf);
                }
            },
        );
    Rungs {
        slot,
        rungs,
        results,
    }
}

/// C_s at a point: the mean of (H_{s+1}(q) - H_s(q))^2 over the points `near`, skipping those
/// where either is undefined; NaN when none is left.
fn criterion(rungs: &Rungs, near: &[u32], s: usize) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for &q in near {
        let r = rungs.of(q as usize);
        if r.len() > s + 1 && is_defined(&r[s].curvature) && is_defined(&r[s + 1].curvature) {
            let d = r[s + 1].curvature.h - r[s].curvature.h;
            sum += d * d;
            count += 1;
        }
    }
    match count {
        0 => f64::NAN,
        c => sum / c as f64,
    }
}
