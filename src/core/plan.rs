//! The tiling plan: square tiles of the requested size anchored at multiples of the size in file
//! coordinates, each point in exactly one tile's core, and an initial halo per tile from its
//! density. Pure: works on counts and bounds gathered by the scan.

use std::collections::BTreeMap;

use crate::core::geometry::V3;

/// Integer tile coordinates (floor(x / size), floor(y / size)).
pub type TileKey = (i64, i64);

/// An axis-aligned rectangle in x/y.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Rect {
    /// Minimum x, y.
    pub min: [f64; 2],
    /// Maximum x, y.
    pub max: [f64; 2],
}

impl Rect {
    /// The rectangle grown by `d` on every side.
    pub fn grown(&self, d: f64) -> Rect {
        Rect {
            min: [self.min[0] - d, self.min[1] - d],
            max: [self.max[0] + d, self.max[1] + d],
        }
    }

    /// Whether (x, y) lies in the closed rectangle.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.min[0] && x <= self.max[0] && y >= self.min[1] && y <= self.max[1]
    }

    /// Whether this rectangle contains all of `other`.
    pub fn covers(&self, other: &Rect) -> bool {
        self.min[0] <= other.min[0]
            && self.min[1] <= other.min[1]
            && self.max[0] >= other.max[0]
            && self.max[1] >= other.max[1]
    }

    /// Distance from (x, y) inside this loaded region to the nearest side behind which points
    /// may exist that were not loaded. Sides at or beyond the scene's bounds hide nothing and are
    /// ignored (infinite distance). Any point not loaded is strictly farther than this.
    pub fn distance_to_open_side(&self, x: f64, y: f64, scene: &Rect) -> f64 {
        let mut d = f64::INFINITY;
        if self.min[0] > scene.min[0] {
            d = d.min(x - self.min[0]);
        }
        if self.max[0] < scene.max[0] {
            d = d.min(self.max[0] - x);
        }
        if self.min[1] > scene.min[1] {
            d = d.min(y - self.min[1]);
        }
        if self.max[1] < scene.max[1] {
            d = d.min(self.max[1] - y);
        }
        d
    }
}

/// The tile grid: tiles of edge `size` anchored at multiples of `size`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TileGrid {
    /// Tile edge length in file units.
    pub size: f64,
}

/// The largest tile key on either axis (in magnitude): keys, their neighbours' keys and their
/// rectangles stay exact in f64 and far from the i64 limits, and a grid of keys counts in u64.
/// A point beyond it is refused before any work ([`TileGrid::holds`]).
pub const MAX_TILE_KEY: i64 = 1 << 40;

/// The largest coordinate magnitude tilecurv computes on: squared distances between any two
/// points stay finite in f64, and coordinates relative to a tile stay finite in f32. No survey
/// comes near it; a coordinate beyond it is a corrupt scale or offset.
pub const MAX_COORDINATE: f64 = 1e30;

/// Whether a decoded coordinate can be computed on: finite and within [`MAX_COORDINATE`].
pub fn computable(xyz: V3) -> bool {
    xyz.iter().all(|c| c.abs() <= MAX_COORDINATE)
}

impl TileGrid {
    /// The tile whose core holds (x, y). The one function that decides core membership. Total:
    /// keys saturate at +-[`MAX_TILE_KEY`] (and NaN gives 0), so no input makes it overflow;
    /// the points it would misplace are refused first ([`TileGrid::holds`]).
    pub fn key(&self, x: f64, y: f64) -> TileKey {
        let k = |v: f64| {
            let t = (v / self.size).floor();
            let m = MAX_TILE_KEY as f64;
            if t.is_nan() {
                0
            } else {
                t.clamp(-m, m) as i64
            }
        };
        (k(x), k(y))
    }

    /// Whether (x, y) has a tile key within +-[`MAX_TILE_KEY`] (the key is then exact).
    pub fn holds(&self, x: f64, y: f64) -> bool {
        let ok = |v: f64| (v / self.size).abs() < MAX_TILE_KEY as f64;
        ok(x) && ok(y)
    }

    /// What is wrong when (x, y) of `what` is outside the grid ([`TileGrid::holds`]), and what
    /// to do: a usage error's text.
    pub fn outside(&self, what: &str, x: f64, y: f64) -> String {
        format!(
            "{what} lies at x = {x:e}, y = {y:e}: more than 2^40 tiles of --tile {} from the origin, which the tile grid cannot index; use a larger --tile (or check the file's scale and offset)",
            self.size
        )
    }

