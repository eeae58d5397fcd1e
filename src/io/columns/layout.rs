//! The layout of a result record: the stored values of a column set in their order and width
//! ([`ResultLayout`]), found once per file rather than per record.

use super::{TerrainValue, Value};
use crate::core::compute::{PointResult, NO_PATCH};
use crate::core::estimate::{Curvature, MAX_EXTRA};
use crate::core::terrain::TerrainValues;

/// The most values [`ColumnSet::stored`] lists: the normal (3), H, K, k1, k2, the two
/// directions (6), the extra values, the scale and its flags, the terrain values and flags.
pub(super) const MAX_STORED: usize = 3 + 4 + 6 + MAX_EXTRA + 2 + TerrainValue::ALL.len();

/// The values of a result record in their order and their width ([`ColumnSet::layout`]):
/// found once rather than per record (the chain of optional groups was half the cost of a
/// decode). No allocation, so that it can be made for each piece of an output.
#[derive(Debug, Clone, Copy)]
pub struct ResultLayout {
    /// The numbers (`values[..numbers]`), then the flag bytes after the curvature flags.
    pub(super) values: [Value; MAX_STORED],
    pub(super) numbers: usize,
    pub(super) len: usize,
    pub(super) width: usize,
}

impl ResultLayout {
    /// Bytes of one record: the numbers, the curvature flags and the other flag bytes.
    pub fn size(&self) -> usize {
        self.width * self.numbers + 1 + (self.len - self.numbers)
    }

    /// Where the stored number `v` starts in a record, if it is stored and not a flag byte
    /// (the result files' H prediction reads k1 and k2 there).
    pub fn offset(&self, v: Value) -> Option<usize> {
        (self.values[..self.numbers].iter())
            .position(|&s| s == v)
            .map(|i| i * self.width)
    }

    /// The stored numbers with where each starts in a record, and their width in bytes.
    pub fn numbers(&self) -> (impl Iterator<Item = (Value, usize)> + '_, usize) {
        let w = self.width;
        let numbers = self.values[..self.numbers].iter().enumerate();
        (numbers.map(move |(i, &v)| (v, i * w)), w)
    }

    /// Appends the stored values of one point to `out` ([`ResultLayout::encode_into`]).
    pub fn encode(&self, r: &PointResult, out: &mut Vec<u8>) {
        let start = out.len();
        out.resize(start + self.size(), 0);
        self.encode_into(r, &mut out[start..]);
    }

    /// Writes the stored values of one point into `rec`, [`ResultLayout::size`] bytes (the
    /// numbers as f64 or f32 little-endian, then the curvature flags and the other flag bytes;
    /// a caller encoding many points makes the layout once: walking the chain of optional
    /// groups for every value of every point cost 5% of a run with the terrain columns).
    pub fn encode_into(&self, r: &PointResult, rec: &mut [u8]) {
        let (numbers, flags) = rec.split_at_mut(self.width * self.numbers);
        match self.width {
            8 => (numbers.chunks_exact_mut(8).zip(&self.values))
                .for_each(|(b, v)| b.copy_from_slice(&v.get(r).to_le_bytes())),
            _ => (numbers.chunks_exact_mut(4).zip(&self.values))
                .for_each(|(b, v)| b.copy_from_slice(&(v.get(r) as f32).to_le_bytes())),
        }
        flags[0] = r.curvature.flags;
        for (b, v) in flags[1..]
            .iter_mut()
            .zip(&self.values[self.numbers..self.len])
        {
            *b = v.get(r) as u8;
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
        let (mut at, w) = (0, self.width);
        for v in &self.values[..self.numbers] {
            let value = match rec.get(at..at + w) {
                Some(b) if w == 8 => b.try_into().map(f64::from_le_bytes).ok(),
                Some(b) => b.try_into().map(|b| f32::from_le_bytes(b) as f64).ok(),
                None => None,
            };
            v.set(&mut r, value.unwrap_or(f64::NAN));
            at += w;
        }
        r.curvature.flags = rec.get(at).copied().unwrap_or(0);
        for (v, b) in self.values[self.numbers..self.len].iter().zip(at + 1..) {
            v.set(&mut r, f64::from(rec.get(b).copied().unwrap_or(0)));
        }
        r
    }
}
