//! PLY input (ASCII, binary little endian, binary big endian): parses the header, reads the
//! `vertex` element as the points (x y z, optional nx ny nz, every other property kept) and
//! skips every other element (faces, unless [`read_faces`] is asked for them). Binary vertices
//! are memory-mapped fixed-size records ([`BinarySource`], which binary PCD shares); ASCII
//! bodies go through the text scanner. Also the PLY type names, which the PLY writer uses too.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::las::extra_bytes::ScalarType;

use super::binary::BinarySource;
use super::faces::{integer, Faces, Place};
use super::text::{tokens, Body, Column, Lines, PointLines, TextSource};
use super::{map_file, InputBytes, PointSource, Property, Stored};

/// The PLY scalar type names with their types: the classic names first (the ones the writer
/// uses), then the sized aliases.
const PLY_TYPES: [(&str, ScalarType); 16] = [
    ("char", ScalarType::I8),
    ("uchar", ScalarType::U8),
    ("short", ScalarType::I16),
    ("ushort", ScalarType::U16),
    ("int", ScalarType::I32),
    ("uint", ScalarType::U32),
    ("float", ScalarType::F32),
    ("double", ScalarType::F64),
    ("int8", ScalarType::I8),
    ("uint8", ScalarType::U8),
    ("int16", ScalarType::I16),
    ("uint16", ScalarType::U16),
    ("int32", ScalarType::I32),
    ("uint32", ScalarType::U32),
    ("float32", ScalarType::F32),
    ("float64", ScalarType::F64),
];

/// The type a PLY type name stands for.
pub fn ply_type(name: &str) -> Option<ScalarType> {
    PLY_TYPES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The PLY name of a type, or None for the 64-bit integers, which PLY lacks.
pub fn ply_type_name(ty: ScalarType) -> Option<&'static str> {
    PLY_TYPES.iter().find(|(_, t)| *t == ty).map(|(n, _)| *n)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

struct PlyProperty {
    name: String,
    ty: ScalarType,
    /// For a list (`property list <count type> <item type> name`), the count type; `ty` is then
    /// the item type.
    list: Option<ScalarType>,
}

struct Element {
    name: String,
    count: u64,
    props: Vec<PlyProperty>,
    /// Header line declaring the element.
    line: u64,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the body.
    end: usize,
    /// Number of header lines.
    lines: u64,
    /// The text of the `comment` lines, in order.
    comments: Vec<String>,
}

fn parse_header(path: &Path, map: &[u8]) -> Result<Header> {
    let bad = |line: u64, what: String| {
        Error::bad_input(path, None, format!("header line {line}: {what}"))
    };
    let mut pos = 0usize;
    let mut line = 0u64;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    loop {
        let rest = &map[pos..];
        let Some(len) = rest.iter().position(|&b| b == b'\n') else {
            return Err(Error::bad_input(
                path,
                None,
                "the PLY header has no end_header line: the file is truncated or not PLY",
            ));
        };
        line += 1;
        pos += len + 1;
        let text = String::from_utf8_lossy(&rest[..len]);
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if line == 1 {
            if words != ["ply"] {
                return Err(bad(
                    1,
                    format!("expected \"ply\" but found {text:?}: not a PLY file"),
                ));
            }
            continue;
        }
        match words.as_slice() {
            ["end_header"] => break,
            ["comment", rest @ ..] => comments.push(rest.join(" ")),
            [] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::LittleEndian,
                    "binary_big_endian" => Encoding::BigEndian,
                    other => {
                        return Err(bad(line, format!(
                            "unknown format {other:?}; expected ascii, binary_little_endian or binary_big_endian"
                        )))
                    }
                })
            }
            ["element", name, count] => {
                let count = count.parse().map_err(|_| {
                    bad(line, format!("element {name} has count {count:?}, not a whole number"))
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                    line,
                });
            }
            ["property", rest @ ..] => {
                let Some(el) = elements.last_mut() else {
                    return Err(bad(line, "property before any element".into()));
                };
                let (list, ty, name) = match rest {
                    ["list", count_ty, ty, name] => {
                        let c = ply_type(count_ty)
                            .ok_or_else(|| unknown_type(path, line, count_ty))?;
                        (Some(c), *ty, *name)
                    }
                    [ty, name] => (None, *ty, *name),
                    _ => {
                        return Err(bad(line, format!(
                            "expected \"property <type> <name>\" or \"property list <type> <type> <name>\", found {text:?}"
                        )))
                    }
                };
                let ty = ply_type(ty).ok_or_else(|| unknown_type(path, line, ty))?;
                if el.props.iter().any(|p| p.name == name) {
                    return Err(bad(line, format!(
                        "element {} declares property {name:?} twice; the values would be ambiguous, rename one of them",
                        el.name
                    )));
                }
                el.props.push(PlyProperty {
                    name: name.to_string(),
                    ty,
                    list,
                });
            }
            _ => return Err(bad(line, format!("unexpected header line {text:?}"))),
        }
    }
    let encoding = encoding.ok_or_else(|| bad(2, "no \"format\" line in the header".into()))?;
    Ok(Header {
        encoding,
        elements,
        end: pos,
        lines: line,
        comments,
    })
}