    /// The core rectangle of a tile.
    pub fn rect(&self, key: TileKey) -> Rect {
        let s = self.size;
        Rect {
            min: [key.0 as f64 * s, key.1 as f64 * s],
            max: [(key.0 + 1) as f64 * s, (key.1 + 1) as f64 * s],
        }
    }
}

/// A running centroid of many points: streaming, and mergeable in any grouping with exactly
/// the same result. Each coordinate is summed as an integer count of 2^-32 units (i128), so the
/// sum does not depend on the order or on how the points were split between scan tasks
/// (floating-point sums do). The quantization is below the f64 spacing of coordinates from
/// 2^21 on (UTM northings, eastings past 2,097 km) and at most 1.2e-10 units elsewhere.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Centroid {
    /// Per axis: the sum of round(coordinate * 2^32), saturating at the i128 range.
    pub sum: [i128; 3],
    /// Points added.
    pub n: u64,
}

/// 2^32: the units per coordinate unit of [`Centroid`]'s sums.
const CENTROID_UNITS: f64 = 4_294_967_296.0;

/// 2^63, the first f64 past the i64 range.
const TWO_POW_63: f64 = 9_223_372_036_854_775_808.0;

impl Centroid {
    /// Adds one point (finite coordinates; others saturate and make the centroid meaningless).
    pub fn add(&mut self, p: V3) {
        for (s, c) in self.sum.iter_mut().zip(p) {
            // `as` saturates: a coordinate beyond 2^95 cannot overflow the sum by itself.
            // Through i64 where the value fits (coordinates below 2^31 units): the same
            // integer without the f64 -> i128 library call, which is slow on every point.
            let v = (c * CENTROID_UNITS).round();
            let q = match v.abs() < TWO_POW_63 {
                true => v as i64 as i128,
                false => v as i128,
            };
            *s = s.saturating_add(q);
        }
        self.n += 1;
    }

    /// Adds every point of `other` (e.g. the centroid of another chunk or scan task).
    pub fn merge(&mut self, other: &Centroid) {
        for (s, o) in self.sum.iter_mut().zip(other.sum) {
            *s = s.saturating_add(o);
        }
        self.n += other.n;
    }

    /// The centroid, or None when no point was added: the exact integer mean, then its
    /// remainder, in f64.
    pub fn get(&self) -> Option<V3> {
        let n = i128::from(self.n);
        (n > 0).then(|| {
            self.sum.map(|s| {
                let (q, r) = (s / n, s % n);
                (q as f64 + r as f64 / n as f64) / CENTROID_UNITS
            })
        })
    }
}

/// What the scan pass learned about the cloud.
#[derive(Debug, Clone, Default)]
pub struct ScanStats {
    /// Number of points.
    pub count: u64,
    /// Minimum x, y, z of the points.
    pub min: [f64; 3],
    /// Maximum x, y, z of the points.
    pub max: [f64; 3],
    /// Points per tile core.
    pub per_tile: BTreeMap<TileKey, u64>,
    /// Centroid of all points, as an exact mergeable sum.
    pub centroid: Centroid,
}

impl ScanStats {
    /// Statistics of no point: bounds that any point widens.
    pub fn empty() -> Self {
        ScanStats {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
            ..Default::default()
        }
    }

    /// Adds one point to the bounds, the centroid and the count; [`ScanStats::in_tile`] counts
    /// it in its tile (once per run of points of one tile, not per point).
    pub fn add(&mut self, xyz: [f64; 3]) {
        for (a, &c) in xyz.iter().enumerate() {
            self.min[a] = self.min[a].min(c);
            self.max[a] = self.max[a].max(c);
        }
        self.centroid.add(xyz);
        self.count += 1;
    }

    /// Counts `n` added points in the core of tile `key`.
    pub fn in_tile(&mut self, key: TileKey, n: u64) {
        *self.per_tile.entry(key).or_default() += n;
    }

    /// Adds the statistics of other points (another scan task's): the result is the same
    /// bits in any grouping and order.
    pub fn merge(&mut self, other: &ScanStats) {
        for a in 0..3 {
            self.min[a] = self.min[a].min(other.min[a]);
            self.max[a] = self.max[a].max(other.max[a]);
        }
        self.centroid.merge(&other.centroid);
        for (k, n) in &other.per_tile {
            *self.per_tile.entry(*k).or_default() += n;
        }
        self.count += other.count;
    }

    /// The centroid of all points (the origin when there is none).
    pub fn centroid(&self) -> [f64; 3] {
        self.centroid.get().unwrap_or_default()
    }
}

