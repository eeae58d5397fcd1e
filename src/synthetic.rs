//! Synthetic surfaces with closed-form curvature (algorithms.md section 6), seeded samplers that
//! return positions with exact unit normals, an exact k-NN and an error summary, for tests of
//! the estimators and of the engine, and for generating synthetic terrain. Everything uses the
//! tool's convention (section 0.1): k1 <= k2, H = (k1 + k2)/2, K = k1 k2, a sphere with outward
//! normals has H = +1/r. Random streams come from [`crate::estimate::rng::Rng`], so clouds are
//! identical across releases for a given seed. The samplers are not used by the production
//! pipeline; the curvature formulas are (the jet estimator reads its fit through
//! [`height_field_curvature`]).

use crate::estimate::rng::Rng;
use crate::estimate::{principal_from_tangent, Curvature, Estimator, Neighbourhood};
use crate::geometry::{dot, norm, normalize, scale, sub, tangent_basis, M3, V3};
use std::f64::consts::{PI, TAU};

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
    fn from_tangent(s: [[f64; 2]; 2], e1: V3, e2: V3) -> Self {
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

/// Sphere of radius `r` with outward normals (section 6.1): k1 = k2 = 1/r, an umbilic.
pub fn sphere_curvature(r: f64) -> TrueCurvature {
    TrueCurvature::umbilic(1.0 / r)
}

/// Plane: all curvatures zero, directions arbitrary.
pub fn plane_curvature() -> TrueCurvature {
    TrueCurvature::umbilic(0.0)
}

/// Cylinder of radius `r` around the z axis with outward normals, at the surface point `p`
/// (section 6.1): k1 = 0 along the axis, k2 = 1/r around it.
pub fn cylinder_curvature(r: f64, p: V3) -> TrueCurvature {
    let around = normalize([-p[1], p[0], 0.0]).unwrap_or([0.0, 1.0, 0.0]);
    TrueCurvature {
        k1: 0.0,
        k2: 1.0 / r,
        h: 0.5 / r,
        k: 0.0,
        directions: Some(([0.0, 0.0, 1.0], around)),
    }
}

/// The torus point and outward unit normal at angles (theta around the tube from the outer
/// equator, phi around the z axis), major radius `big_r`, tube radius `r` (section 6.1).
pub fn torus_point(big_r: f64, r: f64, theta: f64, phi: f64) -> (V3, V3) {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let rho = big_r + r * ct;
    ([rho * cp, rho * sp, r * st], [ct * cp, ct * sp, st])
}

/// Torus curvature from the parametrisation (section 6.1): k1 = cos(theta)/(R + r cos(theta))
/// along the parallel (phi direction), k2 = 1/r along the meridian (theta direction). k1 <= k2
/// holds for every theta because R > 0.
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

/// Gradient and Hessian of the implicit torus of section 6.5,
/// F = (|x|^2 + R^2 - r^2)^2 - 4 R^2 (x^2 + y^2), negative inside.
pub fn torus_implicit(big_r: f64, r: f64, p: V3) -> (V3, M3) {
    let s = dot(p, p) + big_r * big_r - r * r;
    let c = 8.0 * big_r * big_r;
    let g = [
        4.0 * s * p[0] - c * p[0],
        4.0 * s * p[1] - c * p[1],
        4.0 * s * p[2],
    ];
    let mut hs = [[0.0; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            hs[a][b] = 8.0 * p[a] * p[b];
        }
        hs[a][a] += 4.0 * s - if a < 2 { c } else { 0.0 };
    }
    (g, hs)
}

/// The goursat function of section 6.4, F = 0.03 (x^4 + y^4 + z^4) - 2 |x|^2 - 8 (negative
/// inside).
pub fn goursat_value(p: V3) -> f64 {
    let q: f64 = p.iter().map(|x| x.powi(4)).sum();
    0.03 * q - 2.0 * dot(p, p) - 8.0
}

/// Gradient and Hessian of the goursat function (section 6.4).
pub fn goursat_implicit(p: V3) -> (V3, M3) {
    let g = p.map(|x| 0.12 * x * x * x - 4.0 * x);
    let mut hs = [[0.0; 3]; 3];
    for a in 0..3 {
        hs[a][a] = 0.36 * p[a] * p[a] - 4.0;
    }
    (g, hs)
}

/// Goursat curvature at a surface point (outward normal = gradient direction).
pub fn goursat_curvature(p: V3) -> Option<TrueCurvature> {
    let (g, hs) = goursat_implicit(p);
    implicit_curvature(g, &hs)
}

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

/// The saddle z = (x^2 - y^2)/2 (section 6.1: k = (-1, +1) at the origin, upward normal).
#[derive(Debug, Clone, Copy, Default)]
pub struct Saddle;

impl HeightField for Saddle {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        HeightJet {
            h: 0.5 * (x * x - y * y),
            hx: x,
            hy: -y,
            hxx: 1.0,
            hxy: 0.0,
            hyy: -1.0,
        }
    }
}

/// The paraboloid z = a (x^2 + y^2) (section 6.1: k1 = k2 = -2a at the origin, upward normal).
#[derive(Debug, Clone, Copy)]
pub struct Paraboloid {
    /// The coefficient a.
    pub a: f64,
}

impl HeightField for Paraboloid {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        let a = self.a;
        HeightJet {
            h: a * (x * x + y * y),
            hx: 2.0 * a * x,
            hy: 2.0 * a * y,
            hxx: 2.0 * a,
            hxy: 0.0,
            hyy: 2.0 * a,
        }
    }
}

/// Sampled oriented points: positions and exact (or noisy) unit normals, same order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    /// Positions.
    pub positions: Vec<V3>,
    /// Unit normals.
    pub normals: Vec<V3>,
}

impl Cloud {
    fn with_capacity(n: usize) -> Self {
        Cloud {
            positions: Vec::with_capacity(n),
            normals: Vec::with_capacity(n),
        }
    }

