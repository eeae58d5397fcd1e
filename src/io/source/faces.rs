//! A mesh's faces as its readers hand them over for `--sample-faces`: the [`Faces`] collector
//! (index checks, fan triangulation), the [`Place`] of a face for error messages and the
//! [`integer`] parser of face tokens. Shared by the OBJ/OFF reader (`mesh.rs`), the PLY reader
//! (`ply.rs`) and the sampler (`sampled.rs`), none of which it imports.

use std::path::Path;

use crate::error::{Error, Result};

use super::text::parse_number;

/// Where a face is in its file, for error messages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Place {
    /// A 1-based line of a text file.
    Line(u64),
    /// A byte offset in a binary file.
    Byte(u64),
}

/// An integer token of a face (an index or a count), parsed by the shared number parser;
/// None when it is not a number or not a whole number that fits exactly in an f64.
pub fn integer(tok: &[u8]) -> Option<i64> {
    let v = parse_number(tok)?;
    (v.fract() == 0.0 && v.abs() <= (1u64 << 53) as f64).then_some(v as i64)
}

/// Collects a mesh's polygons as triangles: checks each vertex index against the vertex count
/// and fan-triangulates (v0 v1 v2, v0 v2 v3, ...), which keeps the polygon's orientation.
pub struct Faces<'a> {
    path: &'a Path,
    vertices: usize,
    /// The index of the first vertex as the file counts (1 in OBJ, 0 in OFF and PLY), for
    /// messages.
    base: i64,
    triangles: Vec<[u32; 3]>,
    polygons: u64,
}

impl<'a> Faces<'a> {
    /// A collector for a mesh of `vertices` vertices whose file counts them from `base`.
    pub fn new(path: &'a Path, vertices: usize, base: i64) -> Result<Self> {
        if vertices > u32::MAX as usize {
            return Err(Error::bad_input(
                path,
                None,
                format!(
                    "the mesh has {vertices} vertices; --sample-faces handles at most 4294967295"
                ),
            ));
        }
        Ok(Faces {
            path,
            vertices,
            base,
            triangles: Vec::new(),
            polygons: 0,
        })
    }

    /// The number of polygons added.
    pub fn polygons(&self) -> u64 {
        self.polygons
    }

    /// The triangles, three 0-based vertex indices each, in the order the polygons came.
    pub fn into_triangles(self) -> Vec<[u32; 3]> {
        self.triangles
    }

    /// A bad-input error at `at`.
    pub fn bad(&self, at: Place, what: impl std::fmt::Display) -> Error {
        match at {
            Place::Line(no) => Error::bad_input(self.path, None, format!("line {no}: {what}")),
            Place::Byte(o) => Error::bad_input(self.path, Some(o), what.to_string()),
        }
    }

    /// Adds one polygon given by 0-based vertex indices (as resolved by the format's reader).
    pub fn polygon(&mut self, indices: &[i64], at: Place) -> Result<()> {
        if indices.len() < 3 {
            return Err(self.bad(
                at,
                format!(
                    "a face has {} vertices; a face needs at least 3",
                    indices.len()
                ),
            ));
        }
        let n = self.vertices as i64;
        if let Some(&i) = indices.iter().find(|&&i| !(0..n).contains(&i)) {
            let b = self.base;
            return Err(self.bad(
                at,
                format!(
                    "face vertex index {} is out of range: the file has {n} vertices, numbered {b} to {}",
                    i + b,
                    n - 1 + b
                ),
            ));
        }
        // In range, so each fits in u32 (`new` checked the vertex count).
        let v0 = indices[0] as u32;
        for w in indices[1..].windows(2) {
            self.triangles.push([v0, w[0] as u32, w[1] as u32]);
        }
        self.polygons += 1;
        Ok(())
    }
}