/// One tile of the plan.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSpec {
    /// Position of the tile in the plan.
    pub index: u32,
    /// Tile coordinates.
    pub key: TileKey,
    /// Number of core points.
    pub count: u64,
    /// Initial halo width (file units); widened per point when verification fails.
    pub halo: f64,
}

/// The tiling plan.
#[derive(Debug, Clone)]
pub struct TilePlan {
    /// The grid.
    pub grid: TileGrid,
    /// Non-empty tiles, in key order.
    pub tiles: Vec<TileSpec>,
    /// The x/y bounds of all points.
    pub scene: Rect,
    /// Points per tile core, for every tile that has points.
    pub per_tile: BTreeMap<TileKey, u64>,
}

/// Initial halo for a tile of `count` points: three times the radius that holds `k` points at
/// the tile's mean density, enough for a point's neighbours and their neighbours (whose normals
/// the estimator uses) on an evenly sampled surface. Verification catches the rest.
pub fn initial_halo(count: u64, size: f64, k: usize) -> f64 {
    let density = count.max(1) as f64 / (size * size);
    3.0 * (k as f64 / (std::f64::consts::PI * density)).sqrt()
}

/// The initial halo for neighbourhoods of `k` points, or with `radius` (`--radius`) of the
/// points within it, at most `k`: twice the radius is enough for the neighbours' own
/// neighbourhoods, so the halo is the smaller of that and [`initial_halo`] (a radius holding
/// more than `k` points is cut to the `k` nearest). A small margin keeps the points at the
/// tile's edge from failing verification by rounding.
pub fn initial_halo_within(count: u64, size: f64, k: usize, radius: Option<f64>) -> f64 {
    let h = initial_halo(count, size, k);
    match radius {
        Some(r) => h.min(2.05 * r),
        None => h,
    }
}

/// Plans the tiles for `stats` with tile edge `size` (file units), `k` neighbours and the
/// `radius` of `--radius`, if any ([`initial_halo_within`]).
///
/// A tile's initial halo follows the densest of it and its eight neighbours: a sliver of a few
/// points at the edge of the scene has its neighbours in the next tile, at that tile's density,
/// while its own count would ask for a halo hundreds of metres wide (loading millions of points
/// for one). Points whose neighbourhoods reach further are found by verification and retried.
pub fn plan(stats: &ScanStats, size: f64, k: usize, radius: Option<f64>) -> TilePlan {
    let grid = TileGrid { size };
    let densest_around = |(x, y): TileKey| {
        (-1..=1)
            .flat_map(|dx| (-1..=1).map(move |dy| (x + dx, y + dy)))
            .filter_map(|n| stats.per_tile.get(&n).copied())
            .max()
            .unwrap_or(1)
    };
    let tiles = stats
        .per_tile
        .iter()
        .enumerate()
        .map(|(index, (&key, &count))| TileSpec {
            index: index as u32,
            key,
            count,
            halo: initial_halo_within(densest_around(key), size, k, radius),
        })
        .collect();
    TilePlan {
        grid,
        tiles,
        per_tile: stats.per_tile.clone(),
        scene: Rect {
            min: [stats.min[0], stats.min[1]],
            max: [stats.max[0], stats.max[1]],
        },
    }
}

/// How the memory budget (`--memory`) is shared between the stages: every fraction in one
/// place, used by the scan, the tile drivers and `--dry-run` alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryPlan {
    /// The whole budget, bytes.
    pub budget_bytes: usize,
    /// Buckets the scan holds in memory before it spills the largest (2/5 of the budget).
    pub buckets_bytes: usize,
    /// What a spill frees the held buckets down to (half of `buckets_bytes`), so that the scan
    /// does not spill again after every chunk.
    pub buckets_after_spill_bytes: usize,
    /// Decoded spilled buckets kept for neighbouring tiles' halos (1/5), once buckets are on disk.
    pub bucket_cache_bytes: usize,
    /// Tiles (or quadtree parts) in flight: one per tile driver. One driver per worker thread
    /// (each then computes on a worker of its own: run/tiles/drive.rs) as long as each keeps
    /// [`MIN_TILE_SHARE`] of the budget, fewer otherwise (they then share the pool); at least 2,
    /// so that one tile's loading overlaps another's computation.
    pub tiles_in_flight: usize,
    /// Bytes for each tile in flight: 2/5 of the budget shared by `tiles_in_flight`.
    pub per_tile_bytes: usize,
    /// Bytes a loaded tile needs per point (coordinates, ids, neighbour list, normal, result),
    /// measured layout of `TilePoints` and `compute_tile`'s buffers, rounded up: 300 + 4 k;
    /// with `-k auto`, 128 more per rung past the first (a normal and a result per rung, from
    /// the layout of core::compute::auto).
    pub tile_point_bytes: usize,
    /// Most core points of one tile part: a tile with more is computed in quadtree parts
    /// (2/3 of `per_tile_bytes` over `tile_point_bytes`, room for its halo; at least 1024).
    pub max_core_points: usize,
    /// Most bytes of one read chunk of raw records (1/16 of the budget).
    pub chunk_bytes: usize,
}

