//! Points held in memory (a numpy array handed over by the Python package, or any caller's
//! buffer) as a [`PointSource`], so that `run::memory` runs them through the same stages as a
//! file: the same scan, tiles, neighbour search, estimators and orientation. The records are
//! the caller's bytes, read in place (no copy): fixed-length records holding x, y and z either
//! as f64 (an (n, 3) array, or a structured array's X, Y, Z fields: what PDAL hands out) or as
//! LAS integers with a scale and offset (laspy's point records, which are the file's records
//! byte for byte), with the LAS point format's classification and the CRS records that give
//! the units.

use std::ops::Deref;
use std::path::{Path, PathBuf};

use crate::core::grid::AxisGrid;
use crate::core::point::SourcePoint;
use crate::core::select::{las_point_class, PointClass};
use crate::error::{Error, Result};
use crate::io::crs::{horizontal_unit, UnitSource};
use crate::io::crs_summary::{vertical_unit, VerticalUnit};
use crate::io::las::extra_bytes::ScalarType;
use crate::io::las::header::Quantisation;
use crate::io::las::vlr::Vlr;
use crate::io::source::{no_crs, PointSource, Property, SourceLayout, Stored};

/// Bytes that stay valid and unchanged while a source reads them (a numpy array kept alive by
/// the Python package, a `Vec`).
pub type Records = Box<dyn Deref<Target = [u8]> + Send + Sync>;

/// How x, y and z are stored in a record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coordinates {
    /// Little-endian f64 at these byte offsets.
    F64([usize; 3]),
    /// Little-endian i32 at these byte offsets, as a LAS file stores them, with the file's
    /// scale and offset.
    Las {
        /// Byte offsets of X, Y and Z.
        at: [usize; 3],
        /// The scale and offset of each axis.
        grid: Quantisation,
    },
}

/// Points in memory, read in place.
pub struct MemorySource {
    name: PathBuf,
    records: Records,
    record_length: usize,
    coordinates: Coordinates,
    /// How LAS integers become coordinates (`Coordinates::Las`): the LAS reader's grid.
    axes: [AxisGrid; 3],
    normals: Option<Vec<f64>>,
    point_format: Option<u8>,
    vlrs: Vec<Vlr>,
}

impl MemorySource {
    /// `records.len() / record_length` points with their coordinates where `coordinates` says;
    /// `name` names them in messages (`<array>`). Refuses an empty buffer, a record too short
    /// for its coordinates and a length that is not a whole number of records.
    pub fn new(
        name: &str,
        records: Records,
        record_length: usize,
        coordinates: Coordinates,
    ) -> Result<Self> {
        let name = PathBuf::from(name);
        let (at, width) = match coordinates {
            Coordinates::F64(at) => (at, 8),
            Coordinates::Las { at, .. } => (at, 4),
        };
        let usage = |what: String| Err(Error::Usage(format!("{}: {what}", name.display())));
        if record_length == 0 || at.iter().any(|&a| a + width > record_length) {
            return usage(format!(
                "records of {record_length} bytes cannot hold coordinates at byte offsets {at:?}"
            ));
        }
        if records.is_empty() {
            return usage("no points: there is nothing to compute".into());
        }
        if !records.len().is_multiple_of(record_length) {
            return usage(format!(
                "{} bytes are not a whole number of {record_length}-byte records",
                records.len()
            ));
        }
        let axes = match coordinates {
            Coordinates::Las { grid, .. } => {
                [0, 1, 2].map(|a| AxisGrid::new(grid.scale[a], grid.offset[a], 1.0))
            }
            Coordinates::F64(_) => [AxisGrid::new(1.0, 0.0, 1.0); 3],
        };
        Ok(MemorySource {
            name,
            records,
            record_length,
            coordinates,
            axes,
            normals: None,
            point_format: None,
            vlrs: Vec::new(),
        })
    }

    /// The same points with these normals (x, y, z per point, in record order), used as a
    /// file's normals are (a point whose normal is not finite or zero gets a PCA normal).
    pub fn with_normals(mut self, normals: Vec<f64>) -> Result<Self> {
        if normals.len() as u64 != 3 * self.len() {
            return Err(Error::Usage(format!(
                "{}: {} normal components for {} points: give one normal (3 values) per point",
                self.name.display(),
                normals.len(),
                self.len()
            )));
        }
        self.normals = Some(normals);
        Ok(self)
    }

    /// The same points as LAS records of `point_format` (their classification and withheld
    /// flag select the points as `--classes` and `--skip-classes` do), with the file's VLRs and
    /// EVLRs (`vlrs`), whose CRS records give the horizontal and vertical units as a file's do.
    pub fn with_las(mut self, point_format: u8, vlrs: Vec<Vlr>) -> Result<Self> {
        let needed = crate::io::las::header::POINT_FORMAT_SIZES
            .get(point_format as usize)
            .copied();
        match needed {
            Some(size) if size as usize <= self.record_length => {}
            _ => {
                return Err(Error::Usage(format!(
                    "{}: records of {} bytes are not LAS point format {point_format} records",
                    self.name.display(),
                    self.record_length
                )))
            }
        }
        self.point_format = Some(point_format);
        self.vlrs = vlrs;
        Ok(self)
    }

