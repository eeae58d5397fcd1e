//! LAS and LAZ input: a file opened once, memory-mapped, validated against its size, and
//! streamed in file order as chunks of raw point records. Uncompressed LAS is decoded straight from
//! the map; LAZ is decompressed chunk by chunk (in parallel over LAZ chunks). The raw records are
//! what `assemble` copies to the output untouched, unless extra dimensions were dropped
//! ([`LasSource::drop_extra`]: a re-run drops the previous run's columns), in which case every
//! reader of the source sees the trimmed records, header and descriptors only.

mod compressed;
mod properties;

use properties::las_properties;

use std::fs::File;
use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::core::grid::AxisGrid;
use crate::core::tasks::Cuts;
use crate::error::{Error, Result};
use crate::io::crs::{horizontal_unit, UnitSource};
use crate::io::las::chunks::{chunk_of, read_chunk_table, Chunk, ChunkAt};
use crate::io::las::extra_bytes::{self, Descriptor};
use crate::io::las::header::{LasHeader, Quantisation, POINT_FORMAT_SIZES};
use crate::io::las::parts::LasParts;
use crate::io::las::trim::Trim;
use crate::io::las::vlr::{self, read_evlrs, read_vlrs, Vlr};

use super::{InputBytes, PointSource, Property, SourceLayout, SourcePoint};

/// An opened LAS or LAZ file.
pub struct LasSource {
    path: PathBuf,
    map: InputBytes,
    /// The parsed header (its record length the trimmed records' after [`LasSource::drop_extra`]).
    pub header: LasHeader,
    /// The VLRs, in file order.
    pub vlrs: Vec<Vlr>,
    /// The EVLRs with their original byte offsets.
    pub evlrs: Vec<(u64, Vlr)>,
    /// Extra-bytes descriptors of the input (empty if none).
    pub extra: Vec<Descriptor>,
    /// The extra dimensions dropped from every record, if any.
    trim: Option<Trim>,
    normal_dims: Option<[Descriptor; 3]>,
    laz: Option<laz::LazVlr>,
    /// The checked LAZ chunk table (empty for LAS).
    chunks: Vec<Chunk>,
    /// How x, y and z come from the stored integers (offset-independent, [`AxisGrid`]).
    grid: [AxisGrid; 3],
}

