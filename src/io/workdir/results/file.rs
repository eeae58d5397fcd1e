//! The result file format, written and read in id order. Header: [`MAGIC`] (the format and its
//! version), the point count, the column bytes a point ([`ColumnSet::result_size`]), whether
//! patches are stored (only when some point has one: `--orient propagate`), then the tile's
//! [`CurvatureStats`]. Then blocks of records, each `records`, `raw length`, `frame length`,
//! `plain length` (u32 LE), the plain bytes, a zstd frame with a checksum
//! ([`crate::io::pack`]) and the plain bytes' checksum (u64 LE, [`crate::io::pack::checksum`]).
//! A stored row (the global patch as u64 if stored, then the columns, H exclusive-ored with its
//! prediction from k1 and k2: [`HPrediction`]) is split ([`RowSplit`]): its terrain numbers are
//! kept as they are, row after row, at the start of the plain bytes (where the writer puts
//! them as the rows come, in the file's buffer); the rest is cut into byte planes. The frame holds
//! the ids as varints (the first id of the file, then each one's distance past the one before,
//! less 1: ids strictly increase, so a tile's consecutive points take a zero byte) and the
//! planes that compress, in plane order; the others, the low bytes of computed numbers, end
//! the plain bytes. Blocks hold about 32 KiB of records, the memory one reader of a merge
//! keeps. A file is whole only if every block decodes, the ids increase and the count and the
//! file's end agree ([`TileResults::verify`]).

use std::fs::File;
use std::io::{IoSliceMut, Read, Write};
use std::path::{Path, PathBuf};

use super::rows::RowSplit;
use super::{parse_stats, stats_bytes};
use crate::core::orient::GlobalPatch;
use crate::core::quantize::CurvatureStats;
use crate::error::{Error, Result};
use crate::io::columns::{ColumnSet, Value};
use crate::io::durable::tmp_name;
use crate::io::pack::{
    checksum, compress, decompress_into, get_planes, put_planes, put_varint, Checksum, Cursor,
    Effort,
};

/// The first bytes of a result file: its format and version.
const MAGIC: &[u8; 8] = b"TCRES010";

/// Bytes of the header before the statistics: magic, count, column bytes, patches stored,
/// statistics' length.
const HEAD: usize = 40;

/// Largest statistics block a result file may declare (three full histograms are 61 KiB).
const MAX_STATS: u64 = 1 << 20;

/// Bytes of records a block holds at most (the records of a merge's reader in memory: 4000
/// tiles of 100M points merged at once take 160 MiB).
const BLOCK_BYTES: usize = 32 << 10;

/// Largest raw, compressed or plain part of a block a reader accepts (a damaged length is
/// refused before any allocation).
const MAX_BLOCK: usize = 16 << 20;

/// Memory one result file of `cols` takes in a merge: a decoded block (at most
/// [`BLOCK_BYTES`] of rows) with the ids of its rows (8 bytes each: narrow rows make many),
/// and 16 KiB for the rest of the reader; the frame and planes of a block being decoded are
/// freed once it is. About 57 KiB for normals, H, K, k1, k2 and flags, 76 KiB for H, K and
/// flags.
pub(super) fn reader_bytes(cols: &ColumnSet) -> usize {
    BLOCK_BYTES + 8 * BLOCK_BYTES.div_ceil(cols.result_size()) + (16 << 10)
}

/// Bytes of one record in memory: the global patch (u64) then the columns.
pub(crate) fn record_size(cols: &ColumnSet) -> usize {
    8 + cols.result_size()
}

/// The stored H exclusive-ored with `(k1 + k2) / 2` computed from the stored k1 and k2 (as the
/// estimators mostly compute it: the two agree to the bit for about half the points, and to the
/// low bits for most others), which leaves zeros where the value's mantissa was noise. Its own
/// inverse, since k1 and k2 are stored as they are; no prediction (0) when it is NaN, whose
/// bits IEEE leaves to the processor.
#[derive(Debug, Clone, Copy)]
struct HPrediction {
    /// Offsets of H, k1 and k2 in the columns.
    h: usize,
    k1: usize,
    k2: usize,
    /// f64 values (else f32).
    wide: bool,
}

impl HPrediction {
    /// The prediction for a column set that stores H, k1 and k2.
    fn of(cols: &ColumnSet) -> Option<Self> {
        Some(HPrediction {
            h: cols.stored_offset(Value::H)?,
            k1: cols.stored_offset(Value::K1)?,
            k2: cols.stored_offset(Value::K2)?,
            wide: cols.wide,
        })
    }

