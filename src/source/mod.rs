//! Reading points. A [`PointSource`] streams a file's points in file order as chunks of raw
//! records (the bytes `assemble` carries to the output) and decodes coordinates and file normals
//! from them. One module per format; [`open`] picks by content and extension.

pub mod las;

use std::path::Path;

use crate::crs::UnitSource;
use crate::error::{Error, Result};

pub use las::LasSource;

/// One point as the engine sees it: original index, coordinates, and the file's normal if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourcePoint {
    /// Index of the point in its file (file order).
    pub id: u64,
    /// Coordinates in file units.
    pub xyz: [f64; 3],
    /// The normal stored in the file, if any.
    pub normal: Option<[f64; 3]>,
}

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
    /// Bytes per raw record in the chunks passed to `for_each_chunk`.
    fn record_length(&self) -> usize;
    /// Streams the raw records in file order, about `chunk_points` at a time, calling
    /// `f(first_point_index, records)`; stops at the first error.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()>;
    /// Decodes one raw record.
    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint;
    /// A short description of the format for the log, e.g. "LAS 1.4 format 6 (LAZ)".
    fn describe(&self) -> String;
    /// The LAS/LAZ source, when this is one (its records can be written back as LAS untouched).
    fn as_las(&self) -> Option<&LasSource>;
}

/// Opens a point cloud file, choosing the reader from its signature and extension.
pub fn open(path: &Path) -> Result<Box<dyn PointSource>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(LasSource::open(path)?)),
        _ => {
            // Unknown extension: a LAS signature still identifies the format.
            let mut sig = [0u8; 4];
            let is_las = std::fs::File::open(path)
                .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut sig))
                .map(|_| &sig == b"LASF")
                .unwrap_or(false);
            if is_las {
                Ok(Box::new(LasSource::open(path)?))
            } else if !path.exists() {
                Err(Error::ReadIo {
                    path: path.to_path_buf(),
                    source: std::io::Error::from(std::io::ErrorKind::NotFound),
                })
            } else {
                Err(Error::bad_input(
                    path,
                    None,
                    format!(
                        "unsupported input format {ext:?}: tilecurv reads LAS and LAZ (.las, .laz)"
                    ),
                ))
            }
        }
    }
}
