//! `tilecurv info FILE...`: prints what `io::info` gathers about each file, as text or, with
//! `--json`, as one JSON object per file in an array (written here: the fields are few and
//! flat, so no JSON crate is needed).

use super::args::InfoArgs;
use super::{exit, fail};
use crate::io::crs::{LengthUnit, UnitSource};
use crate::io::info::{file_info, FileInfo};
use crate::progress::out;

/// `tilecurv info`: every file's info, an error for each unreadable one, which fails the
/// command with the first one's exit code once the others are printed. With `--json`, the first
/// unreadable file fails it before anything is printed (the array would be incomplete).
pub(super) fn info(a: InfoArgs) -> Result<i32, i32> {
    if a.json {
        out!("{}", info_json(&a.files).map_err(|e| fail(&e))?);
        return Ok(exit::OK);
    }
    let mut failed = None;
    for (i, p) in a.files.iter().enumerate() {
        match file_info(p) {
            Ok(f) => {
                if i > 0 {
                    out!();
                }
                print!("{}", text(&f));
            }
            Err(e) => {
                let code = fail(&e);
                failed = failed.or(Some(code));
            }
        }
    }
    failed.map_or(Ok(exit::OK), Err)
}

/// What `tilecurv info --json FILE...` prints: a JSON array with one object per file (the first
/// unreadable file is the error).
pub fn info_json(files: &[std::path::PathBuf]) -> crate::error::Result<String> {
    let infos = files
        .iter()
        .map(|p| file_info(p))
        .collect::<crate::error::Result<Vec<_>>>()?;
    let items: Vec<String> = infos.iter().map(json).collect();
    Ok(format!("[{}]", items.join(",\n")))
}

/// The horizontal unit of `f`, or why it has none.
fn horizontal(f: &FileInfo) -> Result<&LengthUnit, &str> {
    match &f.crs.horizontal {
        UnitSource::Wkt(u) | UnitSource::GeoTiff(u) => Ok(u),
        UnitSource::Unknown(why) => Err(why),
    }
}

/// A unit in words: `name (metres m)`, or `none: why`.
fn unit_words(unit: Result<&LengthUnit, &str>) -> String {
    match unit {
        Ok(u) => format!("{} ({} m)", u.name, u.metres),
        Err(why) => format!("none: {why}"),
    }
}

/// A unit as JSON: its symbol and metres, or nulls and the reason there is none.
fn unit_json(unit: Result<&LengthUnit, &str>) -> String {
    match unit {
        Ok(u) => format!(
            "{{\"symbol\":{},\"metres\":{}}}",
            s(&u.symbol()),
            n(u.metres)
        ),
        Err(why) => format!("{{\"symbol\":null,\"metres\":null,\"reason\":{}}}", s(why)),
    }
}

fn text(f: &FileInfo) -> String {
    let mut t = format!("{}\n  format: {}", f.path.display(), f.format);
    if f.copc {
        t.push_str(" (COPC)");
    }
    t.push_str(&format!("\n  points: {}\n", f.points));
    let [lo, hi] = f.bounds;
    t.push_str(&format!(
        "  bounds ({}): x {} .. {}, y {} .. {}, z {} .. {}\n",
        f.bounds_from, lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
    ));
    t.push_str(&format!(
        "  CRS: {}{}\n",
        f.crs.stored_as,
        f.crs
            .name
            .as_ref()
            .map(|n| format!(", {n}"))
            .unwrap_or_default()
    ));
    t.push_str(&format!(
        "  horizontal unit: {}\n",
        unit_words(horizontal(f))
    ));
    let vertical = unit_words(f.crs.vertical.as_ref().map_err(String::as_str));
    t.push_str(&format!("  vertical unit: {vertical}\n"));
    if f.extra.is_empty() {
        t.push_str("  extra dimensions: none\n");
    } else {
        t.push_str("  extra dimensions:\n");
        for d in &f.extra {
            t.push_str(&format!("    {} {}", d.name, d.ty));
            if d.scale != 1.0 || d.offset != 0.0 {
                t.push_str(&format!(" scale {} offset {}", d.scale, d.offset));
            }
            if let Some(v) = d.no_data {
                // Integers as they are; others (f64::MAX is common) in exponent form.
                if v.fract() == 0.0 && v.abs() < 1e16 {
                    t.push_str(&format!(" no_data {v}"));
                } else {
                    t.push_str(&format!(" no_data {v:e}"));
                }
            }
            t.push('\n');
        }
    }
    match &f.provenance {
        Some(p) => {
            t.push_str("  tilecurv provenance:\n");
            for l in p.trim_end_matches('\0').lines() {
                t.push_str(&format!("    {l}\n"));
            }
        }
        None => t.push_str("  tilecurv provenance: none\n"),
    }
    t
}

/// A JSON string literal.
fn s(v: &str) -> String {
    crate::progress::json_str(v)
}

/// A JSON number (null when not finite, which JSON cannot hold).
fn n(v: f64) -> String {
    if v.is_finite() {
        format!("{v:?}")
    } else {
        "null".into()
    }
}

fn opt(v: Option<String>) -> String {
    v.map(|x| s(&x)).unwrap_or_else(|| "null".into())
}

fn json(f: &FileInfo) -> String {
    let [lo, hi] = f.bounds;

    let extra: Vec<String> = f
        .extra
        .iter()
        .map(|d| {
            format!(
                "{{\"name\":{},\"type\":{},\"scale\":{},\"offset\":{},\"no_data\":{}}}",
                s(&d.name),
                s(&d.ty),
                n(d.scale),
                n(d.offset),
                d.no_data.map(n).unwrap_or_else(|| "null".into())
            )
        })
        .collect();
    format!(
        "{{\"path\":{},\"format\":{},\"las_version\":{},\"point_format\":{},\"copc\":{},\"points\":{},\"bounds\":{{\"from\":{},\"min\":[{},{},{}],\"max\":[{},{},{}]}},\"crs\":{{\"stored_as\":{},\"name\":{},\"horizontal_unit\":{},\"vertical_unit\":{}}},\"extra_dimensions\":[{}],\"provenance\":{}}}",
        s(&f.path.to_string_lossy()),
        s(&f.format),
        opt(f.las_version.clone()),
        f.point_format.map(|p| p.to_string()).unwrap_or_else(|| "null".into()),
        f.copc,
        f.points,
        s(f.bounds_from),
        n(lo[0]), n(lo[1]), n(lo[2]), n(hi[0]), n(hi[1]), n(hi[2]),
        s(f.crs.stored_as),
        opt(f.crs.name.clone()),
        unit_json(horizontal(f)),
        unit_json(f.crs.vertical.as_ref().map_err(String::as_str)),
        extra.join(","),
        opt(f.provenance.as_ref().map(|p| p.trim_end_matches('\0').to_string())),
    )
}
