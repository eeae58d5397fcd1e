//! k nearest neighbours within a loaded tile. The answer is exact and ranked by (f64 squared
//! distance, original id), so the neighbour set and its order never depend on the index, the
//! tile or the thread. Two interchangeable backends find the candidates:
//!
//! - a uniform 3D grid with cells of 1.25 times the k-NN radius. A query ranks the 27 cells
//!   around its own (gathered once per cell in f32, see [`Block`]): an f32 pass finds a radius
//!   holding a few more than k points, and only those are ranked exactly. When the k-th
//!   distance is not provably inside those cells, a shell search grows rings of cells until it
//!   is. On one 25k-point tile of the 2M terrain at k = 30: 0.84-0.97 us per query against
//!   2.35-2.9 us for kiddo's `nearest_n` (benches/stages.rs, one thread). Used whenever the
//!   density is even enough for one cell size, which is most LIDAR tiles;
//! - kiddo's k-d tree on tile-local f32 coordinates, with exact re-ranking, for tiles whose
//!   density is too uneven for one cell size (a terrestrial scan near its scanner).
//!
//! Pure: no files, no channels.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::core::geometry::{sub, V3};

/// A k-NN index over the points of one loaded tile.
pub struct NeighbourIndex<'a> {
    xyz: &'a [V3],
    ids: &'a [u64],
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

/// Points bucketed in cubic cells, sorted by (column, z cell).
struct Grid {
    lo: V3,
    cell: f64,
    dims: [usize; 3],
    /// For column ix * ny + iy: its z cells are `zcells[cols[c]..cols[c + 1]]`.
    cols: Vec<u32>,
    /// (z cell, first point in `order`), with a sentinel at the end.
    zcells: Vec<(u32, u32)>,
    /// Local point indices in cell order.
    order: Vec<u32>,
    /// Coordinates and original ids in cell order (contiguous reads while scanning cells).
    xyz: Vec<V3>,
    ids: Vec<u64>,
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
/// reuses it: queries arrive in Morton order, so consecutive ones mostly share a cell.
#[derive(Default)]
struct Block {
    /// The grid (its [`Grid::uid`]) and centre cell gathered, or None before the first gather:
    /// a scratch reused with another index must not reuse another grid's block.
    cell: Option<(u64, [usize; 3])>,
    centre: V3,
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    /// Local point index of each gathered point.
    local: Vec<u32>,
    /// Bound on |f32 squared distance - f64 squared distance| between any two gathered points.
    slack2: f64,
}

/// Per-thread scratch for [`NeighbourIndex::knn`], so queries do not allocate.
#[derive(Default)]
pub struct KnnScratch {
    ranked: Vec<(f64, u64, u32)>,
    block: Block,
    d2: Vec<f32>,
    keys: Vec<u64>,
    exact: Vec<(f64, u64, u32)>,
    /// The last query's squared k-th distance, the first guess for the next one.
    hint: f32,
}

#[inline]
fn rank(a: &(f64, u64, u32), b: &(f64, u64, u32)) -> std::cmp::Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

/// Sorts `v` by [`rank`]. Up to 64 entries (the usual case) are sorted as integer keys, the
/// squared distance's bits with the entry's position in the low 6 bits (branch-free and much
/// faster than comparing tuples), then put in exact order by an insertion pass: the keys only
/// misorder distances within 64 ulps of each other, so that pass moves almost nothing.
fn sort_ranked(
    v: &mut Vec<(f64, u64, u32)>,
    keys: &mut Vec<u64>,
    spare: &mut Vec<(f64, u64, u32)>,
) {
    if v.len() > 64 {
        v.sort_unstable_by(rank);
        return;
    }
    keys.clear();
    // Squared distances are >= +0.0, whose bit patterns order like the values.
    keys.extend(
        v.iter()
            .enumerate()
            .map(|(e, r)| (r.0.to_bits() & !63) | e as u64),
    );
    keys.sort_unstable();
    spare.clear();
    spare.extend(keys.iter().map(|&key| v[(key & 63) as usize]));
    for x in 1..spare.len() {
        let mut y = x;
        while y > 0 && rank(&spare[y], &spare[y - 1]).is_lt() {
            spare.swap(y, y - 1);
            y -= 1;
        }
    }
    std::mem::swap(v, spare);
}

/// Offers a candidate to a max-heap (by rank) that keeps the `cap` best.
#[inline]
fn heap_offer(heap: &mut Vec<(f64, u64, u32)>, cap: usize, c: (f64, u64, u32)) {
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

impl Grid {
    /// A grid with cells of about the radius that holds `k` points at the tile's mean x/y
    /// density, or None when the density is too uneven for one cell size (some cell would hold
    /// many neighbourhoods' worth of points).
    fn build(xyz: &[V3], ids: &[u64], lo: V3, hi: V3, k: usize) -> Option<Grid> {
        let n = xyz.len();
        let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(f64::MIN_POSITIVE);
        let cell = (k as f64 * area / (std::f64::consts::PI * n as f64)).sqrt() * 1.25;
        let g = Self::with_cell(xyz, ids, lo, hi, k, cell)?;
        // Points spread in z (vegetation, walls) occupy more cells than a surface would: then
        // grow the cells so that occupied cells hold about k/3 points (occupancy of a surface
        // grows like cell^2).
        let per_cell = n as f64 / (g.zcells.len() - 1).max(1) as f64;
        if per_cell < k as f64 / 4.0 {
            let grown = cell * ((k as f64 / 3.0) / per_cell).sqrt().min(3.0);
            return Self::with_cell(xyz, ids, lo, hi, k, grown).or(Some(g));
        }
        Some(g)
    }

    fn with_cell(xyz: &[V3], ids: &[u64], lo: V3, hi: V3, k: usize, cell: f64) -> Option<Grid> {
        let n = xyz.len();
        let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(f64::MIN_POSITIVE);
        // At most ~4 columns per point, whatever the shape of the tile.
        let cell = cell.max((area / (4.0 * n as f64)).sqrt());
        if !(cell.is_finite() && cell > 0.0) {
            return None;
        }
        let dim = |a: usize| (((hi[a] - lo[a]) / cell) as usize + 1).min(1 << 20);
        let dims = [dim(0), dim(1), dim(2)];
        if dims[0].saturating_mul(dims[1]) > 8 * n + 64 {
            return None;
        }
        let coord = |p: &V3, a: usize| (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1);
        let mut keyed: Vec<(u64, u32)> = xyz
            .iter()
            .enumerate()
            .map(|(i, p)| {
                (
                    ((coord(p, 0) * dims[1] + coord(p, 1)) as u64) << 32 | coord(p, 2) as u64,
                    i as u32,
                )
            })
            .collect();
        keyed.sort_unstable();
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
        let sorted_ids = order.iter().map(|&i| ids[i as usize]).collect();
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
            ids: sorted_ids,
        })
    }

