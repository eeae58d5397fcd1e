//! The uniform grid backend: points bucketed in cubic cells of about 1.25 times the k-NN radius
//! ([`Grid`]), and its fast path, which ranks the 27 cells around a query's cell from an f32
//! block gathered once per cell ([`Block`]; error bound in docs/architecture.md, k-NN). It only
//! narrows the candidates: the answer is ranked exactly in f64, and a query the block cannot
//! settle goes on to the shell search (`shell`). Pure: no files, no channels.

use super::{sort_ranked, sq_dist, KnnScratch, NeighbourIndex};

use crate::core::geometry::V3;

/// Points bucketed in cubic cells, sorted by (column, z cell).
pub(super) struct Grid {
    pub(super) lo: V3,
    pub(super) cell: f64,
    pub(super) dims: [usize; 3],
    /// For column ix * ny + iy: its z cells are `zcells[cols[c]..cols[c + 1]]`.
    pub(super) cols: Vec<u32>,
    /// (z cell, first point in `order`), with a sentinel at the end.
    pub(super) zcells: Vec<(u32, u32)>,
    /// Local point indices in cell order.
    pub(super) order: Vec<u32>,
    /// Coordinates and position ranks in cell order (contiguous reads while scanning cells).
    pub(super) xyz: Vec<V3>,
    pub(super) ranks: Vec<u32>,
    /// Rounding allowance when comparing a distance with a cell face: cell membership and face
    /// positions are computed in f64 at the coordinates' magnitude (1e6 for UTM).
    face_eps: f64,
    /// Unique per grid built in this process (see [`Block`]).
    uid: u64,
}

/// Source of [`Grid::uid`].
static NEXT_GRID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The 3 x 3 x 3 cells around one grid cell, gathered as f32 coordinates relative to the cell's
/// centre (structure of arrays, so the distance pass vectorises). Every query in that cell
/// reuses it: the tile's k-NN tasks query their points in cell order
/// ([`NeighbourIndex::query_key`]), so consecutive ones mostly share a cell.
#[derive(Default)]
pub(super) struct Block {
    /// The grid (its [`Grid::uid`]) and centre cell gathered, or None before the first gather:
    /// a scratch reused with another index must not reuse another grid's block.
    cell: Option<(u64, [usize; 3])>,
    centre: V3,
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    /// The gathered points' absolute f64 coordinates (copied in cell order, so the exact
    /// ranking reads them contiguously instead of at random in the tile's order).
    xyz: Vec<V3>,
    /// Local point index and position rank of each gathered point.
    local: Vec<u32>,
    rank: Vec<u32>,
    /// Bound on |f32 squared distance - f64 squared distance| between any two gathered points.
    slack2: f64,
}

/// The key of cell `c` in a grid of `dims` cells, the order the grid sorts its cells in:
/// column (x, y), then z cell.
#[inline]
pub(super) fn cell_key(dims: [usize; 3], c: [usize; 3]) -> u64 {
    ((c[0] * dims[1] + c[1]) as u64) << 32 | c[2] as u64
}

/// The most cells a grid has along one axis (cell indices stay far from any integer limit).
const MAX_CELLS_PER_AXIS: usize = 1 << 20;

/// The area the points of a tile spread over: the x/y extent, or for a vertical tile (a facade,
/// all points with one x or one y) its largest vertical face, so that the cell size follows the
/// points' spacing rather than a zero area. Never zero.
fn surface_area(lo: V3, hi: V3) -> f64 {
    let e = [0, 1, 2].map(|a| hi[a] - lo[a]);
    let xy = e[0] * e[1];
    let area = if xy > 0.0 {
        xy
    } else {
        (e[0] * e[2]).max(e[1] * e[2])
    };
    area.max(f64::MIN_POSITIVE)
}

