//! Small fixed-size vector and matrix helpers shared by normals and estimators: f64 3-vectors,
//! symmetric eigen-decompositions with sorted eigenvalues, tangent frames. Pure functions.

/// A 3-vector.
pub type V3 = [f64; 3];
/// A 3x3 matrix, row-major.
pub type M3 = [[f64; 3]; 3];

/// A point of a surface and its unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Where it is.
    pub position: V3,
    /// The unit normal there.
    pub normal: V3,
}

/// The first and second derivatives of a scalar field F at a point (F = 0 an implicit surface).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldDerivatives {
    /// grad F.
    pub gradient: V3,
    /// Hess F (symmetric).
    pub hessian: M3,
}

/// a + b
#[inline]
pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
/// a - b
#[inline]
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
/// s a
#[inline]
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
/// <a|b>
#[inline]
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// a x b
#[inline]
pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
/// |a|
#[inline]
pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
/// a / |a|, or None for a zero or non-finite vector.
#[inline]
pub fn normalize(a: V3) -> Option<V3> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale(a, 1.0 / n))
}

/// Two orthonormal vectors of the plane orthogonal to a unit normal n, with e1 x e2 = n.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentBasis {
    /// The first tangent axis.
    pub e1: V3,
    /// The second, n x e1.
    pub e2: V3,
}

/// An orthonormal tangent basis of the plane orthogonal to the unit vector `n`, chosen
/// deterministically from `n` alone (so that it does not depend on the tile or thread).
pub fn tangent_basis(n: V3) -> TangentBasis {
    // Cross with the axis least aligned with n: well conditioned for every n.
    let a = n.map(f64::abs);
    let axis = if a[0] <= a[1] && a[0] <= a[2] {
        [1.0, 0.0, 0.0]
    } else if a[1] <= a[2] {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let e1 = normalize(cross(n, axis)).unwrap_or([1.0, 0.0, 0.0]);
    let e2 = cross(n, e1);
    TangentBasis { e1, e2 }
}

/// The eigen-decomposition of a symmetric 2x2 matrix ([`sym2_eigen`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eigen2 {
    /// The eigenvalues, ascending.
    pub values: [f64; 2],
    /// Their unit eigenvectors, in the same order.
    pub vectors: [[f64; 2]; 2],
}

/// Eigen-decomposition of a symmetric 2x2 matrix [[a, b], [b, c]]: eigenvalues ascending and
/// their unit eigenvectors.
pub fn sym2_eigen(a: f64, b: f64, c: f64) -> Eigen2 {
    let mean = 0.5 * (a + c);
    let diff = 0.5 * (a - c);
    let r = (diff * diff + b * b).sqrt();
    let (l1, l2) = (mean - r, mean + r);
    if r == 0.0 {
        return Eigen2 {
            values: [l1, l2],
            vectors: [[1.0, 0.0], [0.0, 1.0]],
        };
    }
    // Eigenvector of the larger eigenvalue, computed by the better-conditioned formula.
    let v2 = if diff >= 0.0 {
        [diff + r, b]
    } else {
        [b, r - diff]
    };
    let n = (v2[0] * v2[0] + v2[1] * v2[1]).sqrt();
    let v2 = [v2[0] / n, v2[1] / n];
    let v1 = [-v2[1], v2[0]];
    Eigen2 {
        values: [l1, l2],
        vectors: [v1, v2],
    }
}

/// The principal curvatures and directions of a tangent-plane shape operator
/// ([`principal_from_tangent`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Principal {
    /// The smaller principal curvature (the operator's smaller eigenvalue).
    pub k1: f64,
    /// The larger principal curvature.
    pub k2: f64,
    /// Unit 3D direction of k1.
    pub d1: V3,
    /// Unit 3D direction of k2.
    pub d2: V3,
    /// Whether k1 and k2 are indistinguishable (|k2 - k1| at most 1e-6 of the larger |k|, or
    /// both zero): the directions are then arbitrary.
    pub umbilic: bool,
}

/// The principal curvatures and directions of a 2x2 symmetric tangent-plane operator `s` in the
/// basis `b`: eigenvalues ascending with their 3D directions, and whether they are
/// indistinguishable (umbilic).
pub fn principal_from_tangent(s: [[f64; 2]; 2], b: TangentBasis) -> Principal {
    let Eigen2 {
        values: l,
        vectors: w,
    } = sym2_eigen(s[0][0], 0.5 * (s[0][1] + s[1][0]), s[1][1]);
    let dir = |w: [f64; 2]| add(scale(b.e1, w[0]), scale(b.e2, w[1]));
    let spread = (l[1] - l[0]).abs();
    let level = l[0].abs().max(l[1].abs());
    Principal {
        k1: l[0],
        k2: l[1],
        d1: dir(w[0]),
        d2: dir(w[1]),
        umbilic: spread <= 1e-6 * level || level == 0.0,
    }
}

