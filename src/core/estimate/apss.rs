//! APSS: algebraic sphere fitted to positions and normals (algorithms.md 6.2, 6.3). This file
//! holds the fit of eqs. 2-4, generic over the scalar type so that ASO (`aso.rs`) runs the very
//! same formulas on second-order jets, and the APSS estimator H = 2 u^_q.
//!
//! Radius: the kernel's support r is derived per point from the K-NN, so that it follows the
//! density of LIDAR scans (algorithms.md 2.5, 6.1): r = the distance of the farthest neighbour,
//! exactly. The K-NN list is then the complete content of the ball, so F and its derivatives are
//! those of a true range query, and the farthest neighbour gets weight 0 (K - 1 points count).
//! A slightly larger r (e.g. 1.0001 x) is worse: the farthest point then sits at the edge of the
//! support, where the Hessian of the kernel jumps (8 q q^T / r^4 just inside, 0 outside), and
//! adds a spurious term to ASO's Hessian (algorithms.md 6.1 gives its size). With this rule
//! APSS/ASO reproduce Ponca's figures of algorithms.md 14.3.

use super::{flags, local, Curvature, Estimator, Neighbourhood, Scratch};
use crate::core::geometry::{dot, TangentBasis, V3};
use std::ops::{Add, Mul, Sub};

/// Points with |q|^2/r^2 at or above this count as outside the kernel's support. The farthest
/// neighbour sits exactly on the support boundary (r = its distance), where rounding alone
/// would decide whether its Hessian term 8 q q^T / r^4 enters ASO; its weight there is at most
/// 1e-18, so excluding it changes nothing else.
pub(crate) const SUPPORT_EDGE: f64 = 1.0 - 1e-9;

/// A number the sphere fit can run on: plain f64 for APSS, a jet for ASO.
pub(crate) trait FitScalar:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    /// The constant c.
    fn constant(c: f64) -> Self;
    /// The value part.
    fn value(self) -> f64;
    /// 1/self.
    fn recip(self) -> Self;
    /// self * c for a constant c.
    fn times(self, c: f64) -> Self;
    /// The kernel weight K(|q|/r) = (s - 1)^2, s = |q|^2/r^2 < 1 (eq. 5), of a neighbour at `q`
    /// relative to the evaluation point; zero from [`SUPPORT_EDGE`] on.
    fn weight(q: V3, r: f64) -> Self;
}

impl FitScalar for f64 {
    fn constant(c: f64) -> Self {
        c
    }
    fn value(self) -> f64 {
        self
    }
    fn recip(self) -> Self {
        1.0 / self
    }
    fn times(self, c: f64) -> Self {
        self * c
    }
    fn weight(q: V3, r: f64) -> Self {
        let s = dot(q, q) / (r * r);
        if s < SUPPORT_EDGE {
            (s - 1.0) * (s - 1.0)
        } else {
            0.0
        }
    }
}

/// The unnormalised algebraic sphere f(y) = u_c + <u_l | y> + u_q |y|^2, centred at the query
/// point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SphereFit<T> {
    pub uc: T,
    pub ul: [T; 3],
    pub uq: T,
}

fn dot3<T: FitScalar>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Fits the algebraic sphere of eqs. 2-4 (with the 1/Sw factors of the corrected eq. 2) to
/// the neighbourhood with kernel radius `r`. Errors: FEW_NEIGHBOURS with fewer than 3 weighted
/// points, DEGENERATE for coincident or collinear points.
pub(crate) fn fit_sphere<T: FitScalar>(nb: &Neighbourhood<'_>, r: f64) -> Result<SphereFit<T>, u8> {
    if !(r.is_finite() && r > 0.0) {
        return Err(flags::DEGENERATE);
    }
    let zero = T::constant(0.0);
    let (mut sw, mut sp, mut sn, mut spn, mut spp) = (zero, [zero; 3], [zero; 3], zero, zero);
    let mut used = 0;
    for (&q, &n) in nb.positions.iter().zip(nb.normals) {
        let w = T::weight(q, r);
        // Zero outside the support; NaN for a non-finite position.
        if w.value().is_nan() || w.value() <= 0.0 {
            continue;
        }
        used += 1;
        sw = sw + w;
        for a in 0..3 {
            sp[a] = sp[a] + w.times(q[a]);
            sn[a] = sn[a] + w.times(n[a]);
        }
        spn = spn + w.times(dot(q, n));
        spp = spp + w.times(dot(q, q));
    }
    if used < 3 {
        return Err(flags::FEW_NEIGHBOURS);
    }
    let inv_sw = sw.recip();
    // deno is the weighted positional variance: zero only if all points coincide (Ponca's check,
    // made relative to Spp: algorithms.md 6.5).
    let deno = spp - dot3(&sp, &sp) * inv_sw;
    if deno.value().is_nan() || deno.value() <= 1e-12 * spp.value() {
        return Err(flags::DEGENERATE);
    }
    let uq = (spn - dot3(&sp, &sn) * inv_sw) * deno.recip().times(0.5);
    let ul = [0, 1, 2].map(|a| (sn[a] - (uq * sp[a]).times(2.0)) * inv_sw);
    let uc = T::constant(0.0) - (dot3(&ul, &sp) + uq * spp) * inv_sw;
    Ok(SphereFit { uc, ul, uq })
}

