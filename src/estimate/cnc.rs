//! CNC: randomized corrected curvature measures (algorithms.md section 1). This file holds the
//! per-triangle measures and their accumulation (shared by every CNC variant) and the default
//! variant, CNC-Avg-Hexagram.

use super::{flags, principal_from_tangent, Curvature, Estimator, Neighbourhood};
use crate::geometry::{add, cross, dot, normalize, scale, sub, tangent_basis, M3, V3};

/// Sums of the corrected curvature measures over a set of triangles (section 1.5).
#[derive(Debug, Clone, Copy, Default)]
pub struct CncMeasures {
    /// Corrected area A0.
    pub a0: f64,
    /// Corrected mean-curvature measure A1 (factor 1/4, section 1.3).
    pub a1: f64,
    /// Corrected Gaussian-curvature measure A2.
    pub a2: f64,
    /// Anisotropic measure AM (3x3, row = X, column = Y).
    pub am: M3,
    /// Number of triangles accumulated (degenerate ones skipped).
    pub triangles: u32,
}

impl CncMeasures {
    /// Adds one triangle with vertices `x` (relative to the query point) and unit normals `u`,
    /// after the orientation fix of section 1.4 (all measures times sign(mu0)). Triangles whose
    /// |mu0| is negligible relative to their size are skipped (section 1.4: relative epsilon).
    pub fn add_triangle(&mut self, x: [V3; 3], u: [V3; 3]) {
        let [xi, xj, xk] = x;
        let [ui, uj, uk] = u;
        let ubar = scale(add(add(ui, uj), uk), 1.0 / 3.0);
        let eij = sub(xj, xi);
        let eik = sub(xk, xi);
        let mu0 = 0.5 * dot(ubar, cross(eij, eik));
        let size2 = dot(eij, eij) + dot(eik, eik);
        if !(mu0.abs() > 1e-12 * size2) {
            return;
        }
        let s = mu0.signum();
        // mu1 with c1 = 1/4 (section 1.3: the paper's 1/2 gives k1 + k2).
        let m1 = add(
            add(cross(sub(uk, uj), xi), cross(sub(ui, uk), xj)),
            cross(sub(uj, ui), xk),
        );
        let mu1 = 0.25 * dot(ubar, m1);
        let mu2 = 0.5 * dot(ui, cross(uj, uk));
        // M = 1/2 [ (eij x ubar) (x) (uk - ui) - (eik x ubar) (x) (uj - ui) ]   (section 1.3)
        let p = cross(eij, ubar);
        let q = cross(eik, ubar);
        let a = sub(uk, ui);
        let b = sub(uj, ui);
        for r in 0..3 {
            for c in 0..3 {
                self.am[r][c] += s * 0.5 * (p[r] * a[c] - q[r] * b[c]);
            }
        }
        self.a0 += s * mu0;
        self.a1 += s * mu1;
        self.a2 += s * mu2;
        self.triangles += 1;
    }

    /// H = A1/A0, K = A2/A0 and the principal curvatures from the 2x2 compression of
    /// sym(AM)/A0 onto the tangent plane of the query normal `n` (section 1.6: the C -> infinity
    /// limit of the paper's rule; k = -eigenvalue). `extra_flags` are or-ed into the result.
    pub fn finish(&self, n: V3, extra_flags: u8) -> Curvature {
        if self.triangles == 0 || !(self.a0 > 0.0) {
            return Curvature::undefined(flags::DEGENERATE | extra_flags);
        }
        let (e1, e2) = tangent_basis(n);
        let sym = |a: V3, b: V3| {
            let mut acc = 0.0;
            for r in 0..3 {
                for c in 0..3 {
                    acc += a[r] * 0.5 * (self.am[r][c] + self.am[c][r]) * b[c];
                }
            }
            acc / self.a0
        };
        // Minus the tangent block, so that its eigenvalues are the curvatures k1 <= k2.
        let s = [[-sym(e1, e1), -sym(e1, e2)], [-sym(e2, e1), -sym(e2, e2)]];
        let (k1, k2, d1, d2, umb) = principal_from_tangent(s, e1, e2);
        Curvature {
            h: self.a1 / self.a0,
            k: self.a2 / self.a0,
            k1,
            k2,
            d1,
            d2,
            flags: umb | extra_flags,
        }
    }
}