    fn push(&mut self, p: V3, n: V3) {
        self.positions.push(p);
        self.normals.push(n);
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True if there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Adds centred Gaussian noise of standard deviation `sigma_position` to every position
    /// coordinate and `sigma_normal` to every normal coordinate, then renormalises the normals
    /// (section 6.6, as in the CNC paper). A normal that the noise cancels exactly is left unchanged.
    pub fn add_noise(&mut self, sigma_position: f64, sigma_normal: f64, seed: u64) {
        let mut rng = Rng::new(seed);
        for (p, n) in self.positions.iter_mut().zip(self.normals.iter_mut()) {
            for c in p.iter_mut() {
                *c += sigma_position * rng.normal();
            }
            let noisy = [
                n[0] + sigma_normal * rng.normal(),
                n[1] + sigma_normal * rng.normal(),
                n[2] + sigma_normal * rng.normal(),
            ];
            *n = normalize(noisy).unwrap_or(*n);
        }
    }
}

/// A uniform random unit vector (uniform z and azimuth: Archimedes).
fn unit_vector(rng: &mut Rng) -> V3 {
    let z = 2.0 * rng.uniform() - 1.0;
    let phi = TAU * rng.uniform();
    let s = (1.0 - z * z).max(0.0).sqrt();
    [s * phi.cos(), s * phi.sin(), z]
}

/// `n` points uniform in area on the sphere of radius `r` centred at the origin, outward
/// normals.
pub fn sample_sphere(n: usize, r: f64, seed: u64) -> Cloud {
    let mut rng = Rng::new(seed);
    let mut cloud = Cloud::with_capacity(n);
    for _ in 0..n {
        let d = unit_vector(&mut rng);
        cloud.push(scale(d, r), d);
    }
    cloud
}

/// `n` points uniform in area on the cylinder of radius `r` around the z axis, z in
/// [-length/2, length/2], outward normals. Points near the two rims have one-sided
/// neighbourhoods: exclude them when measuring errors.
pub fn sample_cylinder(n: usize, r: f64, length: f64, seed: u64) -> Cloud {
    let mut rng = Rng::new(seed);
    let mut cloud = Cloud::with_capacity(n);
    for _ in 0..n {
        let z = length * (rng.uniform() - 0.5);
        let (s, c) = (TAU * rng.uniform()).sin_cos();
        cloud.push([r * c, r * s, z], [c, s, 0.0]);
    }
    cloud
}

/// `n` points uniform in area on the torus (major radius `big_r`, tube radius `r`) with outward
/// normals: uniform angles, theta accepted with probability (R + r cos theta)/(R + r), the
/// area density (section 6.6).
pub fn sample_torus(n: usize, big_r: f64, r: f64, seed: u64) -> Cloud {
    let mut rng = Rng::new(seed);
    let mut cloud = Cloud::with_capacity(n);
    while cloud.len() < n {
        let theta = TAU * rng.uniform();
        let phi = TAU * rng.uniform();
        if rng.uniform() * (big_r + r) <= big_r + r * theta.cos() {
            let (p, nrm) = torus_point(big_r, r, theta, phi);
            cloud.push(p, nrm);
        }
    }
    cloud
}

/// Upper bound of the goursat area density per unit solid angle, t^2 / <d | n> over the
/// radial projection (measured maximum 217.0 over 2e6 directions; checked in the tests).
const GOURSAT_DENSITY_BOUND: f64 = 230.0;

/// The goursat surface point on the ray from the origin in unit direction `d`. Along the ray
/// F(t d) = a t^4 - 2 t^2 - 8 with a = 0.03 sum d_i^4 > 0, a quadratic in t^2 with one positive
/// root, so the radial projection is closed form (no bisection needed): the surface is
/// star-shaped around the origin.
pub fn goursat_radial(d: V3) -> V3 {
    let a = 0.03 * d.iter().map(|x| x.powi(4)).sum::<f64>();
    let t2 = (1.0 + (1.0 + 8.0 * a).sqrt()) / a;
    scale(d, t2.sqrt())
}

/// `n` points uniform in area on the goursat surface (section 6.4) with outward normals: radial
/// projection of uniform directions, accepted with probability proportional to the area per
/// solid angle t^2 / <d | n> (section 6.6).
pub fn sample_goursat(n: usize, seed: u64) -> Cloud {
    let mut rng = Rng::new(seed);
    let mut cloud = Cloud::with_capacity(n);
    while cloud.len() < n {
        let d = unit_vector(&mut rng);
        let p = goursat_radial(d);
        let Some(nrm) = normalize(goursat_implicit(p).0) else {
            continue;
        };
        let density = dot(p, p) / dot(d, nrm);
        if rng.uniform() * GOURSAT_DENSITY_BOUND <= density {
            cloud.push(p, nrm);
        }
    }
    cloud
}

/// Samples the height field `f` on an `n_side` x `n_side` grid over [-half_width, half_width]^2
/// with upward normals. Each grid node is moved by up to `jitter`/2 grid spacings along x and y
/// (uniform), so `jitter = 0` gives the regular grid and `jitter = 1` a jittered grid.
pub fn sample_height_field(
    f: &impl HeightField,
    half_width: f64,
    n_side: usize,
    jitter: f64,
    seed: u64,
) -> Cloud {
    let mut rng = Rng::new(seed);
    let mut cloud = Cloud::with_capacity(n_side * n_side);
    let step = if n_side > 1 {
        2.0 * half_width / (n_side - 1) as f64
    } else {
        0.0
    };
    for i in 0..n_side {
        for j in 0..n_side {
            let x = -half_width + step * i as f64 + jitter * step * (rng.uniform() - 0.5);
            let y = -half_width + step * j as f64 + jitter * step * (rng.uniform() - 0.5);
            let jet = f.jet(x, y);
            cloud.push([x, y, jet.h], jet.normal());
        }
    }
    cloud
}

/// Reads a text cloud of `x y z nx ny nz` lines (the reference `.pts` files of section 8),
/// skipping empty lines and `#` comments (their header line is wrong anyway).
pub fn read_pts(path: &std::path::Path) -> std::io::Result<Cloud> {
    let text = std::fs::read_to_string(path)?;
    let mut cloud = Cloud::default();
    for (line_no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut v = [0.0; 6];
        let mut count = 0;
        for (slot, tok) in v.iter_mut().zip(line.split_whitespace()) {
            *slot = tok.parse().map_err(|e| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("{}:{}: {tok:?}: {e}", path.display(), line_no + 1),
                )
            })?;
            count += 1;
        }
        if count < 6 {
            let msg = format!(
                "{}:{}: expected 6 numbers (x y z nx ny nz)",
                path.display(),
                line_no + 1
            );
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, msg));
        }
        cloud.push([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
    }
    Ok(cloud)
}

