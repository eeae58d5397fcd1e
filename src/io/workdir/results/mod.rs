//! Per-tile result files: each finished tile writes its core points' encoded columns, sorted by
//! original point id, to `tile_<x>_<y>.res` in the work directory (temporary name, fsync,
//! rename, directory fsync). A tile is done if and only if its result file exists and is whole
//! (every block decodes and the count is the plan's, [`is_complete`]): this is the resume
//! journal. [`Merger`] reads them back in id order with a bounded fan-in. The format
//! ([`mod@file`]): a header with the tile's [`CurvatureStats`] (the magnitudes the outputs' scaled
//! columns take their steps from, core::quantize, so that assemble learns them without reading
//! every record twice), then blocks of ids (varint gaps) and records (the global patch only
//! with `--orient propagate`, the column values of
//! [`crate::io::columns::ResultLayout::encode_all`]): the terrain numbers as they are, the
//! rest as byte planes, the numbers' low bytes beside the zstd frame with the terrain numbers
//! under a checksum of their own (`rows`). The orientation sidecars are in `sidecar`.

mod file;
mod rows;
mod sidecar;

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::path::{Path, PathBuf};

use crate::core::compute::{PointResult, NO_PATCH};
use crate::core::orient::GlobalPatch;
use crate::core::plan::TileKey;
use crate::core::quantize::{Bin, CurvatureStats, Magnitudes};
use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::pack::Cursor;
use crate::io::prefetch::prefetch;
pub(crate) use file::{record_size, TileResults};
use file::{ResultWriter, WriteBuffers};
use sidecar::write_sidecar;
pub(crate) use sidecar::{orientation_path, read_sidecar, TileSidecar};

/// The statistics block: for H, K and the principal curvatures, the largest magnitude (f64),
/// the number of non-empty bins (u16) and each as its biased exponent (u16) and count (u64).
pub(super) fn stats_bytes(s: &CurvatureStats) -> Vec<u8> {
    let mut b = Vec::new();
    for m in [&s.h, &s.k, &s.principal] {
        b.extend_from_slice(&m.max().to_le_bytes());
        let bins: Vec<Bin> = m.bins().collect();
        b.extend_from_slice(&(bins.len() as u16).to_le_bytes());
        for bin in bins {
            b.extend_from_slice(&bin.exponent.to_le_bytes());
            b.extend_from_slice(&bin.count.to_le_bytes());
        }
    }
    b
}

/// Parses [`stats_bytes`]; None when damaged.
pub(super) fn parse_stats(b: &[u8]) -> Option<CurvatureStats> {
    let mut c = Cursor::new(b);
    let mut one = || -> Option<Magnitudes> {
        let max = c.f64()?;
        let n = c.u16()?;
        let mut bins = Vec::with_capacity(n as usize);
        for _ in 0..n {
            bins.push(Bin {
                exponent: c.u16()?,
                count: c.u64()?,
            });
        }
        Magnitudes::from_bins(bins, max)
    };
    let stats = CurvatureStats {
        h: one()?,
        k: one()?,
        principal: one()?,
    };
    c.is_done().then_some(stats)
}

/// Most result files merged at once; more are first partly merged into runs (which the work
/// directory then holds beside the tile files, and which cost a write and a read of every
/// result more). Lowered to what the open-file limit and the memory budget allow (see
/// [`fan_in`]): the default 4 GiB budget holds ~13,800 readers of H, K and flags, the 12,000
/// tiles of 300M points at 50 m.
pub(crate) const MAX_FAN_IN: usize = 16384;

/// How many result files one merge may open: [`MAX_FAN_IN`], or less when the process's
/// open-file limit is low (the CLI raised its soft limit to the hard one at start): what the
/// limit leaves beside the descriptors open now, less a reserve (64, or a quarter of a small
/// limit) for the output, a run file and everything else; and at most what a quarter of
/// `memory_bytes` (the run's budget, free once the tiles are done) holds of readers of `cols`
/// (`file::reader_bytes`: a block of rows and their ids); at least 2. A limit too low even
/// for that makes the open fail with EMFILE, an error that says to raise `ulimit -n`.
pub(crate) fn fan_in(memory_bytes: usize, cols: &ColumnSet) -> usize {
    let by_memory = (memory_bytes / 4 / file::reader_bytes(cols)).clamp(2, MAX_FAN_IN);
    let Some(soft) = crate::io::limits::open_files_limit() else {
        return 64.min(by_memory);
    };
    let in_use = crate::io::limits::open_descriptors().unwrap_or(16);
    let reserve = (soft / 4).min(64);
    (soft.saturating_sub(in_use).saturating_sub(reserve)).clamp(2, by_memory as u64) as usize
}

