//! Large groups of exact duplicates (without a shortcut every query of a group ranks all of its
//! points, each at distance 0, so the cost grows with the square of the group's size:
//! docs/performance.md). A point with at least k - 1 others at
//! its exact position has as neighbours itself and the first k - 1 of them in position-rank
//! order, which is what the full search returns, provided no other point is at squared
//! distance 0 from them (an underflowing difference); [`Duplicates::find`] checks that, and
//! leaves a group to the full search when it cannot tell cheaply. Pure: numbers only.

use crate::core::geometry::{sub, V3};

/// Points scanned beside a group, in rank order, to prove no other point is at squared
/// distance 0 from it; past this the group is left to the full search (always exact).
const SCAN_LIMIT: usize = 4096;

/// The groups of at least k points at one exact position whose k-NN is known without a search.
pub(super) struct Duplicates {
    /// Local indices in rank order (empty when there is no such group).
    by_rank: Vec<u32>,
    /// Rank ranges `[start, end)` of the groups, sorted.
    groups: Vec<(u32, u32)>,
}

impl Duplicates {
    /// Finds the groups of at least `k` exact duplicates among `xyz`, whose position ranks are
    /// `ranks` (a permutation: x, then y, then z, then id).
    pub(super) fn find(xyz: &[V3], ranks: &[u32], k: usize) -> Duplicates {
        let mut by_rank = vec![0u32; ranks.len()];
        for (i, &r) in ranks.iter().enumerate() {
            by_rank[r as usize] = i as u32;
        }
        let at = |r: usize| xyz[by_rank[r] as usize];
        let mut groups = Vec::new();
        let mut start = 0;
        while start < by_rank.len() {
            let p = at(start);
            let mut end = start + 1;
            while end < by_rank.len() && at(end) == p {
                end += 1;
            }
            if end - start >= k.max(2) && alone(p, start, end, &at, by_rank.len()) {
                groups.push((start as u32, end as u32));
            }
            start = end;
        }
        if groups.is_empty() {
            by_rank = Vec::new();
        }
        Duplicates { by_rank, groups }
    }

    /// The members of the group holding rank `r`, in rank order, if it is one of them.
    pub(super) fn group(&self, r: u32) -> Option<&[u32]> {
        if self.groups.is_empty() {
            return None;
        }
        let g = self
            .groups
            .partition_point(|&(s, _)| s <= r)
            .checked_sub(1)?;
        let (s, e) = self.groups[g];
        (r < e).then(|| &self.by_rank[s as usize..e as usize])
    }
}

/// Whether no point outside ranks `[start, end)` is at squared distance 0 from `p`. Ranks are
/// sorted by x first, so the points to look at are the neighbours in rank order whose x
/// difference squares to 0; once one squares above 0, every point farther in rank order does.
fn alone(p: V3, start: usize, end: usize, at: &dyn Fn(usize) -> V3, n: usize) -> bool {
    let d2 = |q: V3| {
        let d = sub(q, p);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    };
    let dx2 = |q: V3| (q[0] - p[0]) * (q[0] - p[0]);
    // One side in rank order: clear once an x difference squares above 0; not clear if a
    // point sits at distance 0 or the scan runs past its limit first.
    let clear = |side: &mut dyn Iterator<Item = V3>| {
        for (seen, q) in side.enumerate() {
            if dx2(q) > 0.0 {
                return true;
            }
            if seen >= SCAN_LIMIT || d2(q) == 0.0 {
                return false;
            }
        }
        true
    };
    clear(&mut (0..start).rev().map(at)) && clear(&mut (end..n).map(at))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A group is found only when it has k points and nothing else sits at distance 0; its
    /// members come in rank order.
    #[test]
    fn groups_of_duplicates() {
        let mut xyz = vec![[1.0, 2.0, 3.0]; 40];
        xyz.push([1.0, 2.5, 3.0]);
        xyz.extend(vec![[5.0, 5.0, 5.0]; 10]);
        let ranks: Vec<u32> = {
            let mut idx: Vec<usize> = (0..xyz.len()).collect();
            idx.sort_by(|&a, &b| {
                crate::core::point::cmp_position(&xyz[a], &xyz[b]).then(a.cmp(&b))
            });
            let mut r = vec![0u32; xyz.len()];
            for (k, &i) in idx.iter().enumerate() {
                r[i] = k as u32;
            }
            r
        };
        let d = Duplicates::find(&xyz, &ranks, 30);
        let g = d.group(ranks[7]).expect("the 40 copies");
        assert_eq!(g.len(), 40);
        assert!(g
            .windows(2)
            .all(|w| ranks[w[0] as usize] < ranks[w[1] as usize]));
        assert!(d.group(ranks[40]).is_none() && d.group(ranks[45]).is_none());
        // A distinct point whose difference squares to 0 (underflow) keeps the full search.
        let mut tiny = vec![[0.0, 0.0, 0.0]; 40];
        tiny.push([1e-200, 0.0, 0.0]);
        let r: Vec<u32> = (0..41).collect();
        assert!(Duplicates::find(&tiny, &r, 30).group(0).is_none());
    }
}
