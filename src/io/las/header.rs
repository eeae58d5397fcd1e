//! The LAS public header block: parsing with validation against the file size, and patching for
//! the output. The original header bytes are kept so that every field we do not change (GUID,
//! system identifier, dates, return counts, bounds) is written back untouched.

use std::path::Path;

use super::fields::padded;
use crate::error::{Error, Result};

/// Size in bytes of the fixed part of each point data record format 0 to 10.
pub const POINT_FORMAT_SIZES: [u16; 11] = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];

/// How LAS records store coordinates: x = X scale\[0\] + offset\[0\] for the record's integer X, and
/// so on for y and z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantisation {
    /// The scale factor of each axis.
    pub scale: [f64; 3],
    /// The offset of each axis.
    pub offset: [f64; 3],
}

/// The fields of a LAS header that tilecurv reads, plus the raw bytes it was parsed from.
#[derive(Debug, Clone)]
pub struct LasHeader {
    /// Version (major, minor), e.g. (1, 4).
    pub version: (u8, u8),
    /// Global encoding bits (bit 4: CRS is WKT).
    pub global_encoding: u16,
    /// Size of the header block in bytes.
    pub header_size: u16,
    /// Byte offset of the first point record.
    pub offset_to_point_data: u32,
    /// Number of VLRs between the header and the points.
    pub num_vlrs: u32,
    /// Point data record format (0 to 10), without the LAZ bits.
    pub point_format: u8,
    /// Whether the point data is LAZ-compressed (bit 7 of the stored format id).
    pub compressed: bool,
    /// Bytes per point record, extra bytes included.
    pub record_length: u16,
    /// Number of point records (the 64-bit count for LAS 1.4 when set).
    pub point_count: u64,
    /// Coordinate scale factors.
    pub scale: [f64; 3],
    /// Coordinate offsets.
    pub offset: [f64; 3],
    /// Minimum x, y, z as stored in the header (not trusted for planning).
    pub min: [f64; 3],
    /// Maximum x, y, z as stored in the header.
    pub max: [f64; 3],
    /// Start of waveform data packet record (LAS 1.3+), 0 if none.
    pub waveform_start: u64,
    /// Start of the first EVLR (LAS 1.4), 0 if none.
    pub evlr_start: u64,
    /// Number of EVLRs (LAS 1.4).
    pub evlr_count: u32,
    /// The original header bytes (`header_size` of them).
    pub raw: Vec<u8>,
}

fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn u64_at(b: &[u8], o: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[o..o + 8]);
    u64::from_le_bytes(a)
}
fn f64_at(b: &[u8], o: usize) -> f64 {
    f64::from_bits(u64_at(b, o))
}

/// The version (major, minor) after the signature, checked to be a LAS 1.0 to 1.4 header of at
/// least 227 bytes; `bad` makes the error at a byte offset.
fn signature_and_version(bytes: &[u8], bad: &dyn Fn(usize, String) -> Error) -> Result<(u8, u8)> {
    if bytes.len() < 227 && bytes.starts_with(b"LASF") {
        return Err(bad(0, format!("the file is only {} bytes, shorter than the 227 of a LAS header alone: it is truncated (re-copy it)", bytes.len())));
    }
    if bytes.len() < 227 || &bytes[0..4] != b"LASF" {
        let got = if bytes.len() >= 4 {
            format!("{:?}", String::from_utf8_lossy(&bytes[0..4]))
        } else {
            format!("{} bytes", bytes.len())
        };
        return Err(bad(0, format!("not a LAS/LAZ file: expected the signature \"LASF\" and a header of at least 227 bytes, found {got}")));
    }
    let version = (bytes[24], bytes[25]);
    if version.0 != 1 || version.1 > 4 {
        return Err(bad(
            24,
            format!(
                "unsupported LAS version {}.{}; tilecurv reads LAS 1.0 to 1.4",
                version.0, version.1
            ),
        ));
    }
    Ok(version)
}

