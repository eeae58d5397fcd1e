//! Writing the output LAS/LAZ file: the input's header, VLRs and EVLRs carried over (a COPC
//! index is dropped: it would be stale), the extra-bytes VLR extended with tilecurv's columns,
//! a provenance VLR, and each input point record followed by its new column bytes. Written to a
//! temporary file beside the output, fsynced, and renamed over the output only by [`LasWriter::finish`].
//! A non-LAS input is converted: [`LasWriter::create_converted`] gives it a LAS 1.4 header,
//! point format 0 records and its other properties as extra bytes, then the same path follows.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::las::extra_bytes::{
    self, encode, encode_undocumented, parse, Descriptor, NewColumn, DESCRIPTOR_SIZE,
};
use crate::io::las::header::{LasHeader, NewHeader, OutputLayout, POINT_FORMAT_SIZES};
use crate::io::las::vlr::Vlr;
use crate::io::output::{commit, temp_path, PointSink};
use crate::io::source::{xyz_and_normals, LasSource, PointSource, Property};

/// User id and record id of the provenance VLR.
pub const PROVENANCE: (&str, u16) = ("tilecurv", 1);

/// Whether a path names a LAZ file (by extension; anything else that is .las is LAS).
pub fn output_is_laz(path: &Path) -> Result<bool> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("laz") => Ok(true),
        Some("las") => Ok(false),
        _ => Err(Error::Usage(format!(
            "{}: the output must end in .las or .laz (the extension chooses the format)",
            path.display()
        ))),
    }
}

fn is_copc(v: &Vlr) -> bool {
    v.user_id == "copc"
}

/// What the writer takes over from its input: a LAS file's header, VLRs, EVLRs and extra-bytes
/// descriptors, or the synthetic ones of a converted non-LAS input.
struct Input<'a> {
    path: &'a Path,
    header: &'a LasHeader,
    vlrs: &'a [Vlr],
    evlrs: &'a [(u64, Vlr)],
    extra: &'a [Descriptor],
}

/// The extra-bytes descriptors of the output: the input's (padded with an "undocumented"
/// descriptor if the input's records have more extra bytes than its VLR describes), then ours.
fn extra_bytes_payload(
    source: &Input<'_>,
    existing: Option<&Vlr>,
    cols: &ColumnSet,
) -> Result<Vec<u8>> {
    let mut data = existing.map(|v| v.data.clone()).unwrap_or_default();
    let described: usize = parse(&data)
        .map(|d| d.iter().map(|d| d.size).sum())
        .unwrap_or(0);
    let mut gap = source.header.extra_bytes_len() as usize - described;
    while gap > 0 {
        let n = gap.min(255);
        data.extend_from_slice(&encode_undocumented(n as u8));
        gap -= n;
    }
    for c in cols.columns() {
        if source
            .extra
            .iter()
            .any(|d| d.name.eq_ignore_ascii_case(&c.name))
        {
            return Err(Error::bad_input(source.path, None, format!(
                "the input already has an extra dimension named {:?} (is it a tilecurv output?); process the original file instead", c.name)));
        }
        data.extend_from_slice(&encode(&c));
    }
    debug_assert_eq!(data.len() % DESCRIPTOR_SIZE, 0);
    Ok(data)
}

/// An output file being written.
pub struct LasWriter {
    tmp: PathBuf,
    output: PathBuf,
    header: crate::io::las::header::LasHeader,
    layout: OutputLayout,
    evlrs: Vec<Vlr>,
    waveform_evlr: Option<usize>,
    sink: Sink,
    /// For a non-LAS input: how its records become LAS records.
    convert: Option<Convert>,
}

enum Sink {
    Plain(BufWriter<File>),
    Laz(Box<laz::ParLasZipCompressor<BufWriter<File>>>),
}

impl LasWriter {
    /// Creates the temporary output beside `output` and writes the header and VLRs.
    pub fn create(
        source: &LasSource,
        output: &Path,
        cols: &ColumnSet,
        provenance: &str,
    ) -> Result<Self> {
        let input = Input {
            path: source.path(),
            header: &source.header,
            vlrs: &source.vlrs,
            evlrs: &source.evlrs,
            extra: &source.extra,
        };
        Self::create_from(&input, output, cols, provenance, None)
    }

