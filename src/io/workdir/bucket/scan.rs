//! The scan of one bucket task: streams its ranges of points of its inputs once, appending every point to the bucket of
//! its core tile and gathering the scan statistics. Buckets stay in memory while they fit the
//! memory plan (when the caller allows it); past it the largest are spilled as zstd frames. A
//! spilled task is written to a directory of its own under a temporary name and renamed into
//! place once complete, so a task run twice, or by two nodes at once, is harmless.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rayon::prelude::*;

use super::frames::{spill, Grids};
use super::stats::stats_text;
use super::{Bucketed, Buckets, TaskDir, DONE};
use crate::core::grid::AxisGrid;
use crate::core::plan::{computable, MemoryPlan, ScanStats, TileGrid, TileKey, MAX_COORDINATE};
use crate::core::point::{Points, SourcePoint};
use crate::core::select::ClassFilter;
use crate::error::{Error, Result};
use crate::io::durable::{sync_dir, sync_files, tmp_name, write_durably};
use crate::io::source::PointSource;
use crate::io::workdir::names::bucket_file;

/// One source of a scan and the id of its first point in the scene.
pub(crate) struct ScanInput<'a> {
    /// The source.
    pub source: &'a dyn PointSource,
    /// Global id of its point 0 (the sum of the earlier inputs' counts).
    pub first_id: u64,
    /// Its points this task scans (indices in the file): a point's id is `first_id` plus its
    /// index whichever task scans it.
    pub points: std::ops::Range<u64>,
    /// Factor from the file's z unit to its horizontal unit (1 unless the CRS says the
    /// vertical unit differs): applied to every decoded z, and to file normals, before any
    /// geometry.
    pub z_scale: f64,
    /// Which points are computed: the others are left out of the buckets (their neighbours
    /// never see them) and written as not computed.
    pub select: &'a ClassFilter,
}

/// Converts a decoded point's z to the horizontal unit. A normal transforms by the inverse
/// transpose of the scaling: its z is divided by the factor, then it is renormalised.
fn rescale_z(p: &mut SourcePoint, s: f64) {
    p.xyz[2] *= s;
    if let Some(n) = p.normal {
        p.normal = crate::core::geometry::normalize([n[0], n[1], n[2] / s]).or(p.normal);
    }
}

/// Buckets held in memory during a scan, and where they spill.
struct Held {
    mem: HashMap<TileKey, Points>,
    /// The held buckets' heap bytes ([`Points::heap_bytes`]).
    bytes: usize,
    tmp: PathBuf,
    spilled: bool,
    /// The inputs' coordinate grids, for the spilled frames.
    grids: Grids,
}

impl Held {
    /// Spills the largest buckets until the held bytes are down to `down_to`.
    fn spill_largest(&mut self, down_to: usize) -> Result<()> {
        std::fs::create_dir_all(&self.tmp).map_err(|e| Error::write(&self.tmp, e))?;
        self.spilled = true;
        let mut sizes: Vec<(usize, TileKey)> =
            self.mem.iter().map(|(k, v)| (v.len(), *k)).collect();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        let mut out = Vec::new();
        for (_, key) in sizes {
            if self.bytes <= down_to {
                break;
            }
            if let Some(v) = self.mem.remove(&key) {
                self.bytes -= v.heap_bytes();
                out.push((key, v));
            }
        }
        spill(&self.tmp, out, &self.grids)
    }
}

