//! Reading points. A [`PointSource`] streams a file's points in file order as chunks of raw
//! records (the bytes `assemble` carries to the output) and decodes coordinates and file normals
//! from them. One module per format, plus [`binary`] (fixed-size binary records, for PLY and
//! PCD) and [`faces`] (a mesh's faces, for `--sample-faces`); [`open`] picks by content and
//! extension. [`PointSource::layout`] tells a writer whether the records are LAS records it can
//! carry over or records to convert.

pub mod binary;
pub mod bytes;
pub mod faces;
pub mod las;
pub mod memory;
pub mod mesh;
pub mod pcd;
pub mod ply;
pub mod sampled;
pub mod text;

use std::ops::Range;
use std::path::Path;

use memmap2::Mmap;

pub use bytes::InputBytes;

use crate::core::tasks::Cuts;
use crate::error::{Error, Result};
use crate::io::crs::UnitSource;
use crate::io::las::extra_bytes::ScalarType;
use crate::io::las::header::Quantisation;
use crate::io::las::parts::LasParts;

pub use las::LasSource;

pub use crate::core::point::SourcePoint;

/// A point cloud file opened for streaming.
pub trait PointSource: Send + Sync {
    /// The file's path.
    fn path(&self) -> &Path;
    /// Number of points (never 0: opening rejects empty clouds).
    fn len(&self) -> u64;
    /// Always false (kept for clippy's `len` convention).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the file carries normals.
    fn has_normals(&self) -> bool;
    /// The horizontal unit of the file's CRS.
    fn unit(&self) -> UnitSource;
    /// The vertical unit of the file's CRS (only LAS files carry one).
    fn vertical_unit(&self) -> crate::io::crs_summary::VerticalUnit {
        crate::io::crs_summary::VerticalUnit::Undeclared(format!("{} has no CRS", self.describe()))
    }
    /// Bytes per raw record in the chunks passed to `for_each_chunk`.
    fn record_length(&self) -> usize;
    /// Streams the raw records in file order, about `chunk_points` at a time, calling
    /// `f(first_point_index, records)`; stops at the first error.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()>;
    /// Where the points may be split between bucket tasks that each stream a range of them
    /// ([`PointSource::for_each_chunk_in`]). The default is nowhere: a text, PLY, PCD or mesh
    /// source is parsed from its start, so it is scanned by one task.
    fn cuts(&self) -> Cuts {
        Cuts::At(Vec::new())
    }
    /// Streams the raw records of the points `points` (indices in the file) as
    /// [`PointSource::for_each_chunk`] streams them all, calling `f(first_point_index,
    /// records)` with the file's own indices. The default streams every record and passes on
    /// those in the range: correct for any source, fast only for the whole file, which is all
    /// a source without [`PointSource::cuts`] is asked for.
    fn for_each_chunk_in(
        &self,
        points: Range<u64>,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        if points == (0..self.len()) {
            return self.for_each_chunk(chunk_points, f);
        }
        let rl = self.record_length();
        self.for_each_chunk(chunk_points, &mut |first, records| {
            within(&points, first, records, rl, &mut *f)
        })
    }
    /// Decodes one raw record.
    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint;
    /// Appends to `out` the coordinates of the raw records in `records`, one every `stride`
    /// bytes (each this source's record, then anything a caller added), the first being point
    /// `first`: what [`PointSource::decode`] gives of each, in one call for a batch (a raster
    /// reads only the coordinates, and a call per point cost more than decoding them).
    fn coordinates(&self, first: u64, records: &[u8], stride: usize, out: &mut Vec<[f64; 3]>) {
        let rl = self.record_length();
        for (i, rec) in records.chunks_exact(stride.max(1)).enumerate() {
            out.push(self.decode(first + i as u64, &rec[..rl.min(rec.len())]).xyz);
        }
    }
    /// The scale and offset of x, y and z when [`PointSource::decode`] gives every coordinate
    /// as the [`crate::core::grid::AxisGrid`] value of a stored integer (LAS records), None
    /// otherwise: the buckets then store the integers (the f64 bits they give back are checked
    /// when a bucket is written).
    fn integer_coordinates(&self) -> Option<Quantisation> {
        None
    }
    /// The LAS classification and withheld flag of one raw record (None: the format has
    /// none, only LAS records do).
    fn class_of(&self, _rec: &[u8]) -> Option<crate::core::select::PointClass> {
        None
    }
    /// Whether the records carry LAS classes and withheld flags ([`PointSource::class_of`]
    /// gives them): LAS records do.
    fn has_classes(&self) -> bool {
        matches!(self.layout(), SourceLayout::Las(_))
    }
    /// A short description of the format for the log, e.g. "LAS 1.4 format 6 (LAZ)".
    fn describe(&self) -> String;
    /// What a user is to be told of the file that does not stop the run (a header that
    /// contradicts itself or its data), each naming the file.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
    /// How the raw records are laid out: LAS records with the file's header, VLRs, EVLRs and
    /// extra-bytes descriptors (a LAS/LAZ output keeps them byte for byte), or the reader's own
    /// records, which a LAS/LAZ writer converts from [`PointSource::properties`].
    fn layout(&self) -> SourceLayout<'_>;
    /// The per-point properties of the raw records (name, type and where each value sits), for
    /// writers that re-encode records in another format. Non-LAS sources list every property of
    /// their file, x, y and z included; a LAS source lists the fields that decode without
    /// tables and its scalar extra dimensions.
    fn properties(&self) -> Vec<Property>;
    /// The exact bounds (min, max) of the coordinates. The default decodes every point once;
    /// readers that already validated every point in `open` return what they found there.
    fn bounds(&self) -> Result<[[f64; 3]; 2]> {
        let mut b = Bounds::default();
        let rl = self.record_length();
        self.for_each_chunk(1 << 16, &mut |first, records| {
            for (i, rec) in records.chunks_exact(rl).enumerate() {
                b.add(self.decode(first + i as u64, rec).xyz);
            }
            Ok(())
        })?;
        Ok(b.get())
    }
}