    /// Creates a LAS 1.4 output for a non-LAS source: point format 0 records (coordinates
    /// quantised as [`quantisation`] says, return 1 of 1, every other standard field 0), the
    /// source's properties other than x, y and z as extra bytes of their own types (renamed
    /// `input_<name>` when named like a standard LAS dimension, e.g. a PLY `intensity`), then
    /// the new columns. The source has no CRS, so the output has none either.
    pub fn create_converted(
        source: &dyn PointSource,
        output: &Path,
        cols: &ColumnSet,
        provenance: &str,
    ) -> Result<Self> {
        let mut props = source.properties();
        let Some(xyz) = xyz_and_normals(props.iter().map(|p| p.name.as_str())).0 else {
            return Err(Error::Internal(format!(
                "{}: the reader lists no x, y, z properties",
                source.path().display()
            )));
        };
        let xyz = xyz.map(|i| props[i].clone());
        props.retain(|p| !xyz.contains(p));
        let mut eb = Vec::new();
        for p in &props {
            // Readers (laspy, PDAL) refuse an extra dimension named like a standard one.
            let name = if STANDARD_NAMES
                .iter()
                .any(|n| n.eq_ignore_ascii_case(&p.name))
            {
                format!("input_{}", p.name)
            } else {
                p.name.clone()
            };
            eb.extend_from_slice(&encode(&NewColumn {
                name,
                ty: p.ty,
                description: String::new(),
            }));
        }
        let extra = parse(&eb).map_err(Error::Internal)?;
        let vlrs: Vec<Vlr> = if eb.is_empty() {
            Vec::new()
        } else {
            vec![Vlr::new(
                extra_bytes::USER_ID,
                extra_bytes::RECORD_ID,
                "Extra Bytes Record",
                eb,
            )]
        };
        let bounds = source.bounds()?;
        let (scale, offset) = quantisation(bounds);
        let extra_len: usize = props.iter().map(|p| p.ty.size()).sum();
        let raw = converted_header(source.len(), extra_len, scale, offset, bounds)?;
        let header = LasHeader::parse(source.path(), &raw, raw.len() as u64)?;
        let input = Input {
            path: source.path(),
            header: &header,
            vlrs: &vlrs,
            evlrs: &[],
            extra: &extra,
        };
        let convert = Convert {
            xyz,
            props,
            record_length: source.record_length(),
            columns_len: cols.record_size(),
            scale,
            offset,
            buf: Vec::new(),
        };
        Self::create_from(&input, output, cols, provenance, Some(convert))
    }

