//! One tile's computation: k-NN for the core points and for the halo points they reach, normals
//! (the file's, or PCA oriented), halo verification, and the estimator for the core points whose
//! whole neighbourhood is verified complete. Parallel over points with rayon; no I/O.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::core::estimate::{flags, Curvature, Estimator, MAX_EXTRA};
use crate::core::geometry::{dot, sub, V3};
use crate::core::neighbors::{KnnScratch, NeighbourIndex};
use crate::core::normals::{orient, pca_normal, Orientation};
use crate::core::plan::Rect;
use crate::core::scale::Ladder;
use crate::core::terrain::TerrainValues;
use crate::core::tile::TilePoints;

mod auto;
mod lists;
mod neighbourhood;

pub use lists::TileBuffers;
use lists::{mark, neighbour_lists, ListNormals, ListQuery, Reach};
#[cfg(test)]
use neighbourhood::sharper_than;
pub use neighbourhood::NeighbourhoodBuf;

/// What to compute per point.
#[derive(Clone, Copy)]
pub struct ComputeParams<'e> {
    /// Neighbours per point, the point itself included; with `radius`, the cap on them.
    pub k: usize,
    /// `--radius`: the neighbourhood is the point and every point within this distance (file
    /// units), the nearest `k` of them; None for the k nearest.
    pub radius: Option<f64>,
    /// Orientation of PCA normals.
    pub orientation: Orientation,
    /// Use the file's normals where present.
    pub use_file_normals: bool,
    /// The estimator.
    pub estimator: &'e dyn Estimator,
    /// How many of the estimator's extra values to compute (`--features`: all of its
    /// [`Estimator::extra_columns`]; otherwise 0).
    pub extra: usize,
    /// `--orient propagate`: the cloud's centroid, from which each tile's propagation is seeded
    /// (orient.rs); None for the per-point rules.
    pub propagate: Option<V3>,
    /// `-k auto`: the ladder of scales chosen from per point (`auto`); `k` is then its top
    /// rung. None for one fixed `k`.
    pub ladder: Option<Ladder>,
    /// Whether to compute the terrain values ([`TerrainValues`]) of each point.
    pub terrain: bool,
}

impl ComputeParams<'_> {
    /// The terrain values of a point with `normal` and `curvature` when they are asked for;
    /// undefined otherwise (a cost of about 1% of a point's, paid only then).
    fn terrain_of(&self, normal: Option<V3>, curvature: &Curvature) -> TerrainValues {
        match (self.terrain, normal) {
            (true, Some(n)) => TerrainValues::of(n, curvature),
            _ => TerrainValues::NONE,
        }
    }
}

/// Which loaded points of a pass another pass also orients (for the cross-tile votes of
/// `--orient propagate`).
#[derive(Debug, Clone, Copy)]
pub enum Shared {
    /// Every loaded point (a wider-halo retry: its points were oriented by earlier passes).
    All,
    /// Points within `width` of the edge of the core rectangle `rect`, inside or outside it.
    Band {
        /// The core (tile or part) rectangle.
        rect: Rect,
        /// The initial halo width.
        width: f64,
    },
}

impl Shared {
    fn contains(&self, p: V3) -> bool {
        match *self {
            Shared::All => true,
            // Outside the inner rectangle (empty when the band is wider than half the core).
            Shared::Band { rect, width } => !rect.grown(-width).contains(p[0], p[1]),
        }
    }
}

/// One point's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointResult {
    /// Original point id.
    pub id: u64,
    /// Oriented unit normal (NaN when undefined).
    pub normal: V3,
    /// Curvature and flags.
    pub curvature: Curvature,
    /// The estimator's extra values (`--features`), NaN where not computed.
    pub extra: [f64; MAX_EXTRA],
    /// With `--orient propagate`: the point's patch, numbered within its tile (see orient.rs);
    /// [`NO_PATCH`] otherwise.
    pub patch: u32,
    /// With `-k auto`: the K of the chosen rung (0 otherwise).
    pub scale: u16,
    /// With `-k auto`: the choice's [`scale_flags`](crate::core::scale::scale_flags).
    pub scale_flags: u8,
    /// The terrain values (with [`ComputeParams::terrain`]; undefined otherwise). They do not
    /// depend on the normal's orientation, so [`PointResult::flipped`] keeps them.
    pub terrain: TerrainValues,
}

impl PointResult {
    /// The result of a point that was not computed (its class is not selected): NaN values,
    /// flag [`flags::NOT_COMPUTED`].
    pub fn not_computed(id: u64) -> PointResult {
        PointResult {
            id,
            normal: [f64::NAN; 3],
            curvature: Curvature::undefined(flags::NOT_COMPUTED),
            extra: [f64::NAN; MAX_EXTRA],
            patch: NO_PATCH,
            scale: 0,
            scale_flags: 0,
            terrain: TerrainValues::NONE,
        }
    }