/// The tilecurv provenance record among a PLY file's header comments (the PLY writer puts
/// each line of its record in a `comment`): from the last comment starting `tilecurv ` through
/// the `key=value` lines after it. None when there is none.
pub fn provenance(path: &Path, map: &[u8]) -> Result<Option<String>> {
    let h = parse_header(path, map)?;
    let Some(start) = h.comments.iter().rposition(|c| c.starts_with("tilecurv ")) else {
        return Ok(None);
    };
    let mut text = format!("{}\n", h.comments[start]);
    for c in h.comments[start + 1..]
        .iter()
        .take_while(|c| c.contains('='))
    {
        text.push_str(c);
        text.push('\n');
    }
    Ok(Some(text))
}

fn unknown_type(path: &Path, line: u64, ty: &str) -> Error {
    Error::bad_input(
        path,
        None,
        format!(
            "header line {line}: unknown property type {ty:?}; expected one of {}",
            PLY_TYPES.map(|(n, _)| n).join(", ")
        ),
    )
}

/// Opens a PLY file (any of the three encodings).
pub fn open(path: &Path) -> Result<Box<dyn PointSource>> {
    from_bytes(path, map_file(path)?)
}

/// [`open`] on bytes already read or mapped; `path` names them in errors.
pub fn from_bytes(path: &Path, map: InputBytes) -> Result<Box<dyn PointSource>> {
    let h = parse_header(path, &map)?;
    let Some(vi) = h.elements.iter().position(|e| e.name == "vertex") else {
        return Err(Error::bad_input(
            path,
            None,
            "the PLY header declares no \"vertex\" element: there are no points",
        ));
    };
    let before = &h.elements[..vi];
    let vertex = &h.elements[vi];
    if let Some(p) = vertex.props.iter().find(|p| p.list.is_some()) {
        return Err(Error::bad_input(path, None, format!(
            "header line {}: the vertex element has a list property ({}); tilecurv reads scalar vertex properties only",
            vertex.line, p.name
        )));
    }
    let describe = |enc: &str| format!("PLY {enc} ({} vertices)", vertex.count);
    if h.encoding == Encoding::Ascii {
        // In ASCII every element instance is one line, so earlier elements are skipped by count.
        let body = Body {
            start: h.end,
            first_line: h.lines + 1,
            lines: Lines::Counted {
                skip: before.iter().fold(0u64, |s, e| s.saturating_add(e.count)),
                count: vertex.count,
                noun: "vertices",
            },
        };
        let columns = vertex
            .props
            .iter()
            .map(|p| Column {
                name: p.name.clone(),
                ty: p.ty,
            })
            .collect();
        return Ok(Box::new(TextSource::new(
            path,
            map,
            describe("ASCII"),
            body,
            columns,
        )?));
    }
    let mut start = h.end;
    for e in before {
        if let Some(p) = e.props.iter().find(|p| p.list.is_some()) {
            return Err(Error::bad_input(path, None, format!(
                "header line {}: element {} precedes the vertices and has a list property ({}); tilecurv reads binary PLY whose vertex element comes first or follows fixed-size elements",
                e.line, e.name, p.name
            )));
        }
        let size: u64 = e.props.iter().map(|p| p.ty.size() as u64).sum();
        start = e
            .count
            .checked_mul(size)
            .and_then(|b| b.checked_add(start as u64))
            .and_then(|b| usize::try_from(b).ok())
            .filter(|&b| b <= map.len())
            .ok_or_else(|| {
                Error::bad_input(path, Some(start as u64), format!(
                    "element {} ({} x {size} bytes) runs past the end of the file ({} bytes): the file is truncated",
                    e.name, e.count, map.len()
                ))
            })?;
    }
    let big = h.encoding == Encoding::BigEndian;
    let mut at = 0usize;
    let props = vertex
        .props
        .iter()
        .map(|p| {
            let stored = if big { Stored::Be(at) } else { Stored::Le(at) };
            at += p.ty.size();
            Property::new(p.name.clone(), p.ty, stored)
        })
        .collect();
    let enc = if big {
        "binary big endian"
    } else {
        "binary little endian"
    };
    Ok(Box::new(BinarySource::new(
        path,
        map,
        describe(enc),
        start,
        vertex.count,
        at,
        props,
    )?))
}