    fn create_from(
        source: &Input<'_>,
        output: &Path,
        cols: &ColumnSet,
        provenance: &str,
        convert: Option<Convert>,
    ) -> Result<Self> {
        let compressed = output_is_laz(output)?;
        let h = source.header;
        let record_length =
            u16::try_from(h.record_length as usize + cols.record_size()).map_err(|_| {
                Error::bad_input(
                    source.path,
                    Some(105),
                    format!(
                        "records of {} bytes plus {} new bytes exceed the LAS limit of 65535",
                        h.record_length,
                        cols.record_size()
                    ),
                )
            })?;
        // VLRs: the input's, minus the LAZ and COPC records (rebuilt or stale), with the
        // extra-bytes VLR extended in place (or added), then provenance and LASzip.
        let eb_in_evlr = source
            .evlrs
            .iter()
            .any(|(_, v)| extra_bytes::is_extra_bytes(v));
        let existing_eb = source
            .vlrs
            .iter()
            .chain(source.evlrs.iter().map(|(_, v)| v))
            .find(|v| extra_bytes::is_extra_bytes(v));
        let eb_data = extra_bytes_payload(source, existing_eb, cols)?;
        let mut vlrs: Vec<Vlr> = Vec::new();
        let mut placed = eb_in_evlr;
        for v in source.vlrs {
            if v.is("laszip encoded", 22204) || is_copc(v) {
                continue;
            }
            if extra_bytes::is_extra_bytes(v) {
                vlrs.push(Vlr {
                    data: eb_data.clone(),
                    ..v.clone()
                });
                placed = true;
            } else {
                vlrs.push(v.clone());
            }
        }
        if !placed {
            vlrs.push(Vlr::new(
                extra_bytes::USER_ID,
                extra_bytes::RECORD_ID,
                "Extra Bytes Record",
                eb_data.clone(),
            ));
        }
        vlrs.push(Vlr::new(
            PROVENANCE.0,
            PROVENANCE.1,
            "tilecurv provenance",
            provenance.as_bytes().to_vec(),
        ));
        let laz_vlr = if compressed {
            let extra = record_length - POINT_FORMAT_SIZES[h.point_format as usize];
            let (lv, vlr) = crate::io::las::vlr::laszip(h.point_format, extra)?;
            vlrs.push(vlr);
            Some(lv)
        } else {
            None
        };
        let mut evlrs = Vec::new();
        let mut waveform_evlr = None;
        for (off, v) in source.evlrs {
            if is_copc(v) {
                continue;
            }
            if *off == h.waveform_start {
                waveform_evlr = Some(evlrs.len());
            }
            if extra_bytes::is_extra_bytes(v) {
                evlrs.push(Vlr {
                    data: eb_data.clone(),
                    ..v.clone()
                });
            } else {
                evlrs.push(v.clone());
            }
        }
        let mut head = Vec::new();
        for v in &vlrs {
            v.write_vlr(&mut head)
                .map_err(|why| Error::bad_input(source.path, None, why))?;
        }
        let offset = h.header_size as usize + head.len();
        let layout = OutputLayout {
            offset_to_point_data: u32::try_from(offset)
                .map_err(|_| Error::Internal("VLRs larger than 4 GiB".into()))?,
            num_vlrs: vlrs.len() as u32,
            compressed,
            record_length,
            evlr_start: 0,
            evlr_count: evlrs.len() as u32,
            waveform_start: 0,
        };
        let tmp = temp_path(output);
        let file = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
        let mut w = BufWriter::with_capacity(4 << 20, file);
        w.write_all(&h.patched(&layout))
            .and_then(|_| w.write_all(&head))
            .map_err(|e| Error::write(&tmp, e))?;
        let sink = match laz_vlr {
            None => Sink::Plain(w),
            Some(lv) => Sink::Laz(Box::new(
                laz::ParLasZipCompressor::new(w, lv)
                    .map_err(|e| Error::Internal(format!("LAZ compressor: {e}")))?,
            )),
        };
        Ok(LasWriter {
            tmp,
            output: output.to_path_buf(),
            header: h.clone(),
            layout,
            evlrs,
            waveform_evlr,
            sink,
            convert,
        })
    }
}

impl PointSink for LasWriter {
    fn write_points(&mut self, records: &[u8]) -> Result<()> {
        let records = match &mut self.convert {
            Some(c) => c.records(records),
            None => records,
        };
        let r = match &mut self.sink {
            Sink::Plain(w) => w.write_all(records),
            Sink::Laz(c) => c.compress_many(records),
        };
        r.map_err(|e| Error::write(&self.tmp, e))
    }

    /// Finishes the points, writes the EVLRs, rewrites the header with the final layout, syncs
    /// the file and renames it over the output.
    fn finish(mut self: Box<Self>) -> Result<()> {
        let tmp = self.tmp.clone();
        let werr = |e: std::io::Error| Error::write(&tmp, e);
        let mut w = match self.sink {
            Sink::Plain(w) => w,
            Sink::Laz(mut c) => {
                c.done()
                    .map_err(|e| Error::Internal(format!("LAZ compressor: {e}")))?;
                c.into_inner()
            }
        };
        let end_of_points = w.stream_position().map_err(werr)?;
        let mut tail = Vec::new();
        let mut pos = end_of_points;
        for (i, v) in self.evlrs.iter().enumerate() {
            if Some(i) == self.waveform_evlr {
                self.layout.waveform_start = pos;
            }
            v.write_evlr(&mut tail);
            pos = end_of_points + tail.len() as u64;
        }
        if !self.evlrs.is_empty() && self.header.version.1 >= 4 {
            self.layout.evlr_start = end_of_points;
        }
        w.write_all(&tail).map_err(werr)?;
        w.seek(SeekFrom::Start(0)).map_err(werr)?;
        w.write_all(&self.header.patched(&self.layout))
            .map_err(werr)?;
        let file = w.into_inner().map_err(|e| werr(e.into_error()))?;
        commit(file, &self.tmp, &self.output)
    }

    fn abandon(self: Box<Self>) {
        let tmp = self.tmp.clone();
        drop(self);
        let _ = std::fs::remove_file(tmp);
    }
}