/// The coordinate scale factors and offsets, checked to be finite (and the scales non-zero);
/// `bad` makes the error at a byte offset.
fn scale_and_offset(bytes: &[u8], bad: &dyn Fn(usize, String) -> Error) -> Result<Quantisation> {
    let scale = [f64_at(bytes, 131), f64_at(bytes, 139), f64_at(bytes, 147)];
    let offset = [f64_at(bytes, 155), f64_at(bytes, 163), f64_at(bytes, 171)];
    for (i, s) in scale.iter().enumerate() {
        if !(s.is_finite() && *s != 0.0) {
            return Err(bad(
                131 + 8 * i,
                format!(
                    "{} scale factor is {s}; it must be finite and non-zero",
                    ["x", "y", "z"][i]
                ),
            ));
        }
        if !offset[i].is_finite() {
            return Err(bad(
                155 + 8 * i,
                format!(
                    "{} offset is {}; it must be finite",
                    ["x", "y", "z"][i],
                    offset[i]
                ),
            ));
        }
    }
    Ok(Quantisation { scale, offset })
}

impl LasHeader {
    /// Parses and validates the header at the start of `bytes` (the whole file or at least its
    /// first 375 bytes), checking it against `file_len`.
    pub fn parse(path: &Path, bytes: &[u8], file_len: u64) -> Result<Self> {
        let bad = |off: usize, what: String| Error::bad_input(path, Some(off as u64), what);
        if file_len == 0 {
            return Err(Error::bad_input(
                path,
                None,
                "the file is empty (0 bytes); expected a LAS or LAZ file",
            ));
        }
        let version = signature_and_version(bytes, &bad)?;
        let header_size = u16_at(bytes, 94);
        let min_header = match version.1 {
            0..=2 => 227,
            3 => 235,
            _ => 375,
        };
        if (header_size as usize) < min_header {
            return Err(bad(94, format!("header size {header_size} is smaller than the {min_header} bytes LAS 1.{} requires", version.1)));
        }
        if header_size as u64 > file_len || header_size as usize > bytes.len() {
            return Err(bad(94, format!("header size {header_size} is larger than the file ({file_len} bytes): the file is truncated")));
        }
        let offset_to_point_data = u32_at(bytes, 96);
        if offset_to_point_data < header_size as u32 {
            return Err(bad(96, format!("offset to point data {offset_to_point_data} lies inside the {header_size}-byte header")));
        }
        if offset_to_point_data as u64 > file_len {
            return Err(bad(96, format!("offset to point data {offset_to_point_data} is past the end of the file ({file_len} bytes): the file is truncated")));
        }
        let raw_format = bytes[104];
        let compressed = raw_format & 0x80 != 0;
        let point_format = raw_format & 0x3f;
        if point_format > 10 {
            return Err(bad(
                104,
                format!(
                    "unknown point data record format {point_format}; LAS defines formats 0 to 10"
                ),
            ));
        }
        let record_length = u16_at(bytes, 105);
        let base = POINT_FORMAT_SIZES[point_format as usize];
        if record_length < base {
            return Err(bad(105, format!("point record length {record_length} is shorter than the {base} bytes of point format {point_format}")));
        }
        let legacy_count = u32_at(bytes, 107) as u64;
        let Quantisation { scale, offset } = scale_and_offset(bytes, &bad)?;
        let max = [f64_at(bytes, 179), f64_at(bytes, 195), f64_at(bytes, 211)];
        let min = [f64_at(bytes, 187), f64_at(bytes, 203), f64_at(bytes, 219)];
        let waveform_start = if version.1 >= 3 {
            u64_at(bytes, 227)
        } else {
            0
        };
        let (evlr_start, evlr_count, point_count) = if version.1 >= 4 {
            let c64 = u64_at(bytes, 247);
            // The 64-bit count rules (LAS 1.4 2.4), as laspy and PDAL read it; a legacy count
            // alone (a writer that filled only it) is read rather than no points.
            let count = if c64 != 0 { c64 } else { legacy_count };
            (u64_at(bytes, 235), u32_at(bytes, 243), count)
        } else {
            (0, 0, legacy_count)
        };
        if evlr_count > 0 && (evlr_start < offset_to_point_data as u64 || evlr_start > file_len) {
            return Err(bad(235, format!("start of first EVLR {evlr_start} is outside the file's data area ({offset_to_point_data}..{file_len})")));
        }
        Ok(LasHeader {
            version,
            global_encoding: u16_at(bytes, 6),
            header_size,
            offset_to_point_data,
            num_vlrs: u32_at(bytes, 100),
            point_format,
            compressed,
            record_length,
            point_count,
            scale,
            offset,
            min,
            max,
            waveform_start,
            evlr_start,
            evlr_count,
            raw: bytes[..header_size as usize].to_vec(),
        })
    }