/// The unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix, in closed form:
/// the trigonometric smallest eigenvalue l0, and the eigenvector as the longest cross product of
/// two rows of M - l0 I (orthogonal to both). About ten times cheaper than the iterative
/// [`sym3_eigen`], and as accurate when l0 is separated from l1 (the error grows like
/// eps * l2 / (l1 - l0), the case where a PCA normal means something). None when that
/// eigenvector is undefined: all eigenvalues equal, or a non-finite matrix. The other two
/// eigenvalues are [`other_two`]'s.
pub fn sym3_smallest(m: &M3) -> Option<V3> {
    let off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
    let q = (m[0][0] + m[1][1] + m[2][2]) / 3.0;
    let d = [m[0][0] - q, m[1][1] - q, m[2][2] - q];
    let p2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * off;
    if !(p2.is_finite() && p2 > 0.0) {
        return None;
    }
    let p = (p2 / 6.0).sqrt();
    // B = (M - q I) / p has eigenvalues 2 cos(phi + 2 pi j / 3) with cos(3 phi) = det(B) / 2.
    let b = |i: usize, j: usize| if i == j { d[i] / p } else { m[i][j] / p };
    let det = b(0, 0) * (b(1, 1) * b(2, 2) - b(1, 2) * b(1, 2))
        - b(0, 1) * (b(0, 1) * b(2, 2) - b(1, 2) * b(0, 2))
        + b(0, 2) * (b(0, 1) * b(1, 2) - b(1, 1) * b(0, 2));
    let phi = (0.5 * det).clamp(-1.0, 1.0).acos() / 3.0;
    let l0 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let r0 = [m[0][0] - l0, m[0][1], m[0][2]];
    let r1 = [m[0][1], m[1][1] - l0, m[1][2]];
    let r2 = [m[0][2], m[1][2], m[2][2] - l0];
    let best = [cross(r0, r1), cross(r0, r2), cross(r1, r2)]
        .into_iter()
        .max_by(|a, b| dot(*a, *a).total_cmp(&dot(*b, *b)))?;
    normalize(best)
}

/// The sum and the product of two eigenvalues ([`other_two`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SumProduct {
    /// l1 + l2.
    pub sum: f64,
    /// l1 l2.
    pub product: f64,
}

/// The sum and the product of the two eigenvalues of a symmetric 3x3 matrix `m` other than the
/// one of its unit eigenvector `v`: the trace and the determinant of m's compression onto the
/// plane orthogonal to v, as tr(m) - v'mv and v' adj(m) v (the cofactor form). Exact to
/// rounding whatever the gaps (the trigonometric eigenvalues lose about half the digits near a
/// double one), and without a square root: a ratio test on the two needs none
/// ([`crate::core::normals::pca_normal`]).
pub fn other_two(m: &M3, v: V3) -> SumProduct {
    let mv = [dot(m[0], v), dot(m[1], v), dot(m[2], v)];
    let sum = m[0][0] + m[1][1] + m[2][2] - dot(v, mv);
    // The cofactors of the symmetric m (adj(m) is symmetric too).
    let a00 = m[1][1] * m[2][2] - m[1][2] * m[1][2];
    let a11 = m[0][0] * m[2][2] - m[0][2] * m[0][2];
    let a22 = m[0][0] * m[1][1] - m[0][1] * m[0][1];
    let a01 = m[0][2] * m[1][2] - m[0][1] * m[2][2];
    let a02 = m[0][1] * m[1][2] - m[0][2] * m[1][1];
    let a12 = m[0][1] * m[0][2] - m[0][0] * m[1][2];
    let product = a00 * v[0] * v[0]
        + a11 * v[1] * v[1]
        + a22 * v[2] * v[2]
        + 2.0 * (a01 * v[0] * v[1] + a02 * v[0] * v[2] + a12 * v[1] * v[2]);
    SumProduct { sum, product }
}

/// The eigen-decomposition of a symmetric 3x3 matrix ([`sym3_eigen`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eigen3 {
    /// The eigenvalues, ascending.
    pub values: [f64; 3],
    /// Their unit eigenvectors, in the same order.
    pub vectors: [V3; 3],
}