/// About how many bytes a point takes in the result files with the columns `cols` (for the
/// plan's estimate of the work directory's disk): its terrain numbers as they are, about 3/4 of
/// its other column bytes (their values' low bits are noise; ids and flag bytes compress to
/// almost nothing).
pub(crate) fn estimated_point_bytes(cols: &ColumnSet) -> f64 {
    let raw = rows::RowSplit::of(cols, false, false).raw_width();
    raw as f64 + 0.75 * (cols.result_size() - raw) as f64
}

/// The result file of a tile.
pub(crate) fn tile_path(dir: &Path, key: TileKey) -> PathBuf {
    crate::io::workdir::names::tile_result(dir, key)
}

/// Writes one tile's results (in id order) under a temporary name; returns it. Patches are
/// stored only if some point has one (`--orient propagate`).
fn write_tile_tmp(
    dir: &Path,
    key: TileKey,
    tile_index: u32,
    results: &[PointResult],
    cols: &ColumnSet,
    scratch: &mut TileScratch,
) -> Result<PathBuf> {
    // Sorted as (id, place) pairs rather than moving the ~160-byte results themselves (ten
    // times the bytes to move: docs/performance.md); ids are unique, so the order is the ids'.
    let order = &mut scratch.order;
    order.clear();
    order.extend((results.iter().enumerate()).map(|(i, r)| (r.id, i as u32)));
    crate::core::radix::sort_by_key(order, &mut scratch.sort);
    // Encoded in the results' order (one sequential pass over them, with the statistics),
    // then taken in id order from the records, a sixth of their size: reading the results
    // themselves in id order missed the cache for most of them.
    let size = record_size(cols);
    // Not cleared first: every byte of a record is written below (the patch here, the rest by
    // `encode_all`), so the previous tile's bytes need no zeroing.
    let records = &mut scratch.records;
    records.resize(results.len() * size, 0);
    let mut stats = CurvatureStats::default();
    let layout = cols.layout();
    // Batches whose results stay in the cache while each value's loop walks them.
    const BATCH: usize = 128;
    for (batch, recs) in results.chunks(BATCH).zip(records.chunks_mut(BATCH * size)) {
        for (r, rec) in batch.iter().zip(recs.chunks_exact_mut(size)) {
            stats.add(&r.curvature);
            rec[..8].copy_from_slice(&GlobalPatch::new(tile_index, r.patch).0.to_le_bytes());
        }
        layout.encode_all(batch, recs, size, 8);
    }
    let patched = results.iter().any(|r| r.patch != NO_PATCH);
    let count = results.len() as u64;
    let path = tile_path(dir, key);
    let mut w = ResultWriter::create(&path, count, cols, patched, &stats, &mut scratch.writer)?;
    for (j, &(id, i)) in order.iter().enumerate() {
        // Taken in id order, the records are scattered over the tile's (more than the
        // second-level cache with the terrain numbers): the next ones' lines are fetched
        // while this one is pushed.
        if let Some(&(_, ahead)) = order.get(j + RECORDS_AHEAD) {
            prefetch(records.as_ptr().wrapping_add(ahead as usize * size), size);
        }
        let at = i as usize * size;
        // The record and the bytes after it (ResultWriter::push).
        w.push(id, &records[at..])?;
    }
    let tmp = w.finish();
    // A tile much larger than the others (the dense tile around a terrestrial scanner) does
    // not leave its buffers to the rest of the run, beside the tiles being computed.
    if records.capacity() > TileScratch::KEEP {
        *scratch = TileScratch::default();
    }
    tmp
}

/// How many records ahead of the one pushed [`write_tile_tmp`] prefetches: enough for the
/// misses of several to overlap.
const RECORDS_AHEAD: usize = 16;

/// What writing a tile's result file needs besides the results, kept from one tile to the
/// next (fresh buffers for each tile cost page faults: [`WriteBuffers`]).
#[derive(Default)]
struct TileScratch {
    order: Vec<(u64, u32)>,
    sort: Vec<(u64, u32)>,
    records: Vec<u8>,
    writer: WriteBuffers,
}

impl TileScratch {
    /// The most bytes of records kept for the next tile (about 350,000 points of the terrain
    /// columns; a 50 m tile of 8 points/m^2 holds 20,000).
    const KEEP: usize = 16 << 20;
}