    /// A LAS 1.4 header's two point counts, (32-bit, 64-bit), when they disagree (the 32-bit
    /// one is not 0 and not the 64-bit one): [`LasHeader::point_count`] is the 64-bit one, or
    /// the 32-bit one when the 64-bit one is 0.
    pub fn disagreeing_counts(&self) -> Option<(u64, u64)> {
        if self.version.1 < 4 {
            return None;
        }
        let (legacy, c64) = (u32_at(&self.raw, 107) as u64, u64_at(&self.raw, 247));
        (legacy != 0 && legacy != c64).then_some((legacy, c64))
    }

    /// The whole records of `record_length` bytes the point data of a file of `file_len` bytes
    /// has room for (an uncompressed file's, whatever the header counts).
    pub fn whole_records(&self, file_len: u64, record_length: usize) -> u64 {
        let data = self.point_data_end(file_len);
        data.saturating_sub(self.offset_to_point_data as u64) / record_length.max(1) as u64
    }

    /// Number of extra bytes per record beyond the point format's fixed fields.
    pub fn extra_bytes_len(&self) -> u16 {
        self.record_length - POINT_FORMAT_SIZES[self.point_format as usize]
    }

    /// The end of the point data region: the first EVLR or the waveform block if either follows
    /// the points, else the file length.
    pub fn point_data_end(&self, file_len: u64) -> u64 {
        let mut end = file_len;
        if self.evlr_count > 0 && self.evlr_start >= self.offset_to_point_data as u64 {
            end = end.min(self.evlr_start);
        }
        if self.waveform_start >= self.offset_to_point_data as u64 && self.waveform_start > 0 {
            end = end.min(self.waveform_start);
        }
        end
    }

    /// Replaces the bounds (for a file whose bounds are known only once its points are written).
    pub fn set_bounds(&mut self, min: [f64; 3], max: [f64; 3]) {
        self.min = min;
        self.max = max;
        put_bounds(&mut self.raw, min, max);
    }

    /// The header bytes for an output file: the original bytes with the layout fields replaced.
    pub fn patched(&self, out: &OutputLayout) -> Vec<u8> {
        let mut b = self.raw.clone();
        b[96..100].copy_from_slice(&out.offset_to_point_data.to_le_bytes());
        b[100..104].copy_from_slice(&out.num_vlrs.to_le_bytes());
        b[104] = self.point_format | if out.compressed { 0x80 } else { 0 };
        b[105..107].copy_from_slice(&out.record_length.to_le_bytes());
        // The counts of the records written, whatever the input's header said of them: the
        // 32-bit count where it fits and the format allows it (0 to 5: LAS 1.4 2.4), 0 where
        // not; LAS 1.4's 64-bit count.
        let legacy = match u32::try_from(self.point_count) {
            Ok(n) if self.point_format <= 5 => n,
            _ => 0,
        };
        b[107..111].copy_from_slice(&legacy.to_le_bytes());
        if self.version.1 >= 3 {
            // Waveform data inside the file moves with the data before it; an external one (0 or
            // "in an auxiliary file" bit) keeps its value.
            let wf = if self.waveform_start > 0 {
                out.waveform_start
            } else {
                0
            };
            b[227..235].copy_from_slice(&wf.to_le_bytes());
        }
        if self.version.1 >= 4 {
            b[235..243].copy_from_slice(&out.evlr_start.to_le_bytes());
            b[243..247].copy_from_slice(&out.evlr_count.to_le_bytes());
            b[247..255].copy_from_slice(&self.point_count.to_le_bytes());
        }
        b
    }
}

