//! An output's columns straight from a result file's records ([`Transcoder`]): each column reads
//! its stored number or flag byte and is encoded as the output stores it, without building a
//! whole `PointResult` for every point (decoding every stored value and encoding from the
//! result was a twentieth of a run with the terrain columns). What the flip of `--orient propagate`
//! does to each column is read off
//! [`PointResult::flipped`](crate::core::compute::PointResult::flipped) once, not written down again here.

use super::output::{scaled_raw, OutputColumns, Storage};
use super::ResultLayout;
use crate::core::estimate::{neg, ExtraColumn};
use crate::io::las::extra_bytes::ScalarType;

/// Where one column's value is in a stored record.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    /// A number (f32 or f64) starting at this byte.
    Number(usize),
    /// A flag byte at this offset.
    Byte(usize),
    /// Not stored: NaN, as [`ResultLayout::decode`] reads it.
    Missing,
}

/// The stored records a [`Transcoder`] writes the output columns of, one for each output
/// record.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Stored<'a> {
    /// Records of `size` bytes one after the other, their columns `at` bytes into each, none
    /// written flipped (every point of a piece has a result and no patch flips: the common
    /// case, whose loops then test neither).
    Run {
        bytes: &'a [u8],
        size: usize,
        at: usize,
    },
    /// Each output record's stored columns and whether they are written flipped; None: no
    /// result, nothing written.
    Each(&'a [Option<(&'a [u8], bool)>]),
}

impl<'a> Stored<'a> {
    /// How many records.
    fn len(&self) -> usize {
        match *self {
            Stored::Run { bytes, size, .. } => bytes.len() / size.max(1),
            Stored::Each(list) => list.len(),
        }
    }

    /// Records `range` of these.
    fn slice(&self, range: std::ops::Range<usize>) -> Stored<'a> {
        match *self {
            Stored::Run { bytes, size, at } => Stored::Run {
                bytes: &bytes[range.start * size..range.end * size],
                size,
                at,
            },
            Stored::Each(list) => Stored::Each(&list[range]),
        }
    }
}

/// Records a [`Transcoder`] writes a column of before the next column: with their output
/// records (about 120 bytes a point with the terrain columns) well within a first-level cache.
const BATCH: usize = 128;

/// How one output column is read from a stored record.
#[derive(Debug, Clone, Copy)]
struct Read {
    /// Its value as stored.
    slot: Slot,
    /// Its value in a flipped record, and whether it is negated there.
    flipped: (Slot, bool),
    storage: Storage,
}

/// The output columns of stored records of one [`ResultLayout`]: what
/// `out.encode(&layout.decode(rec))` (or of the result flipped) writes, to the bit.
#[derive(Debug, Clone)]
pub(crate) struct Transcoder {
    reads: Vec<Read>,
    /// f64 numbers (else f32).
    wide: bool,
    /// Offset of the curvature flags.
    flags_at: usize,
}

impl Transcoder {
    /// The transcoder from records of `layout` to the columns of `out`; `extra` are the
    /// estimator's extra columns (which of them a flip negates).
    pub(crate) fn new(layout: &ResultLayout, out: &OutputColumns, extra: &[ExtraColumn]) -> Self {
        // A record whose every stored value is its own small number (2, 3, ...): the value a
        // column reads from the decoded result, or from it flipped, names the slot it comes
        // from, and its sign says whether the flip negates it. Flag bytes and ScaleK hold these
        // small integers exactly; 0 and 1 are left out so that no probe is a default.
        let width = layout.width;
        let slots: Vec<Slot> = (0..layout.numbers)
            .map(|i| Slot::Number(layout.number_at(i)))
            .chain((0..=layout.len - layout.numbers).map(|j| Slot::Byte(layout.flags_at() + j)))
            .collect();
        let mut probe = vec![0u8; layout.size()];
        for (i, slot) in slots.iter().enumerate() {
            let v = (i + 2) as f64;
            match *slot {
                Slot::Number(at) if width == 8 => {
                    probe[at..at + 8].copy_from_slice(&v.to_le_bytes());
                }
                Slot::Number(at) => probe[at..at + 4].copy_from_slice(&(v as f32).to_le_bytes()),
                Slot::Byte(at) => probe[at] = (i + 2) as u8,
                Slot::Missing => {}
            }
        }
        let plain = layout.decode(&probe);
        let flipped = plain.flipped(extra);
        let slot_of = |v: f64| {
            let i = v.abs() as usize;
            match v.is_finite() && i >= 2 && (i - 2) < slots.len() {
                true => (slots[i - 2], v < 0.0),
                false => (Slot::Missing, false),
            }
        };
        let reads = (out.columns.iter())
            .map(|(c, storage)| Read {
                slot: slot_of(c.value.get(&plain)).0,
                flipped: slot_of(c.value.get(&flipped)),
                storage: *storage,
            })
            .collect();
        Transcoder {
            reads,
            wide: width == 8,
            flags_at: layout.flags_at(),
        }
    }