    /// Applies (or undoes) the prediction on one record's columns.
    fn apply(&self, columns: &mut [u8]) {
        let w = if self.wide { 8 } else { 4 };
        let get = |at: usize| -> Option<f64> {
            let b = columns.get(at..at + w)?;
            Some(match self.wide {
                true => f64::from_le_bytes(b.try_into().ok()?),
                false => f32::from_le_bytes(b.try_into().ok()?) as f64,
            })
        };
        let (Some(k1), Some(k2)) = (get(self.k1), get(self.k2)) else {
            return;
        };
        let mean = (k1 + k2) / 2.0;
        if mean.is_nan() {
            return;
        }
        let mut bits = [0u8; 8];
        match self.wide {
            true => bits = mean.to_le_bytes(),
            false => bits[..4].copy_from_slice(&(mean as f32).to_le_bytes()),
        }
        if let Some(h) = columns.get_mut(self.h..self.h + w) {
            h.iter_mut().zip(bits).for_each(|(b, p)| *b ^= p);
        }
    }
}

/// The buffers of a [`ResultWriter`], kept from one file to the next: a tile's writer
/// allocating them afresh touched new pages for each (its records, its blocks and a
/// megabyte of file buffer: page faults and their zeroing were a fifth of writing the
/// terrain columns' results).
#[derive(Default)]
pub(crate) struct WriteBuffers {
    ids: Vec<u8>,
    /// The packed rows of the block being gathered ([`RowSplit`]).
    rows: Vec<u8>,
    planes: Vec<u8>,
    raw: Vec<u8>,
    /// Bytes of the file not yet written, at most [`FILE_BUFFER`] and a block. The block being
    /// gathered is at its end: room for its lengths, then its raw bytes, pushed there row by
    /// row so that they are copied once on their way to the file, not twice (the terrain
    /// numbers: most of a row's bytes).
    file: Vec<u8>,
    /// Where the block being gathered starts in `file` (while it has rows).
    block: usize,
}

/// Bytes of a block's lengths: records, raw, frame and plain length (u32 LE each).
const BLOCK_HEAD: usize = 16;

/// Bytes a writer gathers before a write to its file.
const FILE_BUFFER: usize = 1 << 20;

/// Writes a result file under its temporary name: records pushed in increasing id order.
pub(super) struct ResultWriter<'b> {
    path: PathBuf,
    tmp: PathBuf,
    w: File,
    /// Whether the patches are stored (else every pushed patch must be none).
    patched: bool,
    /// Bytes of a stored record (patch if stored, then the columns).
    row: usize,
    count: u64,
    written: u64,
    prev: Option<u64>,
    predict: Option<HPrediction>,
    split: RowSplit,
    b: &'b mut WriteBuffers,
}

impl<'b> ResultWriter<'b> {
    /// Starts the file for `path` (under a temporary name) for `count` records of `cols`, with
    /// the patches stored or not, and `stats` in its header, in the buffers `b`.
    pub(super) fn create(
        path: &Path,
        count: u64,
        cols: &ColumnSet,
        patched: bool,
        stats: &CurvatureStats,
        b: &'b mut WriteBuffers,
    ) -> Result<Self> {
        let tmp = tmp_name(path);
        let w = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
        let stats = stats_bytes(stats);
        for v in [&mut b.ids, &mut b.rows, &mut b.file] {
            v.clear();
        }
        for part in [
            &MAGIC[..],
            &count.to_le_bytes(),
            &(cols.result_size() as u64).to_le_bytes(),
            &(patched as u64).to_le_bytes(),
            &(stats.len() as u64).to_le_bytes(),
            &stats,
        ] {
            b.file.extend_from_slice(part);
        }
        let predict = HPrediction::of(cols);
        Ok(ResultWriter {
            path: path.to_path_buf(),
            tmp,
            w,
            patched,
            row: cols.result_size() + if patched { 8 } else { 0 },
            count,
            written: 0,
            prev: None,
            split: RowSplit::of(cols, patched, predict.is_some()),
            predict,
            b,
        })
    }

