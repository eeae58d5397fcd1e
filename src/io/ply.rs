//! PLY output: one `vertex` element with every property of the input (names and types as the
//! input declares them; for LAS input x, y, z as double and the standard fields) followed by
//! tilecurv's columns, binary little endian or ASCII. Written to a temporary file renamed over
//! the output by `finish` and removed on any failure, like the LAS writer.
//!
//! The new columns are named for CloudCompare by default ([`PlyNames`]): its PLY reader (libs/
//! qCC_io/PlyFilter.cpp) takes a vertex property as a scalar field without asking only when its
//! name contains "scal" (or names an intensity), and strips a `scalar_` prefix back off (with
//! `_` read as a space), while `nx ny nz` are its (and MeshLab's) normals. So the normals are
//! written as `nx ny nz` and every other column as `scalar_<name>` (`scalar_H`, ...), which
//! CloudCompare's command line shows as `H`; the LAS names are an option.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Error, Result};
use crate::io::columns::output::OutputColumns;
use crate::io::direct::DirectFile;
use crate::io::durable::{Ready, TempFile};
use crate::io::las::extra_bytes::ScalarType;
use crate::io::output::PointSink;
use crate::io::source::ply::ply_type_name;
use crate::io::source::{encode_le, PointSource, Property};

/// A PLY output being written.
pub struct PlyWriter {
    /// Removed on every path but a successful `finish`.
    tmp: TempFile,
    w: DirectFile,
    ascii: bool,
    /// The input's properties with the type each is written as.
    props: Vec<(Property, ScalarType)>,
    /// Bytes per input record.
    record_length: usize,
    /// The new columns' types, in record order.
    columns: Vec<ScalarType>,
    /// Bytes of new columns per record.
    columns_len: usize,
    buf: Vec<u8>,
    text: String,
}

/// How the new columns are named in a PLY output.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PlyNames {
    /// `nx ny nz` and `scalar_<name>`: what CloudCompare loads as normals and scalar fields.
    #[default]
    CloudCompare,
    /// The LAS column names (`NormalX`, `H`, ...).
    Las,
}

impl PlyNames {
    /// The PLY property name of the new column `name`.
    pub fn name(self, name: &str) -> String {
        match (self, name) {
            (PlyNames::Las, _) => name.to_string(),
            (PlyNames::CloudCompare, "NormalX") => "nx".into(),
            (PlyNames::CloudCompare, "NormalY") => "ny".into(),
            (PlyNames::CloudCompare, "NormalZ") => "nz".into(),
            (PlyNames::CloudCompare, n) => format!("scalar_{n}"),
        }
    }
}

/// A property name PLY can carry: no whitespace (LAS extra dimensions may have some).
fn ply_name(name: &str) -> String {
    let n = name.split_whitespace().collect::<Vec<_>>().join("_");
    if n.is_empty() {
        "unnamed".into()
    } else {
        n
    }
}

/// The PLY property names of the new columns `new` (LAS names, in record order) after an
/// input with the properties `input`, named as `names` says; an input's own `nx ny nz`
/// (ignored with --ignore-file-normals) leave the new normals their LAS names. Err: a new
/// column whose name (PLY or LAS, any case) an input property already has, as (that name, the
/// column's LAS name).
pub fn column_names<'a>(
    input: &[&str],
    new: impl IntoIterator<Item = &'a str>,
    names: PlyNames,
) -> std::result::Result<Vec<String>, (String, String)> {
    let taken = |n: &str| input.iter().any(|p| p.eq_ignore_ascii_case(n));
    let mut out = Vec::new();
    for column in new {
        let mapped = names.name(column);
        let normal = mapped.len() == 2 && mapped.starts_with('n');
        let name = if normal && taken(&mapped) {
            column.to_string()
        } else {
            mapped
        };
        if let Some(clash) = [name.as_str(), column].into_iter().find(|n| taken(n)) {
            return Err((clash.to_string(), column.to_string()));
        }
        out.push(name);
    }
    Ok(out)
}