    /// The cell holding `q` (a point inside the grid's bounds).
    #[inline]
    fn cell_of(&self, q: V3) -> [usize; 3] {
        [0, 1, 2].map(|a| (((q[a] - self.lo[a]) / self.cell) as usize).min(self.dims[a] - 1))
    }

    /// Distance from `q` to the nearest face of the box of cells within Chebyshev distance `r`
    /// of cell `qc`, less the rounding allowance. Faces at the grid's border hide nothing and
    /// do not count (infinite when the box covers the grid).
    fn room(&self, q: V3, qc: [usize; 3], r: usize) -> f64 {
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

    /// Gathers the points of the 3 x 3 x 3 cells around cell `c` into `b`.
    fn gather(&self, c: [usize; 3], b: &mut Block) {
        b.cell = Some((self.uid, c));
        b.centre = [0, 1, 2].map(|a| self.lo[a] + (c[a] as f64 + 0.5) * self.cell);
        b.x.clear();
        b.y.clear();
        b.z.clear();
        b.local.clear();
        let (z_lo, z_hi) = (c[2].saturating_sub(1) as u32, (c[2] + 1) as u32);
        for x in c[0].saturating_sub(1)..(c[0] + 2).min(self.dims[0]) {
            for y in c[1].saturating_sub(1)..(c[1] + 2).min(self.dims[1]) {
                let col = x * self.dims[1] + y;
                let cells = self.cols[col] as usize..self.cols[col + 1] as usize;
                // z cells of a column are sorted, and their points contiguous.
                let first =
                    cells.start + self.zcells[cells.clone()].partition_point(|z| z.0 < z_lo);
                let last = cells.start + self.zcells[cells].partition_point(|z| z.0 <= z_hi);
                let run = self.zcells[first].1 as usize..self.zcells[last].1 as usize;
                for (p, &l) in self.xyz[run.clone()].iter().zip(&self.order[run]) {
                    b.x.push((p[0] - b.centre[0]) as f32);
                    b.y.push((p[1] - b.centre[1]) as f32);
                    b.z.push((p[2] - b.centre[2]) as f32);
                    b.local.push(l);
                }
            }
        }
        // Gathered coordinates are within 1.5 cells of the centre on each axis, so the error of
        // an f32 squared distance (inputs, difference, products, sum) is at most
        // 28 * 2^-24 * R^2 with R = 1.5 * sqrt(3) cells (derivation in docs/architecture.md,
        // k-NN); 100 for margin.
        let r = 1.5 * 3f64.sqrt() * self.cell;
        b.slack2 = 100.0 * (f32::EPSILON as f64 / 2.0) * r * r;
    }
}

impl<'a> NeighbourIndex<'a> {
    /// Builds the index over `xyz` (absolute f64 coordinates) with original ids `ids`, for
    /// queries of about `k` neighbours. Returns None when there are no points or more than
    /// u32::MAX of them.
    pub fn build(xyz: &'a [V3], ids: &'a [u64], k: usize) -> Option<Self> {
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
        if let Some(g) = Grid::build(xyz, ids, lo, hi, k) {
            return Some(NeighbourIndex {
                xyz,
                ids,
                backend: Backend::Grid(g),
            });
        }
        Self::build_tree(xyz, ids, lo, hi)
    }

