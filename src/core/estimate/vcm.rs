//! VCM: Voronoi covariance measure (algorithms.md 5), a per-point version computed from
//! the K-neighbourhood alone. It ignores the normals' orientation and gives **unsigned**
//! principal curvatures: k1 <= k2 are magnitudes |kappa| (so H = (|k1| + |k2|)/2 and
//! K = |k1| |k2| >= 0, even on a saddle). The paper's own use of the VCM is for normals,
//! principal directions and sharp features (the ratio of algorithms.md 5.5); prefer the
//! other estimators for signed curvature. [`Estimator::estimate_extra`] also gives the VCM's own
//! normal (the convolved VCM's leading eigenvector, signed by the input normal,
//! algorithms.md 5.3) and the sharp-feature ratio, written by `--features`.
//!
//! Per point (algorithms.md 5.2, computed without a global Voronoi diagram):
//! * radii from the K-NN radius d_K: offset R = d_K and convolution radius r = d_K / 2, so that
//!   every cell in the convolution ball sees all points within d_K / 2 of its centre (its
//!   tangential neighbours); R stays below the reach when d_K does;
//! * the cell covariance of a point p, cov(Vor(p) ∩ B(p, R), p), is integrated along rays from
//!   p: for the star-shaped cell with radial function rho(u), int y y^T dy =
//!   int_{S^2} rho(u)^5 / 5 u u^T du, rho(u) = min(R, min over bisectors). The direction
//!   quadrature is dense near the normal axis (the cells are pencils along the normal); the
//!   query normal only places the quadrature nodes;
//! * V = sum of the cell covariances over the points within r (indicator kernel, eq. 1.2).
//!
//! Curvature magnitudes (algorithms.md 5.4): V ~ c [n n^T + sum_a kappa_a^2 m_a P_a P_a^T] with m_a
//! the second moment of the convolved points' tangential offsets along P_a (r^2/4 for a uniform
//! disk). The tangential extent of each cell adds a sampling bias of about 3 A_cell / (4 pi R^2) to
//! lambda_a / lambda_1 (algorithms.md 5.4), larger than the curvature term at K-NN scales, so the
//! magnitudes are not read from V's eigenvalues: each convolved cell contributes only its pencil
//! axis v (its leading eigenvector, weighted by its eigenvalue w), and the curvature along a
//! tangent direction is how much the axes turn across the ball there, kappa_a^2 = mu_a /
//! (lambda_1 m_a), with mu_a the tangent eigenvalues of sum w v v^T, lambda_1 its leading one and
//! m_a the w-weighted variance of the cell centres along that direction (`magnitudes`). What
//! remains is biased at second order in R kappa.

use super::{flags, local, Curvature, Estimator, ExtraColumn, Neighbourhood, Scratch};
use crate::core::geometry::{
    add, dot, scale, sub, sym2_eigen, sym3_eigen, tangent_basis, Eigen2, Principal, TangentBasis,
    M3, V3,
};
use std::sync::OnceLock;

/// A quadrature node on the unit sphere.
struct Node {
    /// Its unit direction.
    direction: V3,
    /// The solid angle it stands for.
    weight: f64,
}

/// Quadrature nodes on the unit sphere around the z axis, weights summing to 4 pi. Polar caps
/// of half-angle 0.6 rad get 32 midpoint rings each (the pencil-shaped cells need resolution
/// there), the band between them 24, and every ring 48 azimuths.
fn quadrature() -> &'static [Node] {
    static NODES: OnceLock<Vec<Node>> = OnceLock::new();
    NODES.get_or_init(|| {
        const CAP: f64 = 0.6;
        const AZIMUTHS: usize = 48;
        let pi = std::f64::consts::PI;
        let mut rings = Vec::new();
        for (lo, hi, n) in [(0.0, CAP, 32), (CAP, pi - CAP, 24), (pi - CAP, pi, 32)] {
            let step = (hi - lo) / n as f64;
            for i in 0..n {
                let t0 = lo + step * i as f64;
                // Exact ring area: 2 pi (cos t0 - cos t1), shared by the azimuths.
                rings.push((
                    t0 + 0.5 * step,
                    (t0.cos() - (t0 + step).cos()) * std::f64::consts::TAU,
                ));
            }
        }
        let mut nodes = Vec::with_capacity(rings.len() * AZIMUTHS);
        for (theta, area) in rings {
            let (st, ct) = theta.sin_cos();
            for k in 0..AZIMUTHS {
                let phi = std::f64::consts::TAU * (k as f64 + 0.5) / AZIMUTHS as f64;
                nodes.push(Node {
                    direction: [st * phi.cos(), st * phi.sin(), ct],
                    weight: area / AZIMUTHS as f64,
                });
            }
        }
        nodes
    })
}

