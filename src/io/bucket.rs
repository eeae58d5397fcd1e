//! Buckets: the points of each tile core, gathered in one streaming pass over the sources so that
//! a cloud sorted by GPS time or flight line becomes spatially local work. While the buckets fit
//! their share of the memory budget they stay in memory; past it, the largest ones are appended
//! to per-tile spill files as zstd frames, and after the scan every bucket is on disk. Loading a
//! tile reads its own bucket and its neighbours' (for the halo) through a small cache, so a
//! wider-halo retry and a halo across file borders use the same path and nothing is written twice.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use crate::core::plan::{MemoryPlan, Rect, ScanStats, TileGrid, TileKey};
use crate::core::point::SourcePoint;
use crate::core::tile::{Part, TilePoints};
use crate::error::{Error, Result};
use crate::io::source::PointSource;

use crate::core::point::BUCKET_POINT_BYTES as POINT_BYTES;

/// Name of the marker written once every bucket is on disk.
const DONE: &str = "buckets.done";

/// The points of every tile core.
pub struct Buckets {
    grid: TileGrid,
    mem: HashMap<TileKey, Arc<Vec<SourcePoint>>>,
    dir: Option<PathBuf>,
    cache: Mutex<Cache>,
}

#[derive(Default)]
struct Cache {
    entries: HashMap<TileKey, (Arc<Vec<SourcePoint>>, u64)>,
    bytes: usize,
    budget: usize,
    clock: u64,
}

fn bucket_file(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(format!("b_{}_{}.zst", key.0, key.1))
}

/// Encodes points as a zstd frame: per point id, x, y, z and a normal flag (+ normal).
fn encode_frame(points: &[SourcePoint]) -> std::io::Result<Vec<u8>> {
    let mut raw = Vec::with_capacity(points.len() * 57);
    for p in points {
        raw.extend_from_slice(&p.id.to_le_bytes());
        for c in p.xyz {
            raw.extend_from_slice(&c.to_le_bytes());
        }
        match p.normal {
            Some(n) => {
                raw.push(1);
                for c in n {
                    raw.extend_from_slice(&c.to_le_bytes());
                }
            }
            None => raw.push(0),
        }
    }
    zstd::bulk::compress(&raw, 1)
}