    fn build_tree(xyz: &'a [V3], ids: &'a [u64], lo: V3, hi: V3) -> Option<Self> {
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
            ids,
            backend: Backend::Tree {
                tree,
                origin,
                slack,
            },
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
    /// `i` itself first (as the CNC reference code counts it), then the k - 1 nearest others by
    /// increasing (exact f64 distance, original id). Fewer when the tile has fewer points.
    /// Returns the exact distance to the farthest neighbour returned.
    pub fn knn(&self, i: usize, k: usize, scratch: &mut KnnScratch, out: &mut Vec<u32>) -> f64 {
        out.clear();
        out.push(i as u32);
        let n = self.xyz.len();
        let others = k.min(n).max(1) - 1;
        if others == 0 {
            return 0.0;
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

    /// The fast path of the grid: ranks the points of the 3 x 3 x 3 cells around `i`'s cell
    /// (gathered once per cell, see [`Block`]). An f32 pass over them finds a squared radius
    /// holding at least the k nearest (the point itself included); every point within that
    /// radius plus the f32 rounding bound is ranked exactly by (f64 distance, id) into
    /// `scratch.exact`. The answer stands when the exact k-th distance is inside the block:
    /// returns its squared distance. Otherwise returns the first shell the shell search must
    /// visit: 2 when `scratch.exact` starts with the exact `others` best of the block (shells 0
    /// and 1 are done), 0 when the block has too few points.
    fn grid_block_knn(
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
        let count = |t: f32| d2.iter().map(|&d| (d <= t) as usize).sum::<usize>();
        // Smallest squared radius found holding >= need points, aiming at a few more than need
        // (so that few points are ranked exactly); counts grow about linearly with the squared
        // radius on a surface, so each guess rescales the last.
        let (mut below, mut above) = (0f32, f32::INFINITY);
        let mut t = if s.hint > 0.0 {
            s.hint
        } else {
            (0.5 * g.cell * g.cell) as f32
        };
        let window = need + need / 4 + 2;
        let aim = (need + need / 8 + 1) as f32;
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
        s.keys.clear();
        s.keys.resize(d2.len(), 0);
        let mut n = 0;
        for (j, &d) in d2.iter().enumerate() {
            s.keys[n] = j as u64; // branch-free compaction of the indices within lim
            n += (d <= lim) as usize;
        }
        s.exact.clear();
        for &j in &s.keys[..n] {
            let l = b.local[j as usize];
            if l as usize != i {
                s.exact
                    .push((self.dist2(q, l as usize), self.ids[l as usize], l));
            }
        }
        if s.exact.len() < others {
            return Err(0);
        }
        sort_ranked(&mut s.exact, &mut s.keys, &mut s.ranked);
        let far2 = s.exact[others - 1].0;
        s.hint = (far2 * 1.1) as f32;
        if far2.sqrt() < g.room(q, c, 1) {
            Ok(far2)
        } else {
            Err(2)
        }
    }

    /// Leaves in `ranked` exactly the `others` nearest points other than `i` (as a max-heap by
    /// rank, possibly seeded with the exact best of the shells before `first_shell`): grows a
    /// box of cells around `i`, shell by shell from `first_shell`, until the worst kept distance is
    /// strictly inside the box (every point outside is farther). Cells whose nearest corner is
    /// farther than the worst kept candidate are skipped.
    fn grid_candidates(
        &self,
        g: &Grid,
        i: usize,
        others: usize,
        first_shell: usize,
        heap: &mut Vec<(f64, u64, u32)>,
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
                        for ((&j, p), &id) in g.order[cell.clone()]
                            .iter()
                            .zip(&g.xyz[cell.clone()])
                            .zip(&g.ids[cell])
                        {
                            if j as usize != i {
                                let d = sub(*p, q);
                                heap_offer(
                                    heap,
                                    others,
                                    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2], id, j),
                                );
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

    /// kiddo proposes candidates; if rounding or ties could hide a point at the k-th place, a
    /// radius query with the rounding slack collects all of them.
    fn tree_candidates(
        &self,
        tree: &ImmutableKdTree<f32, 3>,
        origin: V3,
        slack: f64,
        i: usize,
        others: usize,
        ranked: &mut Vec<(f64, u64, u32)>,
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
                    self.ids[c.item as usize],
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
                        self.ids[c.item as usize],
                        c.item,
                    ));
                }
            }
        }
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

