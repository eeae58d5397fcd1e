//! The LAS/LAZ output of `process` for a non-LAS input: a LAS 1.4 header, point format 0
//! records (coordinates quantised as [`quantisation`] says, return 1 of 1, every other standard
//! field 0), the source's properties other than x, y and z as extra bytes of their own types
//! (renamed `input_<name>` when named like a standard LAS dimension, e.g. a PLY `intensity`),
//! then the new columns. The source has no CRS, so the output has none either. The converted
//! header and descriptors then take the path of a LAS input (`carry`).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::columns::output::OutputColumns;
use crate::io::durable::Ready;
use crate::io::las::extra_bytes::{self, encode, parse, NewColumn};
use crate::io::las::header::{LasHeader, NewHeader, Quantisation};
use crate::io::las::parts::LasParts;
use crate::io::las::vlr::Vlr;
use crate::io::las::writer::LasFileWriter;
use crate::io::las_output::carry;
use crate::io::output::PointSink;
use crate::io::source::{xyz_and_normals, PointSource, Property};

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

/// A LAS output of a non-LAS source: each batch of source records (with their new columns) is
/// converted, then written by the one LAS writer.
pub(crate) struct ConvertedSink {
    convert: Convert,
    writer: LasFileWriter,
}

impl ConvertedSink {
    /// Creates the converted output of `source` (see the module doc).
    pub(crate) fn create(
        source: &dyn PointSource,
        output: &Path,
        cols: &OutputColumns,
        provenance: &str,
    ) -> Result<Self> {
        let Split { xyz, others: props } = split_xyz(source)?;
        let eb = descriptors(&props);
        let extra = parse(&eb).map_err(Error::Internal)?;
        let vlrs: Vec<Vlr> = if eb.is_empty() {
            Vec::new()
        } else {
            vec![extra_bytes::vlr(eb)]
        };
        let bounds = source.bounds()?;
        let extra_len: usize = props.iter().map(|p| p.ty.size()).sum();
        let q = quantisation(bounds);
        let raw = converted_header(source.len(), extra_len, q, bounds)?;
        let header = LasHeader::parse(source.path(), &raw, raw.len() as u64)?;
        let input = LasParts {
            path: source.path(),
            header: &header,
            vlrs: &vlrs,
            evlrs: &[],
            extra: &extra,
        };
        let writer = carry::create(input, output, cols, provenance, carry::Version::Input)?;
        let convert = Convert {
            xyz,
            props,
            record_length: source.record_length(),
            columns_len: cols.record_size(),
            scale: q.scale,
            offset: q.offset,
            buf: Vec::new(),
        };
        Ok(ConvertedSink { convert, writer })
    }
}

impl PointSink for ConvertedSink {
    fn write_points(&mut self, records: &[u8]) -> Result<()> {
        let records = self.convert.records(records);
        self.writer.write_records(records)
    }

    fn finish(self: Box<Self>) -> Result<Ready> {
        self.writer.ready()
    }

    fn abandon(self: Box<Self>) {
        self.writer.abandon()
    }
}

/// A source's properties, split by [`split_xyz`].
struct Split {
    /// Its x, y and z.
    xyz: [Property; 3],
    /// The others, in order, which become extra bytes.
    others: Vec<Property>,
}

/// A source's x, y, z properties, and the others.
fn split_xyz(source: &dyn PointSource) -> Result<Split> {
    let mut props = source.properties();
    let Some(xyz) = xyz_and_normals(props.iter().map(|p| p.name.as_str())).xyz else {
        return Err(Error::Internal(format!(
            "{}: the reader lists no x, y, z properties",
            source.path().display()
        )));
    };
    let xyz = xyz.map(|i| props[i].clone());
    props.retain(|p| !xyz.contains(p));
    Ok(Split { xyz, others: props })
}

/// The encoded extra-bytes descriptors of a converted output of `source`, before the new
/// columns': one per property but x, y and z.
pub(crate) fn input_descriptors(source: &dyn PointSource) -> Result<Vec<u8>> {
    Ok(descriptors(&split_xyz(source)?.others))
}

/// The encoded extra-bytes descriptors of the properties kept as extra bytes.
fn descriptors(props: &[Property]) -> Vec<u8> {
    let mut eb = Vec::new();
    for p in props {
        // Readers (laspy, PDAL) refuse an extra dimension named like a standard one.
        let name = if STANDARD_NAMES
            .iter()
            .any(|n| n.eq_ignore_ascii_case(&p.name))
        {
            format!("input_{}", p.name)
        } else {
            p.name.clone()
        };
        eb.extend_from_slice(&encode(&NewColumn::plain(name, p.ty, "")));
    }
    eb
}

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
pub(crate) fn quantisation(bounds: [[f64; 3]; 2]) -> Quantisation {
    let [lo, hi] = bounds;
    let mut extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    if extent <= 0.0 {
        extent = lo.iter().chain(&hi).map(|c| c.abs()).fold(1.0, f64::max);
    }
    let scale = 10f64.powf((extent * 1e-8).log10().floor());
    Quantisation {
        scale: [scale; 3],
        offset: [0, 1, 2].map(|a| (lo[a] + hi[a]) / 2.0),
    }
}

/// A LAS 1.4 header (375 bytes) for point format 0 records with `extra_len` extra bytes; the
/// layout fields are filled in by [`LasHeader::patched`] like those of any input.
fn converted_header(
    points: u64,
    extra_len: usize,
    q: Quantisation,
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
        scale: q.scale,
        offset: q.offset,
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
            let Quantisation {
                scale: s,
                offset: o,
            } = quantisation(b);
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
