//! Variable-length records (VLRs, between header and points) and extended VLRs (EVLRs, after the
//! points): reading them with bounds checks and writing them back byte for byte.

use std::path::Path;

use super::fields::{padded, trimmed};
use super::header::LasHeader;
use crate::error::{Error, Result};

/// One VLR or EVLR, with its payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Vlr {
    /// The 16-byte user id, NUL padding trimmed.
    pub user_id: String,
    /// The record id.
    pub record_id: u16,
    /// The raw 32-byte description field.
    pub description: [u8; 32],
    /// The reserved field as stored.
    pub reserved: u16,
    /// The payload.
    pub data: Vec<u8>,
}

/// Points per LAZ chunk in the files we write (LASzip's default).
pub const LAZ_CHUNK_POINTS: u32 = 50_000;

/// A LASzip layout and the VLR that describes it ([`laszip`]).
pub struct Laszip {
    /// The layout, for the compressor.
    pub layout: laz::LazVlr,
    /// Its "laszip encoded" VLR, to be written among the file's VLRs.
    pub vlr: Vlr,
}

/// The LASzip layout of `point_format` records followed by `extra` bytes, in fixed chunks of
/// [`LAZ_CHUNK_POINTS`], and the "laszip encoded" VLR that describes it.
pub fn laszip(point_format: u8, extra: u16) -> Result<Laszip> {
    let lv = laz::LazVlrBuilder::default()
        .with_point_format(point_format, extra)
        .map_err(|e| {
            Error::Internal(format!(
                "no LAZ layout for point format {point_format}: {e}"
            ))
        })?
        .with_fixed_chunk_size(LAZ_CHUNK_POINTS)
        .build();
    let mut data = Vec::new();
    lv.write_to(&mut data)
        .map_err(|e| Error::Internal(format!("LASzip VLR: {e}")))?;
    let vlr = Vlr::new("laszip encoded", 22204, "http://laszip.org", data);
    Ok(Laszip { layout: lv, vlr })
}

impl Vlr {
    /// A new record with the given identity and payload.
    pub fn new(user_id: &str, record_id: u16, description: &str, data: Vec<u8>) -> Self {
        Vlr {
            user_id: user_id.to_string(),
            record_id,
            description: padded::<32>(description),
            reserved: 0,
            data,
        }
    }

    /// Whether this record is `(user_id, record_id)`.
    pub fn is(&self, user_id: &str, record_id: u16) -> bool {
        self.user_id == user_id && self.record_id == record_id
    }

    /// Appends this record as a VLR to `out`. Fails if the payload does not fit a u16 length.
    pub fn write_vlr(&self, out: &mut Vec<u8>) -> std::result::Result<(), String> {
        let len = u16::try_from(self.data.len()).map_err(|_| {
            format!(
                "VLR {}:{} has {} bytes, more than a VLR can hold (65535)",
                self.user_id,
                self.record_id,
                self.data.len()
            )
        })?;
        out.extend_from_slice(&self.reserved.to_le_bytes());
        out.extend_from_slice(&padded::<16>(&self.user_id));
        out.extend_from_slice(&self.record_id.to_le_bytes());
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&self.description);
        out.extend_from_slice(&self.data);
        Ok(())
    }

    /// Appends this record as an EVLR to `out`.
    pub fn write_evlr(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.reserved.to_le_bytes());
        out.extend_from_slice(&padded::<16>(&self.user_id));
        out.extend_from_slice(&self.record_id.to_le_bytes());
        out.extend_from_slice(&(self.data.len() as u64).to_le_bytes());
        out.extend_from_slice(&self.description);
        out.extend_from_slice(&self.data);
    }
}