    fn check_both_backends(xyz: &[V3], ids: &[u64], ks: &[usize]) {
        let mut lo = xyz[0];
        let mut hi = xyz[0];
        for p in xyz {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let tree = NeighbourIndex::build_tree(xyz, ids, lo, hi).expect("tree");
        let mut scratch = KnnScratch::default();
        let mut out = Vec::new();
        for &k in ks {
            let index = NeighbourIndex::build(xyz, ids, k).expect("index");
            for i in 0..xyz.len() {
                let want = brute(xyz, ids, i, k);
                index.knn(i, k, &mut scratch, &mut out);
                assert_eq!(out, want, "auto backend, point {i} k {k}");
                tree.knn(i, k, &mut scratch, &mut out);
                assert_eq!(out, want, "tree backend, point {i} k {k}");
            }
        }
    }

    #[test]
    fn matches_brute_force_with_duplicates_and_utm_offsets() {
        // A grid with exact duplicates and many equal distances, far from the origin (UTM-like).
        let mut xyz = Vec::new();
        let mut rng = crate::core::rng::Rng::new(12345);
        let mut next = || rng.next_u64();
        for gx in 0..20 {
            for gy in 0..20 {
                let p = [
                    500_000.0 + gx as f64 * 0.5,
                    5_000_000.0 + gy as f64 * 0.5,
                    100.0,
                ];
                xyz.push(p);
                if next() >> 61 == 0 {
                    xyz.push(p); // exact duplicate return
                }
            }
        }
        // A few isolated points far away (sparse shells) and a tree-like vertical column.
        xyz.push([500_030.0, 5_000_030.0, 100.0]);
        xyz.push([499_990.0, 5_000_002.0, 140.0]);
        for h in 0..15 {
            xyz.push([500_004.0, 5_000_004.0, 100.5 + h as f64 * 0.7]);
        }
        // Ids deliberately not in storage order.
        let ids: Vec<u64> = (0..xyz.len() as u64)
            .map(|i| (i * 7919) % 100_003)
            .collect();
        assert!(matches!(
            NeighbourIndex::build(&xyz, &ids, 8).map(|x| x.backend),
            Some(Backend::Grid(_))
        ));
        check_both_backends(&xyz, &ids, &[1, 5, 8, 9, 13, 30]);
    }

    #[test]
    fn block_path_is_exact_on_terrain_with_vegetation() {
        // A bumpy surface at UTM offsets with a vegetated patch (points spread in z), snapped to
        // a 1 cm lattice so that equal distances (ties broken by id) occur.
        let mut rng = crate::core::rng::Rng::new(4242);
        let mut unit = || rng.uniform();
        let mut xyz = Vec::new();
        for _ in 0..6000 {
            let (x, y) = (40.0 * unit(), 40.0 * unit());
            let mut z = 3.0 * (x / 7.0).sin() * (y / 5.0).cos();
            if x < 12.0 && y < 12.0 && unit() < 0.5 {
                z += 15.0 * unit(); // canopy
            }
            let snap = |v: f64| (v * 100.0).round() / 100.0;
            xyz.push([500_000.0 + snap(x), 4_000_000.0 + snap(y), 120.0 + snap(z)]);
        }
        let ids: Vec<u64> = (0..xyz.len() as u64)
            .map(|i| (i * 104_729) % 7919)
            .collect();
        for k in [2, 10, 30, 31, 64] {
            let index = NeighbourIndex::build(&xyz, &ids, k).expect("index");
            let Backend::Grid(g) = &index.backend else {
                panic!("a surface gets the grid");
            };
            let mut s = KnnScratch::default();
            let mut out = Vec::new();
            let mut by_block = 0;
            for i in 0..xyz.len() {
                let want = brute(&xyz, &ids, i, k);
                if index.grid_block_knn(g, i, k - 1, &mut s).is_ok() {
                    by_block += 1;
                    let got: Vec<u32> = std::iter::once(i as u32)
                        .chain(s.exact[..k - 1].iter().map(|r| r.2))
                        .collect();
                    assert_eq!(got, want, "block path, point {i} k {k}");
                }
                index.knn(i, k, &mut s, &mut out);
                assert_eq!(out, want, "point {i} k {k}");
            }
            // The fast path must carry most queries; the canopy sends some to the seeded shell
            // search, which the equality above checked too.
            assert!(
                by_block * 10 > xyz.len() * 8,
                "k {k}: {by_block} by the block"
            );
            assert!(
                by_block < xyz.len(),
                "k {k}: no query reached the shell search"
            );
        }
    }

    #[test]
    fn a_scratch_reused_with_another_index_stays_exact() {
        // Two clouds whose grids have the same cell indices at different places: a block
        // cached for the first must not answer for the second.
        let mut rng = crate::core::rng::Rng::new(5);
        let a: Vec<V3> = (0..3000)
            .map(|_| {
                [
                    30.0 * rng.uniform(),
                    30.0 * rng.uniform(),
                    0.1 * rng.uniform(),
                ]
            })
            .collect();
        let b: Vec<V3> = a.iter().map(|p| [p[1], p[0], p[2] + 0.05]).collect();
        let ids: Vec<u64> = (0..a.len() as u64).collect();
        let (ia, ib) = (
            NeighbourIndex::build(&a, &ids, 20).expect("index"),
            NeighbourIndex::build(&b, &ids, 20).expect("index"),
        );
        let mut s = KnnScratch::default();
        let mut out = Vec::new();
        for i in (0..a.len()).step_by(7) {
            ia.knn(i, 20, &mut s, &mut out);
            assert_eq!(out, brute(&a, &ids, i, 20), "first cloud, point {i}");
            ib.knn(i, 20, &mut s, &mut out);
            assert_eq!(out, brute(&b, &ids, i, 20), "second cloud, point {i}");
        }
    }

    #[test]
    fn uneven_density_uses_the_tree_and_stays_exact() {
        // 2000 points in a 1 cm blob and 200 spread over 100 m: no single cell size fits.
        let mut xyz = Vec::new();
        let mut rng = crate::core::rng::Rng::new(99);
        let mut unit = || rng.uniform();
        for _ in 0..2000 {
            xyz.push([0.01 * unit(), 0.01 * unit(), 0.01 * unit()]);
        }
        for _ in 0..200 {
            xyz.push([100.0 * unit(), 100.0 * unit(), unit()]);
        }
        let ids: Vec<u64> = (0..xyz.len() as u64).collect();
        assert!(matches!(
            NeighbourIndex::build(&xyz, &ids, 10).map(|x| x.backend),
            Some(Backend::Tree { .. })
        ));
        check_both_backends(&xyz, &ids, &[10]);
    }
}