    fn f64_at(rec: &[u8], at: usize) -> f64 {
        let mut b = [0u8; 8];
        b.copy_from_slice(&rec[at..at + 8]);
        f64::from_le_bytes(b)
    }

    fn i32_at(rec: &[u8], at: usize) -> i64 {
        let mut b = [0u8; 4];
        b.copy_from_slice(&rec[at..at + 4]);
        i32::from_le_bytes(b) as i64
    }
}

impl PointSource for MemorySource {
    fn path(&self) -> &Path {
        &self.name
    }

    fn len(&self) -> u64 {
        (self.records.len() / self.record_length) as u64
    }

    fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    fn unit(&self) -> UnitSource {
        match self.point_format {
            Some(_) => horizontal_unit(&self.vlrs),
            None => no_crs("an array of coordinates"),
        }
    }

    fn vertical_unit(&self) -> VerticalUnit {
        match self.point_format {
            Some(_) => vertical_unit(&self.vlrs),
            None => VerticalUnit::Undeclared("an array of coordinates has no CRS".into()),
        }
    }

    fn record_length(&self) -> usize {
        self.record_length
    }

    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        super::for_each_record_chunk(&self.records, self.record_length, chunk_points, f)
    }

    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint {
        let xyz = match self.coordinates {
            Coordinates::F64(at) => at.map(|a| Self::f64_at(rec, a)),
            Coordinates::Las { at, .. } => {
                [0, 1, 2].map(|a| self.axes[a].value(Self::i32_at(rec, at[a])))
            }
        };
        let normal = self.normals.as_ref().and_then(|n| {
            let i = 3 * id as usize;
            crate::io::source::usable_normal([n[i], n[i + 1], n[i + 2]])
        });
        SourcePoint { id, xyz, normal }
    }

    fn integer_coordinates(&self) -> Option<Quantisation> {
        match self.coordinates {
            Coordinates::Las { grid, .. } => Some(grid),
            Coordinates::F64(_) => None,
        }
    }

    fn class_of(&self, rec: &[u8]) -> Option<PointClass> {
        las_point_class(self.point_format?, rec)
    }

    fn has_classes(&self) -> bool {
        self.point_format.is_some()
    }

    fn describe(&self) -> String {
        match self.point_format {
            Some(f) => format!("LAS point format {f} records in memory"),
            None => "coordinates in memory".into(),
        }
    }

    fn layout(&self) -> SourceLayout<'_> {
        SourceLayout::Converted
    }

    fn properties(&self) -> Vec<Property> {
        let names = ["x", "y", "z"];
        match self.coordinates {
            Coordinates::F64(at) => (0..3)
                .map(|a| Property::new(names[a], ScalarType::F64, Stored::Le(at[a])))
                .collect(),
            Coordinates::Las { at, grid } => (0..3)
                .map(|a| {
                    let stored = Stored::Scaled {
                        raw: ScalarType::I32,
                        at: at[a],
                        scale: grid.scale[a],
                        offset: grid.offset[a],
                    };
                    Property::new(names[a], ScalarType::F64, stored)
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Coordinates are read in place at their offsets, chunks cover every record once with
    /// their first index, and a LAS record's class comes from its point format's byte.
    #[test]
    fn records_are_read_in_place() {
        let mut bytes = Vec::new();
        for i in 0..5u8 {
            bytes.push(i); // a leading field
            for c in [1.5 * i as f64, -2.0, 1e9 + i as f64] {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        let s = MemorySource::new("<array>", Box::new(bytes), 25, Coordinates::F64([1, 9, 17]))
            .expect("valid");
        assert_eq!(s.len(), 5);
        let mut seen = Vec::new();
        s.for_each_chunk(2, &mut |first, recs| {
            for (j, r) in recs.chunks_exact(25).enumerate() {
                seen.push(s.decode(first + j as u64, r));
            }
            Ok(())
        })
        .expect("read");
        assert_eq!(seen.len(), 5);
        assert_eq!(seen[3].id, 3);
        assert_eq!(seen[3].xyz, [4.5, -2.0, 1e9 + 3.0]);
        assert!(MemorySource::new(
            "<a>",
            Box::new(vec![0u8; 24]),
            20,
            Coordinates::F64([0, 8, 16])
        )
        .is_err());
        assert!(MemorySource::new(
            "<a>",
            Box::new(vec![0u8; 25]),
            24,
            Coordinates::F64([0, 8, 16])
        )
        .is_err());
        let mut rec = vec![0u8; 30];
        rec[16] = 7;
        rec[15] = 0x04;
        let las = MemorySource::new(
            "<las>",
            Box::new(rec.clone()),
            30,
            Coordinates::Las {
                at: [0, 4, 8],
                grid: Quantisation {
                    scale: [0.01; 3],
                    offset: [0.0; 3],
                },
            },
        )
        .and_then(|s| s.with_las(6, Vec::new()))
        .expect("format 6");
        assert_eq!(
            las.class_of(&rec),
            Some(PointClass {
                class: 7,
                withheld: true
            })
        );
    }
}