    /// The result as it reads with the opposite normal: the normal negated, the curvature
    /// [`Curvature::flipped`], and the extra values marked `flips` in `extra` (the estimator's
    /// [`Estimator::extra_columns`]) negated; NaN stays NaN bit for bit. The one flip of
    /// `--orient propagate` (core::orient).
    pub fn flipped(&self, extra: &[crate::core::estimate::ExtraColumn]) -> PointResult {
        let neg = crate::core::estimate::neg;
        let mut r = PointResult {
            normal: self.normal.map(neg),
            curvature: self.curvature.flipped(),
            ..*self
        };
        for (v, c) in r.extra.iter_mut().zip(extra) {
            if c.flips {
                *v = neg(*v);
            }
        }
        r
    }
}

/// A pass stopped because its cancel flag was set (SIGINT/SIGTERM): its results are incomplete
/// and dropped. Every step checks the flag per point, so a signal never waits for a whole pass
/// over a large tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

/// `Err(Cancelled)` once `cancel` is set: checked between the steps of a pass.
fn stopped(cancel: &AtomicBool) -> Result<(), Cancelled> {
    match cancel.load(Ordering::Relaxed) {
        true => Err(Cancelled),
        false => Ok(()),
    }
}

/// The patch of a point outside any propagation patch.
pub const NO_PATCH: u32 = u32::MAX;

/// The outcome of one pass over a loaded tile.
#[derive(Debug, Default)]
pub struct TileOutcome {
    /// Results of the core points whose neighbourhoods were verified complete.
    pub done: Vec<PointResult>,
    /// Ids of core points whose neighbourhood (or a neighbour's) may reach past the loaded
    /// region: to be recomputed with a wider halo.
    pub retry: Vec<u64>,
    /// With `--orient propagate`: the pass's patch anchors and shared normals.
    pub orientation: Option<crate::core::orient::TileOrientation>,
}

/// Step 3 after the lists (`-k auto`, whose rungs take different prefixes; one fixed k finds
/// the normals with the lists, [`ListNormals`]): the normal of every point with a neighbour
/// list, [`normal_of`] over the first `prefix` entries of its list.
fn tile_normals(
    t: &TilePoints,
    p: &ComputeParams<'_>,
    bufs: &TileBuffers,
    prefix: usize,
    cancel: &AtomicBool,
) -> Vec<Option<V3>> {
    (0..t.xyz.len())
        .into_par_iter()
        .map(|i| {
            if bufs.info[i].len == 0 || cancel.load(Ordering::Relaxed) {
                return None;
            }
            normal_of(t, p, bufs.list(i, p.k), prefix)
        })
        .collect()
}

/// The normal of the point whose neighbour list is `list` (the point first): the file's, or
/// PCA over the first `prefix` entries, oriented.
fn normal_of(t: &TilePoints, p: &ComputeParams<'_>, list: &[u32], prefix: usize) -> Option<V3> {
    let i = *list.first()? as usize;
    if p.use_file_normals {
        if let Some(fnorm) = t.file_normal(i) {
            return crate::core::geometry::normalize(fnorm);
        }
    }
    pca_normal(&t.xyz, &list[..list.len().min(prefix)])
        .map(|nrm| orient(nrm, t.xyz[i], p.orientation))
}

/// The estimator's output at one point.
#[derive(Clone, Copy)]
struct Estimate {
    /// The curvature.
    curvature: Curvature,
    /// The extra values ([`Estimator::extra_columns`]): the first [`ComputeParams::extra`]
    /// computed, the others NaN.
    extra: [f64; MAX_EXTRA],
}

impl Estimate {
    /// Undefined values carrying `flags`.
    fn undefined(flags: u8) -> Self {
        Estimate {
            curvature: Curvature::undefined(flags),
            extra: [f64::NAN; MAX_EXTRA],
        }
    }
}

/// The estimator at point `i` with the neighbour list `list` and the tile's `normals`: its
/// curvature (flagged FILE_NORMAL when the file's normal was used) and extra values; undefined
/// (DEGENERATE_NORMAL, and FEW_NEIGHBOURS below 3 points) without a normal at `i`.
fn estimate_one(
    t: &TilePoints,
    p: &ComputeParams<'_>,
    normals: &[Option<V3>],
    i: usize,
    list: &[u32],
    s: &mut NeighbourhoodBuf,
) -> Estimate {
    let file_flag = if p.use_file_normals && t.file_normal(i).is_some() {
        flags::FILE_NORMAL
    } else {
        0
    };
    let mut extra = [f64::NAN; MAX_EXTRA];
    if normals[i].is_none() {
        // Fewer than 3 points in the whole neighbourhood: both reasons hold.
        let few = if list.len() < 3 {
            flags::FEW_NEIGHBOURS
        } else {
            0
        };
        return Estimate::undefined(flags::DEGENERATE_NORMAL | few | file_flag);
    }
    let out = &mut extra[..p.extra.min(MAX_EXTRA)];
    let mut curvature = s.estimate(p.estimator, &t.xyz, normals, i, list, out);
    curvature.flags |= file_flag;
    Estimate { curvature, extra }
}