fn decode_frames(path: &Path, bytes: &[u8]) -> Result<Vec<SourcePoint>> {
    let bad = |what: &str| {
        Error::Internal(format!(
            "{}: spill file {what}; delete the work directory and run again",
            path.display()
        ))
    };
    let raw = zstd::stream::decode_all(bytes).map_err(|_| bad("is corrupt"))?;
    let mut out = Vec::with_capacity(raw.len() / 33);
    let mut pos = 0;
    let f = |b: &[u8], at: usize| -> Option<f64> {
        Some(f64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
    };
    while pos < raw.len() {
        let id = u64::from_le_bytes(
            raw.get(pos..pos + 8)
                .and_then(|s| s.try_into().ok())
                .ok_or_else(|| bad("is truncated"))?,
        );
        let xyz = [f(&raw, pos + 8), f(&raw, pos + 16), f(&raw, pos + 24)];
        let [Some(x), Some(y), Some(z)] = xyz else {
            return Err(bad("is truncated"));
        };
        let has_normal = *raw.get(pos + 32).ok_or_else(|| bad("is truncated"))?;
        pos += 33;
        let normal = if has_normal == 1 {
            let n = [f(&raw, pos), f(&raw, pos + 8), f(&raw, pos + 16)];
            pos += 24;
            match n {
                [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                _ => return Err(bad("is truncated")),
            }
        } else {
            None
        };
        out.push(SourcePoint {
            id,
            xyz: [x, y, z],
            normal,
        });
    }
    Ok(out)
}

/// Appends one frame per bucket of `buckets` to its bucket file. The frames are compressed in
/// parallel (on the caller's rayon pool), then appended in the given order.
fn spill(dir: &Path, buckets: Vec<(TileKey, Vec<SourcePoint>)>) -> Result<()> {
    let frames: Vec<(TileKey, std::io::Result<Vec<u8>>)> = buckets
        .into_par_iter()
        .map(|(key, points)| (key, encode_frame(&points)))
        .collect();
    for (key, frame) in frames {
        let path = bucket_file(dir, key);
        let frame = frame.map_err(|e| Error::write(&path, e))?;
        let mut f = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(|e| Error::write(&path, e))?;
        f.write_all(&frame).map_err(|e| Error::write(&path, e))?;
    }
    Ok(())
}

/// One source of a scan and the id of its first point in the scene.
pub struct ScanInput<'a> {
    /// The source.
    pub source: &'a dyn PointSource,
    /// Global id of its point 0 (the sum of the earlier inputs' counts).
    pub first_id: u64,
}

impl Buckets {
    /// Streams the sources once, appending every point to its core tile's bucket, and gathers the
    /// scan statistics. Buckets beyond `memory.buckets_bytes` are spilled to `spill_dir` (down to
    /// `memory.buckets_after_spill_bytes`; the directory is created on
    /// first use). `progress(n)` is called after each chunk with the points read; an error from
    /// it (cancellation) stops the scan.
    pub fn scan(
        inputs: &[ScanInput<'_>],
        grid: TileGrid,
        chunk_points: usize,
        memory: &MemoryPlan,
        spill_dir: &Path,
        mut progress: impl FnMut(u64) -> Result<()>,
    ) -> Result<(Self, ScanStats)> {
        let mut mem: HashMap<TileKey, Vec<SourcePoint>> = HashMap::new();
        let mut held = 0usize;
        let mut spilled = false;
        let mut stats = ScanStats {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
            ..Default::default()
        };
        let mut centroid = crate::core::orient::Centroid::default();
        for input in inputs {
            let rl = input.source.record_length();
            input
                .source
                .for_each_chunk(chunk_points, &mut |first, records| {
                    let n = records.len() / rl;
                    for (i, rec) in records.chunks_exact(rl).enumerate() {
                        let mut p = input.source.decode(first + i as u64, rec);
                        p.id += input.first_id;
                        for a in 0..3 {
                            stats.min[a] = stats.min[a].min(p.xyz[a]);
                            stats.max[a] = stats.max[a].max(p.xyz[a]);
                        }
                        centroid.add(p.xyz);
                        let key = grid.key(p.xyz[0], p.xyz[1]);
                        *stats.per_tile.entry(key).or_default() += 1;
                        mem.entry(key).or_default().push(p);
                    }
                    held += n * POINT_BYTES;
                    stats.count += n as u64;
                    if held > memory.buckets_bytes {
                        // Spill the largest buckets until half the budget is free again.
                        std::fs::create_dir_all(spill_dir)
                            .map_err(|e| Error::write(spill_dir, e))?;
                        spilled = true;
                        let mut sizes: Vec<(usize, TileKey)> =
                            mem.iter().map(|(k, v)| (v.len(), *k)).collect();
                        sizes.sort_unstable_by(|a, b| b.cmp(a));
                        let mut out = Vec::new();
                        for (len, key) in sizes {
                            if held <= memory.buckets_after_spill_bytes {
                                break;
                            }
                            if let Some(v) = mem.remove(&key) {
                                out.push((key, v));
                                held -= len * POINT_BYTES;
                            }
                        }
                        spill(spill_dir, out)?;
                    }
                    progress(n as u64)
                })?;
        }
        stats.centroid = centroid.get().unwrap_or_default();
        if spilled {
            // Everything goes to disk, so that the buckets can be reused by a resumed run.
            spill(spill_dir, mem.drain().collect())?;
            let files: Vec<PathBuf> = stats
                .per_tile
                .keys()
                .map(|key| bucket_file(spill_dir, *key))
                .collect();
            crate::io::workdir::sync_files(spill_dir, files.iter().map(PathBuf::as_path))?;
            crate::io::workdir::write_durably(
                &spill_dir.join(DONE),
                stats_text(&stats).as_bytes(),
            )?;
        }
        let mem = mem.into_iter().map(|(k, v)| (k, Arc::new(v))).collect();
        let dir = spilled.then(|| spill_dir.to_path_buf());
        Ok((
            Buckets {
                grid,
                mem,
                dir,
                cache: Mutex::new(Cache::default()),
            },
            stats,
        ))
    }

    /// The buckets a previous run left complete on disk in `spill_dir`, with their statistics,
    /// or None if there are none.
    pub fn reopen(spill_dir: &Path, grid: TileGrid) -> Option<(Self, ScanStats)> {
        let text = std::fs::read_to_string(spill_dir.join(DONE)).ok()?;
        let stats = parse_stats(&text)?;
        Some((
            Buckets {
                grid,
                mem: HashMap::new(),
                dir: Some(spill_dir.to_path_buf()),
                cache: Mutex::new(Cache::default()),
            },
            stats,
        ))
    }

    /// Whether the buckets live on disk.
    pub fn spilled(&self) -> bool {
        self.dir.is_some()
    }

    /// Sets how many bytes of decoded spilled buckets may be kept for reuse by neighbouring tiles.
    pub fn set_cache_budget(&self, bytes: usize) {
        if let Ok(mut c) = self.cache.lock() {
            c.budget = bytes;
        }
    }

    /// The core points of a tile.
    pub fn core(&self, key: TileKey) -> Result<Arc<Vec<SourcePoint>>> {
        if let Some(v) = self.mem.get(&key) {
            return Ok(v.clone());
        }
        let Some(dir) = &self.dir else {
            return Ok(Arc::new(Vec::new()));
        };
        if let Ok(mut c) = self.cache.lock() {
            c.clock += 1;
            let now = c.clock;
            if let Some((v, used)) = c.entries.get_mut(&key) {
                *used = now;
                return Ok(v.clone());
            }
        }
        let path = bucket_file(dir, key);
        let points = match std::fs::read(&path) {
            Ok(bytes) => Arc::new(decode_frames(&path, &bytes)?),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Arc::new(Vec::new()),
            Err(e) => return Err(Error::ReadIo { path, source: e }),
        };
        if let Ok(mut c) = self.cache.lock() {
            let size = points.len() * POINT_BYTES;
            while c.bytes + size > c.budget && !c.entries.is_empty() {
                let oldest = c
                    .entries
                    .iter()
                    .min_by_key(|(_, (_, used))| *used)
                    .map(|(k, _)| *k);
                if let Some(k) = oldest {
                    if let Some((v, _)) = c.entries.remove(&k) {
                        c.bytes -= v.len() * POINT_BYTES;
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
    pub fn gather(
        &self,
        region: &Rect,
        exclude: TileKey,
        known: &BTreeMap<TileKey, u64>,
        mut f: impl FnMut(&SourcePoint),
    ) -> Result<()> {
        let lo = self.grid.key(region.min[0], region.min[1]);
        let hi = self.grid.key(region.max[0], region.max[1]);
        // Only tiles that hold points (the plan knows them): a halo wider than the scene then
        // costs nothing extra.
        for (&key, _) in known.range(lo..=(hi.0, i64::MAX)) {
            if key.1 < lo.1 || key.1 > hi.1 || key == exclude {
                continue;
            }
            for p in self.core(key)?.iter() {
                if region.contains(p.xyz[0], p.xyz[1]) {
                    f(p);
                }
            }
        }
        Ok(())
    }
}

/// Loads `part` of tile `key` with a halo of width `halo`. With `only`, just those core points
/// (by id) are to be computed and the rest of the part is context (a wider-halo retry). `known`
/// lists the tiles that hold points (the plan's counts).
pub fn load_tile(
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
    let selected =
        |p: &&SourcePoint| part.contains(&p.xyz) && only.is_none_or(|s| s.contains(&p.id));
    for p in core.iter().filter(selected) {
        t.push(p);
    }
    t.n_core = t.xyz.len();
    // The rest of this tile's bucket in the region is context (other parts, or on a retry the
    // points of this part already done).
    for p in core
        .iter()
        .filter(|p| !selected(p) && region.contains(p.xyz[0], p.xyz[1]))
    {
        t.push(p);
    }
    buckets.gather(&region, key, known, |p| t.push(p))?;
    t.morton_order();
    Ok(t)
}

fn stats_text(s: &ScanStats) -> String {
    let mut t = format!(
        "count {}\ncentroid {} {} {}\nmin {} {} {}\nmax {} {} {}\n",
        s.count,
        s.centroid[0].to_bits(),
        s.centroid[1].to_bits(),
        s.centroid[2].to_bits(),
        s.min[0].to_bits(),
        s.min[1].to_bits(),
        s.min[2].to_bits(),
        s.max[0].to_bits(),
        s.max[1].to_bits(),
        s.max[2].to_bits()
    );
    for (k, n) in &s.per_tile {
        t.push_str(&format!("tile {} {} {n}\n", k.0, k.1));
    }
    t
}

fn parse_stats(text: &str) -> Option<ScanStats> {
    let mut s = ScanStats::default();
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["count", n] => s.count = n.parse().ok()?,
            ["centroid", a, b, c] => {
                s.centroid = [
                    f64::from_bits(a.parse().ok()?),
                    f64::from_bits(b.parse().ok()?),
                    f64::from_bits(c.parse().ok()?),
                ];
            }
            ["min", a, b, c] => {
                s.min = [
                    f64::from_bits(a.parse().ok()?),
                    f64::from_bits(b.parse().ok()?),
                    f64::from_bits(c.parse().ok()?),
                ]
            }
            ["max", a, b, c] => {
                s.max = [
                    f64::from_bits(a.parse().ok()?),
                    f64::from_bits(b.parse().ok()?),
                    f64::from_bits(c.parse().ok()?),
                ]
            }
            ["tile", x, y, n] => {
                s.per_tile
                    .insert((x.parse().ok()?, y.parse().ok()?), n.parse().ok()?);
            }
            _ => return None,
        }
    }
    (s.count > 0).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_and_stats_text_round_trips() {
        let pts = vec![
            SourcePoint {
                id: 7,
                xyz: [1.5, -2.25, 1e6 + 0.125],
                normal: None,
            },
            SourcePoint {
                id: u64::MAX,
                xyz: [0.1, 0.2, 0.3],
                normal: Some([0.0, 0.6, 0.8]),
            },
        ];
        let mut bytes = encode_frame(&pts).expect("encode");
        bytes.extend(encode_frame(&pts[..1]).expect("encode"));
        let back = decode_frames(Path::new("x"), &bytes).expect("decode");
        assert_eq!(back, [pts[0], pts[1], pts[0]]);
        let mut s = ScanStats {
            count: 3,
            min: [0.1, -0.3, 5.0],
            max: [9.0, 8.0, 7.0],
            centroid: [1.0, 2.5, -3.0],
            ..Default::default()
        };
        s.per_tile.insert((-3, 4), 2);
        s.per_tile.insert((0, 0), 1);
        let t = parse_stats(&stats_text(&s)).expect("parse");
        assert_eq!(
            (t.count, t.min, t.max, t.centroid, t.per_tile),
            (s.count, s.min, s.max, s.centroid, s.per_tile)
        );
    }
}
