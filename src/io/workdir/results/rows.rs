//! How a result block keeps the bytes of its rows (io::workdir::results::file): a stored row is
//! the patch (u64 LE, if stored) then the columns of a [`ColumnSet`]. Its terrain numbers
//! (which end it) are kept as they are, row after row ([`RowSplit::raw`]); the other bytes (the
//! packed row) are cut into byte planes, each plane either in the zstd frame or among the plain
//! bytes beside it ([`RowSplit::plain`]).

use std::ops::Range;

use crate::io::columns::{ColumnSet, Value};

/// Where each byte of a stored row goes in a block.
#[derive(Debug, Clone)]
pub(super) struct RowSplit {
    /// The bytes of a row kept as they are (the terrain numbers; empty without them). Every
    /// one of them is a noisy mantissa or an exponent byte that varies from point to point:
    /// cutting them into planes and compressing their top bytes saved 6.5 bytes a point of the
    /// terrain columns' 29 and took most of their cost in a run (the planes both ways, zstd,
    /// three copies: about 600 instructions a point against 14,000 for a whole point).
    raw: Range<usize>,
    /// For each byte of a packed row (the row without `raw`), whether its plane is kept out
    /// of the frame: all but the top byte of every computed number, whose low mantissa bytes
    /// are noise that zstd stored at 96-100% of their size. Kept in the frame: the patch, the
    /// flag bytes, ScaleK (a small integer, whose low bytes are zero) and H where it is
    /// predicted (the prediction zeroes its low bytes for most points).
    plain: Vec<bool>,
}

impl RowSplit {
    /// The split of the rows of `cols` (with the patch when `patched`); `predicted`: H is
    /// stored exclusive-ored with its prediction.
    pub(super) fn of(cols: &ColumnSet, patched: bool, predicted: bool) -> Self {
        let skip = if patched { 8 } else { 0 };
        let layout = cols.layout();
        let (numbers, width) = layout.numbers();
        let mut raw = skip + layout.size()..skip + layout.size();
        let mut plain = vec![false; skip + layout.size()];
        for (v, at) in numbers {
            match v {
                // The terrain numbers end a row (they end a record: ResultLayout): one range,
                // whose end is the row's.
                Value::Terrain(_) => {
                    raw.start = raw.start.min(skip + at);
                    raw.end = skip + at + width;
                }
                Value::ScaleK => {}
                Value::H if predicted => {}
                _ => plain[skip + at..skip + at + width - 1].fill(true),
            }
        }
        if raw.is_empty() {
            raw = 0..0;
        }
        plain.drain(raw.clone());
        RowSplit { raw, plain }
    }

    /// Bytes of a packed row.
    pub(super) fn packed(&self) -> usize {
        self.plain.len()
    }

    /// Bytes of a row kept as they are.
    pub(super) fn raw_width(&self) -> usize {
        self.raw.len()
    }

    /// Where a packed row's bytes are kept ([`RowSplit::plain`]).
    pub(super) fn plain_planes(&self) -> &[bool] {
        &self.plain
    }

    /// How many planes are plain.
    pub(super) fn plain_count(&self) -> usize {
        self.plain.iter().filter(|&&p| p).count()
    }

    /// Plain bytes of a block of `n` rows: its plain planes, then its raw bytes.
    pub(super) fn plain_len(&self, n: usize) -> usize {
        n * (self.plain_count() + self.raw_width())
    }

    /// Appends the stored row at the start of `from` (which may go on past the row: the bytes
    /// after it let its pieces be copied as chunks of a fixed width, [`extend_short`]): its
    /// packed bytes (the row up to its raw bytes, which end it) to `packed`, its raw bytes to
    /// `raw`.
    pub(super) fn push(&self, from: &[u8], packed: &mut Vec<u8>, raw: &mut Vec<u8>) {
        extend_short(packed, from, 0..self.packed());
        if !self.raw.is_empty() {
            extend_short(raw, from, self.raw.clone());
        }
    }

