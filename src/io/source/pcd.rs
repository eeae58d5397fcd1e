//! PCD input (Point Cloud Library, ASCII and binary): parses the header (FIELDS, SIZE, TYPE,
//! COUNT, WIDTH, HEIGHT, POINTS, DATA) and hands the body to the text scanner (ASCII) or to the
//! memory-mapped [`BinarySource`] (binary). `normal_x/normal_y/normal_z` are the file's normals.
//! `binary_compressed` bodies are rejected.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::las::extra_bytes::ScalarType;

use super::binary::BinarySource;
use super::text::{Body, Column, Lines, TextSource};
use super::{map_file, InputBytes, PointSource, Property, Stored};

/// The type of a PCD field from its TYPE letter and SIZE.
fn pcd_type(kind: &str, size: &str) -> Option<ScalarType> {
    use ScalarType::*;
    Some(match (kind, size) {
        ("I", "1") => I8,
        ("I", "2") => I16,
        ("I", "4") => I32,
        ("I", "8") => I64,
        ("U", "1") => U8,
        ("U", "2") => U16,
        ("U", "4") => U32,
        ("U", "8") => U64,
        ("F", "4") => F32,
        ("F", "8") => F64,
        _ => return None,
    })
}

/// One scalar of a PCD point: a field, or one element of a field with COUNT > 1 (named
/// `field_0`, `field_1`, ...). Fields named `_` are PCL's padding: they take space in binary
/// records but are not properties.
struct Scalar {
    name: String,
    ty: ScalarType,
    padding: bool,
}

/// A `KEY values...` line of a PCD header.
struct KeyLine {
    /// The key.
    key: String,
    /// Its values.
    values: Vec<String>,
    /// Its 1-based line.
    line: u64,
}

/// The header of a PCD file: its `KEY values...` lines and its DATA line.
struct Header {
    /// The key lines, in order.
    keys: Vec<KeyLine>,
    /// The DATA keyword (`ascii`, `binary`, `binary_compressed`).
    data: String,
    /// Byte offset of the body.
    end: usize,
    /// Line of the DATA keyword (the last header line).
    line: u64,
}

impl Header {
    /// Reads the header lines up to and including DATA.
    fn read(path: &Path, map: &[u8]) -> Result<Self> {
        let mut pos = 0usize;
        let mut line = 0u64;
        let mut keys: Vec<KeyLine> = Vec::new();
        let data = loop {
            let rest = &map[pos..];
            let Some(len) = rest.iter().position(|&b| b == b'\n') else {
                return Err(Error::bad_input(
                    path,
                    None,
                    "the PCD header has no DATA line: the file is truncated or not PCD",
                ));
            };
            line += 1;
            pos += len + 1;
            let text = String::from_utf8_lossy(&rest[..len]);
            let mut words = text.split_ascii_whitespace();
            let Some(key) = words.next().filter(|k| !k.starts_with('#')) else {
                continue;
            };
            let values: Vec<String> = words.map(str::to_string).collect();
            if key == "DATA" {
                break values.first().cloned().unwrap_or_default();
            }
            keys.push(KeyLine {
                key: key.to_string(),
                values,
                line,
            });
        };
        Ok(Header {
            keys,
            data,
            end: pos,
            line,
        })
    }

    fn get(&self, key: &str) -> Option<&KeyLine> {
        self.keys.iter().find(|k| k.key == key)
    }

    /// The scalars of a point, from FIELDS, SIZE, TYPE and COUNT.
    fn scalars(&self, path: &Path) -> Result<Vec<Scalar>> {
        let need = |key: &str| {
            self.get(key).ok_or_else(|| {
                Error::bad_input(path, None, format!("the PCD header has no {key} line"))
            })
        };
        let fields_key = need("FIELDS")?;
        let (fields, fields_line) = (&fields_key.values, fields_key.line);
        let sizes = &need("SIZE")?.values;
        let types = &need("TYPE")?.values;
        let ones = vec!["1".to_string(); fields.len()];
        let counts = self.get("COUNT").map_or(&ones, |k| &k.values);
        let bad = |what: String| bad_line(path, fields_line, what);
        if [sizes.len(), types.len(), counts.len()] != [fields.len(); 3] {
            return Err(bad(format!(
                "FIELDS names {} fields but SIZE, TYPE and COUNT give {}, {} and {} values",
                fields.len(),
                sizes.len(),
                types.len(),
                counts.len()
            )));
        }
        let mut scalars = Vec::new();
        for i in 0..fields.len() {
            let ty = pcd_type(&types[i], &sizes[i]).ok_or_else(|| {
                bad(format!(
                    "field {} has TYPE {} and SIZE {}; expected I or U with size 1, 2, 4 or 8, or F with size 4 or 8",
                    fields[i], types[i], sizes[i]
                ))
            })?;
            // PCL's largest descriptors have a few hundred elements; the cap keeps a corrupt
            // COUNT from allocating without bound.
            let n: usize = counts[i]
                .parse()
                .ok()
                .filter(|&n| n > 0 && n <= 1 << 16)
                .ok_or_else(|| {
                    bad(format!(
                        "field {} has COUNT {:?}; expected a whole number from 1 to 65536",
                        fields[i], counts[i]
                    ))
                })?;
            for k in 0..n {
                scalars.push(Scalar {
                    name: if n == 1 {
                        fields[i].clone()
                    } else {
                        format!("{}_{k}", fields[i])
                    },
                    ty,
                    padding: fields[i] == "_",
                });
            }
        }
        Ok(scalars)
    }