/// Writes max and min x, y, z at their places in a header (bytes 179 to 227, interleaved).
fn put_bounds(h: &mut [u8], min: [f64; 3], max: [f64; 3]) {
    for a in 0..3 {
        h[179 + 16 * a..187 + 16 * a].copy_from_slice(&max[a].to_le_bytes());
        h[187 + 16 * a..195 + 16 * a].copy_from_slice(&min[a].to_le_bytes());
    }
}

/// Layout fields that change between the input header and the output header.
#[derive(Debug, Clone, Copy)]
pub struct OutputLayout {
    /// Byte offset of the first point record in the output.
    pub offset_to_point_data: u32,
    /// Number of VLRs in the output.
    pub num_vlrs: u32,
    /// Whether the output points are LAZ-compressed.
    pub compressed: bool,
    /// Output bytes per point record.
    pub record_length: u16,
    /// Start of the first EVLR in the output (LAS 1.4), 0 if none.
    pub evlr_start: u64,
    /// Number of EVLRs in the output.
    pub evlr_count: u32,
    /// Start of the waveform data in the output (LAS 1.3+), 0 if none.
    pub waveform_start: u64,
}

/// The fields of a header written from scratch (generated or converted clouds). The layout
/// fields (offset to the points, VLR and EVLR counts) start as "no VLRs"; callers set them, or
/// pass the header through [`LasHeader::patched`].
#[derive(Debug, Clone)]
pub struct NewHeader<'a> {
    /// Minor version: 2 (227-byte header) or 4 (375 bytes, 64-bit counts).
    pub minor: u8,
    /// System identifier (32 bytes at most).
    pub system: &'a str,
    /// Generating software (32 bytes at most).
    pub software: &'a str,
    /// Point data record format.
    pub point_format: u8,
    /// Bytes per record, extra bytes included.
    pub record_length: u16,
    /// Number of points; every point counts as a first return.
    pub points: u64,
    /// Coordinate scale factors.
    pub scale: [f64; 3],
    /// Coordinate offsets.
    pub offset: [f64; 3],
    /// Minimum x, y, z.
    pub min: [f64; 3],
    /// Maximum x, y, z.
    pub max: [f64; 3],
}

impl NewHeader<'_> {
    /// The header bytes. Legacy 32-bit counts are set when the count fits (LAS 1.4 section 2.4
    /// allows them for formats 0 to 5); LAS 1.4 also gets the 64-bit counts.
    pub fn bytes(&self) -> Vec<u8> {
        let size: u16 = if self.minor >= 4 { 375 } else { 227 };
        let mut h = vec![0u8; size as usize];
        h[0..4].copy_from_slice(b"LASF");
        h[24] = 1;
        h[25] = self.minor;
        h[26..58].copy_from_slice(&padded::<32>(self.system));
        h[58..90].copy_from_slice(&padded::<32>(self.software));
        h[94..96].copy_from_slice(&size.to_le_bytes());
        h[96..100].copy_from_slice(&(size as u32).to_le_bytes());
        h[104] = self.point_format;
        h[105..107].copy_from_slice(&self.record_length.to_le_bytes());
        if let Ok(n) = u32::try_from(self.points) {
            h[107..111].copy_from_slice(&n.to_le_bytes());
            h[111..115].copy_from_slice(&n.to_le_bytes());
        }
        for a in 0..3 {
            h[131 + 8 * a..139 + 8 * a].copy_from_slice(&self.scale[a].to_le_bytes());
            h[155 + 8 * a..163 + 8 * a].copy_from_slice(&self.offset[a].to_le_bytes());
        }
        put_bounds(&mut h, self.min, self.max);
        if self.minor >= 4 {
            h[247..255].copy_from_slice(&self.points.to_le_bytes());
            h[255..263].copy_from_slice(&self.points.to_le_bytes());
        }
        h
    }
}