    /// The curvature flags of the stored record `rec` (0 where it is too short, as
    /// [`ResultLayout::decode`] reads it).
    pub(crate) fn flags(&self, rec: &[u8]) -> u8 {
        rec.get(self.flags_at).copied().unwrap_or(0)
    }

    /// Writes the output columns of each stored record of `stored` into its output record in
    /// `out`, one every `stride` bytes, the columns `at` bytes into it. Column by column, each
    /// with a loop made for its stored type and its storage: record by record, choosing them
    /// again for every value was most of the cost of writing the columns (about 50
    /// instructions a value; the terrain columns' eight values took 3% of a run).
    /// Batches of [`BATCH`] records stay in the first-level cache while each column's loop
    /// walks them (a whole piece did not: a miss for every record read and written in every
    /// column's loop, half again the instructions' time).
    pub(crate) fn encode_all(&self, stored: Stored<'_>, out: &mut [u8], stride: usize, at: usize) {
        let n = stored.len();
        for start in (0..n).step_by(BATCH) {
            let end = (start + BATCH).min(n);
            let rows = out
                .get_mut(start * stride..end * stride)
                .unwrap_or_default();
            self.encode_batch(stored.slice(start..end), rows, stride, at);
        }
    }

    /// [`Transcoder::encode_all`] of one batch.
    fn encode_batch(&self, stored: Stored<'_>, out: &mut [u8], stride: usize, at: usize) {
        let mut o = at;
        for r in &self.reads {
            // A scaled number of unflipped narrow records: its loop of its own, vectorised.
            let run = (stored, r.slot, r.storage);
            if let (
                Stored::Run {
                    bytes,
                    size,
                    at: from,
                },
                Slot::Number(a),
                Storage::Scaled(ty, s),
            ) = run
            {
                if !self.wide {
                    scaled_run((bytes, size, from + a), (ty, s), out, (stride, o));
                    o += r.storage.size();
                    continue;
                }
            }
            // The storage fixed in each loop: `put` of a known storage compiles to its arm.
            match r.storage {
                Storage::Scaled(ScalarType::I32, s) => {
                    self.column(r, stored, out, (stride, o), |v, b| {
                        Storage::Scaled(ScalarType::I32, s).put(v, b)
                    })
                }
                Storage::Scaled(ScalarType::I16, s) => {
                    self.column(r, stored, out, (stride, o), |v, b| {
                        Storage::Scaled(ScalarType::I16, s).put(v, b)
                    })
                }
                Storage::Float(ScalarType::F32) => {
                    self.column(r, stored, out, (stride, o), |v, b| {
                        Storage::Float(ScalarType::F32).put(v, b)
                    })
                }
                Storage::Unsigned(ScalarType::U8) => {
                    self.column(r, stored, out, (stride, o), |v, b| {
                        Storage::Unsigned(ScalarType::U8).put(v, b)
                    })
                }
                other => self.column(r, stored, out, (stride, o), |v, b| other.put(v, b)),
            }
            o += r.storage.size();
        }
    }