impl Grid {
    /// A grid with cells of about the radius that holds `k` points at the tile's mean x/y
    /// density, or None when the density is too uneven for one cell size (some cell would hold
    /// many neighbourhoods' worth of points).
    pub(super) fn build(xyz: &[V3], ranks: &[u32], lo: V3, hi: V3, k: usize) -> Option<Grid> {
        let n = xyz.len();
        let area = surface_area(lo, hi);
        let cell = (k as f64 * area / (std::f64::consts::PI * n as f64)).sqrt() * 1.25;
        let g = Self::with_cell(xyz, ranks, lo, hi, k, cell)?;
        // Points spread in z (vegetation, walls) occupy more cells than a surface would: then
        // grow the cells so that occupied cells hold about k/3 points (occupancy of a surface
        // grows like cell^2).
        let per_cell = n as f64 / (g.zcells.len() - 1).max(1) as f64;
        if per_cell < k as f64 / 4.0 {
            let grown = cell * ((k as f64 / 3.0) / per_cell).sqrt().min(3.0);
            return Self::with_cell(xyz, ranks, lo, hi, k, grown).or(Some(g));
        }
        Some(g)
    }

    fn with_cell(xyz: &[V3], ranks: &[u32], lo: V3, hi: V3, k: usize, cell: f64) -> Option<Grid> {
        let n = xyz.len();
        let area = surface_area(lo, hi);
        // At most ~4 columns per point, whatever the shape of the tile.
        let cell = cell.max((area / (4.0 * n as f64)).sqrt());
        if !(cell.is_finite() && cell > 0.0) {
            return None;
        }
        // Cells per axis, computed in f64: a degenerate extent (all points with one x) or a
        // tiny cell would overflow an integer cast. A grid that would need more than
        // MAX_CELLS_PER_AXIS cells on an axis is refused and the k-d tree takes the tile.
        let dim = |a: usize| {
            let d = ((hi[a] - lo[a]) / cell).floor();
            (d >= 0.0 && d < MAX_CELLS_PER_AXIS as f64).then(|| d as usize + 1)
        };
        let [Some(dx), Some(dy), Some(dz)] = [dim(0), dim(1), dim(2)] else {
            return None;
        };
        let dims = [dx, dy, dz];
        if dims[0] * dims[1] > 8 * n + 64 {
            return None;
        }
        let coord = |p: &V3, a: usize| (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1);
        let mut keyed: Vec<(u64, u32)> = xyz
            .iter()
            .enumerate()
            .map(|(i, p)| (cell_key(dims, [0, 1, 2].map(|a| coord(p, a))), i as u32))
            .collect();
        crate::core::radix::sort_by_key(&mut keyed, &mut Vec::new());
        let mut cols = vec![0u32; dims[0] * dims[1] + 1];
        let mut zcells: Vec<(u32, u32)> = Vec::new();
        let mut biggest = 0usize;
        let mut start = 0usize;
        for (pos, &(key, _)) in keyed.iter().enumerate() {
            if pos == 0 || key != keyed[pos - 1].0 {
                biggest = biggest.max(pos - start);
                start = pos;
                let col = (key >> 32) as usize;
                cols[col + 1] += 1;
                zcells.push(((key & 0xffff_ffff) as u32, pos as u32));
            }
        }
        biggest = biggest.max(n - start);
        if biggest > 16 * k.max(8) {
            return None;
        }
        for c in 1..cols.len() {
            cols[c] += cols[c - 1];
        }
        zcells.push((u32::MAX, n as u32));
        let order: Vec<u32> = keyed.into_iter().map(|(_, i)| i).collect();
        let sorted_xyz = order.iter().map(|&i| xyz[i as usize]).collect();
        let sorted_ranks = order.iter().map(|&i| ranks[i as usize]).collect();
        let magnitude = (0..3)
            .map(|a| lo[a].abs().max(hi[a].abs()))
            .fold(cell, f64::max);
        Some(Grid {
            face_eps: 16.0 * f64::EPSILON * magnitude,
            uid: NEXT_GRID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            lo,
            cell,
            dims,
            cols,
            zcells,
            order,
            xyz: sorted_xyz,
            ranks: sorted_ranks,
        })
    }

    /// The cell holding `q` (a point inside the grid's bounds).
    #[inline]
    pub(super) fn cell_of(&self, q: V3) -> [usize; 3] {
        [0, 1, 2].map(|a| (((q[a] - self.lo[a]) / self.cell) as usize).min(self.dims[a] - 1))
    }