/// The bisector plane of a cell's centre p and a neighbour q: the points x with
/// <x - p, w> = |w|^2 / 2.
#[derive(Clone, Copy)]
struct Plane {
    /// w = q - p, in the quadrature frame.
    w: V3,
    /// |w|^2 / 2.
    half: f64,
}

/// The estimator's buffers in [`super::Scratch`].
#[derive(Default)]
pub struct Buffers {
    /// The bisector planes of one cell.
    planes: Vec<Plane>,
    /// The neighbourhood in the quadrature frame.
    points: Vec<V3>,
}

/// Covariance of Vor(`points[c]`) ∩ B(`points[c]`, big_r) about `points[c]`, with `points` already
/// in the quadrature frame. Points coinciding with the centre (duplicates) do not clip.
fn cell_covariance(points: &[V3], c: usize, big_r: f64, planes: &mut Vec<Plane>) -> M3 {
    let p = points[c];
    planes.clear();
    let tiny = 1e-24 * big_r * big_r;
    for (j, &q) in points.iter().enumerate() {
        let w = sub(q, p);
        let w2 = dot(w, w);
        // Points beyond 2R cannot clip the ball B(p, R) (algorithms.md 5.2).
        if j != c && w2 > tiny && w2 < 4.0 * big_r * big_r {
            planes.push(Plane { w, half: 0.5 * w2 });
        }
    }
    let mut cov = [[0.0; 3]; 3];
    for node in quadrature() {
        let (u, weight) = (node.direction, node.weight);
        let mut rho = big_r;
        for &Plane { w, half } in planes.iter() {
            let s = dot(u, w);
            if s * rho > half {
                rho = half / s;
            }
        }
        let f = weight * rho.powi(5) / 5.0;
        for (row, &ua) in cov.iter_mut().zip(&u) {
            for (x, &ub) in row.iter_mut().zip(&u) {
                *x += f * ua * ub;
            }
        }
    }
    cov
}

/// The convolved VCM at the query point and the axis sums of the same cells ([`convolved_vcm`]),
/// in the quadrature frame.
struct Convolved {
    /// The convolved VCM: the sum of the covariances of the cells of the points within the
    /// convolution radius.
    vcm: M3,
    /// Its rank-one part and the cell centres' moments.
    axes: AxisSums,
}

/// The convolved VCM at the query point (indicator kernel of radius `small_r`, offset
/// `big_r`: the sum of the cells of the points within `small_r`), from points given in the
/// quadrature frame; and its rank-one part, the sum over the same cells of lambda_max v v^T
/// (each cell's pencil axis weighted by its pencil size), returned with the weighted second
/// moments of the cell centres needed by the curvature formula.
fn convolved_vcm(points: &[V3], big_r: f64, small_r: f64, planes: &mut Vec<Plane>) -> Convolved {
    let mut v = [[0.0; 3]; 3];
    let mut axes = AxisSums::default();
    for (c, &p) in points.iter().enumerate() {
        if dot(p, p) <= small_r * small_r {
            let cell = cell_covariance(points, c, big_r, planes);
            let e = sym3_eigen(&cell);
            let (w, axis) = (e.values[2], e.vectors[2]);
            axes.weight += w;
            for a in 0..3 {
                axes.centre[a] += w * p[a];
                for b in 0..3 {
                    v[a][b] += cell[a][b];
                    axes.vcm[a][b] += w * axis[a] * axis[b];
                    axes.moments[a][b] += w * p[a] * p[b];
                }
            }
        }
    }
    Convolved { vcm: v, axes }
}

