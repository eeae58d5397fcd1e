//! Hillshade under a quick look: the cosine of the angle between the surface normal and the
//! sun, from Horn's (1981) 3x3 gradient, the sun where cartographers put it (north-west, 45
//! degrees up) so that relief reads as raised rather than sunken.

use super::Grid;

/// The sun's azimuth, degrees clockwise from north.
pub const SUN_AZIMUTH_DEG: f64 = 315.0;
/// The sun's altitude above the horizon, degrees.
pub const SUN_ALTITUDE_DEG: f64 = 45.0;

/// The hillshade of an elevation grid, made once for all the quick looks over it.
#[derive(Debug, Clone, PartialEq)]
pub struct Shade {
    /// Columns and rows of the elevation grid (a quick look's values must have the same).
    pub(super) width: u32,
    pub(super) height: u32,
    /// The shade of every pixel, 0 (facing away from the sun) to 1 (facing it), row-major.
    pub(super) levels: Vec<f32>,
}

impl Shade {
    /// The shade of `elevation` (north-up, NaN for no data) whose pixels are `cell` wide in
    /// the units of the elevations (the raster's cell size times
    /// [`super::Thumbnail::factor`]). A pixel without elevation is shaded as flat ground, and
    /// a missing neighbour takes the centre's elevation so that the edges of the data and of
    /// the grid do not draw false cliffs.
    pub fn of(elevation: &Grid, cell: f64) -> Shade {
        Shade {
            width: elevation.width,
            height: elevation.height,
            levels: hillshade(elevation, cell),
        }
    }
}

/// The shade of every pixel of `g` (see [`Shade::of`]).
fn hillshade(g: &Grid, cell: f64) -> Vec<f32> {
    let cell = if cell.is_finite() && cell > 0.0 {
        cell
    } else {
        1.0
    };
    let (az, alt) = (SUN_AZIMUTH_DEG.to_radians(), SUN_ALTITUDE_DEG.to_radians());
    // The sun's direction as (east, north, up).
    let sun = [az.sin() * alt.cos(), az.cos() * alt.cos(), alt.sin()];
    let (w, h) = (i64::from(g.width), i64::from(g.height));
    let mut out = Vec::with_capacity((w * h) as usize);
    for row in 0..h {
        for col in 0..w {
            let centre = g.get(col, row);
            let z = |dc: i64, dr: i64| {
                let v = g.get(col + dc, row + dr);
                if v.is_finite() {
                    f64::from(v)
                } else {
                    f64::from(centre)
                }
            };
            let (dz_east, dz_north) = if centre.is_finite() {
                let east =
                    (z(1, -1) + 2.0 * z(1, 0) + z(1, 1)) - (z(-1, -1) + 2.0 * z(-1, 0) + z(-1, 1));
                // Rows run south, so the row above is north.
                let north =
                    (z(-1, -1) + 2.0 * z(0, -1) + z(1, -1)) - (z(-1, 1) + 2.0 * z(0, 1) + z(1, 1));
                (east / (8.0 * cell), north / (8.0 * cell))
            } else {
                (0.0, 0.0)
            };
            let normal = [-dz_east, -dz_north, 1.0];
            let len = (normal[0] * normal[0] + normal[1] * normal[1] + 1.0).sqrt();
            let cos = (normal[0] * sun[0] + normal[1] * sun[1] + normal[2] * sun[2]) / len;
            out.push(cos.clamp(0.0, 1.0) as f32);
        }
    }
    out
}

/// The shade of level ground: the sine of the sun's altitude.
pub(super) fn level_ground() -> f32 {
    SUN_ALTITUDE_DEG.to_radians().sin() as f32
}