    /// Distance from `q` to the nearest face of the box of cells within Chebyshev distance `r`
    /// of cell `qc`, less the rounding allowance. Faces at the grid's border hide nothing and
    /// do not count (infinite when the box covers the grid).
    pub(super) fn room(&self, q: V3, qc: [usize; 3], r: usize) -> f64 {
        let mut room = f64::INFINITY;
        for a in 0..3 {
            if qc[a] > r {
                room = room.min(q[a] - (self.lo[a] + (qc[a] - r) as f64 * self.cell));
            }
            if qc[a] + r + 1 < self.dims[a] {
                room = room.min(self.lo[a] + (qc[a] + r + 1) as f64 * self.cell - q[a]);
            }
        }
        room - self.face_eps
    }

    /// Appends the points `run` (in cell order) to the block `b`.
    fn copy_run(&self, run: std::ops::Range<usize>, b: &mut Block) {
        // One pass per array over a contiguous run: no per-element capacity checks.
        let pts = &self.xyz[run.clone()];
        b.x.extend(pts.iter().map(|p| (p[0] - b.centre[0]) as f32));
        b.y.extend(pts.iter().map(|p| (p[1] - b.centre[1]) as f32));
        b.z.extend(pts.iter().map(|p| (p[2] - b.centre[2]) as f32));
        b.xyz.extend_from_slice(pts);
        b.local.extend_from_slice(&self.order[run.clone()]);
        b.rank.extend_from_slice(&self.ranks[run]);
    }

    /// Gathers the points of the 3 x 3 x 3 cells around cell `c` into `b`.
    fn gather(&self, c: [usize; 3], b: &mut Block) {
        b.cell = Some((self.uid, c));
        b.centre = [0, 1, 2].map(|a| self.lo[a] + (c[a] as f64 + 0.5) * self.cell);
        b.x.clear();
        b.y.clear();
        b.z.clear();
        b.xyz.clear();
        b.local.clear();
        b.rank.clear();
        let (z_lo, z_hi) = (c[2].saturating_sub(1) as u32, (c[2] + 1) as u32);
        for x in c[0].saturating_sub(1)..(c[0] + 2).min(self.dims[0]) {
            // The columns (x, y - 1..=y + 1) are consecutive in the grid's order: where their
            // runs of points touch (one z cell a column, as on terrain), one copy takes them.
            let mut run = 0..0;
            for y in c[1].saturating_sub(1)..(c[1] + 2).min(self.dims[1]) {
                let col = x * self.dims[1] + y;
                let cells = self.cols[col] as usize..self.cols[col + 1] as usize;
                // z cells of a column are sorted, and their points contiguous.
                let first =
                    cells.start + self.zcells[cells.clone()].partition_point(|z| z.0 < z_lo);
                let last = cells.start + self.zcells[cells].partition_point(|z| z.0 <= z_hi);
                let next = self.zcells[first].1 as usize..self.zcells[last].1 as usize;
                if next.start == run.end {
                    run.end = next.end;
                } else {
                    self.copy_run(run, b);
                    run = next;
                }
            }
            self.copy_run(run, b);
        }
        // Gathered coordinates are within 1.5 cells of the centre on each axis, so the error of
        // an f32 squared distance (inputs, difference, products, sum) is at most
        // 28 * 2^-24 * R^2 with R = 1.5 * sqrt(3) cells (derivation in docs/architecture.md,
        // k-NN); 100 for margin.
        let r = 1.5 * 3f64.sqrt() * self.cell;
        b.slack2 = 100.0 * (f32::EPSILON as f64 / 2.0) * r * r;
    }
}

/// Writes to the front of `out` the indices j of `d2` with `d2[j] <= lim`, in increasing
/// order, and returns how many. Branch-free (a branch per point mispredicted often): eight at a
/// time where the build has AVX2 (`simd`), else one at a time.
fn select_within(d2: &[f32], lim: f32, out: &mut Vec<u32>) -> usize {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    // SAFETY: compiled only where the build enables AVX2, whose absence main.rs refuses.
    return unsafe { super::simd::select_within(d2, lim, out) };
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        if out.len() < d2.len() {
            out.resize(d2.len(), 0);
        }
        let mut n = 0;
        for (j, &d) in d2.iter().enumerate() {
            out[n] = j as u32;
            n += (d <= lim) as usize;
        }
        n
    }
}

