//! Normals: PCA over a point's neighbours (the same K-NN the estimator uses) and orientation.
//! Pure: works on coordinates and neighbour lists.

use crate::core::geometry::{dot, other_two, scale, sub, sym3_smallest, SumProduct, V3};

/// How PCA normals are oriented (their sign is otherwise arbitrary).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Orientation {
    /// Towards +Z: aerial LIDAR (the sensor is above).
    Up,
    /// Towards a scanner position (terrestrial LIDAR), in file coordinates.
    Viewpoint(V3),
    /// Away from a centre (the cloud's centroid): closed, star-shaped objects.
    Outward(V3),
}

/// The PCA normal at `xyz[nbrs[0]]` from the points `nbrs` (local indices): the eigenvector of
/// the smallest eigenvalue of their covariance. Coordinates are centred on the query point
/// before any product (algorithms.md 1.3). None when the neighbourhood is degenerate: fewer
/// than 3 points, or collinear/coincident points (second eigenvalue negligible).
pub fn pca_normal(xyz: &[V3], nbrs: &[u32]) -> Option<V3> {
    if nbrs.len() < 3 {
        return None;
    }
    let q = xyz[nbrs[0] as usize];
    // One pass: the sums of d and d d^T (d relative to the query point, which lies among the
    // points, so |mean d| is at most their spread and the difference below loses little).
    let mut s1 = [0.0; 3];
    let mut c = [[0.0; 3]; 3];
    for &j in nbrs {
        let d = sub(xyz[j as usize], q);
        for r in 0..3 {
            s1[r] += d[r];
            for s in r..3 {
                c[r][s] += d[r] * d[s];
            }
        }
    }
    // The scatter matrix: sum (d - mean)(d - mean)^T = sum d d^T - s1 s1^T / n.
    let inv = 1.0 / nbrs.len() as f64;
    for r in 0..3 {
        for s in r..3 {
            c[r][s] -= s1[r] * s1[s] * inv;
        }
    }
    c[1][0] = c[0][1];
    c[2][0] = c[0][2];
    c[2][1] = c[1][2];
    let normal = sym3_smallest(&c)?;
    // Degenerate unless the other eigenvalues l1 <= l2 have l2 > 0 and l1 > EPS l2. With their
    // sum s and product p, l1 is at most t = EPS s / (1 + EPS) iff x^2 - s x + p <= 0 at t
    // (t <= s / 2 lies between the roots then), that is p <= t (s - t): a test without the
    // roots' square root. NaN sums and products are degenerate.
    const EPS: f64 = 1e-12;
    let SumProduct { sum: s, product: p } = other_two(&c, normal);
    let t = EPS * s / (1.0 + EPS);
    (s > 0.0 && p > t * (s - t)).then_some(normal)
}

/// Orients `n` at absolute position `p`. A normal exactly orthogonal to the reference direction
/// (a perfectly vertical wall under `Up`) is oriented by the sign of its first non-zero
/// component, so that the choice is still deterministic.
pub fn orient(n: V3, p: V3, how: Orientation) -> V3 {
    let reference = match how {
        Orientation::Up => [0.0, 0.0, 1.0],
        Orientation::Viewpoint(v) => sub(v, p),
        Orientation::Outward(c) => sub(p, c),
    };
    let s = dot(n, reference);
    let flip = if s != 0.0 {
        s < 0.0
    } else {
        n.iter().find(|c| **c != 0.0).is_some_and(|c| *c < 0.0)
    };
    if flip {
        scale(n, -1.0)
    } else {
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::normalize;

    #[test]
    fn plane_normal_is_z_and_oriented() {
        // A tilted plane z = 0.5 x + 0.25 y at UTM-sized coordinates: normal (-0.5, -0.25, 1)/|.|.
        let mut xyz = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                let (x, y) = (i as f64 * 0.7, j as f64 * 0.9 + (i % 2) as f64 * 0.1);
                xyz.push([600_000.0 + x, 4_000_000.0 + y, 50.0 + 0.5 * x + 0.25 * y]);
            }
        }
        let nb: Vec<u32> = (0..xyz.len() as u32).collect();
        let n = orient(
            pca_normal(&xyz, &nb).expect("normal"),
            xyz[0],
            Orientation::Up,
        );
        let want = normalize([-0.5, -0.25, 1.0]).expect("unit");
        assert!(dot(n, want) > 1.0 - 1e-12, "{n:?}");
        let down = orient(
            n,
            xyz[0],
            Orientation::Viewpoint([600_000.0, 4_000_000.0, -1000.0]),
        );
        assert!(dot(down, want) < -1.0 + 1e-12);
    }

    #[test]
    fn collinear_and_duplicate_points_are_degenerate() {
        let line: Vec<V3> = (0..10).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        let nb: Vec<u32> = (0..10).collect();
        assert!(pca_normal(&line, &nb).is_none());
        let same = vec![[1.0, 2.0, 3.0]; 10];
        assert!(pca_normal(&same, &nb).is_none());
    }
}
