//! Dropping extra dimensions from LAS point records ([`Trim`]): the byte ranges of a record
//! that are kept, and the descriptors of the kept dimensions exactly as the file wrote them
//! (raw, so that names, descriptions, scales and no-data values survive byte for byte). A
//! re-run drops the previous run's columns this way before anything reads the records. Knows
//! records and descriptors, not why a dimension goes.

use std::ops::Range;

use super::extra_bytes::{parse, DESCRIPTOR_SIZE};

/// The extra dimensions dropped from every record of a file, and what is left.
#[derive(Debug, Clone, PartialEq)]
pub struct Trim {
    /// The byte ranges of a stored record that are kept, in order, none adjacent.
    keep: Vec<Range<usize>>,
    /// Bytes per record as stored in the file.
    stored: usize,
    /// Bytes per record once trimmed.
    kept: usize,
    /// The merged extra-bytes payload describing the kept extra bytes (the file's descriptors
    /// of the kept dimensions, unchanged and in order).
    pub payload: Vec<u8>,
}

impl Trim {
    /// Drops every extra dimension whose name is in `names` (any case) from records of
    /// `stored` bytes whose first `base` bytes are the point format's and whose extra bytes
    /// `payload` describes from their first byte (a file's merged extra-bytes payload; bytes it
    /// leaves undescribed at the end are kept). None when no dimension is named; an error
    /// message when the payload does not describe the records.
    pub fn new(
        base: usize,
        stored: usize,
        payload: &[u8],
        names: &[String],
    ) -> Result<Option<Trim>, String> {
        let dims = parse(payload)?;
        let dropped = |name: &str| names.iter().any(|n| n.eq_ignore_ascii_case(name));
        if !dims.iter().any(|d| dropped(&d.name)) {
            return Ok(None);
        }
        let described: usize = dims.iter().map(|d| d.size).sum();
        if base + described > stored {
            return Err(format!(
                "the extra-bytes descriptors describe {described} bytes per point but the records have {}",
                stored.saturating_sub(base)
            ));
        }
        let mut keep: Vec<Range<usize>> = Vec::new();
        let mut add = |r: Range<usize>| match keep.last_mut() {
            Some(last) if last.end == r.start => last.end = r.end,
            _ if r.is_empty() => {}
            _ => keep.push(r),
        };
        add(0..base);
        let mut kept_payload = Vec::with_capacity(payload.len());
        for (d, raw) in dims.iter().zip(payload.chunks_exact(DESCRIPTOR_SIZE)) {
            if !dropped(&d.name) {
                add(base + d.offset..base + d.offset + d.size);
                kept_payload.extend_from_slice(raw);
            }
        }
        add(base + described..stored);
        let kept = keep.iter().map(|r| r.len()).sum();
        Ok(Some(Trim {
            keep,
            stored,
            kept,
            payload: kept_payload,
        }))
    }

    /// Bytes per record as stored in the file.
    pub fn stored_length(&self) -> usize {
        self.stored
    }

    /// Bytes per trimmed record.
    pub fn record_length(&self) -> usize {
        self.kept
    }

    /// Puts the trimmed form of every whole stored record of `records` into `out` (cleared
    /// first): the caller owns the buffer, so that no chunk allocates once it has grown.
    pub fn apply(&self, records: &[u8], out: &mut Vec<u8>) {
        out.clear();
        out.reserve(records.len() / self.stored.max(1) * self.kept);
        for r in records.chunks_exact(self.stored) {
            for k in &self.keep {
                out.extend_from_slice(&r[k.clone()]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::las::extra_bytes::{encode, NewColumn, ScalarType};

    /// Dimensions in the middle and at the end go (any case), the others keep their bytes and
    /// their descriptors byte for byte, and undescribed trailing bytes stay last.
    #[test]
    fn dropped_dimensions_leave_the_others_byte_for_byte() {
        let d = |name: &str, ty| encode(&NewColumn::plain(name, ty, "kept as is")).to_vec();
        let (a, h, b, k) = (
            d("A", ScalarType::U16),
            d("H", ScalarType::I32),
            d("B", ScalarType::U8),
            d("K", ScalarType::F32),
        );
        let payload = [a.clone(), h, b.clone(), k].concat();
        // 4 base bytes, A (2), H (4), B (1), K (4), 2 undescribed bytes: 17 bytes.
        let rec: Vec<u8> = (0..17).collect();
        let records = [rec.clone(), rec.iter().map(|v| v + 100).collect()].concat();
        let names = ["h".to_string(), "K".to_string()];
        let t = Trim::new(4, 17, &payload, &names)
            .expect("valid")
            .expect("drops");
        assert_eq!((t.stored_length(), t.record_length()), (17, 9));
        assert_eq!(t.payload, [a, b].concat());
        let mut out = vec![9; 3];
        t.apply(&records, &mut out);
        let want = [0, 1, 2, 3, 4, 5, 10, 15, 16];
        assert_eq!(out, [&want[..], &want.map(|v| v + 100)[..]].concat());
        assert_eq!(Trim::new(4, 17, &payload, &["C".to_string()]), Ok(None));
        assert!(Trim::new(4, 12, &payload, &names).is_err());
    }
}
