//! Text point formats: `.xyz`, `.pts` and `.txt` clouds (`x y z [nx ny nz] [more columns]`),
//! and the line scanner every text format shares (ASCII PLY and PCD bodies, OFF and OBJ
//! vertices): one tokenizer, one number parser, one validation pass. The file is memory-mapped
//! and parsed a chunk at a time; records are the parsed values as f64 little endian, so a text
//! file streams as fixed-width raw records like a binary one. Headers are the callers' job.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::crs::UnitSource;
use crate::io::las::extra_bytes::ScalarType;

use super::{
    map_file, no_crs, usable_normal, xyz_and_normals, Bounds, InputBytes, PointSource, Property,
    SourceLayout, SourcePoint, Stored, XyzNormals,
};

/// Which lines of a text body hold points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lines {
    /// Every data line (not blank, not a comment) is a point (.xyz).
    All,
    /// Lines whose first token is this keyword; the keyword is not a value (`v` in OBJ).
    Keyword(&'static str),
    /// The `count` data lines after the first `skip` hold the points; the rest are ignored (OFF
    /// and ASCII PLY faces, PCD). Fewer than `count` is an error.
    Counted {
        /// Data lines before the points (ASCII PLY elements declared before `vertex`).
        skip: u64,
        /// Number of point lines the header declares.
        count: u64,
        /// What the header calls them, for messages ("vertices", "points").
        noun: &'static str,
    },
}

/// Where the points of a text file are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    /// Byte offset of the first line after the header.
    pub start: usize,
    /// 1-based line number of that line.
    pub first_line: u64,
    /// Which lines hold points.
    pub lines: Lines,
}

/// One value column of a text format.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// Name (`x`, `nx`, `segment_index`, ...).
    pub name: String,
    /// Declared type (f64 when the format declares none).
    pub ty: ScalarType,
}

impl Column {
    /// An f64 column.
    pub fn f64(name: impl Into<String>) -> Self {
        Column {
            name: name.into(),
            ty: ScalarType::F64,
        }
    }
}

/// Parses one numeric token: the one number parser of every text format (decimal, exponent,
/// `nan` and `inf` as Rust's `f64::from_str` reads them).
pub fn parse_number(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

/// The tokens of a line: separated by whitespace or commas.
pub fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace() || *b == b',')
        .filter(|t| !t.is_empty())
}

/// The point lines of a body, with their 1-based line numbers; comments (`#` to the end of the
/// line) and blank lines are skipped.
pub struct PointLines<'a> {
    data: &'a [u8],
    /// Byte offset of the next line.
    pub pos: usize,
    /// Line number of the next line.
    pub line: u64,
    lines: Lines,
    /// Data lines seen so far (for `Lines::Counted`).
    seen: u64,
    /// Point lines returned so far.
    pub points: u64,
}

impl<'a> PointLines<'a> {
    /// The point lines of `body` in `data`.
    pub fn new(data: &'a [u8], body: Body) -> Self {
        PointLines {
            data,
            pos: body.start,
            line: body.first_line,
            lines: body.lines,
            seen: 0,
            points: 0,
        }
    }
}

