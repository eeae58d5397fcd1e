//! The k-d tree backend, for tiles whose density is too uneven for one cell size: kiddo's
//! tree over tile-local f32 coordinates proposes candidates, which are re-ranked exactly in
//! f64 (with a radius query when rounding could hide a point at the k-th place). kiddo's order
//! among equal distances is unspecified, so nothing here trusts it. Pure: no files, no channels.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::{rank, Backend, Cand, NeighbourIndex};
use crate::core::geometry::{sub, V3};

impl<'a> NeighbourIndex<'a> {
    pub(super) fn build_tree(
        xyz: &'a [V3],
        ranks: Vec<u32>,
        duplicates: super::Duplicates,
        lo: V3,
        hi: V3,
    ) -> Option<Self> {
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
            xyz,
            ranks,
            duplicates,
            backend: Backend::Tree {
                tree,
                origin,
                slack,
            },
        })
    }

    /// kiddo proposes candidates; if rounding or ties could hide a point at the k-th place, a
    /// radius query with the rounding slack collects all of them.
    pub(super) fn tree_candidates(
        &self,
        tree: &ImmutableKdTree<f32, 3>,
        origin: V3,
        slack: f64,
        i: usize,
        others: usize,
        ranked: &mut Vec<Cand>,
    ) {
        let n = self.xyz.len();
        let q = self.xyz[i];
        let ql = sub(q, origin).map(|c| c as f32);
        // The query itself and a few spare candidates usually settle ties and rounding at once.
        let want = (others + 5).min(n);
        let cand = tree
            .query(&ql)
            .nearest_n::<SquaredEuclidean<f32>>(
                NonZeroUsize::new(want).unwrap_or(NonZeroUsize::MIN),
            )
            .execute();
        let mut f_max = 0f64;
        for c in &cand {
            f_max = f_max.max(c.distance as f64);
            if c.item as usize != i {
                ranked.push((
                    self.dist2(q, c.item as usize),
                    self.ranks[c.item as usize],
                    c.item,
                ));
            }
        }
        if ranked.len() < others {
            return; // the whole tile was returned
        }
        ranked.select_nth_unstable_by(others - 1, rank);
        let d_k = ranked[others - 1].0.sqrt();
        // Every point outside the candidates is at f32 distance >= f_max. If that exceeds the
        // exact k-th distance plus the rounding slack, no outside point can enter the top k.
        if cand.len() < n && f_max.sqrt() <= d_k + slack {
            let r = d_k + slack;
            let all = tree
                .query(&ql)
                .within::<SquaredEuclidean<f32>>((r * r) as f32 * (1.0 + 4.0 * f32::EPSILON))
                .execute();
            ranked.clear();
            for c in &all {
                if c.item as usize != i {
                    ranked.push((
                        self.dist2(q, c.item as usize),
                        self.ranks[c.item as usize],
                        c.item,
                    ));
                }
            }
        }
    }
}