    /// One output column (read `r`) of every stored record, written by `write` at byte `o`
    /// of each output record (one every `stride` bytes).
    fn column(
        &self,
        r: &Read,
        stored: Stored<'_>,
        out: &mut [u8],
        (stride, o): (usize, usize),
        write: impl Fn(f64, &mut [u8]) -> usize,
    ) {
        // `write` of `read` of each stored record: a loop of its own for each reader (and for
        // a run of records, one without the flip or the option).
        fn each(
            stored: Stored<'_>,
            out: &mut [u8],
            (stride, o): (usize, usize),
            read: impl Fn(&[u8], bool) -> f64,
            write: impl Fn(f64, &mut [u8]) -> usize,
        ) {
            match stored {
                Stored::Run { bytes, size, at } => {
                    for (cols, rec) in bytes.chunks_exact(size).zip(out.chunks_exact_mut(stride)) {
                        write(read(&cols[at..], false), &mut rec[o..]);
                    }
                }
                Stored::Each(stored) => {
                    for (s, rec) in stored.iter().zip(out.chunks_exact_mut(stride)) {
                        if let Some((cols, flip)) = *s {
                            write(read(cols, flip), &mut rec[o..]);
                        }
                    }
                }
            }
        }
        let negate = r.flipped.1;
        let pick = |a: usize, b: usize, flip: bool| if flip { b } else { a };
        let signed = |v: f64, flip: bool| if flip && negate { neg(v) } else { v };
        let place = (stride, o);
        // A stored value and its flipped one are of one kind (a number, or a flag byte): the
        // kind fixed in each loop, `value` of a known kind compiles to its arm.
        match (r.slot, r.flipped.0) {
            (Slot::Number(a), Slot::Number(b)) => {
                let read = |cols: &[u8], flip| {
                    signed(self.value(cols, Slot::Number(pick(a, b, flip))), flip)
                };
                each(stored, out, place, read, write)
            }
            (Slot::Byte(a), Slot::Byte(b)) => {
                let read = |cols: &[u8], flip| {
                    signed(self.value(cols, Slot::Byte(pick(a, b, flip))), flip)
                };
                each(stored, out, place, read, write)
            }
            (plain, flipped) => {
                let read = |cols: &[u8], flip| {
                    signed(self.value(cols, if flip { flipped } else { plain }), flip)
                };
                each(stored, out, place, read, write)
            }
        }
    }

    /// The value in `slot` of `rec`, where the record is too short NaN (a number) or 0 (a
    /// byte), as [`ResultLayout::decode`] reads it.
    #[inline(always)]
    fn value(&self, rec: &[u8], slot: Slot) -> f64 {
        let bytes = |at: usize, n: usize| rec.get(at..at + n);
        let v = match slot {
            Slot::Number(at) if self.wide => {
                bytes(at, 8).and_then(|b| b.try_into().ok().map(f64::from_le_bytes))
            }
            Slot::Number(at) => {
                bytes(at, 4).and_then(|b| b.try_into().ok().map(|b| f32::from_le_bytes(b) as f64))
            }
            Slot::Byte(at) => Some(rec.get(at).map_or(0.0, |&b| f64::from(b))),
            Slot::Missing => None,
        };
        v.unwrap_or(f64::NAN)
    }
}

