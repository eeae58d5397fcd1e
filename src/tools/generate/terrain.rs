//! The surface of `generate terrain`: a height field z = h(x, y) in metres (a gentle regional
//! slope plus a sum of smooth compactly supported bumps, [`Terrain`]); its curvature comes from
//! the Monge formulas of algorithms.md 13.2 through
//! [`crate::core::surface::height_field_curvature`], in the tool's convention (upward normal, a
//! hilltop has H > 0), in 1/m (K in 1/m^2). Pure: no sampling, no I/O.

use crate::core::rng::Rng;
use crate::core::surface::{HeightField, HeightJet};

/// Base elevation of the terrain in metres.
pub const BASE_ELEVATION_M: f64 = 100.0;
/// Smallest and largest bump support radius in metres.
pub const BUMP_RADIUS_M: (f64, f64) = (20.0, 200.0);
/// Smallest and largest bump height (absolute) in metres; a bump is also at most
/// [`MAX_HEIGHT_PER_RADIUS`] times its radius high, which caps its slope at about 0.57.
pub const BUMP_HEIGHT_M: (f64, f64) = (2.0, 30.0);
/// Largest bump height per metre of radius (the steepest slope of a bump is 1.9 height/radius).
pub const MAX_HEIGHT_PER_RADIUS: f64 = 0.3;
/// Salt of the bump streams, so that they differ from the point streams of the same seed.
const BUMP_SALT: u64 = 0x6275_6d70_7321;

/// One bump of the terrain: h = height (1 - r^2/radius^2)^4 for r < radius, 0 beyond. The
/// quartic makes h, its slope, its curvature and the curvature's first derivatives vanish at
/// the rim (C3), so the sum is smooth, and a point only sees the few bumps whose support
/// covers it: the evaluation cost does not grow with the area (Gaussians would need a
/// truncation and many more bumps per point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bump {
    /// Centre easting, relative to the square's south-west corner, in metres.
    pub cx: f64,
    /// Centre northing, relative to the square's south-west corner, in metres.
    pub cy: f64,
    /// Support radius in metres.
    pub radius_m: f64,
    /// Height at the centre in metres (negative for a hollow).
    pub height_m: f64,
}

impl Bump {
    /// Adds this bump's value and derivatives at (x, y) to `j`.
    fn add_to(&self, x: f64, y: f64, j: &mut HeightJet) {
        let (dx, dy) = (x - self.cx, y - self.cy);
        let r2 = self.radius_m * self.radius_m;
        let u = 1.0 - (dx * dx + dy * dy) / r2;
        if u <= 0.0 {
            return;
        }
        let a = self.height_m;
        let (u2, u3) = (u * u, u * u * u);
        // h = a u^4, u = 1 - (dx^2 + dy^2)/R^2, du/dx = -2 dx/R^2:
        // h_x = -8 a u^3 dx / R^2, h_xx = -8 a u^3 / R^2 + 48 a u^2 dx^2 / R^4,
        // h_xy = 48 a u^2 dx dy / R^4.
        let c1 = -8.0 * a * u3 / r2;
        let c2 = 48.0 * a * u2 / (r2 * r2);
        j.h += a * u2 * u2;
        j.hx += c1 * dx;
        j.hy += c1 * dy;
        j.hxx += c1 + c2 * dx * dx;
        j.hxy += c2 * dx * dy;
        j.hyy += c1 + c2 * dy * dy;
    }
}

/// The synthetic terrain: z = base + slope . (x, y) + sum of [`Bump`]s, over local coordinates
/// (metres from the south-west corner of the square). Bumps are placed per cell of a grid of
/// cells as wide as the largest radius, from a stream seeded by (seed, cell), so a point only
/// looks at the 3 x 3 cells around it.
#[derive(Debug, Clone)]
pub struct Terrain {
    /// Elevation at the south-west corner before bumps, in metres.
    pub base_m: f64,
    /// Regional slope (dz/dx, dz/dy).
    pub slope: [f64; 2],
    /// Cells per side of the bump grid (covering one cell beyond the square on every side).
    cells: usize,
    /// Bumps by cell, row-major, cell (i, j) covering local x in [(i-1) C, i C) with C the cell size.
    bumps: Vec<Vec<Bump>>,
}

