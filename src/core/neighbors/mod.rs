//! k nearest neighbours within a loaded tile. The answer is exact and ranked by (f64 squared
//! distance, position, original id): points at exactly the same distance are ordered by their
//! coordinates (x, then y, then z: [`cmp_position`]), and by original id only between exact
//! duplicates, which are geometrically interchangeable. So the neighbour set and its order
//! depend on the point set alone: not on the index, the tile, the thread, nor the order of the
//! records in the file. Two interchangeable backends find the candidates:
//!
//! - a uniform 3D grid with cells of 1.25 times the k-NN radius. A query ranks the 27 cells
//!   around its own (gathered once per cell in f32, see `Block`): an f32 pass finds a radius
//!   holding a few more than k points, and only those are ranked exactly. When the k-th
//!   distance is not provably inside those cells, a shell search grows rings of cells until it
//!   is. Faster than kiddo's `nearest_n` on LIDAR tiles (docs/performance.md, measured by
//!   benches/stages.rs). Used whenever the density is even enough for one cell
//!   size, which is most LIDAR tiles;
//! - kiddo's k-d tree on tile-local f32 coordinates, with exact re-ranking, for tiles whose
//!   density is too uneven for one cell size (a terrestrial scan near its scanner).
//!
//! Pure: no files, no channels.
//!
//! The grid and its f32 block path live in `grid`, its shell search in `shell`, the k-d tree
//! in `kdtree`; this file holds the index, its scratch and the exact ranking they share.

use kiddo::ImmutableKdTree;

use std::cmp::Ordering;

use crate::core::geometry::{sub, V3};
#[cfg(doc)]
use crate::core::point::{cmp_point, cmp_position};

mod duplicates;
mod grid;
mod kdtree;
mod radius;
mod shell;
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod simd;

use duplicates::Duplicates;

use grid::{Block, Grid};

/// A k-NN index over the points of one loaded tile.
pub struct NeighbourIndex<'a> {
    xyz: &'a [V3],
    /// Per point, its place among the tile's points in the order of [`cmp_point`] (position,
    /// then id): what ties in distance are broken by ([`position_ranks`]). Carried in every
    /// candidate, so that a tie costs one integer comparison (a tile of duplicates is all ties).
    ranks: Vec<u32>,
    /// Groups of at least k exact duplicates, answered without a search.
    duplicates: Duplicates,
    backend: Backend,
}

enum Backend {
    Grid(Grid),
    Tree {
        tree: ImmutableKdTree<f32, 3>,
        origin: V3,
        /// Bound on |f32 distance - f64 distance| for any pair (rounding of local coordinates).
        slack: f64,
    },
}

/// A candidate neighbour: its exact f64 squared distance from the query, its rank in position
/// order ([`NeighbourIndex::ranks`]) and its local index. 16 bytes.
type Cand = (f64, u32, u32);

/// Per-thread scratch for [`NeighbourIndex::knn`], so queries do not allocate.
#[derive(Default)]
pub struct KnnScratch {
    ranked: Vec<Cand>,
    block: Block,
    d2: Vec<f32>,
    /// Block indices of the points the block path ranks exactly.
    within: Vec<u32>,
    keys: Vec<u64>,
    exact: Vec<Cand>,
    /// The last query's squared k-th distance, the first guess for the next one.
    hint: f32,
}

/// Per point of a tile, its place in the order of [`cmp_point`] among the tile's points: x,
/// then y, then z (exactly, -0 as +0), then the original id. The order two points get does not
/// depend on the tile they are compared in (a point in several tiles' halos), and ties in
/// distance then cost one integer comparison. The coordinates are sorted as integers whose
/// order is `f64::total_cmp`'s.
fn position_ranks(xyz: &[V3], ids: &[u64]) -> Vec<u32> {
    let key = |x: f64| {
        let b = (x + 0.0).to_bits();
        if b >> 63 == 1 {
            !b
        } else {
            b | 1 << 63
        }
    };
    // By x (a radix sort), then the points sharing an x (quantized coordinates: a few each) by
    // y, z and id.
    let mut order: Vec<(u64, u32)> = (xyz.iter().enumerate())
        .map(|(i, p)| (key(p[0]), i as u32))
        .collect();
    let rest = |i: u32| {
        let p = xyz[i as usize];
        (key(p[1]), key(p[2]), ids[i as usize], i)
    };
    crate::core::radix::sort_by_key_then(&mut order, &mut Vec::new(), |i, j| rest(i).cmp(&rest(j)));
    let mut ranks = vec![0u32; xyz.len()];
    for (r, o) in order.iter().enumerate() {
        ranks[o.1 as usize] = r as u32;
    }
    ranks
}