impl LasSource {
    /// Opens, maps and validates a LAS/LAZ file. Nothing is decoded yet.
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::read_input(path, e))?;
        let len = file
            .metadata()
            .map_err(|e| Error::read_input(path, e))?
            .len();
        if len == 0 {
            return Err(Error::bad_input(
                path,
                None,
                "the file is empty (0 bytes); expected a LAS or LAZ file",
            ));
        }
        // SAFETY: the map is read-only and tilecurv never writes its inputs. Another process
        // truncating the file while we run would fault; that is the usual mmap contract, and the
        // CLI documents that inputs must not change during a run.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::read_input(path, e))?;
        Self::from_bytes(path, InputBytes::Map(map))
    }

    /// Validates a LAS/LAZ file already read or mapped; `path` names it in errors.
    pub fn from_bytes(path: &Path, map: InputBytes) -> Result<Self> {
        let len = map.len() as u64;
        if len == 0 {
            return Err(Error::bad_input(
                path,
                None,
                "the file is empty (0 bytes); expected a LAS or LAZ file",
            ));
        }
        let header = LasHeader::parse(path, &map, len)?;
        let vlrs = read_vlrs(path, &map, &header)?;
        let evlrs = read_evlrs(path, &map, &header)?;
        let extra = extra_descriptors(path, &header, &vlrs, &evlrs)?;
        let normal_dims = normal_dims(&extra);
        let (laz, chunks) = if header.compressed {
            let lv = laz_layout(path, &header, &vlrs)?;
            let chunks = read_chunk_table(path, &map, &header, &lv)?;
            (Some(lv), chunks)
        } else {
            check_size(path, &header, len)?;
            (None, Vec::new())
        };
        if header.point_count == 0 {
            return Err(Error::bad_input(
                path,
                Some(107),
                "the file contains no points; there is nothing to compute",
            ));
        }
        let grid = [0, 1, 2].map(|a| AxisGrid::new(header.scale[a], header.offset[a], 1.0));
        Ok(LasSource {
            grid,
            path: path.to_path_buf(),
            map,
            header,
            vlrs,
            evlrs,
            extra,
            trim: None,
            normal_dims,
            laz,
            chunks,
        })
    }

    /// Drops the extra dimensions named in `names` (any case) from every record this source
    /// streams: its header, extra-bytes records and descriptors then describe the records
    /// without them (the first extra-bytes record holds the kept descriptors, unchanged, and
    /// the others are gone), so that a writer carries the rest over as it would a file
    /// without them, and NormalX/Y/Z among them are no longer the file's normals. Returns
    /// whether anything was dropped. Once per source.
    pub fn drop_extra(&mut self, names: &[String]) -> Result<bool> {
        if self.trim.is_some() {
            return Err(Error::Internal(format!(
                "{}: extra dimensions dropped twice",
                self.path.display()
            )));
        }
        let bad = |why: String| Error::bad_input(&self.path, None, why);
        let records = vlr::records(&self.vlrs, &self.evlrs);
        let payload = extra_bytes::merged_payload(records).map_err(bad)?;
        let base = POINT_FORMAT_SIZES[self.header.point_format as usize] as usize;
        let stored = self.stored_length();
        let Some(trim) = Trim::new(base, stored, &payload, names).map_err(bad)? else {
            return Ok(false);
        };
        let extra = extra_bytes::parse(&trim.payload).map_err(bad)?;
        let mut first = true;
        let mut put = |v: &mut Vlr| {
            if !extra_bytes::is_extra_bytes(v) {
                return true;
            }
            if std::mem::take(&mut first) {
                v.data = trim.payload.clone();
                return true;
            }
            false
        };
        self.vlrs.retain_mut(|v| put(v));
        self.evlrs.retain_mut(|(_, v)| put(v));
        let length = trim.record_length() as u16;
        self.header.record_length = length;
        self.header.raw[105..107].copy_from_slice(&length.to_le_bytes());
        self.normal_dims = normal_dims(&extra);
        self.extra = extra;
        self.trim = Some(trim);
        Ok(true)
    }

    /// Bytes per record as the file stores them.
    fn stored_length(&self) -> usize {
        self.trim
            .as_ref()
            .map_or(self.header.record_length as usize, Trim::stored_length)
    }

    /// The coordinates of a raw record (stored or trimmed: the point format's fields stay).
    fn xyz(&self, rec: &[u8]) -> [f64; 3] {
        // The three integers from one 12-byte array: one bounds check, not twelve.
        let head: [u8; 12] = rec[..12].try_into().unwrap_or([0; 12]);
        let c = |a: usize| {
            i32::from_le_bytes([
                head[4 * a],
                head[4 * a + 1],
                head[4 * a + 2],
                head[4 * a + 3],
            ])
        };
        [0, 1, 2].map(|a| self.grid[a].value(i64::from(c(a))))
    }
}

