//! Per-tile result files: each finished tile writes its core points' encoded columns, sorted by
//! original point id, to `tile_<x>_<y>.res` in the work directory (temporary name, fsync,
//! rename, directory fsync). A tile is done if and only if its result file exists and holds the
//! plan's number of points: this is the resume journal. [`Merger`] reads them back in id order
//! with a bounded fan-in. Header: magic, point count, record size, then the tile's
//! [`CurvatureStats`] (the magnitudes the outputs' scaled columns take their steps from,
//! core::quantize), so that assemble learns them without reading every record twice. Record:
//! id (u64 LE), the point's global patch (u64), the column values ([`ColumnSet::encode_result`]).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::core::compute::PointResult;
use crate::core::orient::GlobalPatch;
use crate::core::plan::TileKey;
use crate::core::quantize::{CurvatureStats, Magnitudes};
use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::workdir::tmp_name;

const MAGIC: &[u8; 8] = b"TCRES004";
const ORIENT_MAGIC: &[u8; 8] = b"TCORI002";

/// Bytes of one record after the id: the point's global patch (u64, `--orient propagate`) and
/// the encoded columns.
pub fn record_size(cols: &ColumnSet) -> usize {
    8 + cols.result_size()
}

/// Bytes of a result file's header before its statistics: magic, count, record size, and the
/// statistics' length.
const HEAD: usize = 32;

/// Largest statistics block a result file may declare (three full histograms are 61 KiB).
const MAX_STATS: u64 = 1 << 20;

/// The statistics block: for H, K and the principal curvatures, the largest magnitude (f64),
/// the number of non-empty bins (u16) and each as its biased exponent (u16) and count (u64).
fn stats_bytes(s: &CurvatureStats) -> Vec<u8> {
    let mut b = Vec::new();
    for m in [&s.h, &s.k, &s.principal] {
        b.extend_from_slice(&m.max().to_le_bytes());
        let bins: Vec<(u16, u64)> = m.bins().collect();
        b.extend_from_slice(&(bins.len() as u16).to_le_bytes());
        for (bin, count) in bins {
            b.extend_from_slice(&bin.to_le_bytes());
            b.extend_from_slice(&count.to_le_bytes());
        }
    }
    b
}

/// Parses [`stats_bytes`]; None when damaged.
fn parse_stats(b: &[u8]) -> Option<CurvatureStats> {
    let mut at = 0usize;
    let mut take = |n: usize| {
        let s = b.get(at..at + n);
        at += n;
        s
    };
    let mut one = || -> Option<Magnitudes> {
        let max = f64::from_le_bytes(take(8)?.try_into().ok()?);
        let n = u16::from_le_bytes(take(2)?.try_into().ok()?);
        let mut bins = Vec::with_capacity(n as usize);
        for _ in 0..n {
            let bin = u16::from_le_bytes(take(2)?.try_into().ok()?);
            bins.push((bin, u64::from_le_bytes(take(8)?.try_into().ok()?)));
        }
        Magnitudes::from_bins(bins, max)
    };
    let stats = CurvatureStats {
        h: one()?,
        k: one()?,
        principal: one()?,
    };
    (at == b.len()).then_some(stats)
}

/// The orientation sidecar of a tile (`--orient propagate`): its patch anchors and the normals
/// it shares with other tiles, for the cross-tile sign resolution.
pub fn orientation_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(format!("tile_{}_{}.ori", key.0, key.1))
}

/// What a tile's passes contribute to the cross-tile orientation.
#[derive(Debug, Clone, Default)]
pub struct TileSidecar {
    /// One anchor per patch (patches numbered within the tile).
    pub anchors: Vec<crate::core::orient::PatchAnchor>,
    /// Normals of points other passes also orient.
    pub shared: Vec<crate::core::orient::SharedNormal>,
}

/// Bytes of one anchor in a sidecar: patch (u32), dist2 (f64), position (3 f64), id (u64),
/// outward (u8), little-endian.
const ANCHOR_BYTES: usize = 4 + 8 + 24 + 8 + 1;

