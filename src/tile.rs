//! A loaded tile: its core points (the ones it answers for) followed by the halo points that
//! their neighbourhoods may reach, gathered from the buckets.

use std::collections::{BTreeMap, HashSet};

use crate::bucket::Buckets;
use crate::error::Result;
use crate::geometry::V3;
use crate::plan::{Rect, TileGrid, TileKey};

/// The points of one tile in memory: `xyz[..n_core]` are the points to compute, the rest are
/// context (other core points of the tile on a retry, and the halo).
#[derive(Debug, Clone, Default)]
pub struct TilePoints {
    /// Absolute coordinates (file units).
    pub xyz: Vec<V3>,
    /// Original point ids.
    pub ids: Vec<u64>,
    /// Normals stored in the file, per point (None when the file has none).
    pub file_normals: Vec<Option<V3>>,
    /// Number of leading points to compute.
    pub n_core: usize,
    /// The loaded region: every point of the cloud inside it is loaded.
    pub region: Rect,
}

impl TilePoints {
    fn push(&mut self, p: &crate::source::SourcePoint) {
        self.xyz.push(p.xyz);
        self.ids.push(p.id);
        self.file_normals.push(p.normal);
    }
}

/// Loads tile `key` with a halo of width `halo`. With `only`, just those core points (by id)
/// are to be computed and the rest of the core is context (a wider-halo retry). `known` lists
/// the tiles that hold points (the plan's counts).
pub fn load_tile(
    buckets: &Buckets,
    grid: &TileGrid,
    key: TileKey,
    halo: f64,
    only: Option<&HashSet<u64>>,
    known: &BTreeMap<TileKey, u64>,
) -> Result<TilePoints> {
    let region = grid.rect(key).grown(halo);
    let core = buckets.core(key)?;
    let mut t = TilePoints {
        region,
        ..Default::default()
    };
    let selected = |p: &&crate::source::SourcePoint| only.is_none_or(|s| s.contains(&p.id));
    for p in core.iter().filter(selected) {
        t.push(p);
    }
    t.n_core = t.xyz.len();
    if only.is_some() {
        for p in core.iter().filter(|p| !selected(p)) {
            t.push(p);
        }
    }
    buckets.gather(&region, key, known, |p| t.push(p))?;
    Ok(t)
}
