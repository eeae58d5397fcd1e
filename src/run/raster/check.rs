//! What would make rasters fail, checked before any point is read (for `process --raster`,
//! before the curvature work): the raster directory, the columns' names as file names and the
//! size of the grid the inputs' declared bounds span. The inputs' CRSs are checked by
//! `run::one_map`.

use std::path::{Path, PathBuf};

use crate::core::raster::Cell;
use crate::error::{Error, Result};
use crate::io::raster::{check_size, length_text, RasterColumn, COUNT_NAME};
use crate::io::source::{declared_bounds, PointSource};

/// Refuses columns whose names cannot name their raster files in the raster directory (each
/// column's raster is `<name>.tif`, beside `PointCount.tif`): a name with a path separator or
/// a control character, `.` or `..`, a name starting with a dot (hidden, as the rasters'
/// temporary files are), or one that names the file of the point count or of another column
/// (compared without case, as some file systems do).
pub(super) fn check_names(columns: &[RasterColumn], file: &Path) -> Result<()> {
    let mut taken = vec![COUNT_NAME];
    for c in columns {
        let n = c.name.as_str();
        let why = if n
            .chars()
            .any(|ch| ch == '/' || ch == '\\' || ch.is_control())
        {
            Some("it holds a path separator or a control character".to_string())
        } else if n.is_empty() || n.starts_with('.') {
            Some("it is empty or starts with a dot".to_string())
        } else {
            (taken.iter().find(|t| t.eq_ignore_ascii_case(n))).map(|&t| match t {
                COUNT_NAME => format!("{COUNT_NAME}.tif holds the point count"),
                t => format!("{t} is rastered to the same file"),
            })
        };
        if let Some(why) = why {
            return Err(Error::Usage(format!(
                "the column {n:?} of {} cannot name a raster file ({why}): leave it out of the columns to raster, or rename it in the file",
                file.display()
            )));
        }
        taken.push(n);
    }
    Ok(())
}

/// Refuses a raster directory `given` (by `option`) that is a file or cannot be made: the
/// nearest existing folder on its path gets a directory made and removed at once, so that the
/// folder is left as it was.
pub(super) fn check_dir(given: &Path, option: &str) -> Result<()> {
    let refuse = |why: String| {
        Error::Usage(format!(
            "{}: {why}; name another raster directory with {option}",
            given.display()
        ))
    };
    // Without a trailing slash, which makes a file that stands there read as missing.
    let dir: PathBuf = given.components().collect();
    let dir = dir.as_path();
    if dir.exists() {
        if !dir.is_dir() {
            return Err(refuse("exists and is not a directory".into()));
        }
        return probe(dir).map_err(|e| refuse(format!("cannot write in it ({e})")));
    }
    let mut at = dir;
    while !at.exists() {
        at = match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
    }
    if !at.is_dir() {
        return Err(refuse(format!("{} is not a directory", at.display())));
    }
    probe(at).map_err(|e| refuse(format!("cannot be made in {} ({e})", at.display())))
}

/// Makes and removes a directory in `dir`.
fn probe(dir: &Path) -> std::io::Result<()> {
    let p = dir.join(format!(".tilecurv-probe-{}", std::process::id()));
    std::fs::create_dir(&p)?;
    std::fs::remove_dir(&p)
}

/// Refuses a grid of cells of `cell` file units (`unit`) over the declared bounds of `sources`
/// beyond [`crate::core::raster::max_cells`] (files that declare no bounds are checked once
/// their points are binned).
pub(super) fn check_grid(
    sources: &[Box<dyn PointSource>],
    (cell, unit): (f64, &str),
) -> Result<()> {
    let bounds: Option<Vec<[[f64; 3]; 2]>> = sources
        .iter()
        .map(|s| declared_bounds(s.as_ref()))
        .collect();
    if let Some(b) = bounds {
        let fold = |f: fn(f64, f64) -> f64, end: usize, axis: usize| {
            b.iter().map(|x| x[end][axis]).reduce(f).unwrap_or(0.0)
        };
        let (west, south) = (fold(f64::min, 0, 0), fold(f64::min, 0, 1));
        let (east, north) = (fold(f64::max, 1, 0), fold(f64::max, 1, 1));
        let (Some(lo), Some(hi)) = (Cell::of(west, south, cell), Cell::of(east, north, cell))
        else {
            return Err(Error::Usage(format!(
                "the inputs' declared bounds ({west}, {south}) to ({east}, {north}) lie more than 2^31 cells of {} from the origin; use a larger --cell",
                length_text(cell, unit)
            )));
        };
        let points = sources.iter().map(|s| s.len()).sum();
        check_size(lo, hi, (cell, unit), points)?;
    }
    Ok(())
}