/// Weighted sums over the convolved cells (weights = the cells' largest eigenvalues).
#[derive(Debug, Default)]
struct AxisSums {
    /// Sum of w v v^T over the cells' pencil axes v.
    vcm: M3,
    /// Sum of w.
    weight: f64,
    /// Sum of w p over the cell centres.
    centre: V3,
    /// Sum of w p p^T over the cell centres.
    moments: M3,
}

/// The sharp-feature ratio of algorithms.md 5.5, lambda_2 / (lambda_1 + lambda_2 + lambda_3) with
/// the eigenvalues `l` of the convolved VCM in decreasing order, from them in ascending order
/// (as `sym3_eigen` sorts them): lambda_2 of the decreasing order is the middle one. About 0
/// on smooth parts, (alpha - sin alpha) / (2 alpha) ~ alpha^2 / 12 on an edge of external
/// angle alpha, at most 1/2. NaN for a zero matrix.
fn ratio_of(l: [f64; 3]) -> f64 {
    l[1] / (l[0] + l[1] + l[2])
}

/// The VCM's values besides the curvature (`--features`, algorithms.md 5.3, 5.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Features {
    /// Sharp-feature score lambda2 / (lambda1 + lambda2 + lambda3) of the convolved VCM
    /// (eigenvalues in decreasing order): 0 on a plane, about alpha^2 / 12 on an edge of
    /// external angle alpha; in [0, 1/2].
    pub feature: f64,
    /// The VCM's unit normal (its leading eigenvector), oriented to agree with the query
    /// point's input normal.
    pub normal: V3,
}

/// The columns of [`Features`], in the order the estimator writes them.
const EXTRA_COLUMNS: [ExtraColumn; 4] = [
    ExtraColumn {
        name: "SharpFeature",
        description: "VCM edge score l2/(l1+l2+l3)",
        flips: false,
        bound: 0.5,
    },
    ExtraColumn {
        name: "VcmNormalX",
        description: "VCM unit normal x",
        flips: true,
        bound: 1.0,
    },
    ExtraColumn {
        name: "VcmNormalY",
        description: "VCM unit normal y",
        flips: true,
        bound: 1.0,
    },
    ExtraColumn {
        name: "VcmNormalZ",
        description: "VCM unit normal z",
        flips: true,
        bound: 1.0,
    },
];

/// The VCM's own normal and sharp-feature score (algorithms.md 5.3, 5.5) from the convolved VCM
/// `v` given in the query frame `frame` (whose third axis is the query's input normal): the
/// leading eigenvector, signed to agree with the input normal and mapped to world axes, and
/// [`ratio_of`] its eigenvalues. NaN components for a zero or non-finite matrix.
fn extra_of(frame: &M3, v: &M3) -> Features {
    let eig = sym3_eigen(v);
    let (l, e) = (eig.values, eig.vectors[2]);
    let normal = if l[2].is_finite() && l[2] > 0.0 {
        // In the frame the input normal is the z axis: agreeing means a non-negative z.
        from_frame(frame, if e[2] < 0.0 { scale(e, -1.0) } else { e })
    } else {
        [f64::NAN; 3]
    };
    Features {
        feature: ratio_of(l),
        normal,
    }
}

/// In the query frame `frame` ([`frame_of`] the query's input normal), the convolved VCM and
/// the axis sums of the neighbourhood with the radii of the module documentation: offset
/// R = `d_k`, convolution radius r = `d_k` / 2.
fn convolved_in_frame(nb: &Neighbourhood<'_>, frame: &M3, d_k: f64, s: &mut Buffers) -> Convolved {
    let Buffers { planes, points } = s;
    points.clear();
    points.extend(nb.positions.iter().map(|&p| to_frame(frame, p)));
    convolved_vcm(points, d_k, 0.5 * d_k, planes)
}

/// The quadrature frame (e1, e2, n): its rows map world vectors to frame coordinates.
fn frame_of(n: V3) -> M3 {
    let TangentBasis { e1, e2 } = tangent_basis(n);
    [e1, e2, n]
}

fn to_frame(f: &M3, p: V3) -> V3 {
    [dot(f[0], p), dot(f[1], p), dot(f[2], p)]
}

