//! Synthetic surfaces with closed-form curvature (algorithms.md 13), seeded samplers that
//! return positions with exact unit normals, an exact k-NN and an error summary: the oracle the
//! estimators and the engine are tested against. Test kit only: never part of the shipped
//! library. Everything uses the tool's convention (algorithms.md 1.1): k1 <= k2, H = (k1 + k2)/2,
//! K = k1 k2, a sphere with outward normals has H = +1/r. Random streams come from
//! `tilecurv::core::rng::Rng`, so clouds are identical across releases for a given seed. The torus
//! and goursat formulas and samplers are the library's (`core::surface`, `core::sampling`, which
//! `generate torus` and `generate goursat` use too), re-exported here; the clouds they fill and
//! the implicit torus and goursat value that only the checks use are the kit's.

use std::f64::consts::{PI, TAU};
use tilecurv::core::estimate::{Curvature, Estimator, Neighbourhood, Scratch};
use tilecurv::core::geometry::{
    dot, normalize, scale, sub, FieldDerivatives, SurfacePoint, M3, V3,
};
use tilecurv::core::rng::Rng;
pub use tilecurv::core::sampling::{
    goursat_radial, unit_vector, GoursatSampler, Noise, TorusSampler, GOURSAT_DENSITY_BOUND,
};
pub use tilecurv::core::surface::{
    goursat_curvature, goursat_implicit, height_field_curvature, implicit_curvature,
    plane_curvature, torus_curvature, torus_curvature_at, torus_point, HeightField, HeightJet,
    TrueCurvature,
};

/// Sampled oriented points: positions and exact (or noisy) unit normals, same order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    /// Positions.
    pub positions: Vec<V3>,
    /// Unit normals.
    pub normals: Vec<V3>,
}

impl Cloud {
    /// An empty cloud with room for `n` points.
    pub fn with_capacity(n: usize) -> Self {
        Cloud {
            positions: Vec::with_capacity(n),
            normals: Vec::with_capacity(n),
        }
    }

    /// Appends the point `p` with unit normal `n`.
    pub fn push(&mut self, p: V3, n: V3) {
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
    /// (algorithms.md 13.6, as in the CNC paper). A normal that the noise cancels exactly is left unchanged.
    pub fn add_noise(&mut self, sigma_position: f64, sigma_normal: f64, seed: u64) {
        let mut noise = Noise::new(sigma_position, sigma_normal, seed);
        for (p, n) in self.positions.iter_mut().zip(self.normals.iter_mut()) {
            let s = noise.apply(SurfacePoint {
                position: *p,
                normal: *n,
            });
            (*p, *n) = (s.position, s.normal);
        }
    }
}

/// The first `n` points of [`TorusSampler`]`::new(big_r, r, seed)`.
pub fn sample_torus(n: usize, big_r: f64, r: f64, seed: u64) -> Cloud {
    collect(n, TorusSampler::new(big_r, r, seed))
}

/// The first `n` points of a sampler as a cloud.
fn collect(n: usize, sampler: impl Iterator<Item = SurfacePoint>) -> Cloud {
    let mut cloud = Cloud::with_capacity(n);
    for s in sampler.take(n) {
        cloud.push(s.position, s.normal);
    }
    cloud
}

/// The first `n` points of [`GoursatSampler`]`::new(seed)`.
pub fn sample_goursat(n: usize, seed: u64) -> Cloud {
    collect(n, GoursatSampler::new(seed))
}

/// Gradient and Hessian of the implicit torus of algorithms.md 13.4,
/// F = (|x|^2 + R^2 - r^2)^2 - 4 R^2 (x^2 + y^2), negative inside.
pub fn torus_implicit(big_r: f64, r: f64, p: V3) -> FieldDerivatives {
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
    FieldDerivatives {
        gradient: g,
        hessian: hs,
    }
}

/// The goursat function of algorithms.md 13.5, F = 0.03 (x^4 + y^4 + z^4) - 2 |x|^2 - 8 (negative
/// inside).
pub fn goursat_value(p: V3) -> f64 {
    let q: f64 = p.iter().map(|x| x.powi(4)).sum();
    0.03 * q - 2.0 * dot(p, p) - 8.0
}

/// Sphere of radius `r` with outward normals (algorithms.md 13.1): k1 = k2 = 1/r, an umbilic.
pub fn sphere_curvature(r: f64) -> TrueCurvature {
    TrueCurvature::umbilic(1.0 / r)
}

/// Cylinder of radius `r` around the z axis with outward normals, at the surface point `p`
/// (algorithms.md 13.1): k1 = 0 along the axis, k2 = 1/r around it.
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

/// The saddle z = (x^2 - y^2)/2 (algorithms.md 13.1: k = (-1, +1) at the origin, upward normal).
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

/// The paraboloid z = a (x^2 + y^2) (algorithms.md 13.1: k1 = k2 = -2a at the origin, upward
/// normal).
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

/// Reads a text cloud of `x y z nx ny nz` lines (the reference `.pts` files of algorithms.md 14.1),
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
/// the cloud, the point itself first), positions relative to the point (random key 0).
/// Allocates: for tests and tools, not for the pipeline.
pub fn estimate_point(
    estimator: &(impl Estimator + ?Sized),
    cloud: &Cloud,
    nbrs: &[usize],
) -> Curvature {
    let Some(&i) = nbrs.first() else {
        return Curvature::undefined(tilecurv::core::estimate::flags::FEW_NEIGHBOURS);
    };
    let q = cloud.positions[i];
    let positions: Vec<V3> = nbrs.iter().map(|&j| sub(cloud.positions[j], q)).collect();
    let normals: Vec<V3> = nbrs.iter().map(|&j| cloud.normals[j]).collect();
    estimator.estimate(
        &Neighbourhood {
            positions: &positions,
            normals: &normals,
            key: 0,
        },
        &mut Scratch::default(),
    )
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
            .map(|&p| tilecurv::core::geometry::add(apply(rot, p), shift))
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