    /// The number of points, from POINTS or WIDTH x HEIGHT (which must agree when all are given).
    fn points(&self, path: &Path) -> Result<u64> {
        let number = |key: &str| -> Result<Option<u64>> {
            match self.get(key) {
                None => Ok(None),
                Some(k) => match k.values.as_slice() {
                    [n] => n.parse().map(Some).map_err(|_| {
                        bad_line(path, k.line, format!("{key} is {n:?}, not a whole number"))
                    }),
                    _ => Err(bad_line(
                        path,
                        k.line,
                        format!("expected \"{key} <number>\""),
                    )),
                },
            }
        };
        match (number("POINTS")?, number("WIDTH")?, number("HEIGHT")?) {
            (Some(p), Some(w), Some(h)) if w.checked_mul(h) != Some(p) => Err(Error::bad_input(
                path,
                None,
                format!(
                    "the header says POINTS {p} but WIDTH x HEIGHT = {w} x {h}; fix one of them"
                ),
            )),
            (Some(p), _, _) => Ok(p),
            (None, Some(w), Some(h)) => Ok(w.saturating_mul(h)),
            _ => Err(Error::bad_input(
                path,
                None,
                "the PCD header has neither POINTS nor WIDTH and HEIGHT: the point count is unknown",
            )),
        }
    }
}

/// A bad-input error at a header line.
fn bad_line(path: &Path, line: u64, what: String) -> Error {
    Error::bad_input(path, None, format!("header line {line}: {what}"))
}

/// Opens a PCD file.
pub fn open(path: &Path) -> Result<Box<dyn PointSource>> {
    from_bytes(path, map_file(path)?)
}

/// [`open`] on bytes already read or mapped; `path` names them in errors.
pub fn from_bytes(path: &Path, map: InputBytes) -> Result<Box<dyn PointSource>> {
    let h = Header::read(path, &map)?;
    let scalars = h.scalars(path)?;
    let points = h.points(path)?;
    let (pos, line) = (h.end, h.line);
    match h.data.as_str() {
        "ascii" => {
            let body = Body {
                start: pos,
                first_line: line + 1,
                lines: Lines::Counted {
                    skip: 0,
                    count: points,
                    noun: "points",
                },
            };
            // PCL writes no values for padding fields in ASCII.
            let columns = scalars
                .iter()
                .filter(|s| !s.padding)
                .map(|s| Column {
                    name: s.name.clone(),
                    ty: s.ty,
                })
                .collect();
            let describe = format!("PCD ascii ({points} points)");
            Ok(Box::new(TextSource::new(path, map, describe, body, columns)?))
        }
        "binary" => {
            let mut at = 0usize;
            let mut props = Vec::new();
            for s in scalars {
                if !s.padding {
                    props.push(Property::new(s.name, s.ty, Stored::Le(at)));
                }
                at += s.ty.size();
            }
            let describe = format!("PCD binary ({points} points)");
            Ok(Box::new(BinarySource::new(path, map, describe, pos, points, at, props)?))
        }
        "binary_compressed" => Err(Error::bad_input(path, None, format!(
            "header line {line}: DATA binary_compressed is not supported; convert the file to binary or ascii first (e.g. pcl_convert_pcd_ascii_binary in.pcd out.pcd 1)"
        ))),
        other => Err(bad_line(path, line, format!(
            "DATA is {other:?}; expected ascii, binary or binary_compressed"
        ))),
    }
}