impl MemoryPlan {
    /// The plan for a budget of `budget_bytes`, `k` neighbours per point, `rungs` scales per
    /// point (`-k auto`; 1 for one k) and `threads` worker threads.
    pub fn new(budget_bytes: usize, k: usize, rungs: usize, threads: usize) -> Self {
        let tiles_in_flight = (budget_bytes * 2 / 5 / MIN_TILE_SHARE).clamp(2, threads.max(2));
        let buckets_bytes = budget_bytes * 2 / 5;
        let per_tile_bytes = budget_bytes * 2 / 5 / tiles_in_flight;
        let tile_point_bytes = 300 + 4 * k + 128 * rungs.saturating_sub(1);
        MemoryPlan {
            budget_bytes,
            buckets_bytes,
            buckets_after_spill_bytes: buckets_bytes / 2,
            bucket_cache_bytes: budget_bytes / 5,
            tiles_in_flight,
            per_tile_bytes,
            tile_point_bytes,
            max_core_points: (per_tile_bytes / tile_point_bytes * 2 / 3).max(1024),
            chunk_bytes: budget_bytes / 16,
        }
    }

    /// Most core points of one part of a tile whose halo is `halo` wide (file units), at
    /// `density` core points per unit area: [`MemoryPlan::max_core_points`], lowered so that the
    /// part's core and halo ring fit the tile's share. A square part of `n` points has side
    /// `s = sqrt(n / density)` and loads `n (1 + 2 halo / s)^2` points, at most
    /// `B = per_tile_bytes / tile_point_bytes` when `sqrt(n) <= sqrt(B) - 2 halo sqrt(density)`.
    /// The wide halos of `-k auto` (its top rung's neighbours) and of large radii need it: their
    /// ring is far more than the third of the share the plain cap leaves it. At least 1024.
    pub fn core_points_per_part(&self, halo: f64, density: f64) -> usize {
        let loadable = (self.per_tile_bytes / self.tile_point_bytes) as f64;
        let root = loadable.sqrt() - 2.0 * halo.max(0.0) * density.max(0.0).sqrt();
        let fits = if root.is_finite() && root > 0.0 {
            (root * root) as usize
        } else {
            0
        };
        self.max_core_points.min(fits).max(1024)
    }

    /// Points per read chunk: the `requested` number, capped so that a chunk of raw records of
    /// at most `record_bytes` each (plus 64 bytes of decoding per point) fits `chunk_bytes`;
    /// never fewer than 1024.
    pub fn chunk_points(&self, requested: usize, record_bytes: usize) -> usize {
        requested.min((self.chunk_bytes / (record_bytes.max(1) + 64)).max(1024))
    }
}

/// The least share of the budget a tile in flight gets when there is one per thread (about
/// 50,000 points at k = 30 before a tile is split into parts): a small budget on many cores
/// keeps fewer, larger tiles in flight rather than splitting every tile.
pub const MIN_TILE_SHARE: usize = 32 << 20;

/// The smallest memory budget a run accepts (`--memory 64M`).
pub const MIN_BUDGET_BYTES: u64 = 64 << 20;

/// What fitting a memory budget into a limit decided ([`fit_budget`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetFit {
    /// The budget fits as it is.
    Fits,
    /// The budget must be lowered to this many bytes (whole MiB, at least the minimum).
    Lowered(u64),
    /// Not even the smallest budget fits: the limit must be at least this many bytes.
    TooSmall(u64),
}

/// Fits `budget` into a memory `limit` of which `besides` bytes are taken by what the run
/// needs besides its budget (the mapped inputs, the program, thread stacks).
pub fn fit_budget(budget: u64, limit: u64, besides: u64) -> BudgetFit {
    let room = limit.saturating_sub(besides);
    if budget <= room {
        BudgetFit::Fits
    } else if room >= MIN_BUDGET_BYTES {
        BudgetFit::Lowered(room >> 20 << 20)
    } else {
        BudgetFit::TooSmall(besides + MIN_BUDGET_BYTES)
    }
}

#[cfg(test)]
#[path = "plan_tests.rs"]
mod tests;
