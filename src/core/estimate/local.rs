//! Small helpers shared by several estimators for looking at one neighbourhood: its radius, its
//! spread in the tangent plane, and the common validity checks. Pure functions of the
//! [`Neighbourhood`] numbers.

use super::{flags, Neighbourhood};
use crate::core::geometry::{dot, norm, V3};

/// The radius of the K-NN ball: the largest distance from the query point to a neighbour
/// (positions are relative to the query). This is the per-point stand-in for the paper's
/// neighbourhood radius (rho for CNC, r for APSS/ASO), chosen per point so that it follows the
/// density of LIDAR scans (algorithms.md 2.5).
pub fn knn_radius(positions: &[V3]) -> f64 {
    positions.iter().map(|&p| norm(p)).fold(0.0, f64::max)
}

/// Second moments of the neighbours' projections on the tangent plane (e1, e2), about the query
/// point: [[sum a^2, sum a b], [sum a b, sum b^2]] with a = <p | e1>, b = <p | e2>. This is
/// A^T A of WME (algorithms.md 7.1).
pub fn tangent_moments(positions: &[V3], e1: V3, e2: V3) -> [[f64; 2]; 2] {
    let mut m = [[0.0; 2]; 2];
    for &p in positions {
        let (a, b) = (dot(p, e1), dot(p, e2));
        m[0][0] += a * a;
        m[0][1] += a * b;
        m[1][1] += b * b;
    }
    m[1][0] = m[0][1];
    m
}

/// Whether tangent moments `m` (from [`tangent_moments`]) describe a collinear or coincident
/// neighbourhood (a LIDAR scan line, duplicates): smaller eigenvalue at most 1e-8 of the larger,
/// i.e. a transverse spread below 1e-4 of the length. No surface curvature can be estimated
/// across such a set (algorithms.md 2.5).
pub fn is_collinear(m: [[f64; 2]; 2]) -> bool {
    let tr = m[0][0] + m[1][1];
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    // lambda_min ~ det / tr when lambda_min << lambda_max.
    tr.is_nan() || det.is_nan() || tr <= 0.0 || det <= 1e-8 * tr * tr
}

/// The checks every estimator starts with: at least `min_points` points (the query included),
/// consistent slice lengths and a usable (unit, to 1%) query normal. Returns the flag to report when the
/// neighbourhood cannot be used.
pub fn check(nb: &Neighbourhood<'_>, min_points: usize) -> Result<(), u8> {
    let n = nb.positions.len();
    if n < min_points.max(1) || nb.normals.len() != n {
        return Err(flags::FEW_NEIGHBOURS);
    }
    // A loose test: it rejects zero or non-finite normals, not normals rounded to 6 digits
    // (the reference .pts files).
    let n0 = nb.normals[0];
    let off = (dot(n0, n0) - 1.0).abs();
    if off.is_nan() || off >= 1e-2 {
        return Err(flags::DEGENERATE_NORMAL);
    }
    Ok(())
}