/// The ranking of candidates: by exact squared distance, then (ties, which are common on
/// quantized coordinates) by position, and between exact duplicates by original id: the rank
/// of [`position_ranks`]. A total order that compares two points the same in every tile.
#[inline]
fn rank(a: &Cand, b: &Cand) -> Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

/// Sorts `v` by [`rank`] as integer keys: the squared distance's bits with the entry's position
/// in the low bits (as many as the entries need, at least 6; branch-free and much faster than
/// comparing tuples), then put in exact order by an insertion pass: the keys only misorder
/// distances within 2^bits ulps of each other (relative 2^-36 at most: ties among them), so
/// that pass moves almost nothing. Up to 32 entries (a k = 30 query's) the keys are sorted by
/// a sorting network in registers where the build has AVX2 (`simd`); past 2^16, a
/// comparison sort. The order is [`rank`]'s either way.
fn sort_ranked(v: &mut Vec<Cand>, keys: &mut Vec<u64>, spare: &mut Vec<Cand>) {
    if v.len() > 1 << 16 {
        v.sort_unstable_by(rank);
        return;
    }
    let bits = (usize::BITS - v.len().saturating_sub(1).leading_zeros()).max(6);
    let low = (1u64 << bits) - 1;
    spare.clear();
    if !network_order(v, low, spare) {
        keys.clear();
        keys.extend(v.iter().enumerate().map(|e| sort_key(e, low)));
        keys.sort_unstable();
        spare.extend(keys.iter().map(|&key| v[(key & low) as usize]));
    }
    // In order already unless within a tie window (rare): one pass of comparisons.
    if spare.windows(2).all(|w| w[0].0 < w[1].0) {
        std::mem::swap(v, spare);
        return;
    }
    for x in 1..spare.len() {
        if spare[x - 1].0 < spare[x].0 {
            continue;
        }
        let mut y = x;
        while y > 0 && rank(&spare[y], &spare[y - 1]).is_lt() {
            spare.swap(y, y - 1);
            y -= 1;
        }
    }
    std::mem::swap(v, spare);
}

/// The sort key of entry `e` of [`sort_ranked`]: its squared distance's bits (>= +0.0, whose
/// bit patterns order like the values) with `e` in the `low` bits.
#[inline]
fn sort_key((e, r): (usize, &Cand), low: u64) -> u64 {
    (r.0.to_bits() & !low) | e as u64
}

/// Appends to `spare` the entries of `v` in the order of their [`sort_key`]s, sorted by the
/// AVX2 network (`simd`) as doubles (finite and non-negative: ordered like their bits) padded
/// with +inf, which sorts last. Returns false, doing nothing, past 32 entries or in a build
/// without AVX2.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
fn network_order(v: &[Cand], low: u64, spare: &mut Vec<Cand>) -> bool {
    if v.len() > 32 {
        return false;
    }
    let mut k = [f64::INFINITY; 32];
    for (slot, e) in k[..v.len()].iter_mut().zip(v.iter().enumerate()) {
        *slot = f64::from_bits(sort_key(e, low));
    }
    // SAFETY: compiled only where the build enables AVX2, whose absence main.rs refuses at
    // start-up.
    unsafe { simd::sort32(&mut k) };
    spare.extend(k[..v.len()].iter().map(|x| v[(x.to_bits() & low) as usize]));
    true
}

/// Without AVX2 the standard sort takes every list ([`sort_ranked`]).
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
fn network_order(_: &[Cand], _: u64, _: &mut Vec<Cand>) -> bool {
    false
}