/// Scans `inputs` into the buckets of bucket task directory `task_dir`. With
/// `keep_in_memory`, buckets that fit `memory.buckets_bytes` stay in memory and nothing is
/// written; otherwise (or once they do not fit) every bucket ends on disk with the statistics
/// in `buckets.done`. `progress(n)` is called after each chunk with the points read; an error
/// from it (cancellation) stops the scan.
pub(crate) fn scan(
    inputs: &[ScanInput<'_>],
    grid: TileGrid,
    chunk_points: usize,
    memory: &MemoryPlan,
    task_dir: &Path,
    keep_in_memory: bool,
    mut progress: impl FnMut(u64) -> Result<()>,
) -> Result<Bucketed> {
    let mut held = Held {
        mem: HashMap::new(),
        bytes: 0,
        tmp: tmp_name(task_dir),
        spilled: false,
        grids: grids_of(inputs),
    };
    let mut stats = ScanStats::empty();
    // Decoding buffers, reused from group to group of pieces: one group is appended while
    // the next is decoded.
    let mut pieces: [Vec<Piece>; 2] = Default::default();
    for input in inputs {
        let rl = input.source.record_length();
        input
            .source
            .for_each_chunk_in(input.points.clone(), chunk_points, &mut |first, records| {
                let n = records.len() / rl;
                // A few pieces per thread at a time: the decoded points in flight stay a few
                // MiB whatever the chunk size.
                let group = 4 * rayon::current_num_threads().max(1);
                let groups: Vec<&[u8]> = records.chunks(group * PIECE_RECORDS * rl).collect();
                let [full, empty] = &mut pieces;
                let mut decoded: Option<Vec<Result<()>>> = None;
                for g in 0..=groups.len() {
                    // Appending group g - 1 (one thread) while group g is decoded (the others):
                    // the appends, in file order, were half of the scan's time alone.
                    let at = first + (g * group * PIECE_RECORDS) as u64;
                    let (appended, next) = rayon::join(
                        || match decoded.take() {
                            Some(d) => append(full, d, &mut held, &mut stats),
                            None => Ok(()),
                        },
                        || {
                            groups
                                .get(g)
                                .map(|r| decode_group(input, grid, at, r, empty, group))
                        },
                    );
                    appended?;
                    std::mem::swap(full, empty);
                    decoded = next;
                }
                if held.bytes > memory.buckets_bytes {
                    held.spill_largest(memory.buckets_after_spill_bytes)?;
                }
                progress(n as u64)
            })
            .inspect_err(|_| {
                let _ = std::fs::remove_dir_all(&held.tmp);
            })?;
    }
    if held.spilled || !keep_in_memory {
        return publish(held, grid, task_dir, stats);
    }
    let mem = held
        .mem
        .into_iter()
        .map(|(k, v)| (k, Arc::new(v)))
        .collect();
    Ok(Bucketed {
        buckets: Buckets::in_memory(grid, mem),
        stats,
    })
}

/// Records of a chunk decoded by one task: the pieces of a chunk are decoded in parallel (on
/// the caller's rayon pool) and appended to the buckets in file order.
const PIECE_RECORDS: usize = 1 << 14;

/// The selected points of a piece of a chunk, decoded and checked, in file order.
#[derive(Default)]
struct Piece {
    points: Vec<SourcePoint>,
    /// Consecutive points of one core tile, as (tile, count): points arrive in scan order, so
    /// runs are long and the buckets are looked up once a run, not once a point.
    runs: Vec<(TileKey, usize)>,
    /// The statistics of the piece's points (they merge exactly, in any grouping).
    stats: ScanStats,
}

/// Decodes the records `records` of `input` (the first is its point `first`) into `pieces`
/// of [`PIECE_RECORDS`] each, `group` at most, in parallel: each piece's outcome, in order.
fn decode_group(
    input: &ScanInput<'_>,
    grid: TileGrid,
    first: u64,
    records: &[u8],
    pieces: &mut Vec<Piece>,
    group: usize,
) -> Vec<Result<()>> {
    let piece_bytes = PIECE_RECORDS * input.source.record_length();
    pieces.resize_with(group, Piece::default);
    records
        .par_chunks(piece_bytes)
        .zip(pieces.par_iter_mut())
        .enumerate()
        .map(|(j, (r, piece))| {
            decode_piece(input, grid, first + (j * PIECE_RECORDS) as u64, r, piece)
        })
        .collect()
}

/// Appends the decoded `pieces` to the buckets in file order, so that every bucket receives
/// its points in file order, as a one-thread scan appends them; the first error (`decoded`) is
/// the first bad point's.
fn append(
    pieces: &[Piece],
    decoded: Vec<Result<()>>,
    held: &mut Held,
    stats: &mut ScanStats,
) -> Result<()> {
    for (piece, decoded) in pieces.iter().zip(decoded) {
        decoded?;
        stats.merge(&piece.stats);
        let mut start = 0;
        for &(key, len) in &piece.runs {
            let run = &piece.points[start..start + len];
            // One push at a time, as the one-thread scan grew the buckets: extending by whole
            // runs gave capacities that are not powers of two, and 60 MiB more peak RSS on the
            // 20M terrain.
            let bucket = held.mem.entry(key).or_default();
            let before = bucket.heap_bytes();
            for p in run {
                bucket.push(p);
            }
            held.bytes += bucket.heap_bytes() - before;
            start += len;
        }
    }
    Ok(())
}

/// Decodes the records `records` of `input`, the first of which is its point `first`, into
/// `piece` (emptied first): the selected points, z converted, checked ([`check_point`]), with
/// the scene-wide id.
fn decode_piece(
    input: &ScanInput<'_>,
    grid: TileGrid,
    first: u64,
    records: &[u8],
    piece: &mut Piece,
) -> Result<()> {
    piece.points.clear();
    piece.runs.clear();
    piece.stats = ScanStats::empty();
    let rl = input.source.record_length();
    for (i, rec) in records.chunks_exact(rl).enumerate() {
        if !input.select.selects(input.source.class_of(rec)) {
            continue;
        }
        let mut p = input.source.decode(first + i as u64, rec);
        if input.z_scale != 1.0 {
            rescale_z(&mut p, input.z_scale);
        }
        check_point(input.source, grid, &p)?;
        p.id += input.first_id;
        let key = grid.key(p.xyz[0], p.xyz[1]);
        piece.stats.add(p.xyz);
        piece.points.push(p);
        match piece.runs.last_mut() {
            Some((k, len)) if *k == key => *len += 1,
            _ => piece.runs.push((key, 1)),
        }
    }
    for &(key, len) in &piece.runs {
        piece.stats.in_tile(key, len as u64);
    }
    Ok(())
}

/// The coordinate grids of the inputs (LAS scale and offset, z times the z factor), by id.
fn grids_of(inputs: &[ScanInput<'_>]) -> Grids {
    let mut grids = Grids::default();
    for input in inputs {
        let axes = input.source.integer_coordinates().map(|q| {
            [0, 1, 2].map(|a| {
                let post = if a == 2 { input.z_scale } else { 1.0 };
                AxisGrid::new(q.scale[a], q.offset[a], post)
            })
        });
        grids.push(input.first_id, axes);
    }
    grids
}

/// Refuses a decoded point that cannot be computed on: a non-finite or absurdly large
/// coordinate is bad input (a corrupt scale, offset or record), a point beyond the tile grid a
/// usage error (the tile is too small for the extent). `p.id` is the source's own index.
fn check_point(source: &dyn PointSource, grid: TileGrid, p: &SourcePoint) -> Result<()> {
    let [x, y, z] = p.xyz;
    if !computable(p.xyz) {
        // Integer coordinates (LAS) are always finite: their scale or offset is to blame.
        let why = match source.integer_coordinates() {
            Some(_) => "the file's scale, offset or point record is corrupt",
            None => "the data holds a NaN, an infinity or an absurd value there: remove or fix such points",
        };
        return Err(Error::bad_input(source.path(), None, format!(
            "point {} has coordinates ({x:e}, {y:e}, {z:e}), which are not finite or beyond +-{MAX_COORDINATE:e}; {why}",
            p.id)));
    }
    if !grid.holds(x, y) {
        let what = format!("{}: point {}", source.path().display(), p.id);
        return Err(Error::Usage(grid.outside(&what, x, y)));
    }
    Ok(())
}

/// Spills what is still held, makes the task directory durable with its statistics, and
/// renames it into place (keeping an identical one another attempt finished first).
fn publish(mut held: Held, grid: TileGrid, task_dir: &Path, stats: ScanStats) -> Result<Bucketed> {
    let tmp = held.tmp.clone();
    std::fs::create_dir_all(&tmp).map_err(|e| Error::write(&tmp, e))?;
    held.spill_largest(0)?;
    let files: Vec<PathBuf> = stats
        .per_tile
        .keys()
        .map(|key| bucket_file(&tmp, *key))
        .collect();
    sync_files(&tmp, files.iter().map(PathBuf::as_path))?;
    write_durably(&tmp.join(DONE), stats_text(&stats).as_bytes())?;
    if let Err(e) = std::fs::rename(&tmp, task_dir) {
        if task_dir.join(DONE).exists() {
            // Another attempt of the same task finished first: its buckets are the same.
            let _ = std::fs::remove_dir_all(&tmp);
        } else {
            return Err(Error::write(task_dir, e));
        }
    }
    if let Some(parent) = task_dir.parent() {
        sync_dir(parent);
    }
    let dir = TaskDir {
        path: task_dir.to_path_buf(),
        tiles: stats.per_tile.clone(),
    };
    Ok(Bucketed {
        buckets: Buckets::on_disk(grid, vec![dir]),
        stats,
    })
}