    /// Adds the record of point `id` (greater than the last one): the patch (u64 LE) then the
    /// columns, [`record_size`] bytes at the start of `from`, which may go on past the record
    /// (its pieces are then copied as chunks of a fixed width: [`RowSplit::push`]).
    pub(super) fn push(&mut self, id: u64, from: &[u8]) -> Result<()> {
        let (patch, columns) = from.split_at(8.min(from.len()));
        let gap = match self.prev {
            None => Some(id),
            Some(p) => id.checked_sub(p).and_then(|d| d.checked_sub(1)),
        };
        let unpatched = patch == GlobalPatch::NONE.0.to_le_bytes();
        // The stored row: the record with its patch, or its columns alone.
        let row = if self.patched { from } else { columns };
        let whole = row.len() >= self.row;
        let (Some(gap), true, true) = (gap, self.patched || unpatched, whole) else {
            return Err(Error::Internal(format!(
                "{}: result records out of order, cut short or with an unexpected patch (point {id})",
                self.path.display()
            )));
        };
        let b = &mut *self.b;
        if b.rows.is_empty() {
            // Room for the block's lengths, written when it is complete (flush_block).
            b.block = b.file.len();
            b.file.extend_from_slice(&[0; BLOCK_HEAD]);
        }
        put_varint(&mut b.ids, gap);
        let start = b.rows.len() + if self.patched { 8 } else { 0 };
        self.split.push(row, &mut b.rows, &mut b.file);
        if let Some(p) = &self.predict {
            // H, k1 and k2 precede the raw terrain numbers: at their offsets in a packed row.
            p.apply(&mut b.rows[start..]);
        }
        self.prev = Some(id);
        self.written += 1;
        let raw = b.file.len() - b.block - BLOCK_HEAD;
        if b.rows.len() + raw + self.row > BLOCK_BYTES {
            self.flush_block()?;
        }
        Ok(())
    }

    fn flush_block(&mut self) -> Result<()> {
        let b = &mut *self.b;
        if b.rows.is_empty() {
            return Ok(());
        }
        let n = b.rows.len() / self.split.packed();
        b.planes.clear();
        put_planes(&mut b.planes, &b.rows, self.split.packed());
        b.raw.clear();
        b.raw.extend_from_slice(&b.ids);
        let planes = || b.planes.chunks_exact(n).zip(self.split.plain_planes());
        for (plane, _) in planes().filter(|(_, &plain)| !plain) {
            b.raw.extend_from_slice(plane);
        }
        let frame = compress(&b.raw, Effort::Fast).map_err(|e| Error::write(&self.tmp, e))?;
        // The plain planes after the raw bytes already in the file buffer, summed there.
        for (plane, _) in planes().filter(|(_, &plain)| plain) {
            b.file.extend_from_slice(plane);
        }
        let sum = checksum(&b.file[b.block + BLOCK_HEAD..]);
        b.file.extend_from_slice(&frame);
        b.file.extend_from_slice(&sum.to_le_bytes());
        let lengths = [n, b.raw.len(), frame.len(), self.split.plain_len(n)];
        let head = b.file[b.block..b.block + BLOCK_HEAD].chunks_exact_mut(4);
        for (at, v) in head.zip(lengths) {
            at.copy_from_slice(&(v as u32).to_le_bytes());
        }
        b.ids.clear();
        b.rows.clear();
        if b.file.len() >= FILE_BUFFER {
            self.write_out()?;
        }
        Ok(())
    }

    /// Writes the gathered bytes to the file.
    fn write_out(&mut self) -> Result<()> {
        let tmp = &self.tmp;
        self.w
            .write_all(&self.b.file)
            .map_err(|e| Error::write(tmp, e))?;
        self.b.file.clear();
        Ok(())
    }

    /// Writes the last block and flushes; returns the temporary name (the caller renames it).
    pub(super) fn finish(mut self) -> Result<PathBuf> {
        self.flush_block()?;
        if self.written != self.count {
            return Err(Error::Internal(format!(
                "{}: {} results written where the header says {}",
                self.path.display(),
                self.written,
                self.count
            )));
        }
        self.write_out()?;
        Ok(self.tmp)
    }
}

/// Reads one result file in id order, a block at a time.
pub(crate) struct TileResults {
    path: PathBuf,
    file: File,
    /// Records not yet returned.
    remaining: u64,
    /// The header's count.
    pub count: u64,
    patched: bool,
    /// Column bytes a record.
    columns: usize,
    predict: Option<HPrediction>,
    split: RowSplit,
    /// The statistics of the file's points.
    pub stats: CurvatureStats,
    /// The current block: ids, packed rows and raw bytes ([`RowSplit`]), and the next row to
    /// return.
    ids: Vec<u64>,
    rows: Vec<u8>,
    raw_rows: Vec<u8>,
    next: usize,
    prev: Option<u64>,
    /// The next block's lengths, read with the block before it (one read a block, not two).
    next_head: Option<[u8; BLOCK_HEAD]>,
}