/// The smallest and largest coordinate on each axis of `xyz` (not empty).
fn bounds(xyz: &[V3]) -> (V3, V3) {
    let (mut lo, mut hi) = (xyz[0], xyz[0]);
    for p in xyz {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

impl<'a> NeighbourIndex<'a> {
    /// Builds the index over `xyz` (absolute f64 coordinates) with original ids `ids`, for
    /// queries of about `k` neighbours. Returns None when there are no points or more than
    /// u32::MAX of them.
    pub fn build(xyz: &'a [V3], ids: &'a [u64], k: usize) -> Option<Self> {
        if xyz.is_empty() || xyz.len() > u32::MAX as usize {
            return None;
        }
        let (lo, hi) = bounds(xyz);
        let ranks = position_ranks(xyz, ids);
        let duplicates = Duplicates::find(xyz, &ranks, k);
        if let Some(g) = Grid::build(xyz, &ranks, lo, hi, k) {
            return Some(NeighbourIndex {
                xyz,
                ranks,
                duplicates,
                backend: Backend::Grid(g),
            });
        }
        Self::build_tree(xyz, ranks, duplicates, lo, hi)
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// Always false (an index is never built over no points).
    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    /// A key of point `i` (local index) to order queries by: consecutive queries in this
    /// order share the grid's gathered block (its cell, as the grid sorts them); 0 for the
    /// k-d tree. The answers do not depend on the order of the queries.
    pub fn query_key(&self, i: usize) -> u64 {
        match &self.backend {
            Backend::Grid(g) => grid::cell_key(g.dims, g.cell_of(self.xyz[i])),
            Backend::Tree { .. } => 0,
        }
    }

    /// The `k` nearest neighbours of point `i` (local index), written to `out` as local indices:
    /// `i` itself first (as the CNC reference code counts it), then the k - 1 nearest others by
    /// increasing (exact f64 distance, position, original id): see the module documentation.
    /// Fewer when the tile has fewer points.
    /// Returns the exact distance to the farthest neighbour returned.
    pub fn knn(&self, i: usize, k: usize, scratch: &mut KnnScratch, out: &mut Vec<u32>) -> f64 {
        out.clear();
        out.push(i as u32);
        let n = self.xyz.len();
        let others = k.min(n).max(1) - 1;
        if others == 0 {
            return 0.0;
        }
        // At least k - 1 exact duplicates: the first of them in rank order, all at distance 0.
        if let Some(g) = self.duplicates.group(self.ranks[i]) {
            if g.len() > others {
                out.extend(g.iter().filter(|&&j| j as usize != i).take(others));
                return 0.0;
            }
        }
        let mut first_shell = 0;
        if let Backend::Grid(g) = &self.backend {
            match self.grid_block_knn(g, i, others, scratch) {
                Ok(far2) => {
                    out.extend(scratch.exact[..others].iter().map(|r| r.2));
                    return far2.sqrt();
                }
                Err(shell) => first_shell = shell,
            }
        }
        let KnnScratch {
            ranked,
            exact,
            keys,
            ..
        } = scratch;
        ranked.clear();
        match &self.backend {
            Backend::Grid(g) => {
                if first_shell > 0 {
                    // The block's best are exact for the 27 cells: seed the heap with them (in
                    // descending order they already form a max-heap) and search only the
                    // shells beyond.
                    ranked.extend(exact[..others].iter().rev());
                }
                self.grid_candidates(g, i, others, first_shell, ranked)
            }
            Backend::Tree {
                tree,
                origin,
                slack,
            } => self.tree_candidates(tree, *origin, *slack, i, others, ranked),
        }
        // `ranked` holds every point that can be among the nearest others (and maybe more).
        if ranked.len() > others {
            ranked.select_nth_unstable_by(others - 1, rank);
            ranked.truncate(others);
        }
        sort_ranked(ranked, keys, exact);
        out.extend(ranked.iter().map(|r| r.2));
        ranked.last().map(|r| r.0.sqrt()).unwrap_or(0.0)
    }

    #[inline]
    fn dist2(&self, q: V3, j: usize) -> f64 {
        sq_dist(self.xyz[j], q)
    }
}

/// The exact squared distance between `p` and `q`, the one formula every backend ranks by (the
/// same bits whichever copy of a point's coordinates it reads).
#[inline]
fn sq_dist(p: V3, q: V3) -> f64 {
    let d = sub(p, q);
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[cfg(test)]
mod tests;