/// Calls `f` with the records of `records` (of `rl` bytes, the first being point `first`)
/// that hold points in `points`, if any.
pub(crate) fn within(
    points: &Range<u64>,
    first: u64,
    records: &[u8],
    rl: usize,
    f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
) -> Result<()> {
    let end = first + (records.len() / rl.max(1)) as u64;
    let (a, b) = (points.start.max(first), points.end.min(end));
    if a >= b {
        return Ok(());
    }
    let at = |p: u64| (p - first) as usize * rl;
    f(a, &records[at(a)..at(b)])
}

/// How a source's raw records are laid out, for the writers ([`PointSource::layout`]).
#[derive(Debug, Clone, Copy)]
pub enum SourceLayout<'a> {
    /// LAS point records, described by these parts of the file.
    Las(LasParts<'a>),
    /// The reader's own fixed-width records, described by [`PointSource::properties`]: a LAS
    /// writer converts them.
    Converted,
}

/// Where and how a property's value is stored in a raw record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stored {
    /// A value of the property's type at this byte offset, little endian.
    Le(usize),
    /// A value of the property's type at this byte offset, big endian.
    Be(usize),
    /// An f64 (little endian) at this byte offset holding a value of the property's type: the
    /// fixed-width encoding the text readers give their records.
    F64(usize),
    /// `raw * scale + offset` from a little-endian `raw` at byte offset `at` (LAS coordinates and
    /// scaled extra bytes); the property's type is f64.
    Scaled {
        /// The stored type.
        raw: ScalarType,
        /// Byte offset in the record.
        at: usize,
        /// Scale factor.
        scale: f64,
        /// Offset added after scaling.
        offset: f64,
    },
    /// An unsigned field of `width` bits starting at bit `shift` of the byte at `at` (LAS return
    /// numbers, legacy classification); the property's type is u8.
    Bits {
        /// Byte offset in the record.
        at: usize,
        /// Lowest bit of the field.
        shift: u8,
        /// Number of bits.
        width: u8,
    },
}

impl Stored {
    /// The byte offset of the value in a record.
    pub fn offset(&self) -> usize {
        match *self {
            Stored::Le(at) | Stored::Be(at) | Stored::F64(at) => at,
            Stored::Scaled { at, .. } | Stored::Bits { at, .. } => at,
        }
    }
}

/// One per-point property of a source: its name and type as the file declares them, and where
/// its value sits in a raw record.
#[derive(Debug, Clone, PartialEq)]
pub struct Property {
    /// Name as in the file (e.g. `x`, `nx`, `segment_index`, `intensity`).
    pub name: String,
    /// The value's type (the type a writer declares for it).
    pub ty: ScalarType,
    /// Where the value is in a raw record.
    pub stored: Stored,
}

impl Property {
    /// A property of type `ty` stored at `stored`.
    pub fn new(name: impl Into<String>, ty: ScalarType, stored: Stored) -> Self {
        Property {
            name: name.into(),
            ty,
            stored,
        }
    }

    /// The value in `rec`, as f64 (exact for every type but 64-bit integers above 2^53).
    pub fn value(&self, rec: &[u8]) -> f64 {
        match self.stored {
            Stored::Le(at) => self.ty.decode(&rec[at..]),
            Stored::Be(at) => self.ty.decode(&swapped(&rec[at..at + self.ty.size()])),
            Stored::F64(at) => ScalarType::F64.decode(&rec[at..]),
            Stored::Scaled {
                raw,
                at,
                scale,
                offset,
            } => raw.decode(&rec[at..]) * scale + offset,
            Stored::Bits { at, shift, width } => {
                ((rec[at] >> shift) & ((1u16 << width) - 1) as u8) as f64
            }
        }
    }