/// Exact k nearest neighbours of every point, the point itself first, then by increasing
/// distance with ties broken by index (so the result is fully determined). Returns min(k, n)
/// indices per point. The search is exhaustive over a uniform grid (rings of cells until no
/// closer point can remain), so it is exact like a brute force, only faster.
pub fn knn_brute(points: &[V3], k: usize) -> Vec<Vec<usize>> {
    let n = points.len();
    let k = k.min(n);
    if k == 0 {
        return vec![Vec::new(); n];
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let extent = sub(hi, lo);
    let size = extent.iter().cloned().fold(0.0, f64::max);
    // About k/2 points per occupied cell on a surface, and at most ~4n cells in all.
    let volume: f64 = extent.iter().map(|e| e.max(size * 1e-3)).product();
    let cell =
        (size * (k as f64 / (2.0 * n as f64)).sqrt()).max((volume / (4.0 * n as f64)).cbrt());
    let cell = if cell > 0.0 && cell.is_finite() {
        cell
    } else {
        1.0
    };
    let dims = extent.map(|e| ((e / cell) as usize + 1).min(1 << 20));
    let cell_of = |p: V3| -> [usize; 3] {
        let mut c = [0; 3];
        for a in 0..3 {
            c[a] = (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1);
        }
        c
    };
    let flat = |c: [usize; 3]| (c[0] * dims[1] + c[1]) * dims[2] + c[2];
    // Counting sort of the points by cell.
    let mut start = vec![0usize; dims[0] * dims[1] * dims[2] + 1];
    for p in points {
        start[flat(cell_of(*p)) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut fill = start.clone();
    let mut order = vec![0usize; n];
    for (i, p) in points.iter().enumerate() {
        let f = flat(cell_of(*p));
        order[fill[f]] = i;
        fill[f] += 1;
    }
    let max_ring = dims.iter().copied().max().unwrap_or(1);
    let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
    let mut out = Vec::with_capacity(n);
    for (i, &q) in points.iter().enumerate() {
        best.clear();
        // The query itself first, whatever other points coincide with it.
        best.push((f64::NEG_INFINITY, i));
        let c = cell_of(q);
        for m in 0..=max_ring {
            let m_i = m as isize;
            for dx in -m_i..=m_i {
                for dy in -m_i..=m_i {
                    for dz in -m_i..=m_i {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != m_i {
                            continue;
                        }
                        let cc = [c[0] as isize + dx, c[1] as isize + dy, c[2] as isize + dz];
                        if (0..3).any(|a| cc[a] < 0 || cc[a] >= dims[a] as isize) {
                            continue;
                        }
                        let f = flat(cc.map(|x| x as usize));
                        for &j in &order[start[f]..start[f + 1]] {
                            if j == i {
                                continue;
                            }
                            let d = sub(points[j], q);
                            let key = (dot(d, d), j);
                            if best.len() == k && key >= best[k - 1] {
                                continue;
                            }
                            let pos = best.partition_point(|b| *b < key);
                            best.insert(pos, key);
                            best.truncate(k);
                        }
                    }
                }
            }
            // Points in rings beyond m are at least m cells away: stop when the k-th is closer.
            let reach = m as f64 * cell;
            if best.len() == k && best[k - 1].0 < reach * reach {
                break;
            }
        }
        out.push(best.iter().map(|b| b.1).collect());
    }
    out
}

/// Runs `estimator` at the point `nbrs[0]` of `cloud` with the neighbours `nbrs` (indices into
/// the cloud, the point itself first), positions relative to the point and ids = indices.
/// Allocates: for tests and tools, not for the pipeline.
pub fn estimate_point(
    estimator: &(impl Estimator + ?Sized),
    cloud: &Cloud,
    nbrs: &[usize],
) -> Curvature {
    let Some(&i) = nbrs.first() else {
        return Curvature::undefined(crate::estimate::flags::FEW_NEIGHBOURS);
    };
    let q = cloud.positions[i];
    let positions: Vec<V3> = nbrs.iter().map(|&j| sub(cloud.positions[j], q)).collect();
    let normals: Vec<V3> = nbrs.iter().map(|&j| cloud.normals[j]).collect();
    let ids: Vec<u64> = nbrs.iter().map(|&j| j as u64).collect();
    estimator.estimate(&Neighbourhood {
        positions: &positions,
        normals: &normals,
        ids: &ids,
    })
}

/// Root mean square and maximum of absolute errors.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorSummary {
    /// Root mean square error.
    pub rms: f64,
    /// Maximum absolute error.
    pub max: f64,
    sum2: f64,
    count: usize,
}

impl ErrorSummary {
    fn add(&mut self, e: f64) {
        self.sum2 += e * e;
        self.max = self.max.max(e.abs());
        self.count += 1;
        self.rms = (self.sum2 / self.count as f64).sqrt();
    }

    /// Number of values summarised.
    pub fn count(&self) -> usize {
        self.count
    }
}

/// Errors of an estimator against ground truth over a cloud.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorStats {
    /// Mean curvature H.
    pub h: ErrorSummary,
    /// Gaussian curvature K.
    pub k: ErrorSummary,
    /// Smaller principal curvature k1.
    pub k1: ErrorSummary,
    /// Larger principal curvature k2.
    pub k2: ErrorSummary,
    /// Angle in degrees between the estimated and true k1 lines (direction up to sign), over
    /// the points where the truth has directions and |k2 - k1| >= the given gap.
    pub d1_deg: ErrorSummary,
    /// Points whose estimate was undefined (NaN): excluded from the other summaries.
    pub undefined: usize,
}

impl std::fmt::Display for ErrorStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "n={} undefined={} RMS(1e-3) H {:.3} K {:.3} k1 {:.3} k2 {:.3} | max H {:.4} K {:.4} k1 {:.4} k2 {:.4} | d1 RMS {:.2} deg",
            self.h.count,
            self.undefined,
            1e3 * self.h.rms,
            1e3 * self.k.rms,
            1e3 * self.k1.rms,
            1e3 * self.k2.rms,
            self.h.max,
            self.k.max,
            self.k1.max,
            self.k2.max,
            self.d1_deg.rms
        )
    }
}