    /// Appends to `out` the stored row of the packed row at the start of `packed` and the raw
    /// bytes at the start of `raw` (the inverse of [`RowSplit::push`]; either may go on past
    /// its row, as there).
    pub(super) fn join(&self, packed: &[u8], raw: &[u8], out: &mut Vec<u8>) {
        extend_short(out, packed, 0..self.packed());
        if !self.raw.is_empty() {
            extend_short(out, raw, 0..self.raw_width());
        }
    }
}

/// The longest piece [`extend_short`] copies as a chunk of fixed width.
const SHORT: usize = 64;

/// Appends `buf[range]` to `v`, as `v.extend_from_slice(&buf[range])` does. A range of at most
/// [`SHORT`] bytes with [`SHORT`] bytes of `buf` from its start is copied as one chunk of that
/// fixed width, which the compiler moves in a few vector instructions, and the excess cut off
/// again: the two pieces of a result row (the packed bytes and the terrain numbers) are copied
/// once per point each way, and a call to `memcpy` for each, with its dispatch on the length,
/// cost more than the bytes. The last pieces of a buffer take the call.
#[inline(always)]
fn extend_short(v: &mut Vec<u8>, buf: &[u8], range: Range<usize>) {
    let n = range.len();
    match buf.get(range.start..range.start + SHORT) {
        Some(chunk) if n <= SHORT => {
            let len = v.len();
            v.extend_from_slice(chunk);
            v.truncate(len + n);
        }
        _ => v.extend_from_slice(&buf[range]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::columns::ColumnChoice;

    #[test]
    fn short_extensions_append_exactly_the_range() {
        let buf: Vec<u8> = (1..=150).collect();
        for start in [0, 3, 70, 140] {
            for n in 0..=buf.len() - start {
                let mut v = vec![7u8; 5];
                extend_short(&mut v, &buf, start..start + n);
                let mut want = vec![7u8; 5];
                want.extend_from_slice(&buf[start..start + n]);
                assert_eq!(v, want, "{n} bytes from {start}");
            }
        }
    }

    fn set(list: &str, wide: bool) -> ColumnSet {
        ColumnSet {
            choice: ColumnChoice::parse(list).expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide,
        }
    }

    /// The terrain numbers are the raw bytes, at the offset the layout gives the first; the
    /// rest are planes, plain for all but the top byte of each number but a predicted H; a
    /// row goes through push and join unchanged.
    #[test]
    fn rows_split_at_the_terrain_numbers_and_join_again() {
        for (list, wide, patched) in [
            ("H,K,flags,terrain", false, false),
            ("normals,k1,k2,flags,slope,aspect", true, true),
            ("H,K,flags", false, true),
            ("terrain", false, false),
        ] {
            let cols = set(list, wide);
            let split = RowSplit::of(&cols, patched, false);
            let skip = if patched { 8 } else { 0 };
            let layout = cols.layout();
            let (numbers, width) = layout.numbers();
            let terrain: Vec<usize> = numbers
                .filter(|(v, _)| matches!(v, Value::Terrain(_)))
                .map(|(_, at)| at)
                .collect();
            assert_eq!(split.raw_width(), terrain.len() * width, "{list}");
            if let Some(&first) = terrain.first() {
                assert_eq!(split.raw.start, skip + first, "{list}");
            }
            let row = skip + cols.result_size();
            assert_eq!(split.packed() + split.raw_width(), row, "{list}");
            let others = layout.numbers().0.count() - terrain.len();
            assert_eq!(split.plain_count(), others * (width - 1), "{list}");
            let rows: Vec<u8> = (0..3 * row).map(|i| (i * 37 % 251) as u8).collect();
            let (mut packed, mut raw) = (Vec::new(), Vec::new());
            for r in rows.chunks_exact(row) {
                split.push(r, &mut packed, &mut raw);
            }
            assert_eq!(split.plain_len(3), 3 * split.plain_count() + raw.len());
            let mut back = Vec::new();
            let w = split.raw_width();
            for (i, p) in packed.chunks_exact(split.packed()).enumerate() {
                split.join(p, &raw[i * w..(i + 1) * w], &mut back);
            }
            assert_eq!(back, rows, "{list}");
        }
    }
}