/// Validity checks shared by APSS and ASO, then the kernel radius (module documentation).
pub(crate) fn prepare(nb: &Neighbourhood<'_>) -> Result<f64, u8> {
    local::check(nb, 3)?;
    let TangentBasis { e1, e2 } = crate::core::geometry::tangent_basis(nb.normals[0]);
    if local::is_collinear(local::tangent_moments(nb.positions, e1, e2)) {
        return Err(flags::DEGENERATE);
    }
    Ok(local::knn_radius(nb.positions))
}

/// APSS (algorithms.md 6.3): the mean curvature H = 2 u^_q of the Pratt-normalised sphere. A sphere
/// has no anisotropy, so the result is reported as an umbilic: k1 = k2 = H, K = H^2, no
/// directions (UMBILIC flag). Positive for outward normals on a sphere (algorithms.md 1.5).
#[derive(Debug, Clone, Copy, Default)]
pub struct Apss;

impl Estimator for Apss {
    fn name(&self) -> &'static str {
        "apss"
    }

    fn estimate(&self, nb: &Neighbourhood<'_>, _scratch: &mut Scratch) -> Curvature {
        let fit = prepare(nb).and_then(|r| fit_sphere::<f64>(nb, r));
        let fit = match fit {
            Ok(f) => f,
            Err(flag) => return Curvature::undefined(flag),
        };
        // Pratt norm (eq. 6); a non-positive radicand is an "imaginary sphere" (algorithms.md 6.3).
        let pratt2 = dot(fit.ul, fit.ul) - 4.0 * fit.uc * fit.uq;
        if pratt2.is_nan() || pratt2 <= 0.0 {
            return Curvature::undefined(flags::DEGENERATE);
        }
        let h = 2.0 * fit.uq / pratt2.sqrt();
        Curvature {
            h,
            k: h * h,
            k1: h,
            k2: h,
            d1: [0.0; 3],
            d2: [0.0; 3],
            flags: flags::UMBILIC,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kit::testkit::{self, below, errors, Shape};

    /// algorithms.md 13.8: H~ = 1/r exactly on a sphere with exact normals (1e-9 relative), for any
    /// weights.
    #[test]
    fn sphere_identity() {
        let r = 2.5;
        let (pos, nrm) = testkit::sphere_cap(r, 30);
        let c = testkit::run(&Apss, &pos, &nrm);
        assert!((c.h * r - 1.0).abs() < 1e-9, "{c:?}");
        assert!(c.flags == flags::UMBILIC && c.k1 == c.h && c.k2 == c.h);
    }

    /// algorithms.md 14.3 (Ponca's APSS at ~50 points per ball): RMS H goursat 25k 3.88e-3, torus
    /// 25k 8.70e-3 (APSS cannot represent k1 != k2, so its torus error stays high). Bounds 1.25x.
    /// Measured here at K = 50: 3.88e-3 and 8.69e-3.
    #[test]
    fn reference_clouds() {
        for (shape, paper) in [(Shape::GoursatRef, 3.88e-3), (Shape::TorusRef, 8.70e-3)] {
            let Some(e) = errors(&Apss, shape, 50, 1) else {
                return;
            };
            assert_eq!(e.undefined, 0);
            below(e.h.rms, 1.25 * paper, &format!("{shape:?} H"));
        }
    }

    /// Sampled shapes. algorithms.md 14.2 gives APSS H RMS 0.011 on the torus at N = 60000, r = 1,
    /// and H~ = -0.992 for the paraboloid a = 1/2 (true -1); our N = 20000, K = 50 torus measures
    /// 31.8e-3 (smaller, random balls): bound 2x measured. Sphere exact; paraboloid measured 8.5e-3
    /// (bound 2x).
    #[test]
    fn sampled_shapes() {
        let e = errors(&Apss, Shape::Sphere, 30, 1).expect("synthetic");
        below(e.h.max, 1e-9, "sphere H");
        let e = errors(&Apss, Shape::Torus, 50, 1).expect("synthetic");
        below(e.h.rms, 64e-3, "torus H");
        let e = errors(&Apss, Shape::Paraboloid, 30, 1).expect("synthetic");
        below(e.h.rms, 17e-3, "paraboloid H");
    }

    #[test]
    fn flips_motions_and_degenerate_inputs() {
        testkit::flip_symmetry(&Apss, 300, 1e-9);
        testkit::motion_invariance(&Apss, 300, false, 1e-6);
        testkit::motion_invariance(&Apss, 300, true, 1e-6);
        let r = testkit::degenerate_inputs(&Apss, true);
        assert!(r[3].flags & flags::UNDEFINED != 0 && r[4].flags & flags::UNDEFINED != 0);
    }
}