/// Evaluates `estimator` at every point of `cloud` with the neighbour lists `knn` (as from
/// [`knn_brute`]) against `truth(i)`; points where `truth` returns None (rims, boundaries) are
/// skipped. Direction errors are measured where |k2 - k1| >= `min_gap`.
pub fn evaluate(
    estimator: &(impl Estimator + ?Sized),
    cloud: &Cloud,
    knn: &[Vec<usize>],
    truth: impl Fn(usize) -> Option<TrueCurvature>,
    min_gap: f64,
) -> ErrorStats {
    let mut s = ErrorStats::default();
    for (i, nbrs) in knn.iter().enumerate() {
        let Some(t) = truth(i) else { continue };
        let c = estimate_point(estimator, cloud, nbrs);
        if c.h.is_nan() || c.k.is_nan() || c.k1.is_nan() || c.k2.is_nan() {
            s.undefined += 1;
            continue;
        }
        s.h.add(c.h - t.h);
        s.k.add(c.k - t.k);
        s.k1.add(c.k1 - t.k1);
        s.k2.add(c.k2 - t.k2);
        if let (Some((d1, _)), true) = (t.directions, t.k2 - t.k1 >= min_gap) {
            if let Some(e) = normalize(c.d1) {
                s.d1_deg.add(dot(e, d1).abs().min(1.0).acos() * 180.0 / PI);
            }
        }
    }
    s
}

/// Applies the rigid motion x -> rot x + shift to a cloud (normals rotated). For invariance
/// tests.
pub fn transform(cloud: &Cloud, rot: &M3, shift: V3) -> Cloud {
    let apply = |m: &M3, v: V3| [dot(m[0], v), dot(m[1], v), dot(m[2], v)];
    Cloud {
        positions: cloud
            .positions
            .iter()
            .map(|&p| crate::geometry::add(apply(rot, p), shift))
            .collect(),
        normals: cloud.normals.iter().map(|&n| apply(rot, n)).collect(),
    }
}

/// The rotation by `angle` radians around `axis` (Rodrigues: R v = c v + s a x v + (1 - c) <a|v> a).
pub fn rotation(axis: V3, angle: f64) -> M3 {
    let a = normalize(axis).unwrap_or([0.0, 0.0, 1.0]);
    let (s, c) = angle.sin_cos();
    let skew = [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]];
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for k in 0..3 {
            m[r][k] = s * skew[r][k] + (1.0 - c) * a[r] * a[k] + if r == k { c } else { 0.0 };
        }
    }
    m
}

/// The directory of the reference clouds of algorithms.md section 8 (env var
/// `TILECURV_REFERENCE_DIR` overrides it).
#[cfg(test)]
pub(crate) fn reference_dir() -> std::path::PathBuf {
    std::env::var_os("TILECURV_REFERENCE_DIR")
        .map(Into::into)
        .unwrap_or_else(|| "/work/shared/data/reference".into())
}

