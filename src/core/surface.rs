//! Closed-form curvature of smooth surfaces that the library itself needs (algorithms.md 13.2,
//! 13.3): the curvature of a height field z = h(x, y) from its derivatives, used by the jet
//! estimator to read its fit and by `generate terrain` for its truth columns, and the torus and
//! goursat of the CNC paper (algorithms.md 13.4, 13.5), the truth of `generate torus` and
//! `generate goursat` and of the test kit. Pure numbers. Convention (algorithms.md 1.1):
//! k1 <= k2, H = (k1 + k2)/2, K = k1 k2.

use crate::core::geometry::{
    norm, normalize, principal_from_tangent, scale, tangent_basis, FieldDerivatives, SurfacePoint,
    TangentBasis, M3, V3,
};

/// The exact curvature of a smooth surface at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueCurvature {
    /// Smaller principal curvature.
    pub k1: f64,
    /// Larger principal curvature.
    pub k2: f64,
    /// Mean curvature (k1 + k2)/2.
    pub h: f64,
    /// Gaussian curvature k1 k2.
    pub k: f64,
    /// Unit principal directions (d1 of k1, d2 of k2), None at an umbilic (|k2 - k1| at most
    /// 1e-6 of the larger |k|, or both zero) where they are arbitrary.
    pub directions: Option<(V3, V3)>,
}

impl TrueCurvature {
    /// An umbilic point where both principal curvatures equal `k`.
    pub fn umbilic(k: f64) -> Self {
        TrueCurvature {
            k1: k,
            k2: k,
            h: k,
            k: k * k,
            directions: None,
        }
    }

    /// From the 2x2 symmetric shape operator `s` in the tangent basis `b`: its eigenvalues
    /// are the principal curvatures (algorithms.md 13.3).
    pub fn from_tangent(s: [[f64; 2]; 2], b: TangentBasis) -> Self {
        let p = principal_from_tangent(s, b);
        TrueCurvature {
            k1: p.k1,
            k2: p.k2,
            h: 0.5 * (p.k1 + p.k2),
            k: p.k1 * p.k2,
            directions: (!p.umbilic).then_some((p.d1, p.d2)),
        }
    }
}

/// Plane: all curvatures zero, directions arbitrary.
pub fn plane_curvature() -> TrueCurvature {
    TrueCurvature::umbilic(0.0)
}

/// Curvature of the level set of F with gradient `g` and Hessian `hs` at a point, with normal g/|g|
/// (algorithms.md 13.3): the shape operator is the tangent block of Hess F / |g|. None when the
/// gradient vanishes.
pub fn implicit_curvature(g: V3, hs: &M3) -> Option<TrueCurvature> {
    let gn = norm(g);
    let n = normalize(g)?;
    let basis = tangent_basis(n);
    let TangentBasis { e1, e2 } = basis;
    let q = |a: V3, b: V3| {
        let mut acc = 0.0;
        for r in 0..3 {
            for c in 0..3 {
                acc += a[r] * hs[r][c] * b[c];
            }
        }
        acc / gn
    };
    Some(TrueCurvature::from_tangent(
        [[q(e1, e1), q(e1, e2)], [q(e2, e1), q(e2, e2)]],
        basis,
    ))
}

/// Curvature of the height field z = h(x, y) with upward normal (-h_x, -h_y, 1)/|.| from its
/// first and second derivatives (algorithms.md 13.2). Computed as the level set of
/// F = z - h(x, y) (algorithms.md 13.3), which expands to exactly the Monge formulas.
pub fn height_field_curvature(hx: f64, hy: f64, hxx: f64, hxy: f64, hyy: f64) -> TrueCurvature {
    let g = [-hx, -hy, 1.0];
    let hs = [[-hxx, -hxy, 0.0], [-hxy, -hyy, 0.0], [0.0; 3]];
    // |g| >= 1, so the level set is always regular.
    implicit_curvature(g, &hs).unwrap_or_else(plane_curvature)
}

/// Value and derivatives of a height field at one (x, y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightJet {
    /// h
    pub h: f64,
    /// dh/dx
    pub hx: f64,
    /// dh/dy
    pub hy: f64,
    /// d2h/dx2
    pub hxx: f64,
    /// d2h/dxdy
    pub hxy: f64,
    /// d2h/dy2
    pub hyy: f64,
}

impl HeightJet {
    /// The upward unit normal (-h_x, -h_y, 1)/|.|.
    pub fn normal(&self) -> V3 {
        scale(
            [-self.hx, -self.hy, 1.0],
            1.0 / (1.0 + self.hx * self.hx + self.hy * self.hy).sqrt(),
        )
    }

    /// The exact curvature with the upward normal (algorithms.md 13.2).
    pub fn curvature(&self) -> TrueCurvature {
        height_field_curvature(self.hx, self.hy, self.hxx, self.hxy, self.hyy)
    }
}

/// A smooth height field z = h(x, y).
pub trait HeightField {
    /// Value and derivatives at (x, y).
    fn jet(&self, x: f64, y: f64) -> HeightJet;
}

/// Major and tube radius of the CNC paper's torus (algorithms.md 13.4, 14.1): R = 6, r = 2.
pub const PAPER_TORUS: (f64, f64) = (6.0, 2.0);

/// The torus point and outward unit normal at angles (theta around the tube from the outer
/// equator, phi around the z axis), major radius `big_r`, tube radius `r` (algorithms.md 13.4).
pub fn torus_point(big_r: f64, r: f64, theta: f64, phi: f64) -> SurfacePoint {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let rho = big_r + r * ct;
    SurfacePoint {
        position: [rho * cp, rho * sp, r * st],
        normal: [ct * cp, ct * sp, st],
    }
}

/// Torus curvature from the parametrisation (algorithms.md 13.4): k1 = cos(theta)/(R + r
/// cos(theta)) along the parallel (phi direction), k2 = 1/r along the meridian (theta direction).
/// k1 <= k2 holds for every theta because R > 0.
pub fn torus_curvature(big_r: f64, r: f64, theta: f64, phi: f64) -> TrueCurvature {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let k1 = ct / (big_r + r * ct);
    let k2 = 1.0 / r;
    let d1 = [-sp, cp, 0.0];
    let d2 = [-st * cp, -st * sp, ct];
    TrueCurvature {
        k1,
        k2,
        h: 0.5 * (k1 + k2),
        k: k1 * k2,
        directions: Some((d1, d2)),
    }
}

/// Torus curvature at a point `p` near the surface: the angles of its projection onto the
/// tube (for points read from text files with a few digits).
pub fn torus_curvature_at(big_r: f64, r: f64, p: V3) -> TrueCurvature {
    let phi = p[1].atan2(p[0]);
    let theta = p[2].atan2(p[0].hypot(p[1]) - big_r);
    torus_curvature(big_r, r, theta, phi)
}

/// Gradient and Hessian of the goursat function (algorithms.md 13.5).
pub fn goursat_implicit(p: V3) -> FieldDerivatives {
    let g = p.map(|x| 0.12 * x * x * x - 4.0 * x);
    let mut hs = [[0.0; 3]; 3];
    for a in 0..3 {
        hs[a][a] = 0.36 * p[a] * p[a] - 4.0;
    }
    FieldDerivatives {
        gradient: g,
        hessian: hs,
    }
}

/// Goursat curvature at a surface point (outward normal = gradient direction).
pub fn goursat_curvature(p: V3) -> Option<TrueCurvature> {
    let d = goursat_implicit(p);
    implicit_curvature(d.gradient, &d.hessian)
}