/// Step 4: the estimator at the core points `todo` (verified), written in place (an indexed
/// collect: partition_map's intermediate lists and appends fault in pages that the results are
/// then copied out of).
fn estimate_points(
    t: &TilePoints,
    p: &ComputeParams<'_>,
    bufs: &TileBuffers,
    normals: &[Option<V3>],
    todo: &[usize],
    patch_of: &(dyn Fn(usize) -> u32 + Sync),
    cancel: &AtomicBool,
) -> Vec<PointResult> {
    let mut done: Vec<PointResult> = Vec::with_capacity(todo.len());
    todo.par_iter()
        .map_init(
            || NeighbourhoodBuf::with_capacity(p.k),
            |s, &i| {
                let Estimate { curvature, extra } = match cancel.load(Ordering::Relaxed) {
                    true => Estimate::undefined(0),
                    false => estimate_one(t, p, normals, i, bufs.list(i, p.k), s),
                };
                PointResult {
                    id: t.ids[i],
                    normal: normals[i].unwrap_or([f64::NAN; 3]),
                    curvature,
                    extra,
                    patch: if normals[i].is_some() {
                        patch_of(i)
                    } else {
                        NO_PATCH
                    },
                    scale: 0,
                    scale_flags: 0,
                    terrain: p.terrain_of(normals[i], &curvature),
                }
            },
        )
        .collect_into_vec(&mut done);
    done
}

/// Computes the core points of `t`. `scene` is the x/y extent of the whole cloud.
/// With `--orient propagate`, the pass's patches are numbered from `first_patch` and `shared`
/// says which of its points other passes also orient. `bufs` are the caller's reusable buffers
/// (fresh ones cost a zeroed page per 4 KiB every tile). Stops with [`Cancelled`] soon after
/// `cancel` is set.
pub fn compute_tile(
    t: &TilePoints,
    scene: &Rect,
    p: &ComputeParams<'_>,
    first_patch: u32,
    shared: Shared,
    bufs: &mut TileBuffers,
    cancel: &AtomicBool,
) -> Result<TileOutcome, Cancelled> {
    let stop = || stopped(cancel);
    let Some(index) = NeighbourIndex::build(&t.xyz, &t.ids, p.k) else {
        return Ok(TileOutcome::default());
    };
    if let Some(ladder) = p.ladder {
        // The lists hold the top rung (the configuration already makes k that).
        let p = ComputeParams {
            k: ladder.max,
            ..*p
        };
        return auto::compute_auto(t, scene, &p, ladder, &index, bufs, cancel);
    }
    let (n, k, n_core) = (t.xyz.len(), p.k, t.n_core);
    stop()?;
    let reach = Reach {
        k,
        radius: p.radius,
        prefix: k,
    };
    // Steps 1-3: each point's normal is found right after its list (`tile_normals` would
    // read every list and its points again).
    let mut normals = vec![None; n];
    let out = ListNormals {
        p,
        out: &mut normals,
    };
    let q = ListQuery {
        t,
        index: &index,
        scene,
        reach,
    };
    neighbour_lists(&q, &[k], bufs, Some(out), cancel);
    stop()?;
    let bufs = &*bufs;
    // 3b. `--orient propagate`: one consistent orientation per connected patch of the tile.
    let orientation = p.propagate.filter(|_| !p.use_file_normals).map(|centre| {
        let lists: Vec<&[u32]> = (0..n).map(|i| bufs.list(i, k)).collect();
        crate::core::orient::orient_tile(
            &t.xyz,
            &t.ids,
            &lists,
            &mut normals,
            centre,
            first_patch,
            |i| shared.contains(t.xyz[i]),
        )
    });
    let patch_of = |i: usize| {
        orientation
            .as_ref()
            .and_then(|o| o.patch(i))
            .unwrap_or(NO_PATCH)
    };
    let verified: Vec<bool> = (0..n_core)
        .into_par_iter()
        .map(|i| bufs.exact(i, k))
        .collect();
    let todo: Vec<usize> = (0..n_core).filter(|&i| verified[i]).collect();
    let retry: Vec<u64> = (0..n_core)
        .filter(|&i| !verified[i])
        .map(|i| t.ids[i])
        .collect();
    stop()?;
    let done = estimate_points(t, p, bufs, &normals, &todo, &patch_of, cancel);
    stop()?;
    Ok(TileOutcome {
        done,
        retry,
        // Each result carries its patch; the per-point components are not needed any more.
        orientation: orientation.map(|o| crate::core::orient::TileOrientation {
            component: Vec::new(),
            ..o
        }),
    })
}

#[cfg(test)]
mod tests;