/// Loads a reference cloud (path relative to [`reference_dir`]). A missing file fails the test
/// when `CI=true`; otherwise it prints a loud skip reason and returns None.
#[cfg(test)]
pub(crate) fn reference_cloud(rel: &str) -> Option<Cloud> {
    let path = reference_dir().join(rel);
    match read_pts(&path) {
        Ok(c) => Some(c),
        Err(e) if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("reference cloud {} unavailable: {e}", path.display())
        }
        Err(e) => {
            eprintln!("\n*** SKIPPED: reference cloud {} unavailable ({e}); set CI=true to make this fail ***\n", path.display());
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::cross;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// Section 6.4 reference table (6 significant digits quoted there).
    #[test]
    fn goursat_reference_values() {
        let face = goursat_curvature([8.39355, 0.0, 0.0]).unwrap();
        assert!(
            close(face.h, -0.106990, 2e-6) && close(face.k, 0.0114469, 2e-7),
            "{face:?}"
        );
        assert!(face.directions.is_none() || close(face.k1, face.k2, 1e-6));
        let corner = goursat_curvature([8.24466; 3]).unwrap();
        assert!(
            close(corner.h, 0.344849, 2e-6) && close(corner.k, 0.118921, 2e-6),
            "{corner:?}"
        );
        assert!(close(corner.k1, 0.344849, 2e-6) && close(corner.k2, 0.344849, 2e-6));
        let edge = goursat_curvature([8.28312, -8.28312, 0.0]).unwrap();
        assert!(
            close(edge.k1, -0.0806645, 2e-6) && close(edge.k2, 0.417431, 2e-6),
            "{edge:?}"
        );
        assert!(close(edge.h, 0.168383, 2e-6) && close(edge.k, -0.0336718, 2e-6));
        // k1 (negative) runs along the edge (z), k2 across it.
        let (d1, d2) = edge.directions.unwrap();
        assert!(d1[2].abs() > 1.0 - 1e-9 && d2[2].abs() < 1e-9);
        // The quoted points lie on the surface (to the quoted digits).
        for p in [[8.39355, 0.0, 0.0], [8.24466; 3], [8.28312, 8.28312, 0.0]] {
            assert!(goursat_value(p).abs() < 1e-5 * norm(goursat_implicit(p).0));
        }
        assert!(close(norm(goursat_radial([1.0, 0.0, 0.0])), 8.393555, 1e-5));
    }

    /// K from the adjugate formula of 6.3 equals the product of the shape-operator eigenvalues.
    #[test]
    fn implicit_matches_adjugate_formula() {
        let mut rng = Rng::new(3);
        for _ in 0..100 {
            let p = goursat_radial(unit_vector(&mut rng));
            let (g, h) = goursat_implicit(p);
            let t = implicit_curvature(g, &h).unwrap();
            let adj = [cross(h[1], h[2]), cross(h[2], h[0]), cross(h[0], h[1])];
            let gag = dot(g, [dot(adj[0], g), dot(adj[1], g), dot(adj[2], g)]);
            let k = gag / dot(g, g).powi(2);
            let hs_g = [dot(h[0], g), dot(h[1], g), dot(h[2], g)];
            let hm = (dot(g, g) * (h[0][0] + h[1][1] + h[2][2]) - dot(g, hs_g))
                / (2.0 * norm(g).powi(3));
            assert!(
                close(t.k, k, 1e-12) && close(t.h, hm, 1e-12),
                "{t:?} {k} {hm}"
            );
            assert!(t.k1 <= t.k2);
        }
    }

    /// Implicit (6.5) and parametric (6.1) torus agree, including directions, and match the
    /// quoted values at the equators.
    #[test]
    fn torus_implicit_equals_parametric() {
        let (big_r, r) = (6.0, 2.0);
        for i in 0..37 {
            for j in 0..5 {
                let (theta, phi) = (i as f64 * 0.17 - 3.1, j as f64 * 1.3);
                let (p, n) = torus_point(big_r, r, theta, phi);
                let (g, h) = torus_implicit(big_r, r, p);
                assert!(dot(normalize(g).unwrap(), n) > 1.0 - 1e-12);
                let a = implicit_curvature(g, &h).unwrap();
                let b = torus_curvature(big_r, r, theta, phi);
                for (x, y) in [(a.k1, b.k1), (a.k2, b.k2), (a.h, b.h), (a.k, b.k)] {
                    assert!(close(x, y, 1e-12), "theta {theta}: {a:?} {b:?}");
                }
                let ((a1, a2), (b1, b2)) = (a.directions.unwrap(), b.directions.unwrap());
                assert!(dot(a1, b1).abs() > 1.0 - 1e-9 && dot(a2, b2).abs() > 1.0 - 1e-9);
                let c = torus_curvature_at(big_r, r, p);
                assert!(close(c.h, b.h, 1e-12));
            }
        }
        let outer = torus_curvature(6.0, 2.0, 0.0, 0.0);
        let inner = torus_curvature(6.0, 2.0, PI, 0.0);
        assert!(close(outer.k1, 0.125, 1e-15) && close(outer.k2, 0.5, 1e-15));
        assert!(
            close(inner.k1, -0.25, 1e-15)
                && close(inner.h, 0.125, 1e-15)
                && close(inner.k, -0.125, 1e-15)
        );
    }

    /// Height-field curvature equals the explicit Monge formulas of 6.2 and the table of 6.1.
    #[test]
    fn height_field_matches_monge_formulas() {
        let mut rng = Rng::new(5);
        for _ in 0..200 {
            let v: Vec<f64> = (0..5).map(|_| 4.0 * rng.uniform() - 2.0).collect();
            let (hx, hy, hxx, hxy, hyy) = (v[0], v[1], v[2], v[3], v[4]);
            let t = height_field_curvature(hx, hy, hxx, hxy, hyy);
            let w = 1.0 + hx * hx + hy * hy;
            let k = (hxx * hyy - hxy * hxy) / (w * w);
            let h = -((1.0 + hy * hy) * hxx - 2.0 * hx * hy * hxy + (1.0 + hx * hx) * hyy)
                / (2.0 * w.powf(1.5));
            assert!(
                close(t.k, k, 1e-12) && close(t.h, h, 1e-12),
                "{t:?} {h} {k}"
            );
            let disc = (h * h - k).max(0.0).sqrt();
            assert!(close(t.k1, h - disc, 1e-7) && close(t.k2, h + disc, 1e-7));
        }
        let s = Saddle.jet(0.0, 0.0).curvature();
        assert_eq!((s.k1, s.k2, s.h, s.k), (-1.0, 1.0, 0.0, -1.0));
        let (d1, d2) = s.directions.unwrap();
        assert!(d1[0].abs() > 1.0 - 1e-12 && d2[1].abs() > 1.0 - 1e-12);
        let a = 0.5;
        let p = Paraboloid { a };
        assert_eq!(p.jet(0.0, 0.0).curvature().h, -2.0 * a);
        let rho: f64 = 0.7;
        let t = p.jet(rho, 0.0).curvature();
        let q = 1.0 + 4.0 * a * a * rho * rho;
        assert!(
            close(t.k1, -2.0 * a / q.sqrt(), 1e-12) && close(t.k2, -2.0 * a / q.powf(1.5), 1e-12),
            "{t:?}"
        );
        assert!(close(
            t.h,
            -a * (2.0 + 4.0 * a * a * rho * rho) / q.powf(1.5),
            1e-12
        ));
        assert!(close(t.k, 4.0 * a * a / (q * q), 1e-12));
        // k1 (the parallel) is along y at (rho, 0).
        assert!(t.directions.unwrap().0[1].abs() > 1.0 - 1e-12);
    }

    #[test]
    fn simple_shapes_table() {
        assert_eq!(
            sphere_curvature(2.0),
            TrueCurvature {
                k1: 0.5,
                k2: 0.5,
                h: 0.5,
                k: 0.25,
                directions: None
            }
        );
        let c = cylinder_curvature(2.0, [0.0, 2.0, 1.0]);
        assert_eq!((c.k1, c.k2, c.h, c.k), (0.0, 0.5, 0.25, 0.0));
        assert_eq!(c.directions.unwrap().1, [-1.0, 0.0, 0.0]);
        assert_eq!(plane_curvature().h, 0.0);
        let sph = implicit_curvature(
            [0.0, 0.0, 4.0],
            &[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]],
        )
        .unwrap();
        assert!(close(sph.h, 0.5, 1e-15) && close(sph.k, 0.25, 1e-15) && sph.directions.is_none());
        assert!(implicit_curvature([0.0; 3], &[[1.0; 3]; 3]).is_none());
    }

    #[test]
    fn samplers_are_on_surface_seeded_and_uniform() {
        let s = sample_sphere(1000, 2.0, 1);
        assert_eq!(s, sample_sphere(1000, 2.0, 1));
        assert_ne!(s, sample_sphere(1000, 2.0, 2));
        assert!(s
            .positions
            .iter()
            .zip(&s.normals)
            .all(|(p, n)| close(norm(*p), 2.0, 1e-12) && close(dot(*p, *n), 2.0, 1e-12)));
        let t = sample_torus(20000, 6.0, 2.0, 1);
        let mut outer = 0;
        for (p, n) in t.positions.iter().zip(&t.normals) {
            let (g, _) = torus_implicit(6.0, 2.0, *p);
            assert!(dot(normalize(g).unwrap(), *n) > 1.0 - 1e-12);
            outer += usize::from(p[0].hypot(p[1]) > 6.0);
        }
        // Area fraction of the outer half (cos theta > 0): (pi R + 2 r)/(2 pi R) = 0.6061;
        // binomial standard deviation 0.0035, bound ~4 of them.
        let frac = outer as f64 / 20000.0;
        assert!(close(frac, (PI * 6.0 + 4.0) / (TAU * 6.0), 0.014), "{frac}");
        let g = sample_goursat(2000, 1);
        for (p, n) in g.positions.iter().zip(&g.normals) {
            assert!(goursat_value(*p).abs() < 1e-9 && close(norm(*n), 1.0, 1e-12));
            assert!(dot(*p, *p) / dot(normalize(*p).unwrap(), *n) < GOURSAT_DENSITY_BOUND);
        }
        let h = sample_height_field(&Saddle, 1.0, 11, 0.0, 0);
        assert_eq!(h.len(), 121);
        assert_eq!(h.positions[0], [-1.0, -1.0, 0.0]);
        let c = sample_cylinder(100, 1.0, 4.0, 3);
        assert!(c
            .positions
            .iter()
            .all(|p| close(p[0].hypot(p[1]), 1.0, 1e-12) && p[2].abs() <= 2.0));
    }

    #[test]
    fn noise_changes_positions_and_keeps_unit_normals() {
        let mut s = sample_sphere(2000, 1.0, 4);
        let clean = s.clone();
        s.add_noise(0.1, 0.1, 9);
        let mut var = 0.0;
        for (a, b) in s.positions.iter().zip(&clean.positions) {
            let d = sub(*a, *b);
            var += dot(d, d);
        }
        // Expected 3 sigma^2 = 0.03 per point; 6000 squared deviates give ~2% relative error.
        assert!(close(var / 2000.0, 0.03, 0.003), "{}", var / 2000.0);
        assert!(s.normals.iter().all(|n| close(norm(*n), 1.0, 1e-12)));
    }

    /// The grid k-NN equals a plain brute force, including tie order and duplicates.
    #[test]
    fn knn_matches_brute_force() {
        let mut pts = sample_torus(800, 6.0, 2.0, 2).positions;
        pts.extend(sample_height_field(&Saddle, 1.0, 8, 0.0, 0).positions);
        pts.push(pts[3]);
        pts.push(pts[3]);
        for k in [1, 7, 30] {
            let knn = knn_brute(&pts, k);
            for (i, row) in knn.iter().enumerate() {
                let mut all: Vec<(f64, usize)> = (0..pts.len())
                    .filter(|&j| j != i)
                    .map(|j| (dot(sub(pts[j], pts[i]), sub(pts[j], pts[i])), j))
                    .collect();
                all.sort_by(|a, b| a.partial_cmp(b).unwrap());
                let want: Vec<usize> = std::iter::once(i)
                    .chain(all.iter().take(k - 1).map(|x| x.1))
                    .collect();
                assert_eq!(row, &want, "point {i} k {k}");
            }
        }
        assert_eq!(knn_brute(&pts[..2], 5)[1], vec![1, 0]);
        assert!(knn_brute(&[], 5).is_empty());
    }

    /// Every registered name builds an estimator reporting that name, and the estimators run
    /// on a small sphere cap.
    #[test]
    fn all_names_build() {
        let params = crate::estimate::EstimatorParams::default();
        let (pos, nrm) = testkit::sphere_cap(1.0, 30);
        for name in crate::estimate::NAMES {
            let est = crate::estimate::build(name, &params)
                .unwrap_or_else(|| panic!("{name} does not build"));
            assert_eq!(est.name(), *name);
            let c = testkit::run(&*est, &pos, &nrm);
            testkit::assert_valid(&c, name);
            // VCM magnitudes are strongly biased on random samples (see estimate/vcm.rs).
            let tol = if *name == "vcm" { 1.0 } else { 0.1 };
            assert!((c.h - 1.0).abs() < tol, "{name}: {c:?}");
        }
        assert!(crate::estimate::build("no-such", &params).is_none());
    }

    #[test]
    fn rotation_is_orthonormal() {
        let m = rotation([1.0, 2.0, 3.0], 0.7);
        for a in 0..3 {
            for b in 0..3 {
                let d = (0..3).map(|k| m[k][a] * m[k][b]).sum::<f64>();
                assert!(close(d, if a == b { 1.0 } else { 0.0 }, 1e-14));
            }
        }
        let z = rotation([0.0, 0.0, 1.0], PI / 2.0);
        let v = [
            dot(z[0], [1.0, 0.0, 0.0]),
            dot(z[1], [1.0, 0.0, 0.0]),
            dot(z[2], [1.0, 0.0, 0.0]),
        ];
        assert!(close(v[1], 1.0, 1e-15) && close(v[0], 0.0, 1e-15));
    }
}

