//! The layout of a result record: the stored values of a column set in their order and width
//! ([`ResultLayout`]), found once per file rather than per record. A record holds the numbers
//! but the terrain numbers, the curvature flags and the other flag bytes, then the terrain
//! numbers: last, so that a result file's row keeps them as one piece at its end
//! (io::workdir::results::rows), which is copied in one move each way.

use super::{TerrainValue, Value};
use crate::core::compute::{PointResult, NO_PATCH};
use crate::core::estimate::{Curvature, MAX_EXTRA};
use crate::core::terrain::TerrainValues;

/// The most values [`ColumnSet::stored`](super::ColumnSet::stored) lists: the normal (3), H, K, k1, k2, the two
/// directions (6), the extra values, the scale and its flags, the terrain values and flags.
pub(super) const MAX_STORED: usize = 3 + 4 + 6 + MAX_EXTRA + 2 + TerrainValue::ALL.len();

/// Runs `$body` with `$c` bound to `$v`, in one copy of `$body` for each value listed, where
/// `$c` is that value as a constant: with [`Value::get`] inlined, a loop over points in `$body`
/// reads its field directly instead of matching the value again for every point. A value not
/// listed (an extra value, ScaleK) shares one copy that matches it at run time.
macro_rules! by_value {
    ($v:expr, |$c:ident| $body:expr) => {
        by_value!(@each $v, |$c| $body; Value::H, Value::K, Value::K1, Value::K2,
            Value::Normal(0), Value::Normal(1), Value::Normal(2),
            Value::D1(0), Value::D1(1), Value::D1(2), Value::D2(0), Value::D2(1), Value::D2(2),
            Value::Terrain(TerrainValue::Profile), Value::Terrain(TerrainValue::Tangential),
            Value::Terrain(TerrainValue::Plan), Value::Terrain(TerrainValue::ShapeIndex),
            Value::Terrain(TerrainValue::Curvedness), Value::Terrain(TerrainValue::Slope),
            Value::Terrain(TerrainValue::Aspect))
    };
    (@each $v:expr, |$c:ident| $body:expr; $($k:expr),*) => {
        match $v {
            $(v if v == $k => {
                let $c = $k;
                $body
            })*
            other => {
                let $c = other;
                $body
            }
        }
    };
}

/// Writes `put` of value `v` of each of `results` at byte `at` of its record in `records`
/// (one every `stride` bytes). Inlined, so that a constant `v` selects its field once.
#[inline(always)]
fn column(
    results: &[PointResult],
    records: &mut [u8],
    (stride, at): (usize, usize),
    v: Value,
    put: impl Fn(f64, &mut [u8]),
) {
    for (r, rec) in results.iter().zip(records.chunks_exact_mut(stride)) {
        put(v.get(r), &mut rec[at..]);
    }
}

/// The seven terrain numbers in the order a record stores them when every terrain group is
/// written: [`TerrainValue::ALL`] but the flags, the order of [`TerrainValues::numbers`].
const TERRAIN_NUMBERS: [Value; 7] = {
    let mut v = [Value::H; 7];
    let mut i = 0;
    while i < v.len() {
        v[i] = Value::Terrain(TerrainValue::ALL[i]);
        i += 1;
    }
    v
};

/// The seven terrain numbers of each of `results` as f32, one after the other at byte `at` of
/// its record (one every `stride` bytes): in one loop, whose conversions the compiler does
/// four at a time, rather than a loop for each (the seven loops were a tenth of the terrain
/// columns' cost).
fn terrain_block(results: &[PointResult], records: &mut [u8], (stride, at): (usize, usize)) {
    for (r, rec) in results.iter().zip(records.chunks_exact_mut(stride)) {
        let values = r.terrain.numbers();
        if let Some(out) = rec.get_mut(at..at + 28) {
            for (b, v) in out.chunks_exact_mut(4).zip(values) {
                b.copy_from_slice(&(v as f32).to_le_bytes());
            }
        }
    }
}

/// The values of a result record in their order and their width ([`ColumnSet::layout`](super::ColumnSet::layout)):
/// found once rather than per record (the chain of optional groups was half the cost of a
/// decode). No allocation, so that it can be made for each piece of an output.
#[derive(Debug, Clone, Copy)]
pub struct ResultLayout {
    /// The numbers (`values[..numbers]`, the terrain numbers last), then the flag bytes after
    /// the curvature flags.
    pub(super) values: [Value; MAX_STORED],
    pub(super) numbers: usize,
    pub(super) len: usize,
    pub(super) width: usize,
    /// The numbers before the terrain numbers (all of them without terrain numbers).
    pub(super) lead: usize,
}

impl ResultLayout {
    /// Bytes of one record: the numbers, the curvature flags and the other flag bytes.
    pub fn size(&self) -> usize {
        self.width * self.numbers + self.flag_bytes()
    }

    /// The curvature flags and the other flag bytes.
    fn flag_bytes(&self) -> usize {
        1 + (self.len - self.numbers)
    }