fn write_sidecar(path: &Path, s: &TileSidecar) -> Result<PathBuf> {
    let tmp = tmp_name(path);
    let mut b = Vec::with_capacity(24 + ANCHOR_BYTES * s.anchors.len() + 36 * s.shared.len());
    b.extend_from_slice(ORIENT_MAGIC);
    b.extend_from_slice(&(s.anchors.len() as u64).to_le_bytes());
    b.extend_from_slice(&(s.shared.len() as u64).to_le_bytes());
    for a in &s.anchors {
        b.extend_from_slice(&a.patch.to_le_bytes());
        b.extend_from_slice(&a.dist2.to_le_bytes());
        for c in a.pos {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&a.id.to_le_bytes());
        b.push(a.outward as u8);
    }
    for n in &s.shared {
        b.extend_from_slice(&n.id.to_le_bytes());
        b.extend_from_slice(&n.patch.to_le_bytes());
        for c in n.normal {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    std::fs::write(&tmp, &b).map_err(|e| Error::write(&tmp, e))?;
    Ok(tmp)
}

/// Reads a tile's orientation sidecar.
pub fn read_sidecar(path: &Path) -> Result<TileSidecar> {
    let bad = || {
        Error::Internal(format!(
            "{}: orientation sidecar is damaged; delete the work directory and run again",
            path.display()
        ))
    };
    let b = std::fs::read(path).map_err(|e| Error::read_work(path, e))?;
    let u64_at = |o: usize| {
        b.get(o..o + 8)
            .and_then(|s| s.try_into().ok())
            .map(u64::from_le_bytes)
            .ok_or_else(bad)
    };
    let u32_at = |o: usize| {
        b.get(o..o + 4)
            .and_then(|s| s.try_into().ok())
            .map(u32::from_le_bytes)
            .ok_or_else(bad)
    };
    let f64_at = |o: usize| u64_at(o).map(f64::from_bits);
    if b.get(..8) != Some(&ORIENT_MAGIC[..]) {
        return Err(bad());
    }
    let (na, ns) = (u64_at(8)? as usize, u64_at(16)? as usize);
    let mut out = TileSidecar::default();
    let mut o = 24;
    for _ in 0..na {
        let outward = *b.get(o + 44).ok_or_else(bad)? == 1;
        out.anchors.push(crate::core::orient::PatchAnchor {
            patch: u32_at(o)?,
            dist2: f64_at(o + 4)?,
            pos: [f64_at(o + 12)?, f64_at(o + 20)?, f64_at(o + 28)?],
            id: u64_at(o + 36)?,
            outward,
        });
        o += ANCHOR_BYTES;
    }
    for _ in 0..ns {
        out.shared.push(crate::core::orient::SharedNormal {
            id: u64_at(o)?,
            patch: u32_at(o + 8)?,
            normal: [f64_at(o + 12)?, f64_at(o + 20)?, f64_at(o + 28)?],
        });
        o += 36;
    }
    Ok(out)
}
/// Most result files merged at once (one read buffer each: 64 MiB in all); more are first
/// partly merged into runs. Lowered to what the open-file limit allows (see [`fan_in`]).
pub const MAX_FAN_IN: usize = 1024;
const READ_BUFFER: usize = 64 << 10;

/// How many result files one merge may open: [`MAX_FAN_IN`], or less when the process's
/// open-file limit is low (the CLI raised its soft limit to the hard one at start): what the
/// limit leaves beside the descriptors open now, less a reserve (64, or a quarter of a small
/// limit) for the output, a run file and everything else; at least 2. A limit too low even
/// for that makes the open fail with EMFILE, an error that says to raise `ulimit -n`.
pub fn fan_in() -> usize {
    let Some(soft) = crate::io::limits::open_files_limit() else {
        return 64;
    };
    let in_use = crate::io::limits::open_descriptors().unwrap_or(16);
    let reserve = (soft / 4).min(64);
    (soft.saturating_sub(in_use).saturating_sub(reserve)).clamp(2, MAX_FAN_IN as u64) as usize
}

/// The result file of a tile.
pub fn tile_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(format!("tile_{}_{}.res", key.0, key.1))
}

/// Writes a result file under its temporary name and returns that name; the caller renames it.
fn write_file(
    path: &Path,
    count: u64,
    cols: &ColumnSet,
    stats: &CurvatureStats,
    mut body: impl FnMut(&mut BufWriter<File>) -> Result<()>,
) -> Result<PathBuf> {
    let tmp = tmp_name(path);
    let file = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let stats = stats_bytes(stats);
    let head = [
        &MAGIC[..],
        &count.to_le_bytes(),
        &(record_size(cols) as u64).to_le_bytes(),
        &(stats.len() as u64).to_le_bytes(),
        &stats,
    ]
    .concat();
    w.write_all(&head).map_err(|e| Error::write(&tmp, e))?;
    body(&mut w)?;
    w.flush().map_err(|e| Error::write(&tmp, e))?;
    Ok(tmp)
}

/// Writes one tile's results (sorted here by id) under a temporary name; returns it.
fn write_tile_tmp(
    dir: &Path,
    key: TileKey,
    tile_index: u32,
    results: &mut [PointResult],
    cols: &ColumnSet,
) -> Result<PathBuf> {
    results.sort_unstable_by_key(|r| r.id);
    let path = tile_path(dir, key);
    let mut buf = Vec::with_capacity(8 + record_size(cols));
    let mut stats = CurvatureStats::default();
    results.iter().for_each(|r| stats.add(&r.curvature));
    write_file(&path, results.len() as u64, cols, &stats, |w| {
        for r in results.iter() {
            buf.clear();
            buf.extend_from_slice(&r.id.to_le_bytes());
            buf.extend_from_slice(&GlobalPatch::new(tile_index, r.patch).0.to_le_bytes());
            cols.encode_result(r, &mut buf);
            w.write_all(&buf).map_err(|e| Error::write(&path, e))?;
        }
        Ok(())
    })
}

/// The resume journal: finished tiles' result files, made durable in batches. A batch is
/// written under temporary names, flushed to disk with one `syncfs` (one journal commit instead
/// of one per file: thousands of small tiles would otherwise spend seconds in fsync), then
/// renamed to their final names. Only a renamed file counts as a finished tile.
pub struct Journal {
    dir: PathBuf,
    pending: Vec<(PathBuf, PathBuf)>,
    since: std::time::Instant,
}

impl Journal {
    /// A journal writing into `dir`.
    pub fn new(dir: &Path) -> Self {
        Journal {
            dir: dir.to_path_buf(),
            pending: Vec::new(),
            since: std::time::Instant::now(),
        }
    }

    /// Adds a finished tile; commits the batch when it is large or old enough.
    pub fn add(
        &mut self,
        key: TileKey,
        tile_index: u32,
        results: &mut [PointResult],
        sidecar: Option<&TileSidecar>,
        cols: &ColumnSet,
    ) -> Result<()> {
        // The sidecar is renamed before the result file: a tile is done only once both are.
        if let Some(sc) = sidecar {
            let path = orientation_path(&self.dir, key);
            let tmp = write_sidecar(&path, sc)?;
            self.pending.push((tmp, path));
        }
        let tmp = write_tile_tmp(&self.dir, key, tile_index, results, cols)?;
        self.pending.push((tmp, tile_path(&self.dir, key)));
        if self.pending.len() >= 256 || self.since.elapsed().as_secs_f64() > 2.0 {
            self.commit()?;
        }
        Ok(())
    }

    /// Makes every pending tile durable and visible.
    pub fn commit(&mut self) -> Result<()> {
        if self.pending.is_empty() {
            return Ok(());
        }
        crate::io::workdir::sync_files(
            &self.dir,
            self.pending.iter().map(|(tmp, _)| tmp.as_path()),
        )?;
        for (tmp, path) in self.pending.drain(..) {
            std::fs::rename(&tmp, &path).map_err(|e| Error::write(&path, e))?;
        }
        crate::io::workdir::sync_dir(&self.dir);
        self.since = std::time::Instant::now();
        Ok(())
    }
}

/// Whether the result file of a tile is complete: it exists, its header matches the column
/// set, its count is `expected`, and its length is exactly that many records.
pub fn is_complete(path: &Path, expected: u64, cols: &ColumnSet) -> bool {
    let Ok(meta) = std::fs::metadata(path) else {
        return false;
    };
    let Ok(r) = TileResults::open(path, cols) else {
        return false;
    };
    r.remaining == expected
        && meta.len() == r.header_len + expected * (8 + record_size(cols) as u64)
}

/// The curvature statistics of all the tiles whose result files are `files`: the sum of
/// theirs, so the same whatever the tiling.
pub fn scene_stats(files: &[PathBuf], cols: &ColumnSet) -> Result<CurvatureStats> {
    let mut all = CurvatureStats::default();
    for f in files {
        all.merge(&TileResults::open(f, cols)?.stats);
    }
    Ok(all)
}

/// Reads one result file in id order.
pub struct TileResults {
    path: PathBuf,
    reader: BufReader<File>,
    remaining: u64,
    record: usize,
    /// Bytes before the first record.
    header_len: u64,
    /// The statistics of the file's points.
    stats: CurvatureStats,
}

impl TileResults {
    /// Opens a result file written with the same column set.
    pub fn open(path: &Path, cols: &ColumnSet) -> Result<Self> {
        let bad = |what: String| {
            Error::Internal(format!(
                "{}: {what}; delete the work directory and run again",
                path.display()
            ))
        };
        let file = File::open(path).map_err(|e| Error::read_work(path, e))?;
        let mut reader = BufReader::with_capacity(READ_BUFFER, file);
        let mut head = [0u8; HEAD];
        reader
            .read_exact(&mut head)
            .map_err(|e| bad(format!("result header unreadable: {e}")))?;
        let word = |i: usize| u64::from_le_bytes(head[i..i + 8].try_into().unwrap_or([0; 8]));
        if &head[..8] != MAGIC {
            return Err(bad("not a tilecurv result file".into()));
        }
        let record = word(16) as usize;
        if record != record_size(cols) {
            return Err(bad(format!(
                "records of {record} bytes, expected {}",
                record_size(cols)
            )));
        }
        let stats_len = word(24);
        if stats_len > MAX_STATS {
            return Err(bad(format!("statistics of {stats_len} bytes")));
        }
        let mut stats = vec![0u8; stats_len as usize];
        reader
            .read_exact(&mut stats)
            .map_err(|e| bad(format!("result statistics unreadable: {e}")))?;
        let stats = parse_stats(&stats).ok_or_else(|| bad("result statistics damaged".into()))?;
        Ok(TileResults {
            path: path.to_path_buf(),
            reader,
            remaining: word(8),
            record,
            header_len: HEAD as u64 + stats_len,
            stats,
        })
    }

    /// Reads the next record's id and column bytes into `cols`; None at the end.
    pub fn next(&mut self, cols: &mut Vec<u8>) -> Result<Option<u64>> {
        if self.remaining == 0 {
            return Ok(None);
        }
        let mut id = [0u8; 8];
        cols.resize(self.record, 0);
        self.reader
            .read_exact(&mut id)
            .and_then(|_| self.reader.read_exact(cols))
            .map_err(|e| {
                Error::Internal(format!(
                    "{}: result file ends early: {e}",
                    self.path.display()
                ))
            })?;
        self.remaining -= 1;
        Ok(Some(u64::from_le_bytes(id)))
    }
}

/// A k-way merge of result files by point id.
pub struct Merger {
    readers: Vec<TileResults>,
    heads: Vec<Vec<u8>>,
    heap: BinaryHeap<Reverse<(u64, usize)>>,
}

impl Merger {
    /// Opens a merge over `files`, at most [`fan_in`] open at once.
    pub fn open(dir: &Path, files: &[PathBuf], cols: &ColumnSet) -> Result<Self> {
        Self::open_with_fan_in(dir, files, cols, fan_in())
    }

    /// Opens a merge over `files` with at most `fan_in` (>= 2) files open at once: while there
    /// are more, the first ones are merged into a run file in `dir` (at most `fan_in` of them,
    /// and only as many as needed to bring the count down to `fan_in`, so that the least data
    /// is written twice), and the run takes their place at the end.
    pub fn open_with_fan_in(
        dir: &Path,
        files: &[PathBuf],
        cols: &ColumnSet,
        fan_in: usize,
    ) -> Result<Self> {
        let fan_in = fan_in.max(2);
        let mut files: std::collections::VecDeque<PathBuf> = files.iter().cloned().collect();
        let mut runs = std::collections::HashSet::new();
        while files.len() > fan_in {
            let take = (files.len() - fan_in + 1).min(fan_in);
            let group: Vec<PathBuf> = files.drain(..take).collect();
            let run = dir.join(format!("run_{}.res", runs.len()));
            let mut m = Merger::open_direct(&group, cols)?;
            let count = group
                .iter()
                .map(|f| TileResults::open(f, cols).map(|r| r.remaining))
                .sum::<Result<u64>>()?;
            let mut rec = Vec::new();
            // Runs only serve this assemble pass: no need to make them durable, nor to hold
            // statistics (scene_stats reads the tile files).
            let tmp = write_file(&run, count, cols, &CurvatureStats::default(), |w| {
                while let Some(id) = m.next(&mut rec)? {
                    w.write_all(&id.to_le_bytes())
                        .and_then(|_| w.write_all(&rec))
                        .map_err(|e| Error::write(&run, e))?;
                }
                Ok(())
            })?;
            std::fs::rename(&tmp, &run).map_err(|e| Error::write(&run, e))?;
            // Tile files are the journal and stay until the output exists; merged runs go.
            for f in group.iter().filter(|f| runs.contains(*f)) {
                let _ = std::fs::remove_file(f);
            }
            runs.insert(run.clone());
            files.push_back(run);
        }
        Merger::open_direct(files.make_contiguous(), cols)
    }

    fn open_direct(files: &[PathBuf], cols: &ColumnSet) -> Result<Self> {
        let mut readers = files
            .iter()
            .map(|p| TileResults::open(p, cols))
            .collect::<Result<Vec<_>>>()?;
        let mut heads = vec![Vec::new(); readers.len()];
        let mut heap = BinaryHeap::new();
        for (i, r) in readers.iter_mut().enumerate() {
            if let Some(id) = r.next(&mut heads[i])? {
                heap.push(Reverse((id, i)));
            }
        }
        Ok(Merger {
            readers,
            heads,
            heap,
        })
    }

    /// The next record in id order: its id, with its column bytes copied to `out`.
    pub fn next(&mut self, out: &mut Vec<u8>) -> Result<Option<u64>> {
        // The top is replaced in place: one sift, which stops at once while the same file
        // holds the smallest ids (runs of consecutive points in one tile are the common case).
        let Some(mut top) = self.heap.peek_mut() else {
            return Ok(None);
        };
        let Reverse((id, i)) = *top;
        out.clear();
        out.extend_from_slice(&self.heads[i]);
        match self.readers[i].next(&mut self.heads[i])? {
            Some(next) => *top = Reverse((next, i)),
            None => {
                std::collections::binary_heap::PeekMut::pop(top);
            }
        }
        Ok(Some(id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimate::Curvature;
    use crate::io::columns::ColumnChoice;

    #[test]
    fn merge_with_runs_returns_every_id_once_in_order() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cols = ColumnSet {
            choice: ColumnChoice::default(),
            extra: Vec::new(),
            unit: "m".into(),
            wide: true,
        };
        // 150 tiles, ids interleaved across tiles, merged 8 at a time (so runs are made, and
        // runs of runs).
        let mut files = Vec::new();
        let mut journal = Journal::new(dir.path());
        for t in 0..150u64 {
            let mut rs: Vec<PointResult> = (0..7u64)
                .map(|j| PointResult {
                    id: j * 150 + t,
                    normal: [0.0, 0.0, 1.0],
                    curvature: Curvature {
                        h: (j * 150 + t) as f64,
                        ..Curvature::undefined(0)
                    },
                    extra: [f64::NAN; crate::core::estimate::MAX_EXTRA],
                    patch: crate::core::compute::NO_PATCH,
                    scale: 0,
                    scale_flags: 0,
                })
                .collect();
            journal
                .add((t as i64, 0), t as u32, &mut rs, None, &cols)
                .expect("write");
            files.push(tile_path(dir.path(), (t as i64, 0)));
        }
        journal.commit().expect("commit");
        assert!(files
            .iter()
            .all(|p| is_complete(p, 7, &cols) && !is_complete(p, 8, &cols)));
        let mut m = Merger::open_with_fan_in(dir.path(), &files, &cols, 8).expect("merge");
        let mut rec = Vec::new();
        let mut expect = 0;
        while let Some(id) = m.next(&mut rec).expect("next") {
            assert_eq!(id, expect);
            // After the patch (u64, none here), H is the 4th f64, after the normal.
            assert_eq!(
                u64::from_le_bytes(rec[..8].try_into().expect("8 bytes")),
                u64::MAX
            );
            assert_eq!(
                f64::from_le_bytes(rec[32..40].try_into().expect("8 bytes")),
                id as f64
            );
            expect += 1;
        }
        assert_eq!(expect, 150 * 7);
        // The tiles' statistics add up to those of all the points: H = 0..1050, the rest NaN.
        let stats = scene_stats(&files, &cols).expect("stats");
        let mut h = Magnitudes::default();
        (0..1050).for_each(|v| h.add(v as f64));
        assert_eq!(stats.h, h);
        assert_eq!(stats.principal.count(), 0);
        // Every tile file is kept (the journal); only the last runs remain besides.
        assert!(files.iter().all(|f| f.exists()));
        let runs = std::fs::read_dir(dir.path())
            .expect("list")
            .filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().starts_with("run_"))
            })
            .count();
        assert!((1..=8).contains(&runs), "{runs} run files left");
    }
}