impl LasSource {
    /// Refuses decoded LAZ records far outside the header's bounds (by more than the bounds'
    /// largest extent): a corrupt chunk decodes into garbage spread over the whole coordinate
    /// range, which would plan millions of tiles. The error names the chunk and its offset.
    /// Bounds that were never filled (all zero, or min above max) are not checked.
    fn check_decoded(&self, first: u64, records: &[u8]) -> Result<()> {
        let h = &self.header;
        let filled = (0..3)
            .all(|a| h.min[a] <= h.max[a] && h.min[a].is_finite() && h.max[a].is_finite())
            && h.min.iter().chain(&h.max).any(|&v| v != 0.0);
        if !filled {
            return Ok(());
        }
        let extent = (0..3).map(|a| h.max[a] - h.min[a]).fold(0.0, f64::max);
        let step = h.scale.iter().fold(0.0, |m: f64, s| m.max(s.abs()));
        let margin = extent.max(1000.0 * step);
        for (i, rec) in records.chunks_exact(self.stored_length()).enumerate() {
            let p = self.xyz(rec);
            if let Some(a) =
                (0..3).find(|&a| !(p[a] >= h.min[a] - margin && p[a] <= h.max[a] + margin))
            {
                let id = first + i as u64;
                let ChunkAt { index: c, chunk } = chunk_of(&self.chunks, id).unwrap_or_default();
                return Err(Error::bad_input(&self.path, Some(chunk.offset), format!(
                    "LAZ chunk {c} (at the byte offset given) decodes point {id} at {} = {:e}, far outside the header's bounds {:e}..{:e}: the chunk is corrupt",
                    ["x", "y", "z"][a], p[a], h.min[a], h.max[a])));
            }
        }
        Ok(())
    }

    /// The header, VLRs, EVLRs and extra-bytes descriptors, for a writer that carries them over.
    pub fn parts(&self) -> LasParts<'_> {
        LasParts {
            path: &self.path,
            header: &self.header,
            vlrs: &self.vlrs,
            evlrs: &self.evlrs,
            extra: &self.extra,
        }
    }

    /// Drops the mapped pages between `from` and `to` (rounded down to a page) from memory;
    /// returns the new release mark. Only hints the kernel: the data stays readable.
    fn release(&self, from: usize, to: usize) -> usize {
        let to = page_below(to);
        let Some(map) = self.map.mapped() else {
            return from;
        };
        if to > from {
            // SAFETY: the map is a private read-only file mapping; MADV_DONTNEED on it only
            // drops cached pages, which the kernel re-reads from the file if touched again.
            let _ = unsafe {
                map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, from, to - from)
            };
            to
        } else {
            from
        }
    }
}

/// The start of the memory page holding byte `at` of the map (madvise takes whole pages).
fn page_below(at: usize) -> usize {
    const PAGE: usize = 4096;
    at / PAGE * PAGE
}

/// The extra-bytes descriptors of a file (from every extra-bytes VLR and EVLR, in file order),
/// checked against the records' extra bytes.
fn extra_descriptors(
    path: &Path,
    header: &LasHeader,
    vlrs: &[Vlr],
    evlrs: &[(u64, Vlr)],
) -> Result<Vec<Descriptor>> {
    let bad = |why: String| {
        Error::bad_input(
            path,
            None,
            format!("{why}; fix or remove the extra-bytes VLR"),
        )
    };
    let data = extra_bytes::merged_payload(vlr::records(vlrs, evlrs)).map_err(bad)?;
    let extra = extra_bytes::parse(&data).map_err(bad)?;
    let total: usize = extra.iter().map(|d| d.size).sum();
    if total > header.extra_bytes_len() as usize {
        return Err(Error::bad_input(path, Some(105), format!(
            "the extra-bytes VLR describes {total} bytes per point but the records have only {} extra bytes",
            header.extra_bytes_len())));
    }
    Ok(extra)
}

/// The scalar extra dimensions NormalX, NormalY, NormalZ (any case), when all three exist.
fn normal_dims(extra: &[Descriptor]) -> Option<[Descriptor; 3]> {
    let find = |n: &str| {
        extra
            .iter()
            .find(|d| d.name.eq_ignore_ascii_case(n) && d.scalar().is_some())
            .cloned()
    };
    match (find("NormalX"), find("NormalY"), find("NormalZ")) {
        (Some(x), Some(y), Some(z)) => Some([x, y, z]),
        _ => None,
    }
}

