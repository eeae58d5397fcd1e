//! Mesh files read as point clouds: the vertices of OFF (with NOFF normals) and OBJ (`v` lines)
//! files become the points, faces and every other record are ignored, unless the faces are
//! sampled (`--sample-faces`, [`super::sampled`]), for which [`obj_faces`] and [`off_faces`]
//! read them. Both are text: the headers are parsed here, the lines by the shared text scanner.

use std::path::Path;

use crate::error::{Error, Result};

use super::faces::{integer, Faces, Place};
use super::text::{first_point_line, tokens, Body, Column, Lines, PointLines, TextSource};
use super::{map_file, InputBytes};

/// Names for `n` vertex values: x y z, then `then` in order, then `column<i>` (1-based).
fn vertex_columns(n: usize, then: &[&str]) -> Vec<Column> {
    ["x", "y", "z"]
        .iter()
        .chain(then)
        .map(|s| s.to_string())
        .chain((3 + then.len()..).map(|i| format!("column{}", i + 1)))
        .take(n)
        .map(Column::f64)
        .collect()
}

/// What an OFF header says.
struct OffHeader {
    /// The keyword (`OFF`, `NOFF`, ...).
    keyword: String,
    /// The keyword's prefix (`N`, `C`, `ST`, ...).
    prefix: String,
    /// The vertex lines.
    body: Body,
    /// The number of vertices.
    count: u64,
    /// The number of faces, when the header gives one.
    faces: Option<u64>,
}

/// Parses the header of an ASCII OFF file.
fn off_header(path: &Path, map: &[u8]) -> Result<OffHeader> {
    let all = Body {
        start: 0,
        first_line: 1,
        lines: Lines::All,
    };
    let mut lines = PointLines::new(map, all);
    let (no, head) = lines
        .next()
        .ok_or_else(|| Error::bad_input(path, None, "the file is empty: expected an OFF header"))?;
    let mut words = tokens(head).map(|t| String::from_utf8_lossy(t).into_owned());
    let keyword = words.next().unwrap_or_default();
    let prefix = keyword.strip_suffix("OFF").unwrap_or("?");
    if !prefix.chars().all(|c| "STCN".contains(c)) {
        return Err(Error::bad_input(path, None, format!(
            "line {no}: expected an OFF header (OFF, NOFF, COFF, CNOFF, STOFF ...) but found {keyword:?}; 4OFF, nOFF and binary OFF are not supported"
        )));
    }
    let mut counts: Vec<String> = words.collect();
    let mut counts_line = no;
    if counts.is_empty() {
        let (no, c) = lines.next().ok_or_else(|| {
            Error::bad_input(
                path,
                None,
                format!("line {no}: the OFF header ends before the vertex count"),
            )
        })?;
        counts = tokens(c)
            .map(|t| String::from_utf8_lossy(t).into_owned())
            .collect();
        counts_line = no;
    }
    if counts.first().is_some_and(|c| c == "BINARY") {
        return Err(Error::bad_input(
            path,
            None,
            format!(
                "line {counts_line}: binary OFF is not supported; convert the file to ASCII OFF"
            ),
        ));
    }
    let count: u64 = counts.first().and_then(|c| c.parse().ok()).ok_or_else(|| {
        Error::bad_input(
            path,
            None,
            format!(
                "line {counts_line}: expected \"<vertices> <faces> <edges>\" but found {:?}",
                counts.join(" ")
            ),
        )
    })?;
    if count == 0 {
        return Err(Error::bad_input(
            path,
            None,
            format!(
                "line {counts_line}: the header declares 0 vertices; there is nothing to compute"
            ),
        ));
    }
    // The face and edge counts, when given, are whole numbers too: a negative or garbled one
    // means the header is not what it claims.
    for (i, what) in [(1, "face"), (2, "edge")] {
        if let Some(c) = counts.get(i).filter(|c| c.parse::<u64>().is_err()) {
            return Err(Error::bad_input(
                path,
                None,
                format!(
                    "line {counts_line}: the {what} count is {c:?}, not a whole number; expected \"<vertices> <faces> <edges>\""
                ),
            ));
        }
    }
    let body = Body {
        start: lines.pos,
        first_line: lines.line,
        lines: Lines::Counted {
            skip: 0,
            count,
            noun: "vertices",
        },
    };
    Ok(OffHeader {
        prefix: prefix.to_string(),
        keyword,
        body,
        count,
        faces: counts.get(1).and_then(|c| c.parse().ok()),
    })
}

/// Opens an OFF file (`OFF`, `NOFF`, `COFF`, `CNOFF`, `STOFF`... in ASCII): the vertex count
/// from the header, then that many vertex lines `x y z [nx ny nz] [r g b [a]]`.
pub fn open_off(path: &Path) -> Result<TextSource> {
    off_from_bytes(path, map_file(path)?)
}

/// [`open_off`] on bytes already read or mapped; `path` names them in errors.
pub fn off_from_bytes(path: &Path, map: InputBytes) -> Result<TextSource> {
    let h = off_header(path, &map)?;
    let n = first_point_line(path, &map, h.body)?.values;
    let mut then = Vec::new();
    if h.prefix.contains('N') {
        then.extend(["nx", "ny", "nz"]);
    }
    if h.prefix.contains('C') {
        then.extend(["red", "green", "blue", "alpha"]);
    }
    let describe = format!("{} mesh vertices ({})", h.keyword, h.count);
    TextSource::new(path, map, describe, h.body, vertex_columns(n, &then))
}

