//! Buckets: the points of each tile core, gathered in one streaming pass over the source so that
//! a cloud sorted by GPS time or flight line becomes spatially local work. This version keeps
//! the buckets in memory; the spill-to-disk version (zstd frames per tile, for clouds larger than
//! memory) replaces this module's storage behind the same `scan` / `core` / `gather` calls.

use std::collections::HashMap;

use crate::error::Result;
use crate::plan::{Rect, ScanStats, TileGrid, TileKey};
use crate::source::{PointSource, SourcePoint};

/// Points of every tile core.
pub struct Buckets {
    grid: TileGrid,
    tiles: HashMap<TileKey, Vec<SourcePoint>>,
}

impl Buckets {
    /// Streams the source once, appending every point to its core tile's bucket, and gathers the
    /// scan statistics. `progress(n)` is called with the number of points read after each chunk;
    /// returning an error from it (e.g. on cancellation) stops the scan.
    pub fn scan(
        source: &dyn PointSource,
        grid: TileGrid,
        chunk_points: usize,
        mut progress: impl FnMut(u64) -> Result<()>,
    ) -> Result<(Self, ScanStats)> {
        let rl = source.record_length();
        let mut tiles: HashMap<TileKey, Vec<SourcePoint>> = HashMap::new();
        let mut stats = ScanStats {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
            ..Default::default()
        };
        source.for_each_chunk(chunk_points, &mut |first, records| {
            for (i, rec) in records.chunks_exact(rl).enumerate() {
                let p = source.decode(first + i as u64, rec);
                for a in 0..3 {
                    stats.min[a] = stats.min[a].min(p.xyz[a]);
                    stats.max[a] = stats.max[a].max(p.xyz[a]);
                }
                tiles
                    .entry(grid.key(p.xyz[0], p.xyz[1]))
                    .or_default()
                    .push(p);
            }
            stats.count += (records.len() / rl) as u64;
            progress((records.len() / rl) as u64)
        })?;
        stats.per_tile = tiles.iter().map(|(k, v)| (*k, v.len() as u64)).collect();
        Ok((Buckets { grid, tiles }, stats))
    }

    /// The core points of a tile.
    pub fn core(&self, key: TileKey) -> &[SourcePoint] {
        self.tiles.get(&key).map(Vec::as_slice).unwrap_or(&[])
    }

    /// Calls `f` for every point in `region` that is not in the core of `exclude`, tile by tile
    /// in key order (so the halo is assembled the same way whatever the run).
    pub fn gather(&self, region: &Rect, exclude: TileKey, mut f: impl FnMut(&SourcePoint)) {
        let lo = self.grid.key(region.min[0], region.min[1]);
        let hi = self.grid.key(region.max[0], region.max[1]);
        let span = (hi.0 - lo.0 + 1).saturating_mul(hi.1 - lo.1 + 1);
        let mut visit = |key: TileKey| {
            if key != exclude {
                for p in self.core(key) {
                    if region.contains(p.xyz[0], p.xyz[1]) {
                        f(p);
                    }
                }
            }
        };
        if span > self.tiles.len() as i64 {
            // A halo wider than the scene: visit the existing tiles rather than every key.
            let mut keys: Vec<TileKey> = self
                .tiles
                .keys()
                .copied()
                .filter(|k| k.0 >= lo.0 && k.0 <= hi.0 && k.1 >= lo.1 && k.1 <= hi.1)
                .collect();
            keys.sort_unstable();
            keys.into_iter().for_each(visit);
        } else {
            for ix in lo.0..=hi.0 {
                for iy in lo.1..=hi.1 {
                    visit((ix, iy));
                }
            }
        }
    }
}
