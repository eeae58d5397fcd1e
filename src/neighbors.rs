//! k nearest neighbours within a loaded tile: the only user of kiddo. kiddo proposes candidates
//! on tile-local f32 coordinates; the answer is re-ranked exactly by (f64 squared distance,
//! original id), so the neighbour set and its order never depend on the tree, the tile or the
//! thread (kiddo's order among ties is unspecified). Pure: no files, no channels.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::geometry::{sub, V3};

/// A k-NN index over the points of one loaded tile.
pub struct NeighbourIndex<'a> {
    tree: ImmutableKdTree<f32, 3>,
    xyz: &'a [V3],
    ids: &'a [u64],
    origin: V3,
    /// Bound on |f32 distance - f64 distance| for any pair (rounding of tile-local coordinates).
    slack: f64,
}

/// Per-thread scratch for [`NeighbourIndex::knn`], so queries do not allocate their ranking
/// buffer each time.
#[derive(Default)]
pub struct KnnScratch {
    ranked: Vec<(f64, u64, u32)>,
}

impl<'a> NeighbourIndex<'a> {
    /// Builds the index over `xyz` (absolute f64 coordinates) with original ids `ids`.
    /// Returns None when there are no points or more than u32::MAX of them.
    pub fn build(xyz: &'a [V3], ids: &'a [u64]) -> Option<Self> {
        if xyz.is_empty() || xyz.len() > u32::MAX as usize {
            return None;
        }
        let mut lo = xyz[0];
        let mut hi = xyz[0];
        for p in xyz {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let origin = [
            0.5 * (lo[0] + hi[0]),
            0.5 * (lo[1] + hi[1]),
            0.5 * (lo[2] + hi[2]),
        ];
        let extent = (0..3).map(|a| (hi[a] - lo[a]) * 0.5).fold(0.0, f64::max);
        // Each local coordinate is off by at most half an f32 ulp of the extent; a distance
        // between two points by at most sqrt(3) * 2 of those. Doubled for safety.
        let slack = 4.0 * 3f64.sqrt() * (extent * f32::EPSILON as f64) + f64::MIN_POSITIVE;
        let local: Vec<[f32; 3]> = xyz
            .iter()
            .map(|p| sub(*p, origin).map(|c| c as f32))
            .collect();
        let tree = ImmutableKdTree::new_from_slice(&local).ok()?;
        Some(NeighbourIndex {
            tree,
            xyz,
            ids,
            origin,
            slack,
        })
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// Always false (an index is never built over no points).
    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    /// The `k` nearest neighbours of point `i` (local index), written to `out` as local indices:
    /// `i` itself first (as the CNC reference code counts it), then the others by increasing
    /// (exact f64 distance, original id). Fewer than `k` when the tile has fewer points.
    /// Returns the exact distance to the farthest neighbour returned.
    pub fn knn(&self, i: usize, k: usize, scratch: &mut KnnScratch, out: &mut Vec<u32>) -> f64 {
        out.clear();
        let n = self.xyz.len();
        let k = k.min(n).max(1);
        let q = self.xyz[i];
        let ql = sub(q, self.origin).map(|c| c as f32);
        // A few spare candidates usually settle ties and rounding at the k-th place at once.
        let want = (k + 4).min(n);
        let cand = self
            .tree
            .query(&ql)
            .nearest_n::<SquaredEuclidean<f32>>(
                NonZeroUsize::new(want).unwrap_or(NonZeroUsize::MIN),
            )
            .execute();
        let ranked = &mut scratch.ranked;
        ranked.clear();
        let mut f_max = 0f64;
        for c in &cand {
            let j = c.item as usize;
            ranked.push((self.dist2(q, j), self.ids[j], c.item));
            f_max = f_max.max(c.distance as f64);
        }
        ranked.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let d_k = ranked.get(k - 1).map(|r| r.0.sqrt()).unwrap_or(0.0);
        // Every point outside the candidates is at f32 distance >= f_max. If that exceeds the
        // exact k-th distance plus the rounding slack, no outside point can enter the top k.
        if cand.len() < n && f_max.sqrt() <= d_k + self.slack {
            let r = d_k + self.slack;
            let all = self
                .tree
                .query(&ql)
                .within::<SquaredEuclidean<f32>>((r * r) as f32 * (1.0 + 4.0 * f32::EPSILON))
                .execute();
            ranked.clear();
            for c in &all {
                let j = c.item as usize;
                ranked.push((self.dist2(q, j), self.ids[j], c.item));
            }
            ranked.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        out.push(i as u32);
        let mut far = 0f64;
        for r in ranked.iter().filter(|r| r.2 as usize != i).take(k - 1) {
            out.push(r.2);
            far = far.max(r.0);
        }
        far.sqrt()
    }

    #[inline]
    fn dist2(&self, q: V3, j: usize) -> f64 {
        let d = sub(self.xyz[j], q);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: self first, then by (distance, id).
    fn brute(xyz: &[V3], ids: &[u64], i: usize, k: usize) -> Vec<u32> {
        let mut v: Vec<(f64, u64, u32)> = (0..xyz.len())
            .filter(|&j| j != i)
            .map(|j| {
                let d = sub(xyz[j], xyz[i]);
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2], ids[j], j as u32)
            })
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        std::iter::once(i as u32)
            .chain(v.into_iter().take(k - 1).map(|t| t.2))
            .collect()
    }

    #[test]
    fn matches_brute_force_with_duplicates_and_utm_offsets() {
        // A grid with exact duplicates and many equal distances, far from the origin (UTM-like).
        let mut xyz = Vec::new();
        let mut state = 12345u64;
        for gx in 0..20 {
            for gy in 0..20 {
                let p = [
                    500_000.0 + gx as f64 * 0.5,
                    5_000_000.0 + gy as f64 * 0.5,
                    100.0,
                ];
                xyz.push(p);
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                if state >> 61 == 0 {
                    xyz.push(p); // exact duplicate return
                }
            }
        }
        // Ids deliberately not in storage order.
        let ids: Vec<u64> = (0..xyz.len() as u64)
            .map(|i| (i * 7919) % 100_003)
            .collect();
        let index = NeighbourIndex::build(&xyz, &ids).expect("index");
        let mut scratch = KnnScratch::default();
        let mut out = Vec::new();
        for k in [1, 5, 8, 9, 13, 30] {
            for i in 0..xyz.len() {
                index.knn(i, k, &mut scratch, &mut out);
                assert_eq!(out, brute(&xyz, &ids, i, k), "point {i} k {k}");
            }
        }
    }
}