impl TileResults {
    /// The file read.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// Opens a result file written with the same column set and reads its header.
    pub(crate) fn open(path: &Path, cols: &ColumnSet) -> Result<Self> {
        let bad = |what: String| Error::damaged_work(path, &format!("result file {what}"));
        let mut file = File::open(path).map_err(|e| Error::read_work(path, e))?;
        let mut head = [0u8; HEAD];
        read_exact(&mut file, path, &mut head)?;
        let word = |i: usize| u64::from_le_bytes(head[i..i + 8].try_into().unwrap_or([0; 8]));
        if &head[..8] != MAGIC {
            return Err(bad("is not of this version of tilecurv".into()));
        }
        let columns = word(16) as usize;
        if columns != cols.result_size() {
            return Err(bad(format!(
                "has records of {columns} bytes, not {}",
                cols.result_size()
            )));
        }
        let stats_len = word(32);
        if word(24) > 1 || stats_len > MAX_STATS {
            return Err(bad("has a damaged header".into()));
        }
        let mut stats = vec![0u8; stats_len as usize];
        read_exact(&mut file, path, &mut stats)?;
        let stats = parse_stats(&stats).ok_or_else(|| bad("has damaged statistics".into()))?;
        let (predict, patched) = (HPrediction::of(cols), word(24) == 1);
        Ok(TileResults {
            path: path.to_path_buf(),
            file,
            remaining: word(8),
            count: word(8),
            patched,
            columns,
            split: RowSplit::of(cols, patched, predict.is_some()),
            predict,
            stats,
            ids: Vec::new(),
            rows: Vec::new(),
            raw_rows: Vec::new(),
            next: 0,
            prev: None,
            next_head: None,
        })
    }

    /// Whether the file stores patches.
    pub(crate) fn patched(&self) -> bool {
        self.patched
    }

    fn row(&self) -> usize {
        self.columns + if self.patched { 8 } else { 0 }
    }

    /// Reads and decodes the next block.
    fn refill(&mut self) -> Result<()> {
        // No row of the last block stays current: a block that fails to read leaves nothing
        // to return (its raw bytes are read over the last block's before they are checked).
        self.ids.clear();
        self.next = 0;
        let bad = |what: &str| Error::damaged_work(&self.path, &format!("result file {what}"));
        let head = match self.next_head.take() {
            Some(head) => head,
            None => {
                let mut head = [0u8; BLOCK_HEAD];
                read_exact(&mut self.file, &self.path, &mut head)?;
                head
            }
        };
        let word = |i: usize| u32::from_le_bytes(head[i..i + 4].try_into().unwrap_or([0; 4]));
        let [n, raw_len, frame_len, plain_len] = [0, 4, 8, 12].map(|i| word(i) as usize);
        let plain_planes = self.split.plain_count();
        if n == 0
            || n as u64 > self.remaining
            || raw_len > MAX_BLOCK
            || frame_len > MAX_BLOCK
            || plain_len > MAX_BLOCK
            || plain_len != self.split.plain_len(n)
        {
            return Err(bad("has a damaged block"));
        }
        // The raw bytes go straight into the block's buffer, kept from block to block (the
        // terrain numbers: most of a row's bytes, which a buffer of their own per block zeroed
        // and then copied). The next block's lengths come with this block's bytes, when the
        // count says there is a next block.
        let planes_len = n * plain_planes;
        let mut planes_frame = vec![0u8; planes_len + frame_len];
        self.raw_rows.resize(plain_len - planes_len, 0);
        let mut sum = [0u8; 8];
        let mut next_head = [0u8; BLOCK_HEAD];
        let next_len = if self.remaining > n as u64 {
            BLOCK_HEAD
        } else {
            0
        };
        let parts = [
            &mut self.raw_rows[..],
            &mut planes_frame[..],
            &mut sum[..],
            &mut next_head[..next_len],
        ];
        read_parts(&mut self.file, &self.path, parts)?;
        self.next_head = (next_len > 0).then_some(next_head);
        let (plain, frame) = planes_frame.split_at(planes_len);
        let mut summed = Checksum::new();
        summed.update(&self.raw_rows);
        summed.update(plain);
        let mut raw = Vec::new();
        if summed.finish().to_le_bytes() != sum || !decompress_into(frame, raw_len, &mut raw) {
            return Err(bad("has a damaged block"));
        }
        let mut c = Cursor::new(&raw);
        for _ in 0..n {
            let gap = c.varint().ok_or_else(|| bad("has damaged ids"))?;
            let id = match self.prev {
                None => Some(gap),
                Some(p) => p.checked_add(gap).and_then(|v| v.checked_add(1)),
            };
            let id = id.ok_or_else(|| bad("has damaged ids"))?;
            self.ids.push(id);
            self.prev = Some(id);
        }
        let width = self.split.packed();
        let framed = c.take(n * (width - plain_planes)).filter(|_| c.is_done());
        let framed = framed.ok_or_else(|| bad("has a damaged block"))?;
        // The planes back in their order, from the frame or the plain bytes.
        let (mut framed, mut plain) = (framed.chunks_exact(n), plain.chunks_exact(n));
        let mut planes = Vec::with_capacity(n * width);
        for &p in self.split.plain_planes() {
            let plane = if p { plain.next() } else { framed.next() };
            planes.extend_from_slice(plane.unwrap_or_default());
        }
        self.rows.clear();
        get_planes(&mut self.rows, &planes, n, width);
        if let Some(p) = &self.predict {
            let skip = self.row() - self.columns;
            self.rows
                .chunks_exact_mut(width)
                .for_each(|r| p.apply(&mut r[skip..]));
        }
        Ok(())
    }

