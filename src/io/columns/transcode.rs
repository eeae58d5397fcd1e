//! An output's columns straight from a result file's records ([`Transcoder`]): each column reads
//! its stored number or flag byte and is encoded as the output stores it, without building a
//! whole `PointResult` for every point (decoding every stored value and encoding from the
//! result was a twentieth of a run with the terrain columns). What the flip of `--orient propagate`
//! does to each column is read off
//! [`PointResult::flipped`](crate::core::compute::PointResult::flipped) once, not written down again here.

use super::output::{OutputColumns, Storage};
use super::ResultLayout;
use crate::core::estimate::{neg, ExtraColumn};

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
    /// Output bytes a point.
    size: usize,
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
            .map(|i| Slot::Number(i * width))
            .chain(
                (0..=layout.len - layout.numbers).map(|j| Slot::Byte(layout.numbers * width + j)),
            )
            .collect();
        let mut probe = Vec::with_capacity(layout.size());
        for i in 0..layout.numbers {
            let v = (i + 2) as f64;
            match width {
                8 => probe.extend_from_slice(&v.to_le_bytes()),
                _ => probe.extend_from_slice(&(v as f32).to_le_bytes()),
            }
        }
        probe.extend((layout.numbers..slots.len()).map(|i| (i + 2) as u8));
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
            flags_at: layout.numbers * width,
            size: out.record_size(),
        }
    }

    /// Appends the output columns of the stored record `rec` (flipped if `flip`) to `out`;
    /// returns its curvature flags.
    pub(crate) fn encode(&self, rec: &[u8], flip: bool, out: &mut Vec<u8>) -> u8 {
        let start = out.len();
        out.resize(start + self.size, 0);
        let mut at = start;
        for r in &self.reads {
            let (slot, negate) = match flip {
                true => r.flipped,
                false => (r.slot, false),
            };
            let v = self.value(rec, slot);
            at += r
                .storage
                .put(if negate { neg(v) } else { v }, &mut out[at..]);
        }
        rec.get(self.flags_at).copied().unwrap_or(0)
    }

    /// The value in `slot` of `rec`, where the record is too short NaN (a number) or 0 (a
    /// byte), as [`ResultLayout::decode`] reads it.
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
                for _ in 0..400 {
                    let mut rec = Vec::new();
                    for _ in 0..layout.numbers {
                        let v = value(&mut rng);
                        match layout.width {
                            8 => rec.extend_from_slice(&v.to_le_bytes()),
                            _ => rec.extend_from_slice(&(v as f32).to_le_bytes()),
                        }
                    }
                    rec.extend((layout.numbers..=layout.len).map(|_| rng.below(256) as u8));
                    let flip = rng.below(2) == 1;
                    let decoded = layout.decode(&rec);
                    let want_flags = decoded.curvature.flags;
                    let result = match flip {
                        true => decoded.flipped(&set.extra),
                        false => decoded,
                    };
                    let mut want = vec![9u8; 3];
                    out.encode(&result, &mut want);
                    let mut got = vec![9u8; 3];
                    assert_eq!(t.encode(&rec, flip, &mut got), want_flags);
                    assert_eq!(got, want, "{set:?} {encoding:?} flip {flip}");
                    flips += flip as usize;
                }
            }
        }
        assert!(flips > 2000, "{flips} flipped records");
    }
}