impl PlyWriter {
    /// Creates the temporary output beside `output` and writes the header: the provenance and
    /// the column descriptions as comments, then the vertex element.
    pub fn create(
        source: &dyn PointSource,
        output: &Path,
        cols: &OutputColumns,
        provenance: &str,
        ascii: bool,
        names: PlyNames,
    ) -> Result<Self> {
        // PLY has no 64-bit integers: those (from LAS extra bytes or PCD) are written as double.
        let props: Vec<(Property, ScalarType)> = source
            .properties()
            .into_iter()
            .map(|p| {
                let ty = if ply_type_name(p.ty).is_some() {
                    p.ty
                } else {
                    ScalarType::F64
                };
                (p, ty)
            })
            .collect();
        let new = cols.descriptors();
        let input: Vec<&str> = props.iter().map(|(p, _)| p.name.as_str()).collect();
        let new_names = column_names(&input, new.iter().map(|c| c.name.as_str()), names)
            .map_err(|(clash, column)| {
                // `process` refuses this before any work (run::rerun); a safety net.
                Error::bad_input(source.path(), None, format!(
                    "the input already has a property named {clash:?}, the PLY name of the new column {column}; leave the column out with --columns, or rename the input's property"
                ))
            })?;
        let mut head = String::from("ply\n");
        head += if ascii {
            "format ascii 1.0\n"
        } else {
            "format binary_little_endian 1.0\n"
        };
        for line in provenance.lines() {
            let _ = writeln!(head, "comment {line}");
        }
        for (c, name) in new.iter().zip(&new_names) {
            let _ = writeln!(head, "comment {name}: {}", c.description);
        }
        let _ = writeln!(head, "element vertex {}", source.len());
        let typed = props
            .iter()
            .map(|(p, ty)| (*ty, ply_name(&p.name)))
            .chain(new.iter().zip(&new_names).map(|(c, n)| (c.ty, n.clone())));
        for (ty, name) in typed {
            let ty = ply_type_name(ty).unwrap_or("double");
            let _ = writeln!(head, "property {ty} {name}");
        }
        head += "end_header\n";
        let (tmp, file) = TempFile::create(output)?;
        let mut w = DirectFile::new(file, tmp.path());
        w.write_all(head.as_bytes()).map_err(|e| tmp.error(e))?;
        Ok(PlyWriter {
            tmp,
            w,
            ascii,
            props,
            record_length: source.record_length(),
            columns: new.iter().map(|c| c.ty).collect(),
            columns_len: cols.record_size(),
            buf: Vec::new(),
            text: String::new(),
        })
    }

    /// Appends one record as binary little endian.
    fn binary(&mut self, rec: &[u8]) {
        for (p, ty) in &self.props {
            if *ty == p.ty {
                p.put_le(rec, &mut self.buf);
            } else {
                encode_le(*ty, p.value(rec), &mut self.buf);
            }
        }
        self.buf.extend_from_slice(&rec[self.record_length..]);
    }

    /// Appends one record as an ASCII line.
    fn ascii(&mut self, rec: &[u8]) {
        let values = self.props.iter().map(|(p, ty)| (*ty, p.value(rec)));
        let mut at = self.record_length;
        let columns = self.columns.iter().map(|&ty| {
            let v = ty.decode(&rec[at..]);
            at += ty.size();
            (ty, v)
        });
        for (i, (ty, v)) in values.chain(columns).enumerate() {
            if i > 0 {
                self.text.push(' ');
            }
            // Display prints the shortest text that reads back to the same value.
            let _ = match ty {
                ScalarType::F32 => write!(self.text, "{}", v as f32),
                ScalarType::F64 => write!(self.text, "{v}"),
                _ => write!(self.text, "{}", v as i64),
            };
        }
        self.text.push('\n');
    }
}

impl PointSink for PlyWriter {
    fn write_points(&mut self, records: &[u8]) -> Result<()> {
        self.buf.clear();
        self.text.clear();
        for rec in records.chunks_exact(self.record_length + self.columns_len) {
            if self.ascii {
                self.ascii(rec);
            } else {
                self.binary(rec);
            }
        }
        let bytes = if self.ascii {
            self.text.as_bytes()
        } else {
            &self.buf
        };
        self.w.write_all(bytes).map_err(|e| self.tmp.error(e))
    }

    fn finish(self: Box<Self>) -> Result<Ready> {
        let PlyWriter { tmp, w, .. } = *self;
        let file = w.into_file().map_err(|e| tmp.error(e))?;
        tmp.ready(file)
    }

    fn abandon(self: Box<Self>) {
        // The buffered records are discarded, not flushed; dropping `tmp` removes the file.
        drop(self.tmp);
    }
}
