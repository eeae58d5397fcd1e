//! A loaded tile: its core points (the ones it answers for) followed by the halo points that
//! their neighbourhoods may reach; the quadtree parts of a tile too dense for the budget; the
//! Morton order of the points. Pure: `io::workdir::bucket::load_tile` fills it from the buckets.

use crate::core::geometry::V3;
use crate::core::plan::Rect;
use crate::core::point::cmp_point;

/// The points of one tile in memory: `xyz[..n_core]` are the points to compute, the rest are
/// context (other core points of the tile on a retry, and the halo).
#[derive(Debug, Clone, Default)]
pub struct TilePoints {
    /// Absolute coordinates (file units).
    pub xyz: Vec<V3>,
    /// Original point ids.
    pub ids: Vec<u64>,
    /// Normals stored in the file, per point; empty while no loaded point has one
    /// ([`crate::core::point::push_normal`]): read them with [`TilePoints::file_normal`].
    pub file_normals: Vec<Option<V3>>,
    /// Number of leading points to compute.
    pub n_core: usize,
    /// The loaded region: every point of the cloud inside it is loaded.
    pub region: Rect,
}

impl TilePoints {
    /// Appends a point (as context unless it is counted in `n_core` afterwards).
    pub fn push(&mut self, p: &crate::core::point::SourcePoint) {
        crate::core::point::push_normal(&mut self.file_normals, self.xyz.len(), p.normal);
        self.xyz.push(p.xyz);
        self.ids.push(p.id);
    }

    /// The file's normal of point `i`, if it has one.
    pub fn file_normal(&self, i: usize) -> Option<V3> {
        self.file_normals.get(i).copied().flatten()
    }

