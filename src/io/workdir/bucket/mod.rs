//! Buckets: the points of each tile core, gathered by the bucket stage's streaming scan so that
//! a cloud sorted by GPS time or flight line becomes spatially local work. A scan task's
//! buckets stay in memory while they fit their share of the budget (`process`), or live in the
//! task's directory of the work directory as zstd frames (`buckets/t<task>/`). Loading a tile
//! reads its own bucket and its neighbours' (for the halo) from every task directory that holds
//! them, in task order, through a small cache, so a wider-halo retry, a halo across file borders
//! and a scan split into tasks all use the same path and nothing is written twice.

mod frames;
mod scan;
mod stats;

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::core::plan::{Rect, ScanStats, TileGrid, TileKey};
use crate::core::point::{Points, SourcePoint};
use crate::core::tile::{Part, TilePoints};
use crate::error::{Error, Result};
use crate::io::workdir::names::{bucket_file, BUCKETS_DONE as DONE};
use frames::decode_frames;
pub(crate) use scan::{scan, ScanInput};
pub(crate) use stats::parse_stats;

/// The scan's product: the buckets and what the scan learned.
pub(crate) struct Bucketed {
    /// Every tile's core points (in memory, or in the task directories).
    pub(crate) buckets: Buckets,
    /// Bounds, counts per tile, centroid, merged over the bucket tasks.
    pub(crate) stats: ScanStats,
}

/// A complete bucket task directory and the tiles it holds points of, with their counts.
struct TaskDir {
    path: PathBuf,
    tiles: BTreeMap<TileKey, u64>,
}

/// The points of every tile core.
pub(crate) struct Buckets {
    grid: TileGrid,
    mem: HashMap<TileKey, Arc<Points>>,
    dirs: Vec<TaskDir>,
    cache: Mutex<Cache>,
}

#[derive(Default)]
struct Cache {
    entries: HashMap<TileKey, (Arc<Points>, u64)>,
    bytes: usize,
    budget: usize,
    clock: u64,
}

/// The statistics of a complete bucket task directory, or None if it is not complete.
pub(crate) fn task_stats(dir: &Path) -> Option<ScanStats> {
    parse_stats(&std::fs::read_to_string(dir.join(DONE)).ok()?)
}

impl Buckets {
    fn in_memory(grid: TileGrid, mem: HashMap<TileKey, Arc<Points>>) -> Self {
        Buckets {
            grid,
            mem,
            dirs: Vec::new(),
            cache: Mutex::new(Cache::default()),
        }
    }

    fn on_disk(grid: TileGrid, dirs: Vec<TaskDir>) -> Self {
        Buckets {
            grid,
            mem: HashMap::new(),
            dirs,
            cache: Mutex::new(Cache::default()),
        }
    }

    /// The buckets of the complete task directories `dirs` (in task order) with their merged
    /// statistics, or the indices of the tasks that are not complete.
    pub(crate) fn open(
        grid: TileGrid,
        dirs: &[PathBuf],
    ) -> std::result::Result<Bucketed, Vec<usize>> {
        let mut stats = ScanStats::empty();
        let mut tasks = Vec::with_capacity(dirs.len());
        let mut missing = Vec::new();
        for (i, d) in dirs.iter().enumerate() {
            match task_stats(d) {
                Some(s) => {
                    stats.merge(&s);
                    tasks.push(TaskDir {
                        path: d.clone(),
                        tiles: s.per_tile.clone(),
                    });
                }
                None => missing.push(i),
            }
        }
        if missing.is_empty() {
            Ok(Bucketed {
                buckets: Self::on_disk(grid, tasks),
                stats,
            })
        } else {
            Err(missing)
        }
    }

    /// Whether the buckets live on disk.
    pub(crate) fn spilled(&self) -> bool {
        !self.dirs.is_empty()
    }

    /// Sets how many bytes of decoded spilled buckets may be kept for reuse by neighbouring tiles.
    pub(crate) fn set_cache_budget(&self, bytes: usize) {
        if let Ok(mut c) = self.cache.lock() {
            c.budget = bytes;
        }
    }

