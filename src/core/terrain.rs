//! Terrain (geomorphometric) quantities of one point from the values the estimator already has:
//! its oriented normal, principal curvatures and principal directions (algorithms.md 10.2,
//! 10.3). Slope, aspect, profile, tangential and plan curvature, shape index and curvedness,
//! convex positive, with gravity along -z of the file. Also their closed forms from the
//! derivatives of a height field (algorithms.md 10.4), the truth of `generate terrain`, written
//! independently of the shape operator the estimator route goes through. Pure numbers.

use crate::core::angle::{atan2, atan2_finite, is_exceptional, select};
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
        lane::<true>(normal, c).0
    }

    /// Sets the terrain values of every item of `items` from its normal and curvature
    /// (`input`) into its `output`: the values [`TerrainValues::of`] gives, bit for bit, [`BATCH`]
    /// points at a time. The numbers are gathered into one array each, so that the loop over
    /// them computes four points at once: its divisions, square roots and arctangents
    /// ([`crate::core::angle::atan2_finite`]) cost about half what they do a point at a time.
    /// A point whose arctangent needs the library ([`crate::core::angle::is_exceptional`]: a
    /// zero normal, an infinite curvature) is computed again by [`TerrainValues::of`].
    pub fn fill<T>(
        items: &mut [T],
        input: impl Fn(&T) -> (V3, &Curvature),
        output: impl Fn(&mut T) -> &mut TerrainValues,
    ) {
        let mut lanes = Lanes::default();
        for batch in items.chunks_mut(BATCH) {
            for (i, item) in batch.iter().enumerate() {
                let (normal, curvature) = input(item);
                lanes.set(i, normal, curvature);
            }
            lanes.compute(batch.len());
            for (i, item) in batch.iter_mut().enumerate() {
                *output(item) = lanes.get(i);
            }
        }
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
#[inline(always)]
fn azimuth_deg(angle: f64) -> f64 {
    let a = angle.to_degrees();
    // -1e-15 + 360 rounds to 360, which is north again.
    let turned = a + 360.0;
    select(a < 0.0, select(turned < 360.0, turned, 0.0), a)
}

/// Points a batch of [`TerrainValues::fill`] computes together.
pub const BATCH: usize = 64;

/// A batch of points in arrays, one per number, which a loop over them reads and writes four at
/// a time (an array of points would be read a point at a time: the compiler does not vectorise
/// its strided loads).
struct Lanes {
    /// The normals' three components, k1, k2, d1's three and d2's three.
    inputs: [[f64; BATCH]; 11],
    /// The numbers of [`TerrainValues::numbers`], in that order.
    numbers: [[f64; BATCH]; 7],
    flags: [u8; BATCH],
    /// Whether [`lane`] says the point needs the library's arctangent.
    exceptional: [bool; BATCH],
}

impl Default for Lanes {
    fn default() -> Self {
        Lanes {
            inputs: [[0.0; BATCH]; 11],
            numbers: [[0.0; BATCH]; 7],
            flags: [0; BATCH],
            exceptional: [false; BATCH],
        }
    }
}

impl Lanes {
    /// Puts point `i` in the batch.
    #[inline(always)]
    fn set(&mut self, i: usize, n: V3, c: &Curvature) {
        let numbers = [n[0], n[1], n[2], c.k1, c.k2, c.d1[0], c.d1[1], c.d1[2]];
        for (row, v) in self.inputs.iter_mut().zip(numbers.into_iter().chain(c.d2)) {
            row[i] = v;
        }
    }

    /// Point `i` of `inputs` (the curvature's H, K and flags are not needed).
    #[inline(always)]
    fn point(inputs: &[[f64; BATCH]; 11], i: usize) -> (V3, Curvature) {
        let v = |row: usize| inputs[row][i];
        let curvature = Curvature {
            k1: v(3),
            k2: v(4),
            d1: [v(5), v(6), v(7)],
            d2: [v(8), v(9), v(10)],
            ..Curvature::undefined(0)
        };
        ([v(0), v(1), v(2)], curvature)
    }

    /// [`lane`] of the first `len` points.
    fn compute(&mut self, len: usize) {
        lanes(
            &self.inputs,
            &mut self.numbers,
            &mut self.flags,
            &mut self.exceptional,
            len,
        );
    }

    /// Point `i`'s values: [`lane`]'s, or [`TerrainValues::of`] where it needs the library.
    #[inline(always)]
    fn get(&self, i: usize) -> TerrainValues {
        if self.exceptional[i] {
            let (n, c) = Lanes::point(&self.inputs, i);
            return TerrainValues::of(n, &c);
        }
        let v = |row: usize| self.numbers[row][i];
        TerrainValues {
            profile: v(0),
            tangential: v(1),
            plan: v(2),
            shape_index: v(3),
            curvedness: v(4),
            slope_deg: v(5),
            aspect_deg: v(6),
            flags: self.flags[i],
        }
    }
}

/// [`lane`] of the first `len` points of `inputs` ([`Lanes`]). Arrays borrowed apart rather
/// than fields of one struct, which the compiler did not vectorise (it could not tell the
/// writes from the reads).
#[inline(never)]
fn lanes(
    inputs: &[[f64; BATCH]; 11],
    numbers: &mut [[f64; BATCH]; 7],
    flags: &mut [u8; BATCH],
    exceptional: &mut [bool; BATCH],
    len: usize,
) {
    for i in 0..len.min(BATCH) {
        let (n, c) = Lanes::point(inputs, i);
        let (t, e) = lane::<false>(n, &c);
        for (row, v) in numbers.iter_mut().zip(t.numbers()) {
            row[i] = v;
        }
        flags[i] = t.flags;
        exceptional[i] = e;
    }
}

/// The terrain values of one point (algorithms.md 10.2), and whether one of its arctangents
/// whose value is used had arguments [`is_exceptional`]. Every choice is a select, no branch,
/// so that a loop over points in arrays runs four at a time ([`TerrainValues::fill`]) with
/// [`atan2_finite`], which is wrong for those arguments; with `LIBRARY` the arctangent is
/// [`atan2`], which passes them to the library ([`TerrainValues::of`]).
#[inline(always)]
fn lane<const LIBRARY: bool>(normal: V3, c: &Curvature) -> (TerrainValues, bool) {
    let atan = |y: f64, x: f64| match LIBRARY {
        true => atan2(y, x),
        false => atan2_finite(y, x),
    };
    // A downward normal is read as the upward one with the curvature flipped (3.6): k1 and k2
    // negated and exchanged with their directions.
    let down = normal[2] < 0.0;
    let n = normal.map(|v| select(down, -v, v));
    let (k1, k2) = (select(down, -c.k2, c.k1), select(down, -c.k1, c.k2));
    let d2 = [0, 1, 2].map(|i| select(down, c.d1[i], c.d2[i]));
    let s2 = n[0] * n[0] + n[1] * n[1];
    let sin_s = s2.sqrt();
    let slope_deg = atan(sin_s, n[2]).to_degrees();
    let flat = slope_deg < FLAT_SLOPE_DEG;
    let known = n[0].is_finite() & n[1].is_finite() & n[2].is_finite();
    let aspect_deg = select(flat | !known, f64::NAN, azimuth_deg(atan(n[0], n[1])));
    // Without a normal nothing is defined: its curvature is not used either.
    let curved = known & k1.is_finite() & k2.is_finite();
    let (mean, half_gap) = (0.5 * (k1 + k2), 0.5 * (k2 - k1));
    let curvedness = (0.5 * (k1 * k1 + k2 * k2)).sqrt();
    let planar = (mean == 0.0) & (half_gap == 0.0);
    let shape_index = std::f64::consts::FRAC_2_PI * atan(mean, half_gap);
    // c = n x z along the contour and g = c x n up the slope line (10.2), both of length
    // sin(slope), which the ratio of squares below does not need divided out. The normal
    // curvature along a unit tangent u is k1 + (k2 - k1) sin^2(u, d1), with sin^2 = (d2.u)^2
    // read in the (g, c) frame and normalised, so that profile + tangential = k1 + k2 even
    // when d2 leans off the tangent plane. Without directions (zero: an umbilic, where every
    // direction is principal) both are the mean.
    let contour = [n[1], -n[0], 0.0];
    let up = [-n[0] * n[2], -n[1] * n[2], s2];
    let (a, b) = (dot(d2, up), dot(d2, contour));
    let w = a * a + b * b;
    let along_slope = select(w > 0.5 * s2, a * a / w, 0.5);
    let profile = k1 + (k2 - k1) * along_slope;
    let tangential = k1 + (k2 - k1) * (1.0 - along_slope);
    let plan = tangential / sin_s;
    // `&` and `|` rather than `&&` and `||`: no branch, so that the loop stays vectorised.
    let along = curved & !flat;
    let shaped = curved & !planar;
    let values = TerrainValues {
        profile: select(along, profile, f64::NAN),
        tangential: select(along, tangential, f64::NAN),
        plan: select(along, plan, f64::NAN),
        shape_index: select(shaped, shape_index, f64::NAN),
        curvedness: select(curved, curvedness, f64::NAN),
        slope_deg: select(known, slope_deg, f64::NAN),
        aspect_deg,
        flags: u8::from(flat) * terrain_flags::FLAT
            + u8::from(!curved) * terrain_flags::NO_CURVATURE
            + u8::from(curved & planar) * terrain_flags::PLANAR
            + u8::from(!known) * terrain_flags::NO_NORMAL,
    };
    let exceptional = known
        & (is_exceptional(sin_s, n[2])
            | (!flat & is_exceptional(n[0], n[1]))
            | (shaped & is_exceptional(mean, half_gap)));
    (values, exceptional)
}

#[cfg(test)]
#[path = "terrain_tests.rs"]
mod tests;