/// Reads the header's VLRs from the file bytes that precede the point data.
pub fn read_vlrs(path: &Path, head: &[u8], header: &LasHeader) -> Result<Vec<Vlr>> {
    let mut pos = header.header_size as usize;
    let end = header.offset_to_point_data as usize;
    // The count comes from the file: never allocate for more records than the bytes before the
    // point data can hold (a count of 2^32-1 would abort on allocation).
    let fit = end.saturating_sub(pos) / 54;
    if header.num_vlrs as usize > fit {
        return Err(Error::bad_input(path, Some(100), format!(
            "the header declares {} VLRs but the {} bytes between the header and the point data (byte {end}) hold at most {fit}; the header's VLR count or point-data offset is wrong",
            header.num_vlrs, end.saturating_sub(pos))));
    }
    let mut out = Vec::with_capacity(header.num_vlrs as usize);
    for i in 0..header.num_vlrs {
        if pos + 54 > end || pos + 54 > head.len() {
            return Err(Error::bad_input(path, Some(pos as u64), format!(
                "VLR {} of {} starts at byte {pos} but its 54-byte header runs past the start of the point data ({end}); the header's VLR count or point-data offset is wrong",
                i + 1, header.num_vlrs)));
        }
        let h = &head[pos..pos + 54];
        let len = u16::from_le_bytes([h[20], h[21]]) as usize;
        let data_start = pos + 54;
        if data_start + len > end || data_start + len > head.len() {
            return Err(Error::bad_input(path, Some(pos as u64), format!(
                "VLR {} of {} ({}) declares {len} bytes of data, which run past the start of the point data at byte {end}",
                i + 1, header.num_vlrs, trimmed(&h[2..18]))));
        }
        let mut description = [0u8; 32];
        description.copy_from_slice(&h[22..54]);
        out.push(Vlr {
            user_id: trimmed(&h[2..18]),
            record_id: u16::from_le_bytes([h[18], h[19]]),
            description,
            reserved: u16::from_le_bytes([h[0], h[1]]),
            data: head[data_start..data_start + len].to_vec(),
        });
        pos = data_start + len;
    }
    Ok(out)
}

/// Reads the EVLRs (LAS 1.4, or the LAS 1.3 waveform record) from the whole-file bytes.
/// Returns each record with the byte offset it was found at.
pub fn read_evlrs(path: &Path, file: &[u8], header: &LasHeader) -> Result<Vec<(u64, Vlr)>> {
    let (start, count, field) = if header.evlr_count > 0 {
        (header.evlr_start, header.evlr_count, 235)
    } else if header.version.1 == 3 && header.waveform_start > 0 {
        (header.waveform_start, 1, 227)
    } else {
        return Ok(Vec::new());
    };
    // Offsets and counts come from the file: check them against its size, in u64, before any
    // allocation or addition (a start near 2^64 would overflow, a count of 2^32-1 would abort).
    let len = file.len() as u64;
    let fit = len.saturating_sub(start) / 60;
    if start > len || count as u64 > fit {
        let what = if field == 235 {
            "EVLR"
        } else {
            "waveform data packet record (EVLR)"
        };
        return Err(Error::bad_input(path, Some(field), format!(
            "the header declares {count} {what}s from byte {start}, but the file has {len} bytes, room for {fit} from there; the file is truncated or its header is corrupt")));
    }
    let mut pos = start as usize;
    let mut out = Vec::with_capacity(count as usize);
    for i in 0..count {
        if pos + 60 > file.len() {
            return Err(Error::bad_input(path, Some(pos as u64), format!(
                "EVLR {} of {count} starts at byte {pos} but the file ends at {}: the file is truncated", i + 1, file.len())));
        }
        let h = &file[pos..pos + 60];
        let mut l = [0u8; 8];
        l.copy_from_slice(&h[20..28]);
        let len = u64::from_le_bytes(l);
        let data_start = pos + 60;
        if (data_start as u64)
            .checked_add(len)
            .is_none_or(|e| e > file.len() as u64)
        {
            return Err(Error::bad_input(path, Some(pos as u64), format!(
                "EVLR {} of {count} ({}) declares {len} bytes of data past the end of the file ({} bytes): the file is truncated",
                i + 1, trimmed(&h[2..18]), file.len())));
        }
        let len = len as usize;
        let mut description = [0u8; 32];
        description.copy_from_slice(&h[28..60]);
        out.push((
            pos as u64,
            Vlr {
                user_id: trimmed(&h[2..18]),
                record_id: u16::from_le_bytes([h[18], h[19]]),
                description,
                reserved: u16::from_le_bytes([h[0], h[1]]),
                data: file[data_start..data_start + len].to_vec(),
            },
        ));
        pos = data_start + len;
    }
    Ok(out)
}

/// A file's VLRs, then its EVLRs (each with its file offset), as one sequence of records: the
/// order in which readers meet them.
pub fn records<'a>(
    vlrs: &'a [Vlr],
    evlrs: &'a [(u64, Vlr)],
) -> impl Iterator<Item = &'a Vlr> + Clone {
    vlrs.iter().chain(evlrs.iter().map(|(_, v)| v))
}