    /// The core points of a tile.
    pub(crate) fn core(&self, key: TileKey) -> Result<Arc<Points>> {
        if let Some(v) = self.mem.get(&key) {
            return Ok(v.clone());
        }
        if self.dirs.is_empty() {
            return Ok(Arc::new(Points::default()));
        }
        if let Ok(mut c) = self.cache.lock() {
            c.clock += 1;
            let now = c.clock;
            if let Some((v, used)) = c.entries.get_mut(&key) {
                *used = now;
                return Ok(v.clone());
            }
        }
        // The task directories in task order: the points in scan order, as one scan gives them.
        let mut all = Points::default();
        for dir in &self.dirs {
            let Some(&count) = dir.tiles.get(&key) else {
                continue;
            };
            let path = bucket_file(&dir.path, key);
            let bytes = std::fs::read(&path).map_err(|e| Error::read_work(&path, e))?;
            let points = decode_frames(&path, &bytes)?;
            // A file cut at a frame's end decodes: the task's statistics tell.
            if points.len() as u64 != count {
                return Err(Error::damaged_work(
                    &path,
                    &format!("bucket file holds {} points, not {count}", points.len()),
                ));
            }
            if all.is_empty() {
                all = points;
            } else {
                all.extend_from(&points);
            }
        }
        let points = Arc::new(all);
        if let Ok(mut c) = self.cache.lock() {
            let size = points.heap_bytes();
            while c.bytes + size > c.budget && !c.entries.is_empty() {
                let oldest = c
                    .entries
                    .iter()
                    .min_by_key(|(_, (_, used))| *used)
                    .map(|(k, _)| *k);
                if let Some(k) = oldest {
                    if let Some((v, _)) = c.entries.remove(&k) {
                        c.bytes -= v.heap_bytes();
                    }
                }
            }
            if size <= c.budget {
                let now = c.clock;
                c.entries.insert(key, (points.clone(), now));
                c.bytes += size;
            }
        }
        Ok(points)
    }

    /// Calls `f` for every point in `region` that is not in the core of `exclude`, tile by tile
    /// in key order.
    pub(crate) fn gather(
        &self,
        region: &Rect,
        exclude: TileKey,
        known: &BTreeMap<TileKey, u64>,
        mut f: impl FnMut(SourcePoint),
    ) -> Result<()> {
        let lo = self.grid.key(region.min[0], region.min[1]);
        let hi = self.grid.key(region.max[0], region.max[1]);
        // Only tiles that hold points (the plan knows them): a halo wider than the scene then
        // costs nothing extra.
        for (&key, _) in known.range(lo..=(hi.0, i64::MAX)) {
            if key.1 < lo.1 || key.1 > hi.1 || key == exclude {
                continue;
            }
            let core = self.core(key)?;
            for (i, p) in core.xyz().iter().enumerate() {
                if region.contains(p[0], p[1]) {
                    f(core.get(i));
                }
            }
        }
        Ok(())
    }
}

/// Loads `part` of tile `key` with a halo of width `halo`. With `only`, just those core points
/// (by id) are to be computed and the rest of the part is context (a wider-halo retry). `known`
/// lists the tiles that hold points (the plan's counts).
pub(crate) fn load_tile(
    buckets: &Buckets,
    key: TileKey,
    part: &Part,
    halo: f64,
    only: Option<&HashSet<u64>>,
    known: &BTreeMap<TileKey, u64>,
) -> Result<TilePoints> {
    let region = part.rect.grown(halo);
    let core = buckets.core(key)?;
    let mut t = TilePoints {
        region,
        ..Default::default()
    };
    // Room for the core and a halo of a few tenths of it: growing the arrays by doubling
    // would copy them again and again. The file normals' column is
    // filled only when a point has one (`push_normal`), so it is not reserved.
    let room = core.len() + core.len() / 4;
    t.xyz.reserve(room);
    t.ids.reserve(room);
    let selected =
        |p: &SourcePoint| part.contains(&p.xyz) && only.is_none_or(|s| s.contains(&p.id));
    for p in core.iter().filter(selected) {
        t.push(&p);
    }
    t.n_core = t.xyz.len();
    // The rest of this tile's bucket in the region is context (other parts, or on a retry the
    // points of this part already done).
    for p in core
        .iter()
        .filter(|p| !selected(p) && region.contains(p.xyz[0], p.xyz[1]))
    {
        t.push(&p);
    }
    buckets.gather(&region, key, known, |p| t.push(&p))?;
    t.morton_order();
    Ok(t)
}