    /// Appends the value in `rec` to `out` as the property's type, little endian. Values stored
    /// in their own type are copied bit for bit.
    pub fn put_le(&self, rec: &[u8], out: &mut Vec<u8>) {
        let n = self.ty.size();
        match self.stored {
            Stored::Le(at) => out.extend_from_slice(&rec[at..at + n]),
            Stored::Be(at) => out.extend_from_slice(&swapped(&rec[at..at + n])[..n]),
            _ => encode_le(self.ty, self.value(rec), out),
        }
    }
}

/// The bytes of a big-endian value reversed into a little-endian buffer.
fn swapped(b: &[u8]) -> [u8; 8] {
    let mut a = [0u8; 8];
    for (d, s) in a.iter_mut().zip(b.iter().rev()) {
        *d = *s;
    }
    a
}

/// Appends `v` as a little-endian value of type `ty` (integers rounded and saturated: the text
/// readers only let integral, in-range values through for integer properties).
pub fn encode_le(ty: ScalarType, v: f64, out: &mut Vec<u8>) {
    use ScalarType::*;
    let r = v.round();
    match ty {
        U8 => out.push(r as u8),
        I8 => out.push(r as i8 as u8),
        U16 => out.extend_from_slice(&(r as u16).to_le_bytes()),
        I16 => out.extend_from_slice(&(r as i16).to_le_bytes()),
        U32 => out.extend_from_slice(&(r as u32).to_le_bytes()),
        I32 => out.extend_from_slice(&(r as i32).to_le_bytes()),
        U64 => out.extend_from_slice(&(r as u64).to_le_bytes()),
        I64 => out.extend_from_slice(&(r as i64).to_le_bytes()),
        F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
        F64 => out.extend_from_slice(&v.to_le_bytes()),
    }
}

/// Running coordinate bounds.
#[derive(Debug, Clone, Copy)]
pub struct Bounds {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            lo: [f64::INFINITY; 3],
            hi: [f64::NEG_INFINITY; 3],
        }
    }
}

impl Bounds {
    /// Extends the bounds by one point.
    pub fn add(&mut self, p: [f64; 3]) {
        for ((lo, hi), c) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
            *lo = lo.min(c);
            *hi = hi.max(c);
        }
    }

    /// (min, max).
    pub fn get(&self) -> [[f64; 3]; 2] {
        [self.lo, self.hi]
    }
}

/// Where a point's coordinates and normal are among its properties ([`xyz_and_normals`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct XyzNormals {
    /// The indices of x, y and z; None when one is missing.
    pub xyz: Option<[usize; 3]>,
    /// The indices of nx, ny, nz (or normal_x, normal_y, normal_z); None when one is missing.
    pub normals: Option<[usize; 3]>,
}

/// The indices of x, y, z and of the normal (nx ny nz or normal_x normal_y normal_z) among
/// property names.
pub fn xyz_and_normals<'a>(names: impl Iterator<Item = &'a str> + Clone) -> XyzNormals {
    let find = |n: &str| names.clone().position(|m| m == n);
    let three = |a: &str, b: &str, c: &str| Some([find(a)?, find(b)?, find(c)?]);
    let normals = three("nx", "ny", "nz").or_else(|| three("normal_x", "normal_y", "normal_z"));
    XyzNormals {
        xyz: three("x", "y", "z"),
        normals,
    }
}

/// A file normal as the engine wants it: `None` when it is not finite or zero (PCL writes NaN
/// normals where its estimate failed), so that PCA takes over for that point.
pub fn usable_normal(n: [f64; 3]) -> Option<[f64; 3]> {
    (n.iter().all(|c| c.is_finite()) && n != [0.0; 3]).then_some(n)
}

/// Hands `records` (whole records of `record_length` bytes) to `f` about `chunk_points` at a
/// time, with the index of each slice's first record: the streaming of every source whose
/// records lie in memory as they are.
pub(crate) fn for_each_record_chunk(
    records: &[u8],
    record_length: usize,
    chunk_points: usize,
    f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
) -> Result<()> {
    let per = chunk_points.max(1);
    for (i, chunk) in records.chunks(per * record_length.max(1)).enumerate() {
        f((i * per) as u64, chunk)?;
    }
    Ok(())
}

/// The error of a directory given as an input file (bad input: [`detect`] finds it before a
/// reader, [`map_file`] when the name looks like a point file's).
fn a_directory(path: &Path) -> Error {
    Error::bad_input(
        path,
        None,
        format!(
            "is a directory, not a point file; name the files in it (for example {}/*.laz)",
            path.display().to_string().trim_end_matches('/')
        ),
    )
}