/// The LASzip layout of a LAZ file, checked against the header's record length.
fn laz_layout(path: &Path, header: &LasHeader, vlrs: &[Vlr]) -> Result<laz::LazVlr> {
    let v = vlrs.iter().find(|v| v.is("laszip encoded", 22204)).ok_or_else(|| Error::bad_input(path, Some(104),
        "the point format says LAZ-compressed but there is no LASzip VLR (\"laszip encoded\", 22204)"))?;
    let read = |data: &[u8]| {
        laz::LazVlr::from_buffer(data).map_err(|e| {
            Error::bad_input(path, None, format!("the LASzip VLR cannot be read: {e}"))
        })
    };
    let mut lv = read(&v.data)?;
    // A fixed chunk size beyond the point count means one chunk of all the points. The codec
    // reserves a buffer of the chunk size (a fuzz finding: 2^32-2, a 4 GiB allocation), so it
    // is given the point count instead, which decodes the same points.
    let n = header.point_count.max(1);
    if !lv.uses_variable_size_chunks() && lv.chunk_size() as u64 > n && v.data.len() >= 16 {
        let mut data = v.data.clone();
        data[12..16].copy_from_slice(&(n.min(u32::MAX as u64 - 1) as u32).to_le_bytes());
        lv = read(&data)?;
    }
    if lv.items_size() != header.record_length as u64 {
        return Err(Error::bad_input(
            path,
            Some(105),
            format!(
                "the LASzip VLR describes {}-byte points but the header says {}",
                lv.items_size(),
                header.record_length
            ),
        ));
    }
    Ok(lv)
}

/// Checks that an uncompressed file holds the header's points.
fn check_size(path: &Path, header: &LasHeader, len: u64) -> Result<()> {
    let need = (header.point_count)
        .checked_mul(header.record_length as u64)
        .and_then(|b| b.checked_add(header.offset_to_point_data as u64));
    let end = header.point_data_end(len);
    if need.is_none_or(|n| n > end) {
        let whole = header.whole_records(len, header.record_length as usize);
        return Err(Error::bad_input(path, Some(header.offset_to_point_data as u64), format!(
            "the header says {} points of {} bytes, but the point data ends at byte {end}: only {whole} whole points are present. The file is truncated (re-copy it) or its point count is wrong",
            header.point_count, header.record_length)));
    }
    Ok(())
}

impl PointSource for LasSource {
    /// The file's path.
    fn path(&self) -> &Path {
        &self.path
    }

    /// Number of points.
    fn len(&self) -> u64 {
        self.header.point_count
    }

    /// Point counts that disagree, and whole records past the count (uncompressed points,
    /// whose records can be counted from their bytes).
    fn warnings(&self) -> Vec<String> {
        let h = &self.header;
        let mut v = Vec::new();
        if let Some((legacy, c64)) = h.disagreeing_counts() {
            v.push(format!(
                "the header's point counts disagree: {legacy} in the 32-bit field (byte 107), {c64} in the 64-bit one (byte 247); {} points are read, and the output's header gives the count it holds",
                h.point_count
            ));
        }
        if !h.compressed {
            // The stored length: a tilecurv output's own columns are trimmed from the header's.
            let room = h.whole_records(self.map.len() as u64, self.stored_length());
            if room > h.point_count {
                v.push(format!(
                    "the point data holds {room} whole records but the header counts {}: only those {} are read (and written); if the count is wrong, correct the header (LAStools: lasinfo -repair)",
                    h.point_count, h.point_count
                ));
            }
        }
        v.into_iter()
            .map(|w| format!("{}: {w}", self.path.display()))
            .collect()
    }

    /// Whether the file carries NormalX/Y/Z extra dimensions.
    fn has_normals(&self) -> bool {
        self.normal_dims.is_some()
    }

    /// The horizontal unit of the file's CRS.
    fn unit(&self) -> UnitSource {
        horizontal_unit(vlr::records(&self.vlrs, &self.evlrs))
    }

    /// The vertical unit of the file's CRS, from the record that gives the horizontal one.
    fn vertical_unit(&self) -> crate::io::crs_summary::VerticalUnit {
        crate::io::crs_summary::vertical_unit(vlr::records(&self.vlrs, &self.evlrs))
    }

