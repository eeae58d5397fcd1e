//! The values of options that are neither lengths nor counts: how normals are oriented and
//! the value of `-k`. Parsing and printing round-trip, so that the work directory's manifest
//! stores them as text.

use crate::core::geometry::V3;
use crate::core::normals::Orientation;

/// How PCA normals are oriented, as the user asked for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OrientMode {
    /// Towards +Z (aerial scans).
    Up,
    /// Towards a scanner position, in file coordinates (terrestrial scans).
    Viewpoint(V3),
    /// Away from the centroid of all points (closed, star-shaped objects).
    Outward,
    /// Consistent orientation by propagation over the neighbour graph (Hoppe et al. 1992),
    /// seeded outward: objects where no per-point rule works (orient.rs).
    Propagate,
}

impl OrientMode {
    /// Parses `up`, `outward`, `propagate` or `viewpoint:X,Y,Z`.
    pub fn parse(s: &str) -> std::result::Result<OrientMode, String> {
        if s == "up" {
            return Ok(OrientMode::Up);
        }
        if s == "outward" {
            return Ok(OrientMode::Outward);
        }
        if s == "propagate" {
            return Ok(OrientMode::Propagate);
        }
        if let Some(rest) = s.strip_prefix("viewpoint:") {
            let v: Vec<f64> = rest
                .split(',')
                .map(|c| c.trim().parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| format!("{s:?}: expected viewpoint:X,Y,Z with three numbers"))?;
            if let [x, y, z] = v[..] {
                if [x, y, z].iter().all(|c| c.is_finite()) {
                    return Ok(OrientMode::Viewpoint([x, y, z]));
                }
            }
            return Err(format!(
                "{s:?}: expected viewpoint:X,Y,Z with three finite numbers"
            ));
        }
        Err(format!(
            "{s:?}: expected `up`, `outward`, `propagate` or `viewpoint:X,Y,Z`"
        ))
    }

    /// The orientation rule once the cloud's centroid is known.
    pub fn resolve(self, centroid: V3) -> Orientation {
        match self {
            OrientMode::Up => Orientation::Up,
            OrientMode::Viewpoint(v) => Orientation::Viewpoint(v),
            // Propagation starts from outward normals and then makes each patch consistent.
            OrientMode::Outward | OrientMode::Propagate => Orientation::Outward(centroid),
        }
    }
}

impl std::fmt::Display for OrientMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OrientMode::Up => write!(f, "up"),
            OrientMode::Viewpoint(v) => write!(f, "viewpoint:{},{},{}", v[0], v[1], v[2]),
            OrientMode::Outward => write!(f, "outward"),
            OrientMode::Propagate => write!(f, "propagate"),
        }
    }
}

/// The value of `-k`: a count, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KArg {
    /// This many neighbours.
    Count(usize),
    /// The scale chosen per point (`--k-range`).
    Auto,
}

impl KArg {
    /// Parses `-k`: a whole number or `auto`.
    pub fn parse(text: &str) -> std::result::Result<KArg, String> {
        if text.eq_ignore_ascii_case("auto") {
            return Ok(KArg::Auto);
        }
        text.parse::<usize>()
            .map(KArg::Count)
            .map_err(|_| format!("{text:?} is neither a number of neighbours (e.g. 30) nor auto"))
    }
}

impl std::fmt::Display for KArg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            KArg::Count(k) => write!(f, "{k}"),
            KArg::Auto => write!(f, "auto"),
        }
    }
}
