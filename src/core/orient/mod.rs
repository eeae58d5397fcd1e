//! Orientation of PCA normals beyond the per-point rules of [`crate::core::normals::orient`]:
//! `outward` (away from a centre, for closed star-shaped objects) and `propagate` (a consistent
//! orientation by propagation over the neighbour graph, Hoppe et al. 1992), plus the pieces that
//! make propagation work tile by tile in the out-of-core engine. Pure: no I/O, no threads.
//!
//! # Propagation (one set of points in memory)
//!
//! [`propagate`] builds the symmetric k-NN graph (an edge i–j when j is in the list of i or i in
//! the list of j), weights each edge `1 - |<n_i, n_j>|` (nearly parallel normals are cheap), and
//! grows a minimum spanning tree of each connected component from a seed with Prim's algorithm,
//! flipping every point it reaches to agree with its tree parent (`<n_child, n_parent> >= 0`).
//! The seed of a component is its point farthest from a centre (the component's centroid, or a
//! given point such as the cloud's centroid), oriented away from that centre: on a closed
//! object the farthest point is always on the convex hull, where outward is unambiguous.
//! Points without a normal (`None`: degenerate neighbourhoods) are not in the graph.
//! Cost: O(N k log N) time; memory: the reverse adjacency (N k `u32`) and a few words per point.
//!
//! # Tiled runs
//!
//! A tile holds core points plus a halo. Orientation stays consistent across tiles in three steps:
//!
//! 1. **Per tile.** After the PCA normals of every loaded point with a neighbour list (core and
//!    halo) are computed, [`propagate`] runs over the tile's k-NN lists with
//!    [`Seed::OutwardFrom`]`(global centroid)` (the centroid is accumulated during the plan
//!    pass with [`Centroid`]). Each connected component `c` of tile `t` becomes a *patch* (an id
//!    the engine assigns, e.g. a running counter over tile passes, retries included). The tile
//!    applies its flips *before* the estimator runs, so the tile's curvatures are consistent with
//!    its (possibly globally wrong) patch orientation. The tile reports, beside its results:
//!    - one [`PatchAnchor`] per patch: its seed, the seed's squared distance from the global
//!      centroid and the seed's id ([`Propagation::anchor`]);
//!    - one [`SharedNormal`] (`id`, patch, oriented normal) per loaded point that another pass
//!      also loads: every loaded point within the initial halo width of the core rectangle's
//!      edge (inside or outside it), and in a wider-halo retry pass every loaded point (its
//!      points were oriented by the first pass of the same tile or by its neighbours);
//!    - and, with each point result, its patch.
//!
//!    [`orient_tile`] does all of this for one tile.
//! 2. **Across tiles.** [`votes_from_shared`] turns the shared normals into agreement votes
//!    between patches (the same point oriented by two patches: same sign or not), and
//!    [`patch_signs`] solves one sign per patch: in each connected component of the patch graph,
//!    the patch holding the anchor farthest from the centroid keeps (or takes) the outward sign,
//!    and the others follow a maximum spanning tree of the vote margins.
//! 3. **At assemble time** every result of a flipped patch is negated with
//!    `PointResult::flipped` (core::compute, through `Curvature::flipped`): the normal flips, `H' = -H`, `K' = K`, and the principal curvatures swap roles,
//!    `k1' = -k2`, `k2' = -k1` (k1 stays the smaller), with their directions `d1' = d2`,
//!    `d2' = d1` (which keeps `d1 x d2 = n`).
//!
//! # Scans bigger than memory
//!
//! Only the patch tables are global: one anchor and one sign per patch (a few per tile), and the
//! vote margins per pair of adjacent patches. The shared normals are proportional to the halo
//! bands, not to the cloud; they can be reduced to votes as soon as every tile that loads a given
//! point has run (or be spilled to the work directory and sorted by id). Nothing else of a tile
//! outlives it. The result is the same orientation a single in-memory propagation would give
//! wherever the tiles agree; where the surface's neighbour graph is connected only through
//! another tile's region, the votes carry the orientation across; a component that no tile shares
//! with any other is oriented by its own outward seed.
//!
//! # Limits
//!
//! The global sign comes from the outward rule at the point farthest from the centroid: right
//! for objects, arbitrary for open surfaces such as terrain, where `up` or a viewpoint is the
//! rule to use. Normals read from the file are not PCA normals and must not be passed to
//! [`propagate`] (it would flip them). Propagation can go wrong across sharp creases and thin
//! sheets closer than the neighbour spacing (the k-NN graph links both sides).
//!
//! # Files
//!
//! `propagation` holds step 1 (the propagation and [`orient_tile`]), `signs` step 2 (the
//! votes and the sign solve); this file keeps the outward rule, the centroid and the
//! [`GlobalPatch`] numbering, and re-exports the rest so every path stays `orient::*`.

use crate::core::geometry::V3;
use crate::core::normals::{orient, Orientation};

mod propagation;
mod signs;

pub use crate::core::plan::Centroid;
pub use propagation::{orient_tile, propagate, Component, Propagation, Seed, TileOrientation};
pub use signs::{patch_signs, votes_from_shared, PatchAnchor, PatchSigns, PatchVote, SharedNormal};

/// `n` flipped if needed so that it points away from `centre` at position `p`:
/// `<n, p - centre> >= 0`. A normal exactly orthogonal to `p - centre` (or `p == centre`) is
/// oriented by the sign of its first non-zero component, the tie rule of
/// [`crate::core::normals::orient`].
pub fn orient_outward(n: V3, p: V3, centre: V3) -> V3 {
    orient(n, p, Orientation::Outward(centre))
}

/// A propagation patch numbered across the whole run: its tile's index in the plan and its
/// number within the tile, packed in 64 bits as the result files store it (`NONE` for a point
/// outside any patch). The one place that packs and unpacks it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GlobalPatch(pub u64);

impl GlobalPatch {
    /// No patch.
    pub const NONE: GlobalPatch = GlobalPatch(u64::MAX);

    /// Patch `local` of the tile at `tile_index` in the plan; `NONE` when `local` is
    /// `core::compute::NO_PATCH` (`u32::MAX`).
    pub fn new(tile_index: u32, local: u32) -> Self {
        if local == u32::MAX {
            Self::NONE
        } else {
            GlobalPatch(((tile_index as u64) << 32) | local as u64)
        }
    }

    /// The tile index and the patch within the tile, or None for no patch.
    pub fn parts(self) -> Option<(usize, usize)> {
        (self != Self::NONE).then_some(((self.0 >> 32) as usize, (self.0 & 0xffff_ffff) as usize))
    }
}

#[cfg(test)]
mod tests;