/// Reads the faces of an OFF file into `faces`: after the vertex lines, one line per face,
/// `n i1 ... in [colour]` with 0-based indices. Returns false when the header declares no
/// faces.
pub fn off_faces(path: &Path, map: &[u8], faces: &mut Faces) -> Result<bool> {
    let h = off_header(path, map)?;
    let count = match h.faces {
        Some(c) if c > 0 => c,
        _ => return Ok(false),
    };
    let body = Body {
        lines: Lines::Counted {
            skip: h.count,
            count,
            noun: "faces",
        },
        ..h.body
    };
    let mut lines = PointLines::new(map, body);
    let mut idx = Vec::new();
    for (no, content) in lines.by_ref() {
        let at = Place::Line(no);
        let mut toks = tokens(content);
        let first = toks.next().unwrap_or_default();
        let n = integer(first)
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                faces.bad(
                    at,
                    format!(
                        "expected a face \"<n> <index> ...\" but the vertex count is {:?}",
                        String::from_utf8_lossy(first)
                    ),
                )
            })?;
        idx.clear();
        for tok in toks.take(n) {
            let i = integer(tok).ok_or_else(|| {
                faces.bad(
                    at,
                    format!(
                        "face vertex {:?} is not an integer",
                        String::from_utf8_lossy(tok)
                    ),
                )
            })?;
            idx.push(i);
        }
        if idx.len() < n {
            return Err(faces.bad(
                at,
                format!("the face declares {n} vertices but lists {}", idx.len()),
            ));
        }
        faces.polygon(&idx, at)?;
    }
    if lines.points < count {
        return Err(faces.bad(
            Place::Line(lines.line - 1),
            format!(
                "the header declares {count} faces but the file ends after {}: it is truncated or the count is wrong",
                lines.points
            ),
        ));
    }
    Ok(true)
}

/// Reads the faces of an OBJ file into `faces`: its `f` lines, each vertex `v`, `v/vt`,
/// `v//vn` or `v/vt/vn` with `v` 1-based, or negative for relative to the vertices defined so
/// far. Returns false when there is no `f` line.
pub fn obj_faces(map: &[u8], faces: &mut Faces) -> Result<bool> {
    let all = Body {
        start: 0,
        first_line: 1,
        lines: Lines::All,
    };
    let (mut defined, mut any) = (0i64, false);
    let mut idx = Vec::new();
    for (no, content) in PointLines::new(map, all) {
        let mut toks = tokens(content);
        match toks.next() {
            Some(b"v") => defined += 1,
            Some(b"f") => {
                let at = Place::Line(no);
                idx.clear();
                for tok in toks {
                    let v = tok.split(|&b| b == b'/').next().unwrap_or_default();
                    let i = integer(v).ok_or_else(|| {
                        faces.bad(
                            at,
                            format!(
                                "face vertex {:?} is not an integer",
                                String::from_utf8_lossy(tok)
                            ),
                        )
                    })?;
                    idx.push(if i < 0 { defined + i } else { i - 1 });
                }
                faces.polygon(&idx, at)?;
                any = true;
            }
            _ => {}
        }
    }
    Ok(any)
}

/// Opens an OBJ file: its `v x y z [w | r g b]` lines are the points.
pub fn open_obj(path: &Path) -> Result<TextSource> {
    obj_from_bytes(path, map_file(path)?)
}

/// [`open_obj`] on bytes already read or mapped; `path` names them in errors.
pub fn obj_from_bytes(path: &Path, map: InputBytes) -> Result<TextSource> {
    let body = Body {
        start: 0,
        first_line: 1,
        lines: Lines::Keyword("v"),
    };
    let n = first_point_line(path, &map, body)?.values;
    let then: &[&str] = if n == 4 {
        &["w"]
    } else {
        &["red", "green", "blue"]
    };
    TextSource::new(
        path,
        map,
        "OBJ mesh vertices".into(),
        body,
        vertex_columns(n, then),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::source::PointSource;

    fn write(name: &str, text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        (dir, p)
    }

    #[test]
    fn off_reads_vertices_and_normals_and_skips_faces() {
        let (_d, p) = write(
            "a.off",
            "NOFF\n# comment\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n",
        );
        let s = open_off(&p).expect("opens");
        assert_eq!(s.len(), 3);
        assert!(s.has_normals());
        let (_d, p) = write("b.off", "OFF 2 0 0\n0 0 0\n1 0 0\n");
        assert_eq!(open_off(&p).expect("counts on the keyword line").len(), 2);
        let (_d, p) = write("c.off", "OFF\n5 0 0\n0 0 0\n1 0 0\n");
        let e = open_off(&p).err().expect("too few vertices").to_string();
        assert!(e.contains("line 4: the header declares 5 vertices"), "{e}");
        let (_d, p) = write("d.off", "PLY\n");
        assert!(open_off(&p).is_err());
    }

    #[test]
    fn obj_reads_v_lines_only() {
        let (_d, p) = write(
            "a.obj",
            "# c\nv 1 2 3 0.5 0.5 0.5\nvn 0 0 1\nv 4 5 6 1 1 1\nf 1 2 2\n",
        );
        let s = open_obj(&p).expect("opens");
        assert_eq!(s.len(), 2);
        let names: Vec<_> = s.properties().into_iter().map(|p| p.name).collect();
        assert_eq!(names, ["x", "y", "z", "red", "green", "blue"]);
        let (_d, p) = write("b.obj", "v 1 2 3\nv 1 2\n");
        let e = open_obj(&p).err().expect("short line").to_string();
        assert!(e.contains("line 2: expected 3 values"), "{e}");
    }
}