fn from_frame(f: &M3, p: V3) -> V3 {
    add(add(scale(f[0], p[0]), scale(f[1], p[1])), scale(f[2], p[2]))
}

/// The VCM estimator: unsigned principal curvature magnitudes and principal directions (see
/// the module documentation). The cell integration dominates (~4000 directions x K planes per
/// convolved cell, twice), so this is the slowest estimator by far: use it for directions and
/// features.
#[derive(Debug, Clone, Copy, Default)]
pub struct Vcm;

impl Estimator for Vcm {
    fn name(&self) -> &'static str {
        "vcm"
    }

    fn extra_columns(&self) -> &'static [ExtraColumn] {
        &EXTRA_COLUMNS
    }

    fn estimate(&self, nb: &Neighbourhood<'_>, scratch: &mut Scratch) -> Curvature {
        self.estimate_extra(nb, scratch, &mut [])
    }

    fn estimate_extra(
        &self,
        nb: &Neighbourhood<'_>,
        scratch: &mut Scratch,
        extra: &mut [f64],
    ) -> Curvature {
        if let Err(f) = local::check(nb, 3) {
            return Curvature::undefined(f);
        }
        let d_k = local::knn_radius(nb.positions);
        let TangentBasis { e1, e2 } = tangent_basis(nb.normals[0]);
        if d_k.is_nan()
            || d_k <= 0.0
            || local::is_collinear(local::tangent_moments(nb.positions, e1, e2))
        {
            return Curvature::undefined(flags::DEGENERATE);
        }
        let frame = frame_of(nb.normals[0]);
        let c = convolved_in_frame(nb, &frame, d_k, &mut scratch.vcm);
        let f = extra_of(&frame, &c.vcm);
        let values = [f.feature, f.normal[0], f.normal[1], f.normal[2]];
        for (slot, v) in extra.iter_mut().zip(values) {
            *slot = v;
        }
        magnitudes(&frame, &c.axes)
    }
}

/// The unsigned principal curvatures and directions (world axes) from the axis sums of the
/// convolved cells in the query frame `frame` (module documentation); DEGENERATE when the
/// pencils or the centres' spread vanish.
fn magnitudes(frame: &M3, ax: &AxisSums) -> Curvature {
    if ax.weight.is_nan() || ax.weight <= 0.0 {
        return Curvature::undefined(flags::DEGENERATE);
    }
    // The normal: the axis VCM's leading eigenvector (unoriented); lambda_1 its value.
    let eig = sym3_eigen(&ax.vcm);
    let (lambda1, n) = (eig.values[2], eig.vectors[2]);
    let TangentBasis { e1: t1, e2: t2 } = tangent_basis(n);
    let quad = |m: &M3, a: V3, b: V3| {
        let mb = [dot(m[0], b), dot(m[1], b), dot(m[2], b)];
        dot(a, mb)
    };
    let Eigen2 {
        values: mu,
        vectors: w,
    } = sym2_eigen(
        quad(&ax.vcm, t1, t1),
        quad(&ax.vcm, t1, t2),
        quad(&ax.vcm, t2, t2),
    );
    let centre = scale(ax.centre, 1.0 / ax.weight);
    let mut out = [(0.0, [0.0; 3]); 2];
    for (a, o) in out.iter_mut().enumerate() {
        let d = add(scale(t1, w[a][0]), scale(t2, w[a][1]));
        // Weighted variance of the cell centres along d: the m_a of the module docs.
        let m = quad(&ax.moments, d, d) / ax.weight - dot(centre, d).powi(2);
        let kappa2 = mu[a].max(0.0) / (lambda1 * m);
        *o = (kappa2.sqrt(), from_frame(frame, d));
    }
    if lambda1.is_nan() || lambda1 <= 0.0 || !out.iter().all(|o| o.0.is_finite()) {
        return Curvature::undefined(flags::DEGENERATE);
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    let [(k1, d1), (k2, d2)] = out;
    Curvature::from_principal(Principal {
        k1,
        k2,
        d1,
        d2,
        umbilic: k2 - k1 <= 1e-6 * k2 || k2 == 0.0,
    })
}

#[cfg(test)]
#[path = "vcm_tests.rs"]
mod tests;
