//! Small fixed-size vector and matrix helpers shared by normals and estimators: f64 3-vectors,
//! symmetric eigen-decompositions with sorted eigenvalues, tangent frames. Pure functions.

/// A 3-vector.
pub type V3 = [f64; 3];
/// A 3x3 matrix, row-major.
pub type M3 = [[f64; 3]; 3];

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

/// An orthonormal tangent basis (e1, e2) of the plane orthogonal to the unit vector `n`,
/// chosen deterministically from `n` alone (so that it does not depend on the tile or thread).
pub fn tangent_basis(n: V3) -> (V3, V3) {
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
    (e1, e2)
}

/// Eigen-decomposition of a symmetric 2x2 matrix [[a, b], [b, c]]: eigenvalues ascending and
/// their unit eigenvectors.
pub fn sym2_eigen(a: f64, b: f64, c: f64) -> ([f64; 2], [[f64; 2]; 2]) {
    let mean = 0.5 * (a + c);
    let diff = 0.5 * (a - c);
    let r = (diff * diff + b * b).sqrt();
    let (l1, l2) = (mean - r, mean + r);
    if r == 0.0 {
        return ([l1, l2], [[1.0, 0.0], [0.0, 1.0]]);
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
    ([l1, l2], [v1, v2])
}

/// Eigen-decomposition of a symmetric 3x3 matrix: eigenvalues ascending and the matching unit
/// eigenvectors (nalgebra returns them unsorted; we sort).
pub fn sym3_eigen(m: &M3) -> ([f64; 3], [V3; 3]) {
    let mat = nalgebra::Matrix3::new(
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
    );
    let e = nalgebra::SymmetricEigen::new(mat);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| e.eigenvalues[i].total_cmp(&e.eigenvalues[j]));
    let vals = idx.map(|i| e.eigenvalues[i]);
    let vecs = idx.map(|i| {
        let c = e.eigenvectors.column(i);
        [c[0], c[1], c[2]]
    });
    (vals, vecs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sym2_matches_definition() {
        for &(a, b, c) in &[
            (1.0, 0.0, 2.0),
            (2.0, 0.0, 1.0),
            (0.3, -0.7, 0.1),
            (1.0, 1.0, 1.0),
            (-5.0, 1e-9, 3.0),
        ] {
            let (l, v) = sym2_eigen(a, b, c);
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
        let (l, v) = sym3_eigen(&[[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]);
        assert_eq!(l, [1.0, 2.0, 3.0]);
        assert!((v[0][1].abs() - 1.0).abs() < 1e-12);
        let (e1, e2) = tangent_basis([0.0, 0.6, 0.8]);
        assert!(
            dot(e1, [0.0, 0.6, 0.8]).abs() < 1e-15
                && dot(e2, [0.0, 0.6, 0.8]).abs() < 1e-15
                && dot(e1, e2).abs() < 1e-15
        );
    }
}