/// The in-plane frame of the reference code's hexagon (section 1.7): `e` is the axis after the
/// normal's largest component, `u = n x e`, `v = n x u`.
fn hexagon_frame(n: V3) -> (V3, V3) {
    let a = n.map(f64::abs);
    let e = if a[0] >= a[1] && a[0] >= a[2] {
        [0.0, 1.0, 0.0]
    } else if a[1] >= a[2] {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let u = normalize(cross(n, e)).unwrap_or([1.0, 0.0, 0.0]);
    let v = normalize(cross(n, u)).unwrap_or([0.0, 1.0, 0.0]);
    (u, v)
}

/// Directions of the six hexagon vertices, (cos k pi/3, sin k pi/3) for k = 0..5.
const HEX: [[f64; 2]; 6] = [
    [1.0, 0.0],
    [0.5, 0.866_025_403_784_438_6],
    [-0.5, 0.866_025_403_784_438_6],
    [-1.0, 0.0],
    [-0.5, -0.866_025_403_784_438_6],
    [0.5, -0.866_025_403_784_438_6],
];

/// The hexagon sector (0..6) of a neighbour at relative position `d`: the Voronoi region of the
/// nearest hexagon vertex. The vertices are equidistant from the centre, so the nearest one
/// maximises <d | w_k> and the radius drops out (section 1.7 note). Ties go to the lower k.
/// Returns None for a point whose tangential projection is exactly zero (it is equidistant
/// from all six vertices, like the query point itself).
pub fn hexagon_sector(d: V3, u: V3, v: V3) -> Option<usize> {
    let (a, b) = (dot(d, u), dot(d, v));
    if a == 0.0 && b == 0.0 {
        return None;
    }
    let mut best = 0;
    let mut best_score = f64::NEG_INFINITY;
    for (k, w) in HEX.iter().enumerate() {
        let s = w[0] * a + w[1] * b;
        if s > best_score {
            best = k;
            best_score = s;
        }
    }
    Some(best)
}

/// The hexagon plane normal of the reference code: the query normal blended half and half with
/// the normalised mean neighbour normal (section 1.7, W = 0.5).
pub fn hexagon_normal(nb: &Neighbourhood<'_>) -> V3 {
    let n0 = nb.normals[0];
    let mean = nb.normals.iter().fold([0.0; 3], |acc, &u| add(acc, u));
    match normalize(mean) {
        Some(m) => normalize(add(scale(n0, 0.5), scale(m, 0.5))).unwrap_or(n0),
        None => n0,
    }
}

/// CNC-Avg-Hexagram (section 1.7): the K neighbours are split into the six Voronoi sectors of a
/// hexagon around the query point; each sector's mean position and renormalised mean normal is
/// a virtual sample; triangles (0, 2, 4) and (1, 3, 5). The query point itself is left out of the
/// sectors (it is equidistant from all six vertices: section 8, point 3). An empty sector falls
/// back to the query point and flags the result BOUNDARY.
#[derive(Debug, Clone, Copy, Default)]
pub struct CncAvgHexagram;

impl Estimator for CncAvgHexagram {
    fn name(&self) -> &'static str {
        "cnc-avg-hexagram"
    }

    fn estimate(&self, nb: &Neighbourhood<'_>) -> Curvature {
        let n0 = nb.normals[0];
        let (u, v) = hexagon_frame(hexagon_normal(nb));
        let mut pos = [[0.0; 3]; 6];
        let mut nrm = [[0.0; 3]; 6];
        let mut count = [0u32; 6];
        for (&p, &q) in nb.positions.iter().zip(nb.normals).skip(1) {
            if let Some(s) = hexagon_sector(p, u, v) {
                pos[s] = add(pos[s], p);
                nrm[s] = add(nrm[s], q);
                count[s] += 1;
            }
        }
        let mut extra = 0;
        for s in 0..6 {
            if count[s] == 0 {
                pos[s] = [0.0; 3];
                nrm[s] = n0;
                extra |= flags::BOUNDARY;
            } else {
                pos[s] = scale(pos[s], 1.0 / count[s] as f64);
                nrm[s] = normalize(nrm[s]).unwrap_or(n0);
            }
        }
        let mut m = CncMeasures::default();
        m.add_triangle([pos[0], pos[2], pos[4]], [nrm[0], nrm[2], nrm[4]]);
        m.add_triangle([pos[1], pos[3], pos[5]], [nrm[1], nrm[3], nrm[5]]);
        m.finish(n0, extra)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact identity of algorithms.md 5.2: on a sphere with exact outward normals, A1/A0 = 1/r
    /// and A2/A0 = 1/r^2 for any triangles (c1 = 1/4).
    #[test]
    fn sphere_identity_any_triangles() {
        let r = 2.5;
        let c = [0.3, -1.0, 4.0];
        let dirs: [V3; 5] = [
            [0.2, 0.1, 1.0],
            [0.5, -0.3, 0.9],
            [-0.4, 0.2, 0.95],
            [0.1, 0.6, 0.7],
            [-0.2, -0.5, 0.8],
        ];
        let dirs = dirs.map(|d| normalize(d).unwrap_or([0.0, 0.0, 1.0]));
        let q = dirs[0];
        let base = add(c, scale(q, r));
        let mut m = CncMeasures::default();
        for t in [[0, 1, 2], [1, 3, 4], [0, 4, 2], [2, 3, 1]] {
            let x = t.map(|i| sub(add(c, scale(dirs[i], r)), base));
            let u = t.map(|i| dirs[i]);
            m.add_triangle(x, u);
        }
        let out = m.finish(q, 0);
        assert!((out.h - 1.0 / r).abs() < 1e-9 * (1.0 / r), "H = {}", out.h);
        assert!(
            (out.k - 1.0 / (r * r)).abs() < 1e-9 / (r * r),
            "K = {}",
            out.k
        );
    }

    /// Flipping every normal negates H and keeps K (section 0.1).
    #[test]
    fn flipped_normals_negate_h() {
        let r = 1.5;
        let dirs: [V3; 3] = [[0.1, 0.1, 1.0], [0.6, -0.2, 0.8], [-0.3, 0.5, 0.8]];
        let dirs = dirs.map(|d| normalize(d).unwrap_or([0.0, 0.0, 1.0]));
        let x = dirs.map(|d| sub(scale(d, r), scale(dirs[0], r)));
        let mut a = CncMeasures::default();
        a.add_triangle(x, dirs);
        let mut b = CncMeasures::default();
        b.add_triangle(x, dirs.map(|d| scale(d, -1.0)));
        let (fa, fb) = (a.finish(dirs[0], 0), b.finish(scale(dirs[0], -1.0), 0));
        assert!((fa.h - 1.0 / r).abs() < 1e-12 && (fb.h + 1.0 / r).abs() < 1e-12);
        assert!((fa.k - fb.k).abs() < 1e-12);
    }

    #[test]
    fn degenerate_triangles_give_flag_not_nan_without_flag() {
        let mut m = CncMeasures::default();
        m.add_triangle(
            [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            [[0.0, 0.0, 1.0]; 3],
        );
        let out = m.finish([0.0, 0.0, 1.0], 0);
        assert!(out.h.is_nan() && out.flags & flags::DEGENERATE != 0);
    }
}
