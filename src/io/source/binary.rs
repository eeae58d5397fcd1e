//! Fixed-size binary point records in a memory-mapped file: binary PLY vertices and binary PCD
//! bodies, validated against the file size and for finite coordinates when opened, then handed
//! out as slices of the map. Headers are the formats' job (`ply.rs`, `pcd.rs`).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::crs::UnitSource;

use super::{
    no_crs, usable_normal, xyz_and_normals, Bounds, InputBytes, PointSource, Property,
    SourceLayout, SourcePoint, XyzNormals,
};

/// Fixed-size binary point records in a memory-mapped file (binary PLY vertices, binary PCD),
/// validated against the file size and for finite coordinates when opened.
pub struct BinarySource {
    path: PathBuf,
    map: InputBytes,
    describe: String,
    start: usize,
    count: u64,
    record_length: usize,
    props: Vec<Property>,
    xyz: [usize; 3],
    normals: Option<[usize; 3]>,
    bounds: [[f64; 3]; 2],
}

impl BinarySource {
    /// `count` records of `record_length` bytes starting at byte `start` of `map`, holding
    /// `props` (which must include x, y and z; bytes no property covers are padding).
    pub fn new(
        path: &Path,
        map: InputBytes,
        describe: String,
        start: usize,
        count: u64,
        record_length: usize,
        props: Vec<Property>,
    ) -> Result<Self> {
        let XyzNormals { xyz, normals } = xyz_and_normals(props.iter().map(|p| p.name.as_str()));
        let Some(xyz) = xyz else {
            let names: Vec<_> = props.iter().map(|p| p.name.as_str()).collect();
            return Err(Error::bad_input(path, None, format!(
                "the points have no x, y and z (their properties are {}); expected properties named x, y and z",
                names.join(" ")
            )));
        };
        if count == 0 {
            return Err(Error::bad_input(
                path,
                None,
                "the header declares 0 points; there is nothing to compute",
            ));
        }
        if props
            .iter()
            .any(|p| p.stored.offset() + p.ty.size() > record_length)
        {
            return Err(Error::Internal(format!(
                "{}: a property lies outside the {record_length}-byte record",
                path.display()
            )));
        }
        let end = count
            .checked_mul(record_length as u64)
            .and_then(|b| b.checked_add(start as u64));
        if end.is_none_or(|e| e > map.len() as u64) {
            let whole = (map.len().saturating_sub(start) / record_length) as u64;
            return Err(Error::bad_input(path, Some(start as u64), format!(
                "the header declares {count} points of {record_length} bytes from byte {start}, but the file ends at byte {}: only {whole} whole points are present. The file is truncated or its point count is wrong",
                map.len()
            )));
        }
        let mut src = BinarySource {
            path: path.to_path_buf(),
            map,
            describe,
            start,
            count,
            record_length,
            props,
            xyz,
            normals,
            bounds: [[0.0; 3]; 2],
        };
        let mut b = Bounds::default();
        for i in 0..count as usize {
            let at = start + i * record_length;
            let p = src.decode(i as u64, &src.map[at..at + record_length]);
            if let Some(a) = (0..3).find(|&a| !p.xyz[a].is_finite()) {
                let o = src.props[xyz[a]].stored.offset();
                return Err(Error::bad_input(path, Some((at + o) as u64), format!(
                    "point {i} has {} = {}; every point needs finite x, y and z (remove invalid points first)",
                    src.props[xyz[a]].name, p.xyz[a]
                )));
            }
            b.add(p.xyz);
        }
        src.bounds = b.get();
        Ok(src)
    }
}

impl PointSource for BinarySource {
    fn path(&self) -> &Path {
        &self.path
    }

    fn len(&self) -> u64 {
        self.count
    }

    fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    fn unit(&self) -> UnitSource {
        no_crs(&self.describe)
    }

    fn record_length(&self) -> usize {
        self.record_length
    }

    /// Hands out slices of the map, about `chunk_points` records at a time.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let records = &self.map[self.start..self.start + self.count as usize * self.record_length];
        super::for_each_record_chunk(records, self.record_length, chunk_points, f)
    }

    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint {
        let at = |i: usize| self.props[i].value(rec);
        SourcePoint {
            id,
            xyz: self.xyz.map(at),
            normal: self.normals.and_then(|n| usable_normal(n.map(at))),
        }
    }

    fn describe(&self) -> String {
        self.describe.clone()
    }

    fn layout(&self) -> SourceLayout<'_> {
        SourceLayout::Converted
    }

    fn properties(&self) -> Vec<Property> {
        self.props.clone()
    }

    fn bounds(&self) -> Result<[[f64; 3]; 2]> {
        Ok(self.bounds)
    }
}