impl Terrain {
    /// The terrain over a square of side `side_m` metres for `seed`.
    pub fn new(side_m: f64, seed: u64) -> Self {
        let cell = BUMP_RADIUS_M.1;
        // One cell of margin on each side, so that bumps centred outside the square reach in.
        let cells = (side_m / cell).ceil() as usize + 2;
        let mut head = Rng::new(seed ^ BUMP_SALT);
        let slope = [
            0.03 * (2.0 * head.uniform() - 1.0),
            0.03 * (2.0 * head.uniform() - 1.0),
        ];
        let (lo, hi) = BUMP_RADIUS_M;
        let mut bumps = Vec::with_capacity(cells * cells);
        for j in 0..cells {
            for i in 0..cells {
                let mut rng = Rng::for_point(seed ^ BUMP_SALT, (j * cells + i) as u64);
                // 1 to 4 bumps per 200 m cell: with log-uniform radii (mean area 27,000 m^2)
                // a point lies under 1.7 bumps on average, so bumps overlap into saddles.
                let n = 1 + rng.below(4);
                let v = (0..n)
                    .map(|_| {
                        let cx = (i as f64 - 1.0 + rng.uniform()) * cell;
                        let cy = (j as f64 - 1.0 + rng.uniform()) * cell;
                        let radius_m = lo * (hi / lo).powf(rng.uniform());
                        let top = BUMP_HEIGHT_M.1.min(MAX_HEIGHT_PER_RADIUS * radius_m);
                        let size = BUMP_HEIGHT_M.0 + (top - BUMP_HEIGHT_M.0) * rng.uniform();
                        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                        Bump {
                            cx,
                            cy,
                            radius_m,
                            height_m: sign * size,
                        }
                    })
                    .collect();
                bumps.push(v);
            }
        }
        Terrain {
            base_m: BASE_ELEVATION_M,
            slope,
            cells,
            bumps,
        }
    }

    /// Number of bumps.
    pub fn bump_count(&self) -> usize {
        self.bumps.iter().map(Vec::len).sum()
    }
}

impl HeightField for Terrain {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        let mut j = HeightJet {
            h: self.base_m + self.slope[0] * x + self.slope[1] * y,
            hx: self.slope[0],
            hy: self.slope[1],
            hxx: 0.0,
            hxy: 0.0,
            hyy: 0.0,
        };
        let cell = BUMP_RADIUS_M.1;
        // The grid cell of (x, y), shifted by the margin; the support of a bump (radius at most
        // one cell) reaches at most the neighbouring cells.
        let ci = ((x / cell).floor() + 1.0) as isize;
        let cj = ((y / cell).floor() + 1.0) as isize;
        for j_cell in cj - 1..=cj + 1 {
            for i_cell in ci - 1..=ci + 1 {
                if i_cell < 0
                    || j_cell < 0
                    || i_cell as usize >= self.cells
                    || j_cell as usize >= self.cells
                {
                    continue;
                }
                for b in &self.bumps[j_cell as usize * self.cells + i_cell as usize] {
                    b.add_to(x, y, &mut j);
                }
            }
        }
        j
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bump_derivatives_match_finite_differences() {
        let t = Terrain::new(600.0, 3);
        assert!(t.bump_count() > 0);
        let e = 1e-4;
        for &(x, y) in &[(10.0, 20.0), (150.3, 333.7), (420.0, 77.0), (599.0, 1.0)] {
            let j = t.jet(x, y);
            let (px, mx) = (t.jet(x + e, y), t.jet(x - e, y));
            let (py, my) = (t.jet(x, y + e), t.jet(x, y - e));
            let close = |a: f64, b: f64, what: &str| {
                assert!(
                    (a - b).abs() <= 1e-6 * (1.0 + b.abs()),
                    "{what} at ({x}, {y}): {a} vs finite difference {b}"
                )
            };
            close(j.hx, (px.h - mx.h) / (2.0 * e), "h_x");
            close(j.hy, (py.h - my.h) / (2.0 * e), "h_y");
            close(j.hxx, (px.hx - mx.hx) / (2.0 * e), "h_xx");
            close(j.hxy, (py.hx - my.hx) / (2.0 * e), "h_xy");
            close(j.hyy, (py.hy - my.hy) / (2.0 * e), "h_yy");
        }
    }

    #[test]
    fn a_hilltop_has_positive_mean_curvature() {
        let b = Bump {
            cx: 0.0,
            cy: 0.0,
            radius_m: 50.0,
            height_m: 10.0,
        };
        let mut j = HeightJet {
            h: 0.0,
            hx: 0.0,
            hy: 0.0,
            hxx: 0.0,
            hxy: 0.0,
            hyy: 0.0,
        };
        b.add_to(0.0, 0.0, &mut j);
        let c = j.curvature();
        // h_xx = h_yy = -8 a / R^2 at the centre: k1 = k2 = 8 * 10 / 2500 (the sign of
        // algorithms.md 13.2).
        assert!((c.k1 - 0.032).abs() < 1e-12 && (c.k2 - 0.032).abs() < 1e-12);
        assert!(c.h > 0.0);
    }
}