/// The resume journal: finished tiles' result files, made durable in batches. A batch is
/// written under temporary names, flushed to disk with one `syncfs` (one journal commit instead
/// of one per file: thousands of small tiles would otherwise spend seconds in fsync), then
/// renamed to their final names. Only a renamed file counts as a finished tile.
pub(crate) struct Journal {
    dir: PathBuf,
    pending: Vec<(PathBuf, PathBuf)>,
    since: std::time::Instant,
    scratch: TileScratch,
}

impl Journal {
    /// A journal writing into `dir`.
    pub(crate) fn new(dir: &Path) -> Self {
        Journal {
            dir: dir.to_path_buf(),
            pending: Vec::new(),
            since: std::time::Instant::now(),
            scratch: TileScratch::default(),
        }
    }

    /// Adds a finished tile; commits the batch when it is large or old enough.
    pub(crate) fn add(
        &mut self,
        key: TileKey,
        tile_index: u32,
        results: &[PointResult],
        sidecar: Option<&TileSidecar>,
        cols: &ColumnSet,
    ) -> Result<()> {
        // The sidecar is renamed before the result file: a tile is done only once both are.
        if let Some(sc) = sidecar {
            let path = orientation_path(&self.dir, key);
            let tmp = write_sidecar(&path, sc)?;
            self.pending.push((tmp, path));
        }
        let tmp = write_tile_tmp(&self.dir, key, tile_index, results, cols, &mut self.scratch)?;
        self.pending.push((tmp, tile_path(&self.dir, key)));
        if self.pending.len() >= 256 || self.since.elapsed().as_secs_f64() > 2.0 {
            self.commit()?;
        }
        Ok(())
    }

    /// Makes every pending tile durable and visible.
    pub(crate) fn commit(&mut self) -> Result<()> {
        if self.pending.is_empty() {
            return Ok(());
        }
        crate::io::durable::sync_files(
            &self.dir,
            self.pending.iter().map(|(tmp, _)| tmp.as_path()),
        )?;
        for (tmp, path) in self.pending.drain(..) {
            std::fs::rename(&tmp, &path).map_err(|e| Error::write(&path, e))?;
        }
        crate::io::durable::sync_dir(&self.dir);
        self.since = std::time::Instant::now();
        Ok(())
    }
}

/// Whether the result file of a tile is complete: it exists, its header matches the column
/// set, its count is `expected`, and it is whole ([`TileResults::verify`]). A damaged file is
/// not complete: its tile is computed again.
pub(crate) fn is_complete(path: &Path, expected: u64, cols: &ColumnSet) -> bool {
    match TileResults::open(path, cols) {
        Ok(r) => r.count == expected && r.verify().is_ok(),
        Err(_) => false,
    }
}

/// The curvature statistics of all the tiles whose result files are `files`: the sum of
/// theirs, so the same whatever the tiling.
pub(crate) fn scene_stats(files: &[PathBuf], cols: &ColumnSet) -> Result<CurvatureStats> {
    let mut all = CurvatureStats::default();
    for f in files {
        all.merge(&TileResults::open(f, cols)?.stats);
    }
    Ok(all)
}

/// A k-way merge of result files by point id.
pub(crate) struct Merger {
    /// The files, each at the record whose id the heap holds for it.
    readers: Vec<TileResults>,
    heap: BinaryHeap<Reverse<(u64, usize)>>,
    /// The result directory, named when the files do not hold what the run needs.
    dir: PathBuf,
    /// The last id returned: each comes once, in increasing order, unless the files are damaged.
    last: Option<u64>,
}

impl Merger {
    /// Opens a merge over `files`, at most [`fan_in`] open at once (for a budget of
    /// `memory_bytes`).
    pub(crate) fn open(
        dir: &Path,
        files: &[PathBuf],
        cols: &ColumnSet,
        memory_bytes: usize,
    ) -> Result<Self> {
        Self::open_with_fan_in(dir, files, cols, fan_in(memory_bytes, cols))
    }

