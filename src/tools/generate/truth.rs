//! The truth columns of a generated file: their extra-bytes descriptors, and the terrain values
//! of `generate terrain --terrain-truth` from the surface's derivatives by Florinsky's closed
//! forms ([`TerrainValues::from_derivatives`], algorithms.md 10.4), not through the shape
//! operator the estimators' route takes.

use crate::core::surface::HeightJet;
use crate::core::terrain::TerrainValues;
use crate::io::las::extra_bytes::{encode, NewColumn, ScalarType};

use super::TRUTH_COLUMNS;

/// Names of the terrain truth columns, in record order after [`TRUTH_COLUMNS`].
pub const TERRAIN_TRUTH_COLUMNS: [&str; 7] = [
    "TrueProfileCurvature",
    "TrueTangentialCurvature",
    "TruePlanCurvature",
    "TrueShapeIndex",
    "TrueCurvedness",
    "TrueSlope",
    "TrueAspect",
];

/// The most truth columns a record holds.
pub const MAX_TRUTH: usize = TRUTH_COLUMNS.len() + TERRAIN_TRUTH_COLUMNS.len();

/// Which truth columns a generated record carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Truth {
    /// None: plain point format 1 records (`--no-truth`), for runs whose input would not fit
    /// the disk with 32 more bytes a point.
    None,
    /// The curvature truth: TrueH, TrueK, Truek1, Truek2 (the default).
    #[default]
    Curvature,
    /// The curvature truth and [`TERRAIN_TRUTH_COLUMNS`] (`--terrain-truth`).
    Terrain,
}

impl Truth {
    /// The number of f64 truth columns of a record.
    pub fn columns(self) -> usize {
        match self {
            Truth::None => 0,
            Truth::Curvature => TRUTH_COLUMNS.len(),
            Truth::Terrain => MAX_TRUTH,
        }
    }

    /// Its name in the provenance record.
    pub fn name(self) -> &'static str {
        match self {
            Truth::None => "none",
            Truth::Curvature => "curvature",
            Truth::Terrain => "terrain",
        }
    }
}

/// The extra-bytes descriptors of the truth columns of `truth`.
pub(super) fn truth_descriptors(truth: Truth) -> Vec<u8> {
    let descriptions = [
        "true mean curvature (1/m)",
        "true Gaussian curvature (1/m^2)",
        "true min principal curv. (1/m)",
        "true max principal curv. (1/m)",
        "true profile curvature (1/m)",
        "true tangential curvature (1/m)",
        "true plan curvature (1/m)",
        "true shape index",
        "true curvedness (1/m)",
        "true slope (degrees)",
        "true aspect (degrees from N)",
    ];
    let count = truth.columns();
    TRUTH_COLUMNS
        .iter()
        .chain(TERRAIN_TRUTH_COLUMNS.iter())
        .zip(descriptions)
        .take(count)
        .flat_map(|(name, description)| {
            encode(&NewColumn::plain(*name, ScalarType::F64, description))
        })
        .collect()
}

/// The terrain truth at a point of the height field: profile, tangential, plan, shape index,
/// curvedness, slope, aspect (NaN where undefined).
pub(super) fn terrain_truth(j: &HeightJet) -> [f64; 7] {
    TerrainValues::from_derivatives(j.hx, j.hy, j.hxx, j.hxy, j.hyy).numbers()
}
