//! Terrain (geomorphometric) quantities of one point from the values the estimator already has:
//! its oriented normal, principal curvatures and principal directions (algorithms.md 10.2,
//! 10.3). Slope, aspect, profile, tangential and plan curvature, shape index and curvedness,
//! convex positive, with gravity along -z of the file. Also their closed forms from the
//! derivatives of a height field (algorithms.md 10.4), the truth of `generate terrain`, written
//! independently of the shape operator the estimator route goes through. Pure numbers.

use crate::core::angle::{atan2, atan2_finite};
use crate::core::estimate::Curvature;
use crate::core::geometry::{dot, V3};

/// Below this slope (degrees) the slope line is taken as undefined: profile, tangential and
/// plan curvature and aspect are NaN and [`terrain_flags::FLAT`] is set (algorithms.md 10.5).
/// 0.1 degree is a rise of 1.7 mm per metre: over the 2 m radius of a 30-point neighbourhood at
/// 8 points/m^2 that is 3.5 mm, below what a plane fit through LIDAR heights with 2-5 cm of
/// noise resolves, so the direction of such a slope is the noise's. Above it the columns are
/// written; the `Slope` column lets a user mask a gentler threshold of their own.
pub const FLAT_SLOPE_DEG: f64 = 0.1;

/// The bits of the `TerrainFlags` column: why terrain values of a point are undefined.
pub mod terrain_flags {
    /// Slope below [`super::FLAT_SLOPE_DEG`]: the slope line and the contour have no direction,
    /// so profile, tangential and plan curvature and aspect are NaN.
    pub const FLAT: u8 = 1;
    /// The curvature is undefined (`CurvatureFlags` 1, 2, 4 or 128): every curvature-derived
    /// value (profile, tangential, plan, shape index, curvedness) is NaN.
    pub const NO_CURVATURE: u8 = 2;
    /// k1 = k2 = 0: a plane, whose shape index is undefined (NaN).
    pub const PLANAR: u8 = 4;
    /// The normal is undefined: slope and aspect are NaN too.
    pub const NO_NORMAL: u8 = 8;
}

/// The terrain values of one point (NaN where undefined, [`terrain_flags`] saying why).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TerrainValues {
    /// Profile (vertical) curvature: the normal curvature along the slope line, 1/unit.
    pub profile: f64,
    /// Tangential (horizontal) curvature: the normal curvature along the contour, 1/unit.
    pub tangential: f64,
    /// Plan (contour) curvature: the curvature of the contour line in the map plane,
    /// tangential / sin(slope), 1/unit.
    pub plan: f64,
    /// Koenderink's shape index in [-1, 1]: +1 dome, +0.5 ridge, 0 saddle, -0.5 valley, -1 bowl.
    pub shape_index: f64,
    /// Curvedness sqrt((k1^2 + k2^2)/2), 1/unit.
    pub curvedness: f64,
    /// Slope in degrees, 0 (level) to 90 (vertical).
    pub slope_deg: f64,
    /// Aspect: the downslope azimuth in degrees clockwise from north (+y), in [0, 360).
    pub aspect_deg: f64,
    /// [`terrain_flags`].
    pub flags: u8,
}

impl TerrainValues {
    /// The seven numbers in their record order: profile, tangential, plan, shape index,
    /// curvedness, slope, aspect.
    #[inline(always)]
    pub fn numbers(&self) -> [f64; 7] {
        [
            self.profile,
            self.tangential,
            self.plan,
            self.shape_index,
            self.curvedness,
            self.slope_deg,
            self.aspect_deg,
        ]
    }

    /// The values of a point without a normal or curvature (undefined, or terrain values not
    /// asked for): every value NaN.
    pub const NONE: TerrainValues =
        TerrainValues::undefined(terrain_flags::NO_NORMAL | terrain_flags::NO_CURVATURE);

    /// Every value NaN, with `flags`.
    pub const fn undefined(flags: u8) -> Self {
        TerrainValues {
            profile: f64::NAN,
            tangential: f64::NAN,
            plan: f64::NAN,
            shape_index: f64::NAN,
            curvedness: f64::NAN,
            slope_deg: f64::NAN,
            aspect_deg: f64::NAN,
            flags,
        }
    }

