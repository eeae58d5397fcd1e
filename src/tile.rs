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

    /// Reorders the points to follow a Z-order (Morton) curve over x/y, core and context
    /// separately, so that consecutive queries touch the same part of the k-d tree (cache
    /// locality). Results do not depend on the order: neighbours are ranked by (distance, id).
    fn morton_order(&mut self) {
        let r = self.region;
        let (w, h) = (
            (r.max[0] - r.min[0]).max(f64::MIN_POSITIVE),
            (r.max[1] - r.min[1]).max(f64::MIN_POSITIVE),
        );
        let key = |p: &V3| {
            let q = |v: f64, lo: f64, ext: f64| (((v - lo) / ext).clamp(0.0, 1.0) * 65535.0) as u32;
            interleave(q(p[0], r.min[0], w)) | (interleave(q(p[1], r.min[1], h)) << 1)
        };
        for range in [0..self.n_core, self.n_core..self.xyz.len()] {
            let mut order: Vec<(u32, usize)> =
                range.clone().map(|i| (key(&self.xyz[i]), i)).collect();
            order.sort_unstable();
            let xyz: Vec<V3> = order.iter().map(|&(_, i)| self.xyz[i]).collect();
            let ids: Vec<u64> = order.iter().map(|&(_, i)| self.ids[i]).collect();
            let nrm: Vec<Option<V3>> = order.iter().map(|&(_, i)| self.file_normals[i]).collect();
            self.xyz[range.clone()].copy_from_slice(&xyz);
            self.ids[range.clone()].copy_from_slice(&ids);
            self.file_normals[range].copy_from_slice(&nrm);
        }
    }
}

/// Spreads the 16 low bits of `v` to the even bit positions.
fn interleave(v: u32) -> u32 {
    let mut x = v & 0xffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    (x | (x << 1)) & 0x5555_5555
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
    t.morton_order();
    Ok(t)
}