/// Reads the `face` element of a PLY file into `faces`: its `vertex_indices` (or
/// `vertex_index`) list, 0-based, in any encoding; other face properties are skipped. Returns
/// false when the file declares no faces.
pub fn read_faces(path: &Path, map: &[u8], faces: &mut Faces) -> Result<bool> {
    let h = parse_header(path, map)?;
    let Some(fi) = h.elements.iter().position(|e| e.name == "face") else {
        return Ok(false);
    };
    let face = &h.elements[fi];
    if face.count == 0 {
        return Ok(false);
    }
    if !face.props.iter().any(is_indices) {
        let names: Vec<_> = face.props.iter().map(|p| p.name.as_str()).collect();
        return Err(Error::bad_input(path, None, format!(
            "header line {}: the face element has no list property vertex_indices (or vertex_index); its properties are: {}",
            face.line,
            names.join(" ")
        )));
    }
    if h.encoding == Encoding::Ascii {
        ascii_faces(map, &h, fi, faces)?;
    } else {
        binary_faces(map, &h, fi, faces)?;
    }
    Ok(true)
}

/// Whether a face property is the list of vertex indices.
fn is_indices(p: &PlyProperty) -> bool {
    p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
}

/// Reads the faces (element `fi`) of an ASCII body: one line per face, after one line per
/// instance of every earlier element.
fn ascii_faces(map: &[u8], h: &Header, fi: usize, faces: &mut Faces) -> Result<()> {
    let face = &h.elements[fi];
    let body = Body {
        start: h.end,
        first_line: h.lines + 1,
        lines: Lines::Counted {
            skip: h.elements[..fi]
                .iter()
                .fold(0u64, |s, e| s.saturating_add(e.count)),
            count: face.count,
            noun: "faces",
        },
    };
    let mut idx = Vec::new();
    let mut lines = PointLines::new(map, body);
    for (no, content) in lines.by_ref() {
        let at = Place::Line(no);
        ascii_face(content, at, face, faces, &mut idx)?;
        faces.polygon(&idx, at)?;
    }
    if lines.points < face.count {
        return Err(faces.bad(
            Place::Line(lines.line - 1),
            format!(
                "the header declares {} faces but the file ends after {}: it is truncated or the count is wrong",
                face.count, lines.points
            ),
        ));
    }
    Ok(())
}

/// Parses one ASCII face line into `idx` (its vertex indices); other properties are skipped.
fn ascii_face(
    content: &[u8],
    at: Place,
    face: &Element,
    faces: &Faces,
    idx: &mut Vec<i64>,
) -> Result<()> {
    let mut toks = tokens(content);
    let mut take = |what: &dyn Fn() -> String| {
        toks.next()
            .ok_or_else(|| faces.bad(at, format!("the face line ends before {}", what())))
    };
    let int = |tok: &[u8], what: &dyn Fn() -> String| {
        integer(tok).ok_or_else(|| {
            let tok = String::from_utf8_lossy(tok);
            faces.bad(at, format!("{} is {tok:?}, not an integer", what()))
        })
    };
    idx.clear();
    for p in &face.props {
        let name = || p.name.clone();
        let tok = take(&name)?;
        if p.list.is_none() {
            continue;
        }
        let len = || format!("the length of {}", p.name);
        let n = u64::try_from(int(tok, &len)?)
            .map_err(|_| faces.bad(at, format!("{} is negative", len())))?;
        for k in 0..n {
            let item = || format!("{} item {}", p.name, k + 1);
            let tok = take(&item)?;
            if is_indices(p) {
                idx.push(int(tok, &item)?);
            }
        }
    }
    if let Some(extra) = toks.next() {
        return Err(faces.bad(at, format!(
            "the face line has more values than the face element's properties ({:?} is one too many)",
            String::from_utf8_lossy(extra)
        )));
    }
    Ok(())
}