/// One scaled column of a batch (at most [`BATCH`] records) of narrow records one after the
/// other (none flipped: the common case): the f32 at byte `at` of each `size`-byte record in `bytes` as the integer
/// [`Storage::put`] writes for `ty` at `scale`, at byte `o` of its output record (one every
/// `stride` bytes of `out`). The values are gathered first, so that the loop making the
/// integers has nothing else in it and compiles to vector instructions (four at a time): a
/// value at a time, the division, rounding and clamping were most of writing a column.
fn scaled_run(
    (bytes, size, at): (&[u8], usize, usize),
    (ty, scale): (ScalarType, f64),
    out: &mut [u8],
    (stride, o): (usize, usize),
) {
    let mut values = [0f32; BATCH];
    let mut raw = [0i32; BATCH];
    let n = (values.iter_mut().zip(bytes.chunks_exact(size.max(1))))
        .map(|(v, rec)| {
            let b = rec.get(at..at + 4).and_then(|b| b.try_into().ok());
            *v = b.map_or(f32::NAN, f32::from_le_bytes);
        })
        .count();
    for (r, &v) in raw.iter_mut().zip(&values[..n]) {
        *r = scaled_raw(v as f64, scale, ty);
    }
    let recs = out.chunks_exact_mut(stride).zip(&raw[..n]);
    match ty {
        ScalarType::I16 => recs.for_each(|(rec, &r)| {
            if let Some(b) = rec.get_mut(o..o + 2) {
                b.copy_from_slice(&(r as i16).to_le_bytes());
            }
        }),
        _ => recs.for_each(|(rec, &r)| {
            if let Some(b) = rec.get_mut(o..o + 4) {
                b.copy_from_slice(&r.to_le_bytes());
            }
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::Rng;
    use crate::io::columns::output::{Encoding, Steps};
    use crate::io::columns::tests::vcm_columns;
    use crate::io::columns::{ColumnChoice, ColumnSet, Group};

    /// A stored value of every kind an encoding treats apart: ordinary, tiny, huge (clamped),
    /// negative, signed zeros, NaN, and for flag bytes any byte.
    fn value(rng: &mut Rng) -> f64 {
        match rng.below(8) {
            0 => f64::NAN,
            1 => 0.0,
            2 => -0.0,
            3 => (rng.uniform() - 0.5) * 1e12,
            4 => (rng.uniform() - 0.5) * 1e-9,
            5 => rng.below(70_000) as f64,
            _ => rng.normal(),
        }
    }

    /// For every column group with and without the flip, narrow and wide records, and every
    /// encoding: the transcoder writes what decoding the record to a result (flipped as
    /// `--orient propagate` flips it) and encoding that writes, to the bit, and returns the
    /// record's curvature flags.
    #[test]
    fn transcoding_writes_what_the_decoded_result_encodes() {
        let steps = Steps {
            h: 1.0 / 1024.0,
            k: 1.0 / 65536.0,
            principal: 1.0 / 2048.0,
        };
        let terrain = |list: &str, wide| ColumnSet {
            choice: ColumnChoice::parse(list).expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide,
        };
        let all = ColumnSet {
            choice: vcm_columns().choice.with(Group::Scale),
            ..vcm_columns()
        };
        let sets = [
            all.clone(),
            ColumnSet { wide: false, ..all },
            terrain("H,K,flags", false),
            terrain("k2,flags,terrain", false),
            terrain("normals,slope,aspect", true),
        ];
        let mut rng = Rng::new(7);
        let mut flips = 0;
        for set in &sets {
            let layout = set.layout();
            for encoding in [Encoding::Scaled(steps), Encoding::F32, Encoding::F64] {
                let out = OutputColumns::new(set, encoding);
                let t = Transcoder::new(&layout, &out, &set.extra);
                let mut batch = Vec::new();
                for _ in 0..400 {
                    // Each number at its place, the flag bytes random.
                    let mut rec: Vec<u8> =
                        (0..layout.size()).map(|_| rng.below(256) as u8).collect();
                    for i in 0..layout.numbers {
                        let (v, at) = (value(&mut rng), layout.number_at(i));
                        match layout.width {
                            8 => rec[at..at + 8].copy_from_slice(&v.to_le_bytes()),
                            _ => rec[at..at + 4].copy_from_slice(&(v as f32).to_le_bytes()),
                        }
                    }
                    let flip = rng.below(2) == 1;
                    let decoded = layout.decode(&rec);
                    let want_flags = decoded.curvature.flags;
                    let result = match flip {
                        true => decoded.flipped(&set.extra),
                        false => decoded,
                    };
                    let mut want = vec![9u8; 3];
                    out.encode(&result, &mut want);
                    let mut got = vec![9u8; 3 + out.record_size()];
                    let one = [Some((&rec[..], flip))];
                    t.encode_all(Stored::Each(&one), &mut got, 3 + out.record_size(), 3);
                    assert_eq!(t.flags(&rec), want_flags);
                    assert_eq!(got, want, "{set:?} {encoding:?} flip {flip}");
                    flips += flip as usize;
                    batch.push((rec, flip, want));
                }
                // All at once, with records without a result among them left as they were.
                let row = 3 + out.record_size();
                let stored: Vec<Option<(&[u8], bool)>> = (batch.iter())
                    .flat_map(|(rec, flip, _)| [Some((&rec[..], *flip)), None])
                    .collect();
                let mut all = vec![7u8; row * stored.len()];
                t.encode_all(Stored::Each(&stored), &mut all, row, 3);
                // The unflipped records one after the other, behind two bytes each.
                let unflipped: Vec<&(Vec<u8>, bool, Vec<u8>)> =
                    batch.iter().filter(|(_, flip, _)| !flip).collect();
                let size = 2 + layout.size();
                let bytes: Vec<u8> = (unflipped.iter())
                    .flat_map(|(rec, _, _)| [&[5u8, 6][..], &rec[..]].concat())
                    .collect();
                let mut run = vec![7u8; row * unflipped.len()];
                let stored = Stored::Run {
                    bytes: &bytes,
                    size,
                    at: 2,
                };
                t.encode_all(stored, &mut run, row, 3);
                for ((_, _, want), got) in unflipped.iter().zip(run.chunks_exact(row)) {
                    assert_eq!(got[3..], want[3..], "{set:?} {encoding:?} run");
                    assert_eq!(got[..3], [7; 3]);
                }
                for (i, (_, _, want)) in batch.iter().enumerate() {
                    let (got, skipped) = all[2 * i * row..].split_at(row);
                    assert_eq!(got[3..], want[3..], "{set:?} {encoding:?} record {i}");
                    assert_eq!(got[..3], [7; 3]);
                    assert!(skipped[..row].iter().all(|&b| b == 7));
                }
            }
        }
        assert!(flips > 2000, "{flips} flipped records");
    }
}
