//! What `tilecurv info` reports about a point cloud file: format and version, point count,
//! bounds, CRS with its horizontal and vertical units, the extra dimensions with their types
//! and scales, and the provenance a tilecurv output carries. Gathers only: the CLI prints it.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::io::crs_summary::{crs_summary, CrsSummary};
use crate::io::las::extra_bytes::Descriptor;
use crate::io::las::provenance;
use crate::io::source::{PointSource, SourceLayout};

/// One extra dimension (LAS extra bytes) or non-coordinate property (other formats).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraDim {
    /// Its name.
    pub name: String,
    /// Its stored type: `u8` .. `f64`, or what a non-scalar descriptor holds.
    pub ty: String,
    /// The scale applied to the stored value (1 when none).
    pub scale: f64,
    /// The offset added after the scale (0 when none).
    pub offset: f64,
    /// The raw value declared as "no data", if any (tilecurv's scaled columns: the type's
    /// minimum, for undefined values).
    pub no_data: Option<f64>,
}

/// What a file holds, as `tilecurv info` reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct FileInfo {
    /// The file.
    pub path: PathBuf,
    /// The format in words, e.g. `LAS 1.2 format 1 (LAZ)`.
    pub format: String,
    /// The LAS version (`1.4`), for a LAS/LAZ file.
    pub las_version: Option<String>,
    /// The LAS point data record format, for a LAS/LAZ file.
    pub point_format: Option<u8>,
    /// Whether the LAS file is COPC (its index VLR is present).
    pub copc: bool,
    /// Number of points.
    pub points: u64,
    /// Minimum and maximum x, y, z.
    pub bounds: [[f64; 3]; 2],
    /// Where the bounds come from: `header` (LAS, as stored) or `points` (scanned).
    pub bounds_from: &'static str,
    /// The CRS.
    pub crs: CrsSummary,
    /// The extra dimensions, in record order.
    pub extra: Vec<ExtraDim>,
    /// The text of tilecurv's provenance record, for a tilecurv output (the newest, when the
    /// file also carries its input's).
    pub provenance: Option<String>,
}

/// The type name of an extra-bytes descriptor.
fn descriptor_type(d: &Descriptor) -> String {
    match (d.scalar(), d.data_type) {
        (Some(t), _) => type_name(t).into(),
        (None, 0) => format!("undocumented ({} bytes)", d.size),
        (None, code) => format!("deprecated tuple type {code} ({} bytes)", d.size),
    }
}

fn type_name(t: crate::io::las::extra_bytes::ScalarType) -> &'static str {
    use crate::io::las::extra_bytes::ScalarType::*;
    match t {
        U8 => "u8",
        I8 => "i8",
        U16 => "u16",
        I16 => "i16",
        U32 => "u32",
        I32 => "i32",
        U64 => "u64",
        I64 => "i64",
        F32 => "f32",
        F64 => "f64",
    }
}

/// Opens `path` and gathers its [`FileInfo`]. A LAS/LAZ file is described from its header and
/// VLRs (the bounds as the header stores them); any other format is scanned for its bounds.
pub fn file_info(path: &Path) -> Result<FileInfo> {
    let source = crate::io::source::open(path)?;
    let format = source.describe();
    let points = source.len();
    Ok(match source.layout() {
        SourceLayout::Las(parts) => {
            let records: Vec<_> = crate::io::las::vlr::records(parts.vlrs, parts.evlrs).collect();
            let h = parts.header;
            FileInfo {
                path: path.to_path_buf(),
                format,
                las_version: Some(format!("{}.{}", h.version.0, h.version.1)),
                point_format: Some(h.point_format),
                copc: records.iter().any(|v| v.is("copc", 1)),
                points,
                bounds: [h.min, h.max],
                bounds_from: "header",
                crs: crs_summary(
                    records.iter().copied(),
                    h.version.1 >= 4 && h.global_encoding & 0x10 != 0,
                ),
                extra: parts
                    .extra
                    .iter()
                    .map(|d| ExtraDim {
                        name: d.name.clone(),
                        ty: descriptor_type(d),
                        scale: d.scale,
                        offset: d.value_offset,
                        no_data: d.no_data,
                    })
                    .collect(),
                // The writer appends its record after the carried ones: a tilecurv output of a
                // generated terrain carries `generate`'s record first.
                provenance: provenance::texts(records.iter().copied()).pop(),
            }
        }
        SourceLayout::Converted => other_format(path, source.as_ref(), format, points)?,
    })
}

/// The info of a non-LAS file: its properties other than x, y, z as extra dimensions, the
/// bounds from a scan, no CRS (these formats have none), and a PLY's provenance.
fn other_format(
    path: &Path,
    source: &dyn PointSource,
    format: String,
    points: u64,
) -> Result<FileInfo> {
    let extra = source
        .properties()
        .into_iter()
        .filter(|p| !["x", "y", "z"].contains(&p.name.as_str()))
        .map(|p| ExtraDim {
            name: p.name,
            ty: type_name(p.ty).into(),
            scale: 1.0,
            offset: 0.0,
            no_data: None,
        })
        .collect();
    // A PLY output of tilecurv carries its record in header comments.
    let provenance = match crate::io::source::detect(path)? {
        crate::io::source::Format::Ply => {
            crate::io::source::ply::provenance(path, &crate::io::source::map_file(path)?)?
        }
        _ => None,
    };
    Ok(FileInfo {
        path: path.to_path_buf(),
        format,
        las_version: None,
        point_format: None,
        copc: false,
        points,
        bounds: source.bounds()?,
        bounds_from: "points",
        crs: CrsSummary {
            stored_as: "none",
            name: None,
            horizontal: source.unit(),
            vertical: Err("the format has no CRS".into()),
        },
        extra,
        provenance,
    })
}