/// Shared test scenarios for the estimators (algorithms.md 5.2, 6, 7, 8): cached clouds with
/// neighbour lists and truth, degenerate inputs, sign flips and rigid motions.
#[cfg(test)]
pub(crate) mod testkit {
    use super::*;
    use crate::estimate::flags;
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};

    /// The test seed: `TILECURV_TEST_SEED` or 1. Printed by failing assertions.
    pub(crate) fn seed() -> u64 {
        std::env::var("TILECURV_TEST_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(1)
    }

    /// Test surfaces.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    pub(crate) enum Shape {
        /// Sphere r = 1, N = 5000 uniform.
        Sphere,
        /// Cylinder r = 1, length 6, N = 10000; truth only for |z| < 2 (away from the rims).
        Cylinder,
        /// Saddle (x^2 - y^2)/2, jittered 101 x 101 grid on [-1, 1]^2; truth for |x|, |y| < 0.75.
        Saddle,
        /// Paraboloid a = 1/2, same grid and window as the saddle.
        Paraboloid,
        /// Torus (6, 2), N = 20000 uniform in area (section 7).
        Torus,
        /// Goursat, N = 20000 uniform in area.
        Goursat,
        /// The reference torus_025000.pts (section 8).
        TorusRef,
        /// The reference goursat_025000.pts (section 8).
        GoursatRef,
    }

    /// A cloud with its K-NN lists and per-point truth (None where not evaluated).
    pub(crate) struct Case {
        pub cloud: Cloud,
        pub knn: Vec<Vec<usize>>,
        pub truth: Vec<Option<TrueCurvature>>,
    }

    fn build(shape: Shape, k: usize) -> Option<Case> {
        let s = seed();
        let window = |p: V3| p[0].abs() < 0.75 && p[1].abs() < 0.75;
        let (cloud, truth): (Cloud, Box<dyn Fn(V3) -> Option<TrueCurvature>>) = match shape {
            Shape::Sphere => (
                sample_sphere(5000, 1.0, s),
                Box::new(|_| Some(sphere_curvature(1.0))),
            ),
            Shape::Cylinder => (
                sample_cylinder(10000, 1.0, 6.0, s),
                Box::new(|p: V3| (p[2].abs() < 2.0).then(|| cylinder_curvature(1.0, p))),
            ),
            Shape::Saddle => (
                sample_height_field(&Saddle, 1.0, 101, 1.0, s),
                Box::new(move |p: V3| window(p).then(|| Saddle.jet(p[0], p[1]).curvature())),
            ),
            Shape::Paraboloid => {
                let f = Paraboloid { a: 0.5 };
                (
                    sample_height_field(&f, 1.0, 101, 1.0, s),
                    Box::new(move |p: V3| window(p).then(|| f.jet(p[0], p[1]).curvature())),
                )
            }
            Shape::Torus => (
                sample_torus(20000, 6.0, 2.0, s),
                Box::new(|p| Some(torus_curvature_at(6.0, 2.0, p))),
            ),
            Shape::Goursat => (sample_goursat(20000, s), Box::new(goursat_curvature)),
            Shape::TorusRef => (
                reference_cloud("torus/torus_025000.pts")?,
                Box::new(|p| Some(torus_curvature_at(6.0, 2.0, p))),
            ),
            Shape::GoursatRef => (
                reference_cloud("goursat/goursat_025000.pts")?,
                Box::new(goursat_curvature),
            ),
        };
        let knn = knn_brute(&cloud.positions, k);
        let truth = cloud.positions.iter().map(|&p| truth(p)).collect();
        Some(Case { cloud, knn, truth })
    }

    /// Built cases by (shape, K); None records a skipped reference file.
    type Cache = Mutex<HashMap<(Shape, usize), Option<&'static Case>>>;

    /// The cached case of `shape` with `k` neighbours (None: reference file skipped).
    pub(crate) fn case(shape: Shape, k: usize) -> Option<&'static Case> {
        static CACHE: OnceLock<Cache> = OnceLock::new();
        let cache = CACHE.get_or_init(Default::default);
        let mut map = cache.lock().unwrap_or_else(|e| e.into_inner());
        *map.entry((shape, k))
            .or_insert_with(|| build(shape, k).map(|c| &*Box::leak(Box::new(c))))
    }

    /// Errors of `est` on every `stride`-th point of `shape` with `k` neighbours (directions
    /// where k2 - k1 >= 0.1); prints them (visible with --nocapture). None when a reference
    /// file is skipped.
    pub(crate) fn errors(
        est: &dyn Estimator,
        shape: Shape,
        k: usize,
        stride: usize,
    ) -> Option<ErrorStats> {
        let c = case(shape, k)?;
        let e = evaluate(
            est,
            &c.cloud,
            &c.knn,
            |i| c.truth[i].filter(|_| i % stride == 0),
            0.1,
        );
        eprintln!("{:>16} {:?} K={k} seed={}: {e}", est.name(), shape, seed());
        Some(e)
    }

    /// Asserts `value < bound`, printing `what` and the seed.
    pub(crate) fn below(value: f64, bound: f64, what: &str) {
        assert!(
            value < bound,
            "{what}: {value:.6} >= bound {bound:.6} (seed {})",
            seed()
        );
    }

    /// NaN exactly when an UNDEFINED flag is set, and k1 <= k2 otherwise.
    pub(crate) fn assert_valid(c: &Curvature, what: &str) {
        let nan = c.h.is_nan() || c.k.is_nan() || c.k1.is_nan() || c.k2.is_nan();
        let undefined = c.flags & flags::UNDEFINED != 0;
        assert_eq!(
            nan, undefined,
            "{what}: NaN without UNDEFINED flag or the reverse: {c:?}"
        );
        assert!(nan || c.k1 <= c.k2, "{what}: k1 > k2: {c:?}");
        assert!(
            c.d1.iter().chain(&c.d2).all(|x| x.is_finite()),
            "{what}: non-finite direction {c:?}"
        );
    }

    /// Runs `est` on one neighbourhood given as slices.
    pub(crate) fn run(est: &dyn Estimator, pos: &[V3], nrm: &[V3]) -> Curvature {
        let ids: Vec<u64> = (0..pos.len() as u64).collect();
        est.estimate(&Neighbourhood {
            positions: pos,
            normals: nrm,
            ids: &ids,
        })
    }

    /// Degenerate inputs (algorithms.md 5.3) give flags, never a panic, never NaN without a flag.
    /// Returns the results in order: empty, one point, two points, duplicates, collinear,
    /// plane, opposing normals, zero query normal, a NaN neighbour.
    /// `with_empty = false` leaves out the empty neighbourhood (which the engine never passes).
    pub(crate) fn degenerate_inputs(est: &dyn Estimator, with_empty: bool) -> Vec<Curvature> {
        let up = [0.0, 0.0, 1.0];
        let grid: Vec<V3> = (0..49)
            .map(|i| [(i % 7) as f64 * 0.1 - 0.3, (i / 7) as f64 * 0.1 - 0.3, 0.0])
            .collect();
        let mut grid_q = grid.clone();
        grid_q.swap(0, 24); // the query (origin) first
        let line: Vec<V3> = (0..20).map(|i| [i as f64 * 0.1, 0.0, 0.0]).collect();
        let alternating: Vec<V3> = (0..49)
            .map(|i| if i % 2 == 0 { up } else { [0.0, 0.0, -1.0] })
            .collect();
        let mut with_nan = grid_q.clone();
        with_nan[5] = [f64::NAN, 0.0, 0.0];
        let cases: Vec<(&str, Vec<V3>, Vec<V3>)> = vec![
            ("empty", vec![], vec![]),
            ("one point", vec![[0.0; 3]], vec![up]),
            ("two points", vec![[0.0; 3], [0.1, 0.0, 0.0]], vec![up; 2]),
            ("duplicates", vec![[0.0; 3]; 30], vec![up; 30]),
            ("collinear", line, vec![up; 20]),
            ("plane", grid_q.clone(), vec![up; 49]),
            ("opposing normals", grid_q.clone(), alternating),
            (
                "zero query normal",
                grid_q.clone(),
                std::iter::once([0.0; 3]).chain(vec![up; 48]).collect(),
            ),
            ("nan neighbour", with_nan, vec![up; 49]),
        ];
        let mut out = Vec::new();
        for (what, pos, nrm) in cases {
            if pos.is_empty() && !with_empty {
                out.push(Curvature::undefined(flags::FEW_NEIGHBOURS));
                continue;
            }
            let c = run(est, &pos, &nrm);
            assert_valid(&c, &format!("{} {what}", est.name()));
            out.push(c);
        }
        let [empty, one, two, dup, line, plane, ..] = out[..] else {
            unreachable!()
        };
        for (what, c) in [
            ("empty", empty),
            ("one", one),
            ("two", two),
            ("duplicates", dup),
            ("collinear", line),
        ] {
            assert!(
                c.flags & flags::UNDEFINED != 0,
                "{} {what}: {c:?}",
                est.name()
            );
        }
        assert!(
            plane.flags & flags::UNDEFINED != 0 || (plane.h.abs() < 1e-9 && plane.k.abs() < 1e-9),
            "{} plane: {plane:?}",
            est.name()
        );
        out
    }

    fn check_close(a: f64, b: f64, tol: f64, what: &str) {
        assert!(
            (a - b).abs() <= tol * (1.0 + b.abs()),
            "{what}: {a} vs {b} (tol {tol}, seed {})",
            seed()
        );
    }

    /// Flipping every normal negates H, k1 <-> -k2 and keeps K (section 0.1), to `tol`
    /// (relative to 1 + |value|), on the first `n` points of the sampled torus (K = 50).
    pub(crate) fn flip_symmetry(est: &dyn Estimator, n: usize, tol: f64) {
        let c = case(Shape::Torus, 50).expect("synthetic case");
        let flipped = Cloud {
            positions: c.cloud.positions.clone(),
            normals: c.cloud.normals.iter().map(|&v| scale(v, -1.0)).collect(),
        };
        for nbrs in c.knn.iter().take(n) {
            let a = estimate_point(est, &c.cloud, nbrs);
            let b = estimate_point(est, &flipped, nbrs);
            let what = format!("{} flip at {}", est.name(), nbrs[0]);
            check_close(-b.h, a.h, tol, &what);
            check_close(b.k, a.k, tol, &what);
            check_close(-b.k2, a.k1, tol, &what);
            check_close(-b.k1, a.k2, tol, &what);
        }
    }

    /// The same points after translation by (1e6, -2e6, 3e6) (UTM-like coordinates) and, if
    /// `rotate`, a rotation about a skew axis first: H, K, k1, k2 must agree to `tol` (relative
    /// to 1 + |value|) on the first `n` points of the sampled torus (K = 50), and the k1
    /// directions must be the rotated ones (to `tol` in sin(angle)) where k2 - k1 > 0.1.
    pub(crate) fn motion_invariance(est: &dyn Estimator, n: usize, rotate: bool, tol: f64) {
        let c = case(Shape::Torus, 50).expect("synthetic case");
        let rot = if rotate {
            rotation([1.0, 2.0, 3.0], 0.7)
        } else {
            rotation([0.0, 0.0, 1.0], 0.0)
        };
        let moved = transform(&c.cloud, &rot, [1e6, -2e6, 3e6]);
        for nbrs in c.knn.iter().take(n) {
            let a = estimate_point(est, &c.cloud, nbrs);
            let b = estimate_point(est, &moved, nbrs);
            let what = format!("{} motion (rotate {rotate}) at {}", est.name(), nbrs[0]);
            for (x, y) in [(b.h, a.h), (b.k, a.k), (b.k1, a.k1), (b.k2, a.k2)] {
                check_close(x, y, tol, &what);
            }
            if a.k2 - a.k1 > 0.1 && a.d1 != [0.0; 3] {
                let ra = [dot(rot[0], a.d1), dot(rot[1], a.d1), dot(rot[2], a.d1)];
                let sin = norm(crate::geometry::cross(ra, b.d1));
                assert!(sin <= tol.max(1e-9), "{what}: direction off by sin {sin}");
            }
        }
    }

    /// A spherical cap: the query at `c + r q` first, then `k - 1` points uniform on the sphere
    /// within 0.15 r of it, with exact outward normals (for the exact identities of 5.2).
    pub(crate) fn sphere_cap(r: f64, k: usize) -> (Vec<V3>, Vec<V3>) {
        let q = normalize([0.3, -0.5, 0.8]).unwrap_or([0.0, 0.0, 1.0]);
        let mut rng = Rng::new(seed());
        let (mut pos, mut nrm) = (vec![[0.0; 3]], vec![q]);
        while pos.len() < k {
            let d = unit_vector(&mut rng);
            if norm(sub(d, q)) < 0.15 {
                pos.push(sub(scale(d, r), scale(q, r)));
                nrm.push(d);
            }
        }
        (pos, nrm)
    }
}
