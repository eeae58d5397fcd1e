//! What would make rasters fail or come out wrong, checked before any point is read (for
//! `process --raster`, before the curvature work): the raster directory, the inputs' CRSs and
//! the size of the grid their declared bounds span.

use std::path::Path;

use crate::core::raster::Cell;
use crate::error::{Error, Result};
use crate::io::raster::geokeys::RasterCrs;
use crate::io::raster::{check_size, length_text};
use crate::io::source::{declared_bounds, PointSource};
use crate::progress::Reporter;
use crate::run::prepare::same_file;

use super::source_crs;

/// Refuses a raster directory `dir` (given by `option`) that is a file or cannot be made: the
/// nearest existing folder on its path gets a directory made and removed at once, so that the
/// folder is left as it was.
pub(super) fn check_dir(dir: &Path, option: &str) -> Result<()> {
    let refuse = |why: String| {
        Error::Usage(format!(
            "{}: {why}; name another raster directory with {option}",
            dir.display()
        ))
    };
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

/// The CRS of the rasters of `sources` (the first's), refusing inputs it cannot hold: the same
/// file twice (its points would count twice), a file in another CRS (one raster has one CRS:
/// the other's points would land at the wrong place), or a grid of cells of `cell` file units
/// (`unit`) over their declared bounds beyond [`crate::core::raster::max_cells`]. A file
/// without a CRS beside one with it, or user-defined CRSs whose keys differ, are warned about:
/// the coordinates may well be in one CRS.
pub(super) fn check_inputs(
    sources: &[Box<dyn PointSource>],
    (cell, unit): (f64, &str),
    reporter: &dyn Reporter,
) -> Result<RasterCrs> {
    let Some(first) = sources.first() else {
        return Err(Error::Usage("raster: name at least one input file".into()));
    };
    let crs = source_crs(first.as_ref());
    for (i, s) in sources.iter().enumerate().skip(1) {
        if let Some(twin) = sources[..i].iter().find(|t| same_file(t.path(), s.path())) {
            return Err(Error::Usage(format!(
                "{} is named twice (also as {}): its points would count twice; name each file once",
                s.path().display(),
                twin.path().display()
            )));
        }
        let other = source_crs(s.as_ref());
        match crs.same_map(&other) {
            Some(false) => return Err(Error::Usage(format!(
                "{} is in another CRS ({}) than {} ({}): one raster has one CRS, and this file's points would land elsewhere on its map. Reproject one of them first (PDAL: filters.reprojection; LAStools: las2las -target_epsg), or make the rasters of each file apart",
                s.path().display(),
                other.described,
                first.path().display(),
                crs.described
            ))),
            None if other.directory != crs.directory => reporter.warn(&format!(
                "{} has {} and {} has {}: the rasters take the first's, and the points of both are placed by their coordinates as they are",
                first.path().display(),
                crs_words(&crs),
                s.path().display(),
                crs_words(&other)
            )),
            _ => {}
        }
    }
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
    Ok(crs)
}

/// "the CRS EPSG:2949, from ..." or "no CRS".
fn crs_words(c: &RasterCrs) -> String {
    match c.described.as_str() {
        "none" => "no CRS".into(),
        d => format!("the CRS {d}"),
    }
}
