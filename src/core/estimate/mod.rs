//! Curvature estimators: one trait, one file per family. Every estimator is a pure function of a
//! [`Neighbourhood`] (positions relative to the query point, oriented unit normals, original
//! ids): no I/O, no globals, no dependence on the tile or the thread. Sign convention and units
//! as in algorithms.md section 0.1: k1 <= k2, positive where the surface bends away from its
//! normal (a sphere with outward normals has H = 1/r), in 1/(coordinate unit).

pub mod apss;
pub mod aso;
pub mod cnc;
pub mod cnc_delaunay;
pub mod jet;
pub mod local;
pub mod vcm;
pub mod wme;

use crate::core::geometry::V3;

/// Quality flag bits of a point's result (the `CurvatureFlags` column).
pub mod flags {
    /// Fewer than 3 distinct neighbours: nothing could be estimated.
    pub const FEW_NEIGHBOURS: u8 = 1;
    /// The PCA normal is undefined (collinear or coincident neighbours).
    pub const DEGENERATE_NORMAL: u8 = 2;
    /// The estimator's fit is undefined (e.g. CNC area A0 <= 0): no curvature.
    pub const DEGENERATE: u8 = 4;
    /// One-sided neighbourhood (an empty hexagon sector): the value is biased (scan border,
    /// occlusion hole).
    pub const BOUNDARY: u8 = 8;
    /// |k2 - k1| is tiny relative to |H|: principal directions are arbitrary (umbilic).
    pub const UMBILIC: u8 = 16;
    /// The normal came from the file, not from PCA.
    pub const FILE_NORMAL: u8 = 32;
    /// Flags under which H, K, k1, k2 are NaN.
    pub const UNDEFINED: u8 = FEW_NEIGHBOURS | DEGENERATE_NORMAL | DEGENERATE;
}

/// What an estimator sees for one query point. Index 0 is the query point itself.
#[derive(Debug, Clone, Copy)]
pub struct Neighbourhood<'a> {
    /// Positions relative to the query point (so `positions[0] == [0, 0, 0]`), in f64.
    pub positions: &'a [V3],
    /// Oriented unit normals, in the same order (`normals[0]` is the query normal).
    pub normals: &'a [V3],
    /// Original point ids, in the same order (for per-point random seeds).
    pub ids: &'a [u64],
}

/// An estimator's result for one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curvature {
    /// Mean curvature H.
    pub h: f64,
    /// Gaussian curvature K.
    pub k: f64,
    /// Smaller principal curvature.
    pub k1: f64,
    /// Larger principal curvature.
    pub k2: f64,
    /// Unit principal direction of k1 (zero when undefined).
    pub d1: V3,
    /// Unit principal direction of k2 (zero when undefined).
    pub d2: V3,
    /// Quality flags ([`flags`]).
    pub flags: u8,
    /// Values beyond the curvature that only some estimators compute (None for the others).
    pub extra: Option<Extra>,
}

/// Per-point values an estimator may compute besides the curvature: today the VCM's own
/// normal and its sharp-feature score (algorithms.md sections 2.4 and 2.5), written by
/// `--features`. Plain numbers, no I/O; NaN components mean "computed but undefined".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extra {
    /// Sharp-feature score lambda2 / (lambda1 + lambda2 + lambda3) of the convolved VCM
    /// (eigenvalues in decreasing order): 0 on a plane, about alpha^2 / 12 on an edge of
    /// external angle alpha; in [0, 1/2].
    pub feature: f64,
    /// Unit normal estimated by the estimator itself (the VCM's leading eigenvector), oriented
    /// to agree with the query point's input normal.
    pub normal: V3,
}

impl Curvature {
    /// A result from its principal curvatures and directions, with H = (k1 + k2)/2 and
    /// K = k1 k2 (section 0.1), for estimators that produce no separate H and K.
    pub fn from_principal(k1: f64, k2: f64, d1: V3, d2: V3, flags: u8) -> Self {
        Curvature {
            h: 0.5 * (k1 + k2),
            k: k1 * k2,
            k1,
            k2,
            d1,
            d2,
            flags,
            extra: None,
        }
    }

    /// An undefined result carrying `flags`: NaN values, zero directions.
    pub fn undefined(flags: u8) -> Self {
        Curvature {
            h: f64::NAN,
            k: f64::NAN,
            k1: f64::NAN,
            k2: f64::NAN,
            d1: [0.0; 3],
            d2: [0.0; 3],
            flags,
            extra: None,
        }
    }
}

/// A curvature estimator.
pub trait Estimator: Sync + Send {
    /// The estimator's command-line name, e.g. `cnc-avg-hexagram`.
    fn name(&self) -> &'static str;
    /// Estimates the curvature at `nb.positions[0]`.
    fn estimate(&self, nb: &Neighbourhood<'_>) -> Curvature;
}

/// The principal curvatures and directions of a 2x2 symmetric tangent-plane operator `s` in the
/// basis (e1, e2): eigenvalues ascending with their 3D directions, plus the UMBILIC flag when
/// they are indistinguishable.
pub fn principal_from_tangent(s: [[f64; 2]; 2], e1: V3, e2: V3) -> (f64, f64, V3, V3, u8) {
    let (l, w) = crate::core::geometry::sym2_eigen(s[0][0], 0.5 * (s[0][1] + s[1][0]), s[1][1]);
    let dir = |w: [f64; 2]| {
        crate::core::geometry::add(
            crate::core::geometry::scale(e1, w[0]),
            crate::core::geometry::scale(e2, w[1]),
        )
    };
    let spread = (l[1] - l[0]).abs();
    let level = l[0].abs().max(l[1].abs());
    let umbilic = if spread <= 1e-6 * level || level == 0.0 {
        flags::UMBILIC
    } else {
        0
    };
    (l[0], l[1], dir(w[0]), dir(w[1]), umbilic)
}

/// Parameters shared by the estimator family constructors (each uses what it needs).
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorParams {
    /// Seed for randomised estimators; each point's stream is derived from (seed, original id).
    pub seed: u64,
    /// Number of random triangles L for CNC-Uniform.
    pub triangles: usize,
    /// Polynomial degree of the osculating jet (2 to 4).
    pub jet_degree: usize,
}

impl Default for EstimatorParams {
    fn default() -> Self {
        EstimatorParams {
            seed: 0,
            triangles: 100,
            jet_degree: 2,
        }
    }
}

/// Command-line names of the available estimators, default first.
pub const NAMES: &[&str] = &[
    "cnc-avg-hexagram",
    "cnc-hexagram",
    "cnc-uniform",
    "cnc-delaunay",
    "apss",
    "aso",
    "wme",
    "jet",
    "vcm",
];

/// Builds the estimator called `name`, or None if there is no such estimator.
pub fn build(name: &str, params: &EstimatorParams) -> Option<Box<dyn Estimator>> {
    match name {
        "cnc-avg-hexagram" => Some(Box::new(cnc::CncAvgHexagram)),
        "cnc-hexagram" => Some(Box::new(cnc::CncHexagram)),
        "cnc-uniform" => Some(Box::new(cnc::CncUniform {
            triangles: params.triangles,
            seed: params.seed,
        })),
        "cnc-delaunay" => Some(Box::new(cnc_delaunay::CncDelaunay)),
        "apss" => Some(Box::new(apss::Apss)),
        "aso" => Some(Box::new(aso::Aso)),
        "wme" => Some(Box::new(wme::Wme)),
        "vcm" => Some(Box::new(vcm::Vcm)),
        "jet" => Some(Box::new(jet::Jet {
            degree: params.jet_degree,
        })),
        _ => None,
    }
}
