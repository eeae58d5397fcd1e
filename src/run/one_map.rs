//! Inputs joined in one run must lie on one map: `process` computes their points as one scene
//! (a neighbourhood may take points of several files) and `raster` bins them into one grid, so
//! a file in another CRS would put its points at the wrong place among the others'. Checked
//! before any point is read.

use crate::error::{Error, Result};
use crate::io::raster::geokeys::{source_crs, RasterCrs};
use crate::io::source::PointSource;

/// What the joined inputs become: the words of the messages about them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Joined {
    /// One scene whose curvature `process` (or a cluster stage) computes.
    Scene,
    /// One set of rasters (`tilecurv raster`).
    Rasters,
}

impl Joined {
    /// Why a file in another CRS cannot join, and what to do instead.
    fn refusal(self) -> (&'static str, &'static str) {
        match self {
            Joined::Scene => (
                "the inputs are computed as one scene, so a neighbourhood would take points of two maps",
                "or process each file apart",
            ),
            Joined::Rasters => (
                "one raster has one CRS, and this file's points would land elsewhere on its map",
                "or make the rasters of each file apart",
            ),
        }
    }

    /// What happens to inputs whose CRSs cannot be compared.
    fn undecided(self) -> &'static str {
        match self {
            Joined::Scene => {
                "their points are taken together by their coordinates as they are, and each output keeps its input's CRS"
            }
            Joined::Rasters => {
                "the rasters take the first's, and the points of both are placed by their coordinates as they are"
            }
        }
    }
}

/// The CRS of the first of `sources` and the warnings about the others, refusing a file in
/// another CRS than the first's (by EPSG code: [`RasterCrs::same_map`]); the same file named
/// twice is `run::prepare::check_distinct_files`'s to refuse, before the files are opened.
/// CRSs that cannot be compared are warned about when they differ (a file without a CRS beside
/// one with it, user-defined keys that differ, WKTs without an EPSG code that differ): the
/// coordinates may well be in one CRS. The warnings are the caller's to
/// print once its other checks have passed, so that a run refused later does not first say how
/// it would have joined the files.
pub(crate) fn check_one_map(
    sources: &[Box<dyn PointSource>],
    joined: Joined,
) -> Result<(RasterCrs, Vec<String>)> {
    let mut warnings = Vec::new();
    let Some(first) = sources.first() else {
        return Err(Error::Usage("name at least one input file".into()));
    };
    let crs = source_crs(first.as_ref());
    for s in sources.iter().skip(1) {
        let other = source_crs(s.as_ref());
        match crs.same_map(&other) {
            Some(false) => {
                let (why, apart) = joined.refusal();
                return Err(Error::Usage(format!(
                    "{} is in another CRS ({}) than {} ({}): {why}. Reproject one of them first (PDAL: filters.reprojection; LAStools: las2las -target_epsg), {apart}",
                    s.path().display(),
                    other.described,
                    first.path().display(),
                    crs.described
                )));
            }
            None if (&other.directory, &other.wkt) != (&crs.directory, &crs.wkt) => {
                warnings.push(format!(
                    "{} has {} and {} has {}: {}",
                    first.path().display(),
                    crs_words(&crs),
                    s.path().display(),
                    crs_words(&other),
                    joined.undecided()
                ))
            }
            _ => {}
        }
    }
    Ok((crs, warnings))
}

/// "the CRS EPSG:2949, from ..." or "no CRS".
fn crs_words(c: &RasterCrs) -> String {
    match c.described.as_str() {
        "none" => "no CRS".into(),
        d => format!("the CRS {d}"),
    }
}