impl<'a> Iterator for PointLines<'a> {
    /// (line number, the line's values as text).
    type Item = (u64, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        while self.pos < self.data.len() {
            let rest = &self.data[self.pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let no = self.line;
            self.pos += len + 1;
            self.line += 1;
            let mut content = &rest[..len];
            if let Some(c) = content.iter().position(|&b| b == b'#') {
                content = &content[..c];
            }
            let Some(first) = tokens(content).next() else {
                continue;
            };
            match self.lines {
                Lines::All => {}
                Lines::Keyword(k) => {
                    if first != k.as_bytes() {
                        continue;
                    }
                    // `first` is a subslice of `content`: drop everything up to its end.
                    let end = first.as_ptr() as usize - content.as_ptr() as usize + first.len();
                    content = &content[end..];
                }
                Lines::Counted { skip, count, .. } => {
                    self.seen += 1;
                    if self.seen <= skip {
                        continue;
                    }
                    if self.seen > skip.saturating_add(count) {
                        self.pos = self.data.len();
                        return None;
                    }
                }
            }
            self.points += 1;
            return Some((no, content));
        }
        None
    }
}

/// The first point line of a body ([`first_point_line`]).
pub struct FirstPoint {
    /// Its line number.
    pub line: u64,
    /// How many values it holds.
    pub values: usize,
    /// The byte offset of the line after it.
    pub next_pos: usize,
    /// The line number of the line after it.
    pub next_line: u64,
}

/// The first point line of `body`. Fails when the body holds no point.
pub fn first_point_line(path: &Path, data: &[u8], body: Body) -> Result<FirstPoint> {
    let mut it = PointLines::new(data, body);
    match it.next() {
        Some((no, content)) => Ok(FirstPoint {
            line: no,
            values: tokens(content).count(),
            next_pos: it.pos,
            next_line: it.line,
        }),
        None => Err(no_points(path)),
    }
}

fn no_points(path: &Path) -> Error {
    Error::bad_input(
        path,
        None,
        "the file contains no points; there is nothing to compute",
    )
}

/// A memory-mapped text point cloud, validated in full when opened.
pub struct TextSource {
    path: PathBuf,
    map: InputBytes,
    describe: String,
    body: Body,
    columns: Vec<Column>,
    xyz: [usize; 3],
    normals: Option<[usize; 3]>,
    len: u64,
    bounds: [[f64; 3]; 2],
}

impl TextSource {
    /// Opens an `.xyz`/`.pts`/`.txt` cloud: one point per line, `x y z`, `x y z nx ny nz` or
    /// more columns (named `column7`, ...), whitespace or comma separated, `#` comments. A first
    /// line holding a single number (the point count of Leica `.pts`) is skipped.
    pub fn open_xyz(path: &Path) -> Result<Self> {
        Self::xyz_from_bytes(path, map_file(path)?)
    }

    /// [`TextSource::open_xyz`] on bytes already read or mapped; `path` names them in errors.
    pub fn xyz_from_bytes(path: &Path, map: InputBytes) -> Result<Self> {
        let mut body = Body {
            start: 0,
            first_line: 1,
            lines: Lines::All,
        };
        let mut first = first_point_line(path, &map, body)?;
        if first.values == 1 {
            body.start = first.next_pos;
            body.first_line = first.next_line;
            first = first_point_line(path, &map, body)?;
        }
        let (no, n) = (first.line, first.values);
        if n < 3 {
            return Err(Error::bad_input(
                path,
                None,
                format!("line {no}: expected at least 3 values (x y z) but found {n}"),
            ));
        }
        let columns = (0..n)
            .map(|i| match i {
                0..=2 => Column::f64(["x", "y", "z"][i]),
                3..=5 if n >= 6 => Column::f64(["nx", "ny", "nz"][i - 3]),
                _ => Column::f64(format!("column{}", i + 1)),
            })
            .collect();
        Self::new(path, map, format!("XYZ text ({n} columns)"), body, columns)
    }

    /// A text source over `body` of the mapped file with the given columns (which must include
    /// x, y and z). Parses and checks every point line once, counting the points and finding
    /// their bounds.
    pub fn new(
        path: &Path,
        map: InputBytes,
        describe: String,
        body: Body,
        columns: Vec<Column>,
    ) -> Result<Self> {
        let XyzNormals { xyz, normals } = xyz_and_normals(columns.iter().map(|c| c.name.as_str()));
        let Some(xyz) = xyz else {
            return Err(Error::bad_input(
                path,
                None,
                format!(
                    "the points have no x, y and z (their values are {}); expected properties named x, y and z",
                    names(&columns)
                ),
            ));
        };
        let mut src = TextSource {
            path: path.to_path_buf(),
            map,
            describe,
            body,
            columns,
            xyz,
            normals,
            len: 0,
            bounds: [[0.0; 3]; 2],
        };
        let mut b = Bounds::default();
        src.len = src.scan(&mut |v| {
            b.add(xyz.map(|a| v[a]));
            Ok(())
        })?;
        if src.len == 0 {
            return Err(no_points(path));
        }
        src.bounds = b.get();
        Ok(src)
    }