/// Memory-maps an input file read-only.
pub fn map_file(path: &Path) -> Result<InputBytes> {
    let io = |e| Error::read_input(path, e);
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if meta.is_dir() {
        return Err(a_directory(path));
    }
    if meta.len() == 0 {
        return Err(Error::bad_input(path, None, "the file is empty (0 bytes)"));
    }
    // SAFETY: the map is read-only and tilecurv never writes its inputs; another process
    // truncating the file during the run would fault, the usual mmap contract (see LasSource).
    unsafe { Mmap::map(&file) }.map(InputBytes::Map).map_err(io)
}

/// The bounds a source declares without reading its points: a LAS header's, when all six are
/// finite (they can still be wrong: callers treat them as a hint); None for other formats.
pub fn declared_bounds(s: &dyn PointSource) -> Option<[[f64; 3]; 2]> {
    match s.layout() {
        SourceLayout::Las(parts) => {
            let (min, max) = (parts.header.min, parts.header.max);
            min.iter()
                .chain(&max)
                .all(|v| v.is_finite())
                .then_some([min, max])
        }
        SourceLayout::Converted => None,
    }
}

/// The unit of every format without a CRS.
pub fn no_crs(format: &str) -> UnitSource {
    UnitSource::Unknown(format!("{format} has no CRS"))
}

/// The input formats, as [`detect`] tells them apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// LAS or LAZ.
    Las,
    /// PLY (any encoding).
    Ply,
    /// PCD.
    Pcd,
    /// XYZ text (`.xyz`, `.pts`, `.txt`).
    Xyz,
    /// ASCII OFF mesh.
    Off,
    /// OBJ mesh.
    Obj,
}

/// The format of a file, from its extension, or from a LAS or PLY signature when the extension
/// is unknown.
pub fn detect(path: &Path) -> Result<Format> {
    if path.is_dir() {
        return Err(a_directory(path));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    Ok(match ext.as_str() {
        "las" | "laz" => Format::Las,
        "ply" => Format::Ply,
        "pcd" => Format::Pcd,
        "xyz" | "pts" | "txt" => Format::Xyz,
        "off" => Format::Off,
        "obj" => Format::Obj,
        _ => {
            let mut sig = [0u8; 4];
            let sig = std::fs::File::open(path)
                .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut sig))
                .map(|_| sig)
                .unwrap_or_default();
            if &sig == b"LASF" {
                Format::Las
            } else if &sig[..3] == b"ply" {
                Format::Ply
            } else if !path.exists() {
                return Err(Error::read_input(
                    path,
                    std::io::Error::from(std::io::ErrorKind::NotFound),
                ));
            } else {
                return Err(Error::bad_input(
                    path,
                    None,
                    format!(
                        "unsupported input format {ext:?}: tilecurv reads .las, .laz, .ply, .pcd, .xyz, .pts, .txt, .off and .obj"
                    ),
                ));
            }
        }
    })
}

/// Opens a point cloud file, choosing the reader from its signature and extension.
pub fn open(path: &Path) -> Result<Box<dyn PointSource>> {
    open_format(path, detect(path)?)
}

/// Opens a file with the reader of `format`.
pub fn open_format(path: &Path, format: Format) -> Result<Box<dyn PointSource>> {
    open_bytes(path, format, map_file(path)?)
}

/// Opens `bytes` as a file of `format`; `path` only names it in errors. The one
/// implementation behind [`open_format`] (bytes of a memory-mapped file) and the fuzz targets
/// (bytes in memory, no file written).
pub fn open_bytes(path: &Path, format: Format, bytes: InputBytes) -> Result<Box<dyn PointSource>> {
    if bytes.is_empty() {
        return Err(Error::bad_input(path, None, "the file is empty (0 bytes)"));
    }
    Ok(match format {
        Format::Las => Box::new(LasSource::from_bytes(path, bytes)?),
        Format::Ply => ply::from_bytes(path, bytes)?,
        Format::Pcd => pcd::from_bytes(path, bytes)?,
        Format::Xyz => Box::new(text::TextSource::xyz_from_bytes(path, bytes)?),
        Format::Off => Box::new(mesh::off_from_bytes(path, bytes)?),
        Format::Obj => Box::new(mesh::obj_from_bytes(path, bytes)?),
    })
}

/// Opens a mesh file as `n` points sampled uniformly by area on its faces, with the faces'
/// normals, from the run's `seed` (`process --sample-faces`; see [`sampled`]).
pub fn open_sampled(path: &Path, n: u64, seed: u64) -> Result<Box<dyn PointSource>> {
    sampled::open(path, n, seed)
}
