//! Closed-form curvature of smooth surfaces that the library itself needs (algorithms.md
//! sections 6.2 and 6.3): the curvature of a height field z = h(x, y) from its derivatives, used
//! by the jet estimator to read its fit and by `generate terrain` for its truth columns. Pure
//! numbers. Convention (section 0.1): k1 <= k2, H = (k1 + k2)/2, K = k1 k2.

use crate::core::estimate::principal_from_tangent;
use crate::core::geometry::{norm, normalize, scale, tangent_basis, M3, V3};

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

    /// From the 2x2 symmetric shape operator `s` in the tangent basis (e1, e2): its eigenvalues
    /// are the principal curvatures (section 6.3).
    pub fn from_tangent(s: [[f64; 2]; 2], e1: V3, e2: V3) -> Self {
        let (k1, k2, d1, d2, umbilic) = principal_from_tangent(s, e1, e2);
        let directions = (umbilic == 0).then_some((d1, d2));
        TrueCurvature {
            k1,
            k2,
            h: 0.5 * (k1 + k2),
            k: k1 * k2,
            directions,
        }
    }
}

/// Plane: all curvatures zero, directions arbitrary.
pub fn plane_curvature() -> TrueCurvature {
    TrueCurvature::umbilic(0.0)
}

/// Cylinder of radius `r` around the z axis with outward normals, at the surface point `p`
/// Curvature of the level set of F with gradient `g` and Hessian `hs` at a point, with normal
/// g/|g| (section 6.3): the shape operator is the tangent block of Hess F / |g|. None when the
/// gradient vanishes.
pub fn implicit_curvature(g: V3, hs: &M3) -> Option<TrueCurvature> {
    let gn = norm(g);
    let n = normalize(g)?;
    let (e1, e2) = tangent_basis(n);
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
        e1,
        e2,
    ))
}

/// Curvature of the height field z = h(x, y) with upward normal (-h_x, -h_y, 1)/|.| from its
/// first and second derivatives (section 6.2). Computed as the level set of F = z - h(x, y)
/// (section 6.3), which expands to exactly the Monge formulas of 6.2.
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

    /// The exact curvature with the upward normal (section 6.2).
    pub fn curvature(&self) -> TrueCurvature {
        height_field_curvature(self.hx, self.hy, self.hxx, self.hxy, self.hyy)
    }
}

/// A smooth height field z = h(x, y).
pub trait HeightField {
    /// Value and derivatives at (x, y).
    fn jet(&self, x: f64, y: f64) -> HeightJet;
}