/// The dimension names LAS readers give the fields of point formats 0 to 10, which an extra
/// dimension must not reuse.
const STANDARD_NAMES: [&str; 22] = [
    "X",
    "Y",
    "Z",
    "intensity",
    "return_number",
    "number_of_returns",
    "scan_direction_flag",
    "edge_of_flight_line",
    "classification",
    "synthetic",
    "key_point",
    "withheld",
    "overlap",
    "scanner_channel",
    "scan_angle_rank",
    "scan_angle",
    "user_data",
    "point_source_id",
    "gps_time",
    "red",
    "green",
    "blue",
];

/// How a non-LAS source's records become LAS point format 0 records with extra bytes.
struct Convert {
    xyz: [Property; 3],
    /// The properties kept as extra bytes, in order.
    props: Vec<Property>,
    /// Bytes per source record.
    record_length: usize,
    /// Bytes of new columns after each source record.
    columns_len: usize,
    scale: [f64; 3],
    offset: [f64; 3],
    buf: Vec<u8>,
}

impl Convert {
    /// The LAS records (with the new columns carried over) of whole input records.
    fn records(&mut self, records: &[u8]) -> &[u8] {
        self.buf.clear();
        for rec in records.chunks_exact(self.record_length + self.columns_len) {
            for a in 0..3 {
                let q = ((self.xyz[a].value(rec) - self.offset[a]) / self.scale[a]).round();
                self.buf.extend_from_slice(&(q as i32).to_le_bytes());
            }
            // Intensity 0, return 1 of 1, classification 0 (never classified), scan angle 0,
            // user data 0, point source id 0.
            self.buf.extend_from_slice(&[0, 0, 0x09, 0, 0, 0, 0, 0]);
            for p in &self.props {
                p.put_le(rec, &mut self.buf);
            }
            self.buf.extend_from_slice(&rec[self.record_length..]);
        }
        &self.buf
    }
}

/// The scale and offset of a converted output, from the exact bounds: the offset is the centre
/// of the bounds; the scale, the same on every axis, is the largest power of ten at most 1e-8
/// times the largest extent E. The quantisation error is then at most 0.5e-8 E (far better
/// than 1e-6 relative to the cloud's size), and since the scale exceeds 1e-9 E, coordinates
/// stay below 5e8 < 2^31 in magnitude. A cloud of one position uses E = max(|coordinate|, 1).
pub fn quantisation(bounds: [[f64; 3]; 2]) -> ([f64; 3], [f64; 3]) {
    let [lo, hi] = bounds;
    let mut extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    if extent <= 0.0 {
        extent = lo.iter().chain(&hi).map(|c| c.abs()).fold(1.0, f64::max);
    }
    let scale = 10f64.powf((extent * 1e-8).log10().floor());
    let offset = [0, 1, 2].map(|a| (lo[a] + hi[a]) / 2.0);
    ([scale; 3], offset)
}

/// A LAS 1.4 header (375 bytes) for point format 0 records with `extra_len` extra bytes; the
/// layout fields are filled in by [`LasHeader::patched`] like those of any input.
fn converted_header(
    points: u64,
    extra_len: usize,
    scale: [f64; 3],
    offset: [f64; 3],
    bounds: [[f64; 3]; 2],
) -> Result<Vec<u8>> {
    let record_length = u16::try_from(20 + extra_len).map_err(|_| {
        Error::Usage(format!(
            "the input's properties take {extra_len} bytes per point, more than a LAS record holds"
        ))
    })?;
    let software = format!("tilecurv {}", env!("CARGO_PKG_VERSION"));
    Ok(NewHeader {
        minor: 4,
        system: "OTHER",
        software: &software,
        point_format: 0,
        record_length,
        points,
        scale,
        offset,
        min: bounds[0],
        max: bounds[1],
    }
    .bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_keeps_precision_and_fits_i32() {
        for (lo, hi) in [
            (-1.2, 1.19),
            (500_000.0, 500_123.4),
            (0.0, 1e-3),
            (7.0, 7.0),
        ] {
            let b = [[lo, lo, lo], [hi, hi, lo]];
            let (s, o) = quantisation(b);
            let extent = if hi > lo { hi - lo } else { lo.abs().max(1.0) };
            assert!(
                s[0] <= 1e-8 * extent && s[0] > 1e-9 * extent,
                "{lo}..{hi}: scale {}",
                s[0]
            );
            for v in [lo, hi] {
                assert!(((v - o[0]) / s[0]).abs() < i32::MAX as f64);
            }
        }
    }
}
