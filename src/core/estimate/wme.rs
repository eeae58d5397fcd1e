//! WME: least-squares Weingarten map estimation (algorithms.md 7.1). The tangent differences of
//! the neighbours' normals are regressed on the tangent differences of their positions,
//! B = A G, with neighbour normals first reoriented towards the query normal (one flipped normal
//! would be a huge outlier).

use super::{flags, local, Curvature, Estimator, Neighbourhood, Scratch};
use crate::core::geometry::{dot, principal_from_tangent, tangent_basis, TangentBasis};

/// Solves the 2x2 system (m + eps I) x = b for symmetric positive semi-definite `m`, with
/// eps = 1e-12 trace(m) (algorithms.md 7.1). None if the regularised matrix is still
/// singular (m = 0). A small helper local to this file.
fn solve_sym2_regularised(m: [[f64; 2]; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let eps = 1e-12 * (m[0][0] + m[1][1]);
    let (a, c, d) = (m[0][0] + eps, m[0][1], m[1][1] + eps);
    let det = a * d - c * c;
    (det > 0.0).then(|| [(d * b[0] - c * b[1]) / det, (a * b[1] - c * b[0]) / det])
}

/// WME (algorithms.md 7.1), unweighted as in the paper. G = (A^T A + eps I)^{-1} A^T B in the
/// tangent basis of the query normal; with the conversion of algorithms.md 7.2:
/// k = eig((G + G^T)/2) ascending, H = tr(G)/2, K = det(G) (so K is not forced to equal k1 k2).
/// A collinear neighbourhood (scan line) is flagged DEGENERATE rather than regularised into
/// noise.
#[derive(Debug, Clone, Copy, Default)]
pub struct Wme;

impl Estimator for Wme {
    fn name(&self) -> &'static str {
        "wme"
    }

    fn estimate(&self, nb: &Neighbourhood<'_>, _scratch: &mut Scratch) -> Curvature {
        if let Err(f) = local::check(nb, 3) {
            return Curvature::undefined(f);
        }
        let n0 = nb.normals[0];
        let basis = tangent_basis(n0);
        let TangentBasis { e1, e2 } = basis;
        // omega = A^T A (the query point contributes a zero row).
        let omega = local::tangent_moments(nb.positions, e1, e2);
        if local::is_collinear(omega) {
            return Curvature::undefined(flags::DEGENERATE);
        }
        // theta = A^T B, b_i = tangent part of the reoriented N_i (<N|E_j> = 0).
        let mut theta = [[0.0; 2]; 2];
        for (&p, &n) in nb.positions.iter().zip(nb.normals) {
            let n = if dot(n, n0) < 0.0 { n.map(|x| -x) } else { n };
            let (a, b) = ([dot(p, e1), dot(p, e2)], [dot(n, e1), dot(n, e2)]);
            for r in 0..2 {
                for c in 0..2 {
                    theta[r][c] += a[r] * b[c];
                }
            }
        }
        // Column c of G solves omega g_c = theta[.][c].
        let (Some(c0), Some(c1)) = (
            solve_sym2_regularised(omega, [theta[0][0], theta[1][0]]),
            solve_sym2_regularised(omega, [theta[0][1], theta[1][1]]),
        ) else {
            return Curvature::undefined(flags::DEGENERATE);
        };
        let g = [[c0[0], c1[0]], [c0[1], c1[1]]];
        let h = 0.5 * (g[0][0] + g[1][1]);
        let k = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        Curvature::with_principal(h, k, principal_from_tangent(g, basis))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kit::testkit::{self, below, errors, Shape};

    /// algorithms.md 13.8: G = I/r exactly on a sphere with exact normals (Delta N = Delta P / r).
    #[test]
    fn sphere_identity() {
        let r = 2.5;
        let (pos, nrm) = testkit::sphere_cap(r, 30);
        let c = testkit::run(&Wme, &pos, &nrm);
        for v in [c.k1 * r, c.k2 * r, c.h * r, c.k * r * r] {
            assert!((v - 1.0).abs() < 1e-9, "{c:?}");
        }
    }

    /// No algorithms.md 14.3 figure for WME. algorithms.md 14.2 (torus N = 20000, k = 100): RMS
    /// kmin 4.0e-3, kmax 1.8e-3, H 2.4e-3, K 2.0e-3; at K = 50 on the denser Lloyd cloud we
    /// measure H 1.15e-3, and on goursat 3.7e-3 (the CNC-Uniform figure there is 3.62e-3).
    /// Bounds: 2x the algorithms.md 14.2 torus values, and 1.25x CNC-Uniform's 3.62e-3 x 1.25
    /// on goursat.
    #[test]
    fn reference_clouds() {
        if let Some(e) = errors(&Wme, Shape::TorusRef, 50, 1) {
            assert_eq!(e.undefined, 0);
            below(e.h.rms, 4.8e-3, "torus H");
            below(e.k.rms, 4.0e-3, "torus K");
        }
        if let Some(e) = errors(&Wme, Shape::GoursatRef, 50, 1) {
            below(e.h.rms, 1.25 * 1.25 * 3.62e-3, "goursat H");
        }
    }

    /// Sampled shapes. Torus N = 20000, K = 50 against algorithms.md 14.2's k = 100 figures x2 (H
    /// 4.8e-3, K 4.0e-3, kmin 8.0e-3, kmax 3.6e-3); measured 2.2, 1.5, 3.1, 1.6 (1e-3). Sphere and
    /// cylinder are exact (Delta N is linear in Delta P on both). Saddle/paraboloid: 2x measured (H
    /// 1.6e-3 / 1.9e-3, k 2.5e-3 / 3.1e-3).
    #[test]
    fn sampled_shapes() {
        let e = errors(&Wme, Shape::Torus, 50, 1).expect("synthetic");
        below(e.h.rms, 4.8e-3, "torus H");
        below(e.k.rms, 4.0e-3, "torus K");
        below(e.k1.rms, 8.0e-3, "torus k1");
        below(e.k2.rms, 3.6e-3, "torus k2");
        // Measured 0.27 degrees RMS.
        below(e.d1_deg.rms, 0.6, "torus d1 (deg)");
        for shape in [Shape::Sphere, Shape::Cylinder] {
            let e = errors(&Wme, shape, 30, 1).expect("synthetic");
            below(
                e.h.max.max(e.k1.max).max(e.k2.max),
                1e-9,
                &format!("{shape:?} exact"),
            );
        }
        for shape in [Shape::Saddle, Shape::Paraboloid] {
            let e = errors(&Wme, shape, 30, 1).expect("synthetic");
            below(e.h.rms, 4.0e-3, &format!("{shape:?} H"));
            below(e.k1.rms.max(e.k2.rms), 6.4e-3, &format!("{shape:?} k"));
        }
    }

    #[test]
    fn flips_motions_and_degenerate_inputs() {
        testkit::flip_symmetry(&Wme, 300, 1e-9);
        testkit::motion_invariance(&Wme, 300, false, 1e-6);
        testkit::motion_invariance(&Wme, 300, true, 1e-6);
        let r = testkit::degenerate_inputs(&Wme, true);
        assert!(r[3].flags & flags::UNDEFINED != 0 && r[4].flags & flags::UNDEFINED != 0);
        // Opposing normals are reoriented towards the query normal: the plane stays flat.
        assert!(r[6].h.abs() < 1e-12 && r[6].k.abs() < 1e-12, "{:?}", r[6]);
    }
}