    /// Where the curvature flags are in a record (the other flag bytes follow them).
    pub(super) fn flags_at(&self) -> usize {
        self.lead * self.width
    }

    /// Where the `i`-th stored number starts in a record: the numbers before the terrain
    /// numbers from the start, the terrain numbers after the flag bytes.
    pub(super) fn number_at(&self, i: usize) -> usize {
        match i.checked_sub(self.lead) {
            None => i * self.width,
            Some(j) => self.flags_at() + self.flag_bytes() + j * self.width,
        }
    }

    /// Where the stored number `v` starts in a record, if it is stored and not a flag byte
    /// (the result files' H prediction reads k1 and k2 there).
    pub fn offset(&self, v: Value) -> Option<usize> {
        (self.values[..self.numbers].iter())
            .position(|&s| s == v)
            .map(|i| self.number_at(i))
    }

    /// The stored numbers with where each starts in a record, and their width in bytes.
    pub fn numbers(&self) -> (impl Iterator<Item = (Value, usize)> + '_, usize) {
        let numbers = self.values[..self.numbers].iter().enumerate();
        (numbers.map(|(i, &v)| (v, self.number_at(i))), self.width)
    }

    /// Appends the stored values of one point to `out` ([`ResultLayout::encode_all`]).
    pub fn encode(&self, r: &PointResult, out: &mut Vec<u8>) {
        let start = out.len();
        out.resize(start + self.size(), 0);
        self.encode_all(std::slice::from_ref(r), &mut out[start..], self.size(), 0);
    }

    /// Writes the stored values of each of `results` into its record in `records`, one every
    /// `stride` bytes, `at` bytes into it: [`ResultLayout::size`] bytes, the numbers as f64
    /// or f32 little-endian and the flag bytes, at their places ([`ResultLayout::number_at`],
    /// [`ResultLayout::flags_at`]). Value by
    /// value, each in a loop made for it (`by_value`): point by point, choosing each value's
    /// field again for every point was a tenth of the cost of the terrain columns. Callers
    /// pass batches that stay in the cache (a loop a value walks the whole batch).
    pub fn encode_all(
        &self,
        results: &[PointResult],
        records: &mut [u8],
        stride: usize,
        at: usize,
    ) {
        let w = self.width;
        let terrain = self.values[..self.numbers]
            .windows(TERRAIN_NUMBERS.len())
            .position(|s| s == TERRAIN_NUMBERS)
            .filter(|_| w == 4);
        for (i, &v) in self.values[..self.numbers].iter().enumerate() {
            let place = (stride, at + self.number_at(i));
            match terrain.map(|first| i.wrapping_sub(first)) {
                Some(0) => {
                    terrain_block(results, records, place);
                    continue;
                }
                Some(j) if j < TERRAIN_NUMBERS.len() => continue,
                _ => {}
            }
            match w {
                8 => by_value!(v, |c| column(results, records, place, c, |x, b| b[..8]
                    .copy_from_slice(&x.to_le_bytes()))),
                _ => by_value!(v, |c| column(results, records, place, c, |x, b| b[..4]
                    .copy_from_slice(&(x as f32).to_le_bytes()))),
            }
        }
        let flags_at = at + self.flags_at();
        let byte = |x: f64, b: &mut [u8]| b[0] = x as u8;
        column(results, records, (stride, flags_at), Value::Flags, byte);
        for (j, &v) in self.values[self.numbers..self.len].iter().enumerate() {
            column(results, records, (stride, flags_at + 1 + j), v, byte);
        }
    }

    /// Decodes one point's stored values (as [`ResultLayout::encode`] wrote them) into a
    /// result with id 0 and no patch; values not stored are NaN (directions zero).
    pub fn decode(&self, rec: &[u8]) -> PointResult {
        let mut r = PointResult {
            id: 0,
            normal: [f64::NAN; 3],
            curvature: Curvature::undefined(0),
            extra: [f64::NAN; MAX_EXTRA],
            patch: NO_PATCH,
            scale: 0,
            scale_flags: 0,
            terrain: TerrainValues::NONE,
        };
        let w = self.width;
        for (i, v) in self.values[..self.numbers].iter().enumerate() {
            let at = self.number_at(i);
            let value = match rec.get(at..at + w) {
                Some(b) if w == 8 => b.try_into().map(f64::from_le_bytes).ok(),
                Some(b) => b.try_into().map(|b| f32::from_le_bytes(b) as f64).ok(),
                None => None,
            };
            v.set(&mut r, value.unwrap_or(f64::NAN));
        }
        let at = self.flags_at();
        r.curvature.flags = rec.get(at).copied().unwrap_or(0);
        for (v, b) in self.values[self.numbers..self.len].iter().zip(at + 1..) {
            v.set(&mut r, f64::from(rec.get(b).copied().unwrap_or(0)));
        }
        r
    }
}