    /// Calls `f` with the values of every point line in order, after checking them: exactly
    /// one value per column, numeric, integral and in range for integer columns, finite
    /// coordinates. Returns the number of points.
    fn scan(&self, f: &mut dyn FnMut(&[f64]) -> Result<()>) -> Result<u64> {
        let bad = |no: u64, what: String| {
            Error::bad_input(&self.path, None, format!("line {no}: {what}"))
        };
        let mut values = Vec::with_capacity(self.columns.len());
        let mut lines = PointLines::new(&self.map, self.body);
        for (no, content) in lines.by_ref() {
            values.clear();
            for tok in tokens(content) {
                let i = values.len();
                let Some(col) = self.columns.get(i) else {
                    values.push(0.0);
                    continue; // counted below
                };
                let v = parse_number(tok).ok_or_else(|| {
                    bad(
                        no,
                        format!(
                            "value {} ({}) is {:?}, not a number",
                            i + 1,
                            col.name,
                            String::from_utf8_lossy(tok)
                        ),
                    )
                })?;
                if let Some((lo, hi)) = integer_range(col.ty) {
                    if !(v.fract() == 0.0 && (lo..=hi).contains(&v)) {
                        return Err(bad(
                            no,
                            format!(
                            "{} is {v} but is declared {:?}: expected an integer in {lo}..={hi}",
                            col.name, col.ty
                        ),
                        ));
                    }
                }
                values.push(v);
            }
            if values.len() != self.columns.len() {
                let hint = match self.body.lines {
                    Lines::Counted { count, noun, .. } => format!(
                        " (the header declares {count} {noun}: is the count too large, or the line damaged?)"
                    ),
                    _ => String::new(),
                };
                return Err(bad(
                    no,
                    format!(
                        "expected {} values ({}) but found {}{hint}",
                        self.columns.len(),
                        names(&self.columns),
                        values.len()
                    ),
                ));
            }
            if let Some(a) = self.xyz.iter().find(|&&a| !values[a].is_finite()) {
                return Err(bad(no, format!(
                    "coordinate {} is {}; every point needs finite x, y and z (remove invalid points first)",
                    self.columns[*a].name, values[*a]
                )));
            }
            f(&values)?;
        }
        if let Lines::Counted { count, noun, .. } = self.body.lines {
            if lines.points < count {
                return Err(bad(lines.line - 1, format!(
                    "the header declares {count} {noun} but the file ends after {}: it is truncated or the count is wrong",
                    lines.points
                )));
            }
        }
        Ok(lines.points)
    }
}

/// The range of an integer type as f64, or None for float types.
fn integer_range(ty: ScalarType) -> Option<(f64, f64)> {
    use ScalarType::*;
    Some(match ty {
        U8 => (0.0, u8::MAX as f64),
        I8 => (i8::MIN as f64, i8::MAX as f64),
        U16 => (0.0, u16::MAX as f64),
        I16 => (i16::MIN as f64, i16::MAX as f64),
        U32 => (0.0, u32::MAX as f64),
        I32 => (i32::MIN as f64, i32::MAX as f64),
        U64 => (0.0, u64::MAX as f64),
        I64 => (i64::MIN as f64, i64::MAX as f64),
        F32 | F64 => return None,
    })
}

fn names(columns: &[Column]) -> String {
    columns
        .iter()
        .map(|c| c.name.as_str())
        .collect::<Vec<_>>()
        .join(" ")
}

impl PointSource for TextSource {
    fn path(&self) -> &Path {
        &self.path
    }

    fn len(&self) -> u64 {
        self.len
    }

    fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    fn unit(&self) -> UnitSource {
        no_crs(&self.describe)
    }

    /// Eight bytes (an f64) per column.
    fn record_length(&self) -> usize {
        8 * self.columns.len()
    }

    /// Parses about `chunk_points` lines at a time into f64 records.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let chunk = chunk_points.max(1);
        let mut buf = Vec::with_capacity(chunk.min(1 << 20) * self.record_length());
        let (mut first, mut held) = (0u64, 0usize);
        self.scan(&mut |values| {
            for v in values {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            held += 1;
            if held == chunk {
                f(first, &buf)?;
                first += held as u64;
                held = 0;
                buf.clear();
            }
            Ok(())
        })?;
        if held > 0 {
            f(first, &buf)?;
        }
        Ok(())
    }

    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint {
        let at = |i: usize| ScalarType::F64.decode(&rec[8 * i..]);
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
        self.columns
            .iter()
            .enumerate()
            .map(|(i, c)| Property::new(c.name.clone(), c.ty, Stored::F64(8 * i)))
            .collect()
    }

    fn bounds(&self) -> Result<[[f64; 3]; 2]> {
        Ok(self.bounds)
    }
}

#[cfg(test)]
#[path = "text_tests.rs"]
mod tests;