/// Eigen-decomposition of a symmetric 3x3 matrix: eigenvalues ascending and the matching unit
/// eigenvectors (nalgebra returns them unsorted; we sort).
pub fn sym3_eigen(m: &M3) -> Eigen3 {
    let mat = nalgebra::Matrix3::new(
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
    );
    let e = nalgebra::SymmetricEigen::new(mat);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| e.eigenvalues[i].total_cmp(&e.eigenvalues[j]));
    Eigen3 {
        values: idx.map(|i| e.eigenvalues[i]),
        vectors: idx.map(|i| {
            let c = e.eigenvectors.column(i);
            [c[0], c[1], c[2]]
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sym3_smallest_matches_the_iterative_solver() {
        // Covariances of flat, curved, elongated and nearly isotropic neighbourhoods, at UTM-like
        // and tiny scales, against nalgebra's iterative solver.
        let mut rng = crate::core::rng::Rng::new(7);
        let mut unit = || rng.uniform() - 0.5;
        for case in 0..2000 {
            let spread = [1.0, 10f64.powi(-(case % 7)), 10f64.powi(-(case % 11) / 2)];
            let scale = 10f64.powi(case % 5 - 2);
            let rot = [unit(), unit(), unit()];
            let TangentBasis { e1, e2 } = tangent_basis(normalize(rot).unwrap_or([0.0, 0.0, 1.0]));
            let e3 = cross(e1, e2);
            let mut m = [[0.0; 3]; 3];
            for (w, e) in spread.iter().zip([e1, e2, e3]) {
                for r in 0..3 {
                    for c in 0..3 {
                        m[r][c] += scale * w * e[r] * e[c];
                    }
                }
            }
            let Eigen3 {
                values: want_l,
                vectors: want_v,
            } = sym3_eigen(&m);
            let Some(v) = sym3_smallest(&m) else {
                // Undefined only for a multiple of the identity (up to rounding).
                assert!(spread[1] == 1.0 && spread[2] == 1.0, "case {case}: {m:?}");
                continue;
            };
            // The other two eigenvalues' sum and product, from v (Rayleigh-accurate).
            let SumProduct { sum, product } = other_two(&m, v);
            let l2 = want_l[2];
            assert!(
                (sum - (want_l[1] + l2)).abs() <= 1e-13 * l2,
                "case {case}: sum {sum} vs {want_l:?}"
            );
            assert!(
                (product - want_l[1] * l2).abs() <= 1e-13 * l2 * l2,
                "case {case}: product {product} vs {want_l:?}"
            );
            let gap = (want_l[1] - want_l[0]) / want_l[2];
            if gap > 1e-6 {
                let cos = dot(v, want_v[0]).abs();
                assert!(
                    1.0 - cos <= 1e-20 / (gap * gap) + 1e-14,
                    "case {case}: |cos| {cos}, gap {gap}"
                );
            }
        }
        assert!(sym3_smallest(&[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]).is_none());
        assert!(sym3_smallest(&[[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]).is_none());
    }

    #[test]
    fn sym2_matches_definition() {
        for &(a, b, c) in &[
            (1.0, 0.0, 2.0),
            (2.0, 0.0, 1.0),
            (0.3, -0.7, 0.1),
            (1.0, 1.0, 1.0),
            (-5.0, 1e-9, 3.0),
        ] {
            let Eigen2 {
                values: l,
                vectors: v,
            } = sym2_eigen(a, b, c);
            assert!(l[0] <= l[1]);
            for k in 0..2 {
                let mv = [a * v[k][0] + b * v[k][1], b * v[k][0] + c * v[k][1]];
                assert!(
                    (mv[0] - l[k] * v[k][0]).abs() < 1e-12
                        && (mv[1] - l[k] * v[k][1]).abs() < 1e-12,
                    "{a} {b} {c}"
                );
            }
        }
    }

    #[test]
    fn sym3_sorted_and_orthonormal_basis() {
        let Eigen3 {
            values: l,
            vectors: v,
        } = sym3_eigen(&[[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]);
        assert_eq!(l, [1.0, 2.0, 3.0]);
        assert!((v[0][1].abs() - 1.0).abs() < 1e-12);
        let TangentBasis { e1, e2 } = tangent_basis([0.0, 0.6, 0.8]);
        assert!(
            dot(e1, [0.0, 0.6, 0.8]).abs() < 1e-15
                && dot(e2, [0.0, 0.6, 0.8]).abs() < 1e-15
                && dot(e1, e2).abs() < 1e-15
        );
    }
}