    /// The terrain values of a point with the oriented unit `normal` and curvature `c`
    /// (algorithms.md 10.2). The result does not depend on the orientation of the normal: a
    /// downward normal is read as the upward one with the curvature flipped (3.6), so a flip by
    /// `--orient propagate` changes nothing here.
    pub fn of(normal: V3, c: &Curvature) -> Self {
        if !normal.iter().all(|v| v.is_finite()) {
            return TerrainValues::NONE;
        }
        let (n, c) = if normal[2] < 0.0 {
            (normal.map(|v| -v), c.flipped())
        } else {
            (normal, *c)
        };
        let s2 = n[0] * n[0] + n[1] * n[1];
        let sin_s = s2.sqrt();
        // n[2] >= 0 here: the library's special cases are the normal's zero vector alone.
        let slope = if n[2] > 0.0 || s2 > 0.0 {
            atan2_finite(sin_s, n[2])
        } else {
            atan2(sin_s, n[2])
        };
        let slope_deg = slope.to_degrees();
        let flat = slope_deg < FLAT_SLOPE_DEG;
        let mut t = TerrainValues {
            slope_deg,
            aspect_deg: if flat {
                f64::NAN
            } else {
                // Not flat: (n[0], n[1]) is not the zero vector.
                azimuth_deg(atan2_finite(n[0], n[1]))
            },
            flags: if flat { terrain_flags::FLAT } else { 0 },
            ..TerrainValues::undefined(0)
        };
        let (k1, k2) = (c.k1, c.k2);
        if !(k1.is_finite() && k2.is_finite()) {
            t.flags |= terrain_flags::NO_CURVATURE;
            return t;
        }
        // Halved before they are added: finite for every finite k1 and k2 (the bits of halving
        // the sum, but where the sum would overflow or a half is subnormal).
        let (mean, half_gap) = (0.5 * k1 + 0.5 * k2, 0.5 * k2 - 0.5 * k1);
        t.curvedness = (0.5 * (k1 * k1 + k2 * k2)).sqrt();
        if mean == 0.0 && half_gap == 0.0 {
            t.flags |= terrain_flags::PLANAR;
        } else {
            t.shape_index = std::f64::consts::FRAC_2_PI * atan2_finite(mean, half_gap);
        }
        if !flat {
            // c = n x z along the contour and g = c x n up the slope line (10.2), both of
            // length sin(slope), which the ratio of squares below does not need divided out.
            let contour = [n[1], -n[0], 0.0];
            let up = [-n[0] * n[2], -n[1] * n[2], s2];
            // The normal curvature along a unit tangent u is k1 + (k2 - k1) sin^2(u, d1), with
            // sin^2 = (d2.u)^2 read in the (g, c) frame and normalised, so that profile +
            // tangential = k1 + k2 even when d2 leans off the tangent plane. Without directions
            // (zero: an umbilic, where every direction is principal) both are the mean.
            let (a, b) = (dot(c.d2, up), dot(c.d2, contour));
            let w = a * a + b * b;
            let along_slope = if w > 0.5 * s2 { a * a / w } else { 0.5 };
            t.profile = k1 + (k2 - k1) * along_slope;
            t.tangential = k1 + (k2 - k1) * (1.0 - along_slope);
            t.plan = t.tangential / sin_s;
        }
        t
    }

    /// The closed forms of algorithms.md 10.4 for the height field z = f(x, y) with
    /// p = f_x, q = f_y, r = f_xx, s = f_xy, t = f_yy (upward normal, convex positive), with the
    /// same flat threshold and flags as [`TerrainValues::of`]. Written from Florinsky's
    /// formulas, not from a shape operator, so that it checks [`TerrainValues::of`].
    pub fn from_derivatives(p: f64, q: f64, r: f64, s: f64, t: f64) -> Self {
        let g2 = p * p + q * q;
        let w2 = 1.0 + g2;
        let w = w2.sqrt();
        let g = g2.sqrt();
        let slope_deg = g.atan().to_degrees();
        let flat = slope_deg < FLAT_SLOPE_DEG;
        let h = -((1.0 + q * q) * r - 2.0 * p * q * s + (1.0 + p * p) * t) / (2.0 * w2 * w);
        let k = (r * t - s * s) / (w2 * w2);
        let m = (h * h - k).max(0.0).sqrt();
        let (k1, k2) = (h - m, h + m);
        let mut v = TerrainValues {
            slope_deg,
            curvedness: (0.5 * (k1 * k1 + k2 * k2)).sqrt(),
            shape_index: if h == 0.0 && m == 0.0 {
                f64::NAN
            } else {
                std::f64::consts::FRAC_2_PI * h.atan2(m)
            },
            flags: if h == 0.0 && m == 0.0 {
                terrain_flags::PLANAR
            } else {
                0
            },
            ..TerrainValues::undefined(0)
        };
        if flat {
            v.flags |= terrain_flags::FLAT;
            return v;
        }
        let across = q * q * r - 2.0 * p * q * s + p * p * t;
        v.profile = -(p * p * r + 2.0 * p * q * s + q * q * t) / (g2 * w2 * w);
        v.tangential = -across / (g2 * w);
        v.plan = -across / (g2 * g);
        // The library's arctangent: the truth does not share the estimate's.
        v.aspect_deg = azimuth_deg((-p).atan2(-q));
        v
    }
}

/// The azimuth in degrees clockwise from north, in [0, 360), of a horizontal vector (east,
/// north) whose `atan2(east, north)` is `angle` (radians).
fn azimuth_deg(angle: f64) -> f64 {
    let a = angle.to_degrees();
    // -1e-15 + 360 rounds to 360, which is north again.
    match a < 0.0 {
        true if a + 360.0 < 360.0 => a + 360.0,
        true => 0.0,
        false => a,
    }
}

#[cfg(test)]
#[path = "terrain_tests.rs"]
mod tests;