    /// The classification and withheld flag of a record: point formats 0-5 keep both in byte
    /// 15 (class in bits 0-4, withheld bit 7), formats 6-10 the class in byte 16 and withheld
    /// as bit 2 of byte 15.
    fn class_of(&self, rec: &[u8]) -> Option<crate::core::select::PointClass> {
        crate::core::select::las_point_class(self.header.point_format, rec)
    }

    fn integer_coordinates(&self) -> Option<Quantisation> {
        let h = &self.header;
        Some(Quantisation {
            scale: h.scale,
            offset: h.offset,
        })
    }

    /// The coordinates of a batch of records: `LasSource::xyz` of each, which is what
    /// `decode` reads them with.
    fn coordinates(&self, _first: u64, records: &[u8], stride: usize, out: &mut Vec<[f64; 3]>) {
        out.extend(records.chunks_exact(stride.max(1)).map(|r| self.xyz(r)));
    }

    /// Decodes one raw record into a [`SourcePoint`].
    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint {
        let xyz = self.xyz(rec);
        let normal = self.normal_dims.as_ref().and_then(|d| {
            let extra = &rec[POINT_FORMAT_SIZES[self.header.point_format as usize] as usize..];
            Some([d[0].read(extra)?, d[1].read(extra)?, d[2].read(extra)?])
        });
        SourcePoint { id, xyz, normal }
    }

    /// Streams the raw point records in file order, about `chunk_points` at a time, calling
    /// `f(first_point_index, records)` (trimmed records when dimensions were dropped). Stops
    /// at the first error `f` returns.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        self.for_each_chunk_in(0..self.header.point_count, chunk_points, f)
    }

    /// LAS records are read in place, so a task may start at any of them; LAZ is decoded from
    /// a chunk's start, so only there.
    fn cuts(&self) -> Cuts {
        match self.laz {
            None => Cuts::Anywhere,
            Some(_) => Cuts::At(self.chunks.iter().map(|c| c.first_point).collect()),
        }
    }

    /// The records of the points `points` only: LAS records straight from the map, LAZ by
    /// decoding just the chunks that hold them.
    fn for_each_chunk_in(
        &self,
        points: Range<u64>,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let mut trimmed = Vec::new();
        let mut f = |first: u64, records: &[u8]| match &self.trim {
            None => f(first, records),
            Some(t) => {
                t.apply(records, &mut trimmed);
                f(first, &trimmed)
            }
        };
        let rl = self.stored_length();
        let n = self.header.point_count;
        let (mut first, end) = (points.start.min(n), points.end.min(n));
        let start = self.header.offset_to_point_data as usize;
        // Pages already streamed are handed back to the kernel, so that resident memory does
        // not grow with the file size (mapped pages count in RSS).
        let mut released = page_below(start + first as usize * rl);
        match &self.laz {
            None => {
                let chunk = chunk_points.max(1);
                while first < end {
                    let m = (end - first).min(chunk as u64) as usize;
                    let a = start + first as usize * rl;
                    f(first, &self.map[a..a + m * rl])?;
                    released = self.release(released, a + m * rl);
                    first += m as u64;
                }
                Ok(())
            }
            Some(vlr) => self.for_each_laz_chunk(vlr, first..end, chunk_points, &mut f),
        }
    }

    fn record_length(&self) -> usize {
        self.header.record_length as usize
    }

    fn describe(&self) -> String {
        let h = &self.header;
        format!(
            "LAS {}.{} format {}{}",
            h.version.0,
            h.version.1,
            h.point_format,
            if h.compressed { " (LAZ)" } else { "" }
        )
    }

    fn layout(&self) -> SourceLayout<'_> {
        SourceLayout::Las(self.parts())
    }

    fn properties(&self) -> Vec<Property> {
        las_properties(&self.header, &self.extra)
    }
}