    /// Reorders the points to follow a Z-order (Morton) curve over x/y, core and context
    /// separately, so that consecutive queries touch the same part of the k-d tree (cache
    /// locality). Points with the same Morton key are ordered by position, and exact duplicates
    /// by id ([`cmp_point`]), so the order is a function of the tile's point set and region,
    /// never of the order the points were loaded in (the records' order in the file): the
    /// neighbour ranking does not depend on it, and what is ordered by local index (the
    /// propagation's components, seeds and spanning trees) then does not depend on the file
    /// order either.
    pub fn morton_order(&mut self) {
        let r = self.region;
        let (w, h) = (
            (r.max[0] - r.min[0]).max(f64::MIN_POSITIVE),
            (r.max[1] - r.min[1]).max(f64::MIN_POSITIVE),
        );
        let key = |p: &V3| {
            let q = |v: f64, lo: f64, ext: f64| (((v - lo) / ext).clamp(0.0, 1.0) * 65535.0) as u32;
            interleave(q(p[0], r.min[0], w)) | (interleave(q(p[1], r.min[1], h)) << 1)
        };
        let mut spare = Vec::new();
        for range in [0..self.n_core, self.n_core..self.xyz.len()] {
            let mut order: Vec<(u64, u32)> = range
                .clone()
                .map(|i| (key(&self.xyz[i]) as u64, i as u32))
                .collect();
            // Points sharing a key (rare: 1/65536 of the region's width apart) by position, then
            // id, whatever order they were loaded in.
            crate::core::radix::sort_by_key_then(&mut order, &mut spare, |i, j| {
                let (i, j) = (i as usize, j as usize);
                cmp_point((&self.xyz[i], self.ids[i]), (&self.xyz[j], self.ids[j]))
            });
            let xyz: Vec<V3> = order.iter().map(|&(_, i)| self.xyz[i as usize]).collect();
            let ids: Vec<u64> = order.iter().map(|&(_, i)| self.ids[i as usize]).collect();
            self.xyz[range.clone()].copy_from_slice(&xyz);
            self.ids[range.clone()].copy_from_slice(&ids);
            if !self.file_normals.is_empty() {
                let nrm: Vec<Option<V3>> = (order.iter())
                    .map(|&(_, i)| self.file_normals[i as usize])
                    .collect();
                self.file_normals[range].copy_from_slice(&nrm);
            }
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

/// A part of a tile's core: the whole tile, or a quadrant of a quadrant ... (a quadtree split
/// of a tile too dense for the memory budget). Membership is decided by comparing a point with
/// the midlines of each level, so the parts of a tile partition its points exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// The part's rectangle.
    pub rect: Rect,
    /// Per level: the midlines (x, y) split and the quadrant taken (bit 0: x >= mid x, bit 1:
    /// y >= mid y).
    pub splits: Vec<([f64; 2], u8)>,
}

impl Part {
    /// The whole tile.
    pub fn whole(rect: Rect) -> Self {
        Part {
            rect,
            splits: Vec::new(),
        }
    }

    fn quadrant(mid: [f64; 2], p: &V3) -> u8 {
        (p[0] >= mid[0]) as u8 | (((p[1] >= mid[1]) as u8) << 1)
    }

    /// Whether a point of the tile belongs to this part.
    pub fn contains(&self, p: &V3) -> bool {
        self.splits
            .iter()
            .all(|(mid, q)| Self::quadrant(*mid, p) == *q)
    }

    /// The four quadrants of this part.
    pub fn split(&self) -> [Part; 4] {
        let r = self.rect;
        let mid = [0.5 * (r.min[0] + r.max[0]), 0.5 * (r.min[1] + r.max[1])];
        [0u8, 1, 2, 3].map(|q| {
            let (x0, x1) = if q & 1 == 0 {
                (r.min[0], mid[0])
            } else {
                (mid[0], r.max[0])
            };
            let (y0, y1) = if q & 2 == 0 {
                (r.min[1], mid[1])
            } else {
                (mid[1], r.max[1])
            };
            let mut splits = self.splits.clone();
            splits.push((mid, q));
            Part {
                rect: Rect {
                    min: [x0, y0],
                    max: [x1, y1],
                },
                splits,
            }
        })
    }
}

/// Splits a tile whose points (the positions of its core, `points`) are too many into quadtree
/// parts of at most `max_points` each (never deeper than 10 levels: duplicates cannot be split).
pub fn split_parts(points: &[V3], whole: Part, max_points: usize) -> Vec<Part> {
    let mut out = Vec::new();
    let mut stack = vec![whole];
    while let Some(part) = stack.pop() {
        let n = points.iter().filter(|p| part.contains(p)).count();
        if n == 0 {
            continue;
        }
        if n <= max_points.max(1) || part.splits.len() >= 10 {
            out.push(part);
        } else {
            // Reversed so that parts come out in quadrant order.
            stack.extend(part.split().into_iter().rev());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::point::SourcePoint;

    #[test]
    fn morton_order_follows_the_points_not_their_loading_order() {
        // Points sharing Morton keys (0.1 mm apart in a 100 m region, and exact duplicates),
        // loaded in two orders, come out in one order: by key, then position, then id.
        let pts: Vec<SourcePoint> = (0..60u64)
            .map(|i| SourcePoint {
                id: 1000 - 7 * i,
                xyz: [50.0 + (i % 3) as f64 * 1e-4, 20.0, (i % 5) as f64],
                normal: None,
            })
            .collect();
        let load = |order: Vec<&SourcePoint>| {
            let mut t = TilePoints {
                region: Rect {
                    min: [0.0, 0.0],
                    max: [100.0, 100.0],
                },
                ..Default::default()
            };
            for p in order {
                t.push(p);
            }
            t.n_core = t.xyz.len();
            t.morton_order();
            t
        };
        let a = load(pts.iter().collect());
        let b = load(pts.iter().rev().collect());
        assert_eq!((&a.xyz, &a.ids), (&b.xyz, &b.ids));
        assert!((1..60)
            .all(|i| { cmp_point((&a.xyz[i - 1], a.ids[i - 1]), (&a.xyz[i], a.ids[i])).is_lt() }));
    }

    #[test]
    fn parts_partition_a_dense_tile() {
        let rect = Rect {
            min: [0.0, 0.0],
            max: [8.0, 8.0],
        };
        let mut pts = Vec::new();
        for i in 0..40u64 {
            // Dense in one corner, including points exactly on the midlines.
            let x = if i < 30 {
                (i % 6) as f64 * 0.5
            } else {
                4.0 + (i % 3) as f64
            };
            let y = if i < 30 { (i / 6) as f64 * 0.5 } else { 4.0 };
            pts.push(SourcePoint {
                id: i,
                xyz: [x, y, 0.0],
                normal: None,
            });
        }
        let xyz: Vec<V3> = pts.iter().map(|p| p.xyz).collect();
        let parts = split_parts(&xyz, Part::whole(rect), 8);
        assert!(parts.len() > 4);
        for p in &pts {
            assert_eq!(
                parts.iter().filter(|part| part.contains(&p.xyz)).count(),
                1,
                "point {:?}",
                p.xyz
            );
        }
        for part in &parts {
            let n = pts.iter().filter(|p| part.contains(&p.xyz)).count();
            assert!(n <= 8 && n > 0);
        }
    }
}