/// Reads the faces (element `fi`) of a binary body, walking the earlier elements (with list
/// properties, record by record).
fn binary_faces(map: &[u8], h: &Header, fi: usize, faces: &mut Faces) -> Result<()> {
    let face = &h.elements[fi];
    let mut cur = Cursor {
        map,
        pos: h.end,
        big: h.encoding == Encoding::BigEndian,
        faces,
    };
    for e in &h.elements[..fi] {
        if e.props.iter().all(|p| p.list.is_none()) {
            let size: u64 = e.props.iter().map(|p| p.ty.size() as u64).sum();
            cur.skip(e.count.saturating_mul(size), &e.name)?;
            continue;
        }
        for _ in 0..e.count {
            for p in &e.props {
                cur.property(p, &e.name, None)?;
            }
        }
    }
    let mut idx = Vec::new();
    for _ in 0..face.count {
        let at = Place::Byte(cur.pos as u64);
        idx.clear();
        for p in &face.props {
            let wanted = is_indices(p).then_some(&mut idx);
            cur.property(p, "face", wanted)?;
        }
        cur.faces.polygon(&idx, at)?;
    }
    Ok(())
}

/// A read position in a binary PLY body, for walking elements with list properties.
struct Cursor<'m, 'f, 'p> {
    map: &'m [u8],
    pos: usize,
    big: bool,
    faces: &'f mut Faces<'p>,
}

impl Cursor<'_, '_, '_> {
    /// Advances `bytes`, failing when that runs past the end of the file.
    fn skip(&mut self, bytes: u64, element: &str) -> Result<()> {
        let end = (self.pos as u64).saturating_add(bytes);
        if end > self.map.len() as u64 {
            return Err(self.faces.bad(Place::Byte(self.pos as u64), format!(
                "element {element} runs past the end of the file ({} bytes): the file is truncated or its counts are wrong",
                self.map.len()
            )));
        }
        self.pos = end as usize;
        Ok(())
    }

    /// Reads one integer value of type `ty`.
    fn integer(&mut self, ty: ScalarType, what: &str, element: &str) -> Result<i64> {
        let at = self.pos;
        self.skip(ty.size() as u64, element)?;
        let stored = if self.big {
            Stored::Be(at)
        } else {
            Stored::Le(at)
        };
        let v = Property::new(what, ty, stored).value(self.map);
        if v.fract() != 0.0 || v.abs() > (1u64 << 53) as f64 {
            return Err(self.faces.bad(
                Place::Byte(at as u64),
                format!("{element} {what} is {v}, not an integer"),
            ));
        }
        Ok(v as i64)
    }

    /// Reads one property: a list's items are appended to `items` when given, skipped
    /// otherwise; scalars are skipped.
    fn property(
        &mut self,
        p: &PlyProperty,
        element: &str,
        items: Option<&mut Vec<i64>>,
    ) -> Result<()> {
        let Some(count_ty) = p.list else {
            return self.skip(p.ty.size() as u64, element);
        };
        let n = self.integer(count_ty, &format!("{} length", p.name), element)?;
        let n = u64::try_from(n).map_err(|_| {
            self.faces.bad(
                Place::Byte((self.pos - count_ty.size()) as u64),
                format!("{element} {} has a negative length {n}", p.name),
            )
        })?;
        match items {
            Some(items) => {
                for _ in 0..n {
                    items.push(self.integer(p.ty, &p.name, element)?);
                }
                Ok(())
            }
            None => self.skip(n.saturating_mul(p.ty.size() as u64), element),
        }
    }
}
