//! The grid's shell search, for queries the 27-cell block cannot settle: a bounded max-heap of
//! exact candidates, ranked by (f64 distance, position, id), grown ring by ring of cells until
//! the k-th distance is provably inside the searched box. Pure: no files, no channels.

use super::grid::Grid;
use super::{rank, Cand, NeighbourIndex};
use crate::core::geometry::sub;

/// Offers a candidate to a max-heap (by [`rank`]) that keeps the `cap` best.
#[inline]
fn heap_offer(heap: &mut Vec<Cand>, cap: usize, c: Cand) {
    if heap.len() < cap {
        heap.push(c);
        let mut i = heap.len() - 1;
        while i > 0 {
            let p = (i - 1) / 2;
            if rank(&heap[p], &heap[i]).is_lt() {
                heap.swap(p, i);
                i = p;
            } else {
                break;
            }
        }
    } else if rank(&c, &heap[0]).is_lt() {
        heap[0] = c;
        let mut i = 0;
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut big = i;
            if l < cap && rank(&heap[l], &heap[big]).is_gt() {
                big = l;
            }
            if r < cap && rank(&heap[r], &heap[big]).is_gt() {
                big = r;
            }
            if big == i {
                break;
            }
            heap.swap(i, big);
            i = big;
        }
    }
}

impl NeighbourIndex<'_> {
    /// Leaves in `ranked` exactly the `others` nearest points other than `i` (as a max-heap by
    /// rank, possibly seeded with the exact best of the shells before `first_shell`): grows a
    /// box of cells around `i`, shell by shell from `first_shell`, until the worst kept distance is
    /// strictly inside the box (every point outside is farther). Cells whose nearest corner is
    /// farther than the worst kept candidate are skipped.
    pub(super) fn grid_candidates(
        &self,
        g: &Grid,
        i: usize,
        others: usize,
        first_shell: usize,
        heap: &mut Vec<Cand>,
    ) {
        let q = self.xyz[i];
        let cell = g.cell_of(q);
        let qc = cell.map(|c| c as i64);
        // Squared distance from q to the slab of cell index c along axis a (0 inside it).
        let gap = |a: usize, c: i64| {
            let lo = g.lo[a] + c as f64 * g.cell;
            let d = (lo - q[a]).max(q[a] - (lo + g.cell)).max(0.0);
            d * d
        };
        let mut r = first_shell as i64;
        loop {
            // Visit the shell of cells at Chebyshev distance r from the query's cell.
            for dx in -r..=r {
                let x = qc[0] + dx;
                if x < 0 || x >= g.dims[0] as i64 {
                    continue;
                }
                let gx = gap(0, x);
                for dy in -r..=r {
                    let y = qc[1] + dy;
                    if y < 0 || y >= g.dims[1] as i64 {
                        continue;
                    }
                    let gxy = gx + gap(1, y);
                    if heap.len() == others && gxy > heap[0].0 {
                        continue;
                    }
                    let col = x as usize * g.dims[1] + y as usize;
                    let edge_xy = dx.abs() == r || dy.abs() == r;
                    for w in g.cols[col] as usize..g.cols[col + 1] as usize {
                        let (z, start) = g.zcells[w];
                        let dz = z as i64 - qc[2];
                        if dz.abs() > r || (!edge_xy && dz.abs() != r) {
                            continue;
                        }
                        if heap.len() == others && gxy + gap(2, z as i64) > heap[0].0 {
                            continue;
                        }
                        let cell = start as usize..g.zcells[w + 1].1 as usize;
                        for ((&j, p), &r) in g.order[cell.clone()]
                            .iter()
                            .zip(&g.xyz[cell.clone()])
                            .zip(&g.ranks[cell])
                        {
                            if j as usize != i {
                                let d = sub(*p, q);
                                let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                                heap_offer(heap, others, (d2, r, j));
                            }
                        }
                    }
                }
            }
            if (0..3).all(|a| qc[a] - r <= 0 && qc[a] + r >= g.dims[a] as i64 - 1) {
                return; // the box covers the whole grid
            }
            if heap.len() == others && heap[0].0.sqrt() < g.room(q, cell, r as usize) {
                return;
            }
            r += 1;
        }
    }
}
