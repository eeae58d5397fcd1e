//! The terrain columns' values (algorithms.md 10): which of a point's [`TerrainValues`] each
//! holds, its name and description, and the group `--columns` picks it by.

use crate::core::terrain::TerrainValues;

use super::Group;

/// One of a point's terrain values ([`TerrainValues`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TerrainValue {
    /// Profile curvature.
    Profile,
    /// Tangential curvature.
    Tangential,
    /// Plan curvature.
    Plan,
    /// Shape index.
    ShapeIndex,
    /// Curvedness.
    Curvedness,
    /// Slope in degrees.
    Slope,
    /// Aspect in degrees.
    Aspect,
    /// The terrain flags.
    Flags,
}

impl TerrainValue {
    /// Every terrain value, in record order (one per terrain group, then the flags).
    pub const ALL: [TerrainValue; 8] = [
        TerrainValue::Profile,
        TerrainValue::Tangential,
        TerrainValue::Plan,
        TerrainValue::ShapeIndex,
        TerrainValue::Curvedness,
        TerrainValue::Slope,
        TerrainValue::Aspect,
        TerrainValue::Flags,
    ];

    /// The group whose column holds it (None for the flags, written with any terrain group).
    pub fn group(self) -> Option<Group> {
        (self != TerrainValue::Flags).then_some(Group::Terrain(self))
    }

    /// The name `--columns` gives its group.
    pub(super) fn word(self) -> &'static str {
        match self {
            TerrainValue::Profile => "profile",
            TerrainValue::Tangential => "tangential",
            TerrainValue::Plan => "plan",
            TerrainValue::ShapeIndex => "shape_index",
            TerrainValue::Curvedness => "curvedness",
            TerrainValue::Slope => "slope",
            TerrainValue::Aspect => "aspect",
            TerrainValue::Flags => "terrain_flags",
        }
    }

    /// The column's name, description (with the unit symbol `u`) and value.
    pub(super) fn column(self, u: &str) -> (&'static str, String) {
        match self {
            TerrainValue::Profile => ("ProfileCurvature", format!("profile curvature (1/{u})")),
            TerrainValue::Tangential => (
                "TangentialCurvature",
                format!("tangential curvature (1/{u})"),
            ),
            TerrainValue::Plan => ("PlanCurvature", format!("plan curvature (1/{u})")),
            TerrainValue::ShapeIndex => ("ShapeIndex", "shape index (-1 bowl, +1 dome)".into()),
            TerrainValue::Curvedness => ("Curvedness", format!("curvedness (1/{u})")),
            TerrainValue::Slope => ("Slope", "slope (degrees)".into()),
            TerrainValue::Aspect => ("Aspect", "downslope azimuth (deg from N)".into()),
            TerrainValue::Flags => (TERRAIN_FLAGS_NAME, "1flat 2nocurv 4planar 8nonormal".into()),
        }
    }

    #[inline(always)]
    pub(super) fn get(self, t: &TerrainValues) -> f64 {
        match self {
            TerrainValue::Profile => t.profile,
            TerrainValue::Tangential => t.tangential,
            TerrainValue::Plan => t.plan,
            TerrainValue::ShapeIndex => t.shape_index,
            TerrainValue::Curvedness => t.curvedness,
            TerrainValue::Slope => t.slope_deg,
            TerrainValue::Aspect => t.aspect_deg,
            TerrainValue::Flags => t.flags as f64,
        }
    }

    pub(super) fn set(self, t: &mut TerrainValues, v: f64) {
        match self {
            TerrainValue::Profile => t.profile = v,
            TerrainValue::Tangential => t.tangential = v,
            TerrainValue::Plan => t.plan = v,
            TerrainValue::ShapeIndex => t.shape_index = v,
            TerrainValue::Curvedness => t.curvedness = v,
            TerrainValue::Slope => t.slope_deg = v,
            TerrainValue::Aspect => t.aspect_deg = v,
            TerrainValue::Flags => t.flags = v as u8,
        }
    }
}

/// Name of the terrain flag column.
const TERRAIN_FLAGS_NAME: &str = "TerrainFlags";