    /// Opens a merge over `files` with at most `fan_in` (>= 2) files open at once: while there
    /// are more, the first ones are merged into a run file in `dir` (at most `fan_in` of them,
    /// and only as many as needed to bring the count down to `fan_in`, so that the least data
    /// is written twice), and the run takes their place at the end.
    pub(crate) fn open_with_fan_in(
        dir: &Path,
        files: &[PathBuf],
        cols: &ColumnSet,
        fan_in: usize,
    ) -> Result<Self> {
        let fan_in = fan_in.max(2);
        let mut files: std::collections::VecDeque<PathBuf> = files.iter().cloned().collect();
        let mut runs = std::collections::HashSet::new();
        let mut bufs = WriteBuffers::default();
        while files.len() > fan_in {
            let take = (files.len() - fan_in + 1).min(fan_in);
            let group: Vec<PathBuf> = files.drain(..take).collect();
            let run = crate::io::workdir::names::merge_run(dir, runs.len());
            let mut m = Merger::open_direct(dir, &group, cols)?;
            // Counts come from the files' headers: a sum past u64 is damage.
            let count = m
                .readers
                .iter()
                .try_fold(0u64, |n, r| n.checked_add(r.count))
                .ok_or_else(|| Error::damaged_work(&group[0], "point counts overflow"))?;
            let patched = m.readers.iter().any(TileResults::patched);
            let mut rec = Vec::new();
            // Runs only serve this assemble pass: no need to make them durable, nor to hold
            // statistics (scene_stats reads the tile files).
            let stats = CurvatureStats::default();
            let mut w = ResultWriter::create(&run, count, cols, patched, &stats, &mut bufs)?;
            while let Some(id) = m.next(&mut rec)? {
                w.push(id, &rec)?;
            }
            let tmp = w.finish()?;
            std::fs::rename(&tmp, &run).map_err(|e| Error::write(&run, e))?;
            // Tile files are the journal and stay until the output exists; merged runs go.
            for f in group.iter().filter(|f| runs.contains(*f)) {
                let _ = std::fs::remove_file(f);
            }
            runs.insert(run.clone());
            files.push_back(run);
        }
        Merger::open_direct(dir, files.make_contiguous(), cols)
    }

    fn open_direct(dir: &Path, files: &[PathBuf], cols: &ColumnSet) -> Result<Self> {
        let mut readers = files
            .iter()
            .map(|p| TileResults::open(p, cols))
            .collect::<Result<Vec<_>>>()?;
        let mut heap = BinaryHeap::new();
        for (i, r) in readers.iter_mut().enumerate() {
            if let Some(id) = r.advance()? {
                heap.push(Reverse((id, i)));
            }
        }
        Ok(Merger {
            readers,
            heap,
            dir: dir.to_path_buf(),
            last: None,
        })
    }

    /// The next record in id order: its id, with its column bytes copied to `out`.
    pub(crate) fn next(&mut self, out: &mut Vec<u8>) -> Result<Option<u64>> {
        out.clear();
        self.append_next(out)
    }

    /// The error for results that do not match the points: `found` (None: no more results)
    /// where point `expected` was due. The files were checked as they were read, so they are
    /// whole; a tile's file missing or another run's in its place leaves points without one.
    pub(crate) fn mismatch(&self, expected: u64, found: Option<u64>) -> Error {
        let what = match found {
            Some(id) => format!("the result files hold point {id} where point {expected} is due"),
            None => format!("the result files hold no result for point {expected}"),
        };
        Error::damaged_work(&self.dir, &what)
    }