    /// Reads the next record's id, with its patch (u64 LE, none if not stored) and column bytes
    /// in `record` ([`record_size`] bytes); None at the end.
    pub(crate) fn next(&mut self, record: &mut Vec<u8>) -> Result<Option<u64>> {
        record.clear();
        let id = self.advance()?;
        if id.is_some() {
            self.append_current(record);
        }
        Ok(id)
    }

    /// Moves to the next record and returns its id (None at the end); its bytes stay in the
    /// block for [`TileResults::append_current`], which a merge calls without copying them
    /// anywhere else first.
    pub(crate) fn advance(&mut self) -> Result<Option<u64>> {
        if self.remaining == 0 {
            return Ok(None);
        }
        if self.next == self.ids.len() {
            self.refill()?;
        }
        let id = self.ids[self.next];
        self.next += 1;
        self.remaining -= 1;
        Ok(Some(id))
    }

    /// Appends the record [`TileResults::advance`] last moved to (its patch, none if not
    /// stored, and its column bytes: [`record_size`] bytes) to `out`; nothing before the first.
    pub(crate) fn append_current(&self, out: &mut Vec<u8>) {
        let Some(i) = self.next.checked_sub(1) else {
            return;
        };
        let (width, raw) = (self.split.packed(), self.split.raw_width());
        if !self.patched {
            out.extend_from_slice(&GlobalPatch::NONE.0.to_le_bytes());
        }
        self.split
            .join(&self.rows[i * width..], &self.raw_rows[i * raw..], out);
    }

    /// Reads every record, checking that the file is whole: every block decodes with its
    /// checksum, the ids increase, and the file ends with the header's count.
    pub(crate) fn verify(mut self) -> Result<()> {
        let mut rec = Vec::new();
        while self.next(&mut rec)?.is_some() {}
        let mut rest = [0u8; 1];
        match self.file.read(&mut rest) {
            Ok(0) => Ok(()),
            Ok(_) => Err(Error::damaged_work(
                &self.path,
                "result file goes on past its records",
            )),
            Err(e) => Err(Error::read_work(&self.path, e)),
        }
    }
}

/// `read_exact` into each of `parts` in turn, with as few reads as the system allows; a short
/// file is damage (not an I/O failure).
fn read_parts<const N: usize>(file: &mut File, path: &Path, parts: [&mut [u8]; N]) -> Result<()> {
    let mut slices = parts.map(IoSliceMut::new);
    let mut left = &mut slices[..];
    IoSliceMut::advance_slices(&mut left, 0);
    while !left.is_empty() {
        match file.read_vectored(left) {
            Ok(0) => return Err(Error::damaged_work(path, "result file ends early")),
            Ok(k) => IoSliceMut::advance_slices(&mut left, k),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(Error::read_work(path, e)),
        }
    }
    Ok(())
}

/// `read_exact` into one buffer ([`read_parts`]).
fn read_exact(file: &mut File, path: &Path, buf: &mut [u8]) -> Result<()> {
    read_parts(file, path, [buf])
}

#[cfg(test)]
#[path = "file_tests.rs"]
mod tests;