impl NeighbourIndex<'_> {
    /// The fast path of the grid: ranks the points of the 3 x 3 x 3 cells around `i`'s cell
    /// (gathered once per cell, see [`Block`]). An f32 pass over them finds a squared radius
    /// holding at least the k nearest (the point itself included); every point within that
    /// radius plus the f32 rounding bound is ranked exactly (f64 distance, position, id) into
    /// `scratch.exact`. The answer stands when the exact k-th distance is inside the block:
    /// returns its squared distance. Otherwise returns the first shell the shell search must
    /// visit: 2 when `scratch.exact` starts with the exact `others` best of the block (shells 0
    /// and 1 are done), 0 when the block has too few points.
    pub(super) fn grid_block_knn(
        &self,
        g: &Grid,
        i: usize,
        others: usize,
        s: &mut KnnScratch,
    ) -> Result<f64, usize> {
        let q = self.xyz[i];
        let c = g.cell_of(q);
        if s.block.cell != Some((g.uid, c)) {
            g.gather(c, &mut s.block);
        }
        let b = &s.block;
        let need = others + 1; // the query itself is gathered too, at distance 0
        if b.x.len() < need {
            return Err(0);
        }
        let ql = [0, 1, 2].map(|a| (q[a] - b.centre[a]) as f32);
        s.d2.clear();
        s.d2.extend(b.x.iter().zip(&b.y).zip(&b.z).map(|((&x, &y), &z)| {
            let (dx, dy, dz) = (x - ql[0], y - ql[1], z - ql[2]);
            dx * dx + dy * dy + dz * dz
        }));
        let d2 = &s.d2[..];
        // u32 lanes: twice as many per vector as usize (a block holds far fewer than 2^32).
        let count = |t: f32| d2.iter().map(|&d| (d <= t) as u32).sum::<u32>() as usize;
        // Smallest squared radius found holding >= need points, aiming at a few more than need
        // (so that few points are ranked exactly); counts grow about linearly with the squared
        // radius on a surface, so each guess rescales the last.
        let (mut below, mut above) = (0f32, f32::INFINITY);
        let mut t = if s.hint > 0.0 {
            s.hint
        } else {
            (0.5 * g.cell * g.cell) as f32
        };
        // A narrow window: every point in it is ranked exactly and sorted, and the standard
        // library sorts up to 32 keys with its small-sort network but partitions more first.
        // At k = 30 the former window (need + 9) left 29-38 keys to sort; an extra count pass
        // costs far less than that partition.
        let window = need + 2 + need / 16;
        let aim = (need + 1 + need / 32) as f32;
        for _ in 0..8 {
            let n = count(t);
            if n >= need {
                above = t;
                if n <= window {
                    break;
                }
            } else {
                below = t;
            }
            let mut next = if n == 0 {
                4.0 * t
            } else {
                t * (aim / n as f32).clamp(0.25, 4.0)
            };
            if !(next > below && next < above) {
                next = if above.is_finite() {
                    0.5 * (below + above)
                } else {
                    4.0 * t
                };
            }
            t = next;
        }
        // Every point that can be among the exact k nearest is within `above` plus twice the
        // rounding bound (f32 k-th <= above; exact and f32 values differ by <= slack2).
        let lim = ((above as f64 + 2.0 * b.slack2) * (1.0 + 1e-6)) as f32;
        // The block points within lim (about a quarter of the block), then the exact ranking
        // of those.
        let n = select_within(d2, lim, &mut s.within);
        s.exact.clear();
        for &j in &s.within[..n] {
            let (j, l) = (j as usize, b.local[j as usize]);
            if l as usize != i {
                s.exact.push((sq_dist(b.xyz[j], q), b.rank[j], l));
            }
        }
        if s.exact.len() < others {
            return Err(0);
        }
        sort_ranked(&mut s.exact, &mut s.keys, &mut s.ranked);
        let far2 = s.exact[others - 1].0;
        s.hint = (far2 * 1.04) as f32;
        if far2.sqrt() < g.room(q, c, 1) {
            Ok(far2)
        } else {
            Err(2)
        }
    }
}