    /// [`Merger::next`] appending the column bytes to `out` (no copy in between).
    pub(crate) fn append_next(&mut self, out: &mut Vec<u8>) -> Result<Option<u64>> {
        // The top is replaced in place: one sift, which stops at once while the same file
        // holds the smallest ids (runs of consecutive points in one tile are the common case).
        let Some(mut top) = self.heap.peek_mut() else {
            return Ok(None);
        };
        let Reverse((id, i)) = *top;
        if self.last.is_some_and(|l| l >= id) {
            return Err(Error::damaged_work(
                self.readers[i].path(),
                &format!("point {id} has results in two result files"),
            ));
        }
        self.last = Some(id);
        self.readers[i].append_current(out);
        match self.readers[i].advance()? {
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

    /// The column set `choice`, in f64.
    fn columns(choice: &str) -> ColumnSet {
        ColumnSet {
            choice: ColumnChoice::parse(choice).expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide: true,
        }
    }

    /// Point `id`'s result: an upward normal, H = `h`, everything else undefined.
    fn result(id: u64, h: f64) -> PointResult {
        PointResult {
            id,
            normal: [0.0, 0.0, 1.0],
            curvature: Curvature {
                h,
                ..Curvature::undefined(0)
            },
            extra: [f64::NAN; crate::core::estimate::MAX_EXTRA],
            patch: crate::core::compute::NO_PATCH,
            scale: 0,
            scale_flags: 0,
            terrain: crate::core::terrain::TerrainValues::NONE,
        }
    }

    /// The disk estimate of the results against the bytes a tile's results take, for
    /// curvatures and normals of noisy magnitudes and their true terrain values: within a
    /// sixth for the default columns, the terrain columns and normals with k1 and k2.
    #[test]
    fn the_disk_estimate_is_within_a_sixth_of_the_files() {
        use crate::core::rng::Rng;
        use crate::core::terrain::TerrainValues;
        let dir = tempfile::tempdir().expect("temp dir");
        let mut rng = Rng::new(5);
        let n = 20_000u64;
        let results: Vec<PointResult> = (0..n)
            .map(|i| {
                let (k1, k2) = (0.05 * rng.normal(), 0.05 * rng.normal());
                let (k1, k2) = (k1.min(k2), k1.max(k2));
                let t = [rng.normal() * 0.3, rng.normal() * 0.3, 1.0];
                let len = (t[0] * t[0] + t[1] * t[1] + 1.0).sqrt();
                let normal = t.map(|v| v / len);
                let curvature = Curvature {
                    h: (k1 + k2) / 2.0,
                    k: k1 * k2,
                    k1,
                    k2,
                    d1: [1.0, 0.0, 0.0],
                    d2: [0.0, normal[2], -normal[1]],
                    flags: 0,
                };
                PointResult {
                    normal,
                    curvature,
                    terrain: TerrainValues::of(normal, &curvature),
                    ..result(i, 0.0)
                }
            })
            .collect();
        for list in ["H,K,flags", "H,K,flags,terrain", "normals,H,K,k1,k2,flags"] {
            let cols = ColumnSet {
                wide: false,
                ..columns(list)
            };
            let mut journal = Journal::new(dir.path());
            journal
                .add((0, 0), 0, &results, None, &cols)
                .expect("write");
            journal.commit().expect("commit");
            let path = tile_path(dir.path(), (0, 0));
            let bytes = std::fs::metadata(&path).expect("size").len() as f64 / n as f64;
            let estimate = estimated_point_bytes(&cols);
            assert!(
                (estimate / bytes - 1.0).abs() < 1.0 / 6.0,
                "{list}: estimated {estimate:.2} bytes a point, the file holds {bytes:.2}"
            );
            std::fs::remove_file(&path).expect("remove");
        }
    }

    /// Two whole result files that share a point (one copied over another tile's of the same
    /// size): the merge stops with damaged work naming a file, not with a record twice.
    #[test]
    fn a_point_in_two_result_files_is_damaged_work() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cols = columns("H,flags");
        let mut journal = Journal::new(dir.path());
        for (t, ids) in [(0i64, [0u64, 2, 4]), (1, [1, 2, 5])] {
            let rs: Vec<PointResult> = ids.iter().map(|&i| result(i, f64::NAN)).collect();
            journal
                .add((t, 0), t as u32, &rs, None, &cols)
                .expect("write");
        }
        journal.commit().expect("commit");
        let files = [tile_path(dir.path(), (0, 0)), tile_path(dir.path(), (1, 0))];
        let mut m = Merger::open_with_fan_in(dir.path(), &files, &cols, 8).expect("merge");
        let mut rec = Vec::new();
        assert_eq!(m.next(&mut rec).expect("0"), Some(0));
        assert_eq!(m.next(&mut rec).expect("1"), Some(1));
        assert_eq!(m.next(&mut rec).expect("2"), Some(2));
        let e = m.next(&mut rec).expect_err("point 2 again").to_string();
        assert!(
            e.contains("point 2 has results in two result files")
                && e.contains("tile_")
                && e.contains("delete the work directory"),
            "{e}"
        );
        assert_eq!(e, e.trim());
    }

    #[test]
    fn merge_with_runs_returns_every_id_once_in_order() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cols = columns("normals,H,K,k1,k2,flags");
        // 150 tiles, ids interleaved across tiles, merged 8 at a time (so runs are made, and
        // runs of runs).
        let mut files = Vec::new();
        let mut journal = Journal::new(dir.path());
        for t in 0..150u64 {
            let rs: Vec<PointResult> = (0..7u64)
                .map(|j| result(j * 150 + t, (j * 150 + t) as f64))
                .collect();
            journal
                .add((t as i64, 0), t as u32, &rs, None, &cols)
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
