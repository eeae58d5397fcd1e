//! Curvature estimators: one trait, one file per family. Every estimator is a pure function of a
//! [`Neighbourhood`] (positions relative to the query point, oriented unit normals, a key of
//! the query's position for random streams): no I/O, no globals, no dependence on the tile,
//! the thread or the order of the records. Sign convention and units as in
//! algorithms.md 1.1, 1.2: k1 <= k2, positive where the surface bends away from its normal (a
//! sphere with outward normals has H = 1/r), in 1/(coordinate unit).

pub mod apss;
pub mod aso;
pub mod cnc;
pub mod cnc_delaunay;
pub mod hexagon;
pub mod jet;
pub mod local;
pub mod vcm;
pub mod wme;

use crate::core::geometry::{Principal, V3};

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
    /// The radius of curvature is below half the neighbourhood's radius (max(|k1|, |k2|, |H|,
    /// sqrt|K|) times the distance r to the farthest neighbour exceeds 2): no sphere of that
    /// radius can hold points r away, so the value says more about noise or the sampling than
    /// about the surface (e.g. |H| > 100 /m from a 0.17 m neighbourhood). The value is kept.
    pub const SHARPER_THAN_NEIGHBOURHOOD: u8 = 64;
    /// Not computed: the point's class is not selected (`--classes`, `--skip-classes`,
    /// `--skip-withheld`); every value is NaN.
    pub const NOT_COMPUTED: u8 = 128;
    /// Flags under which H, K, k1, k2 are NaN.
    pub const UNDEFINED: u8 = FEW_NEIGHBOURS | DEGENERATE_NORMAL | DEGENERATE | NOT_COMPUTED;
}

/// What an estimator sees for one query point. Index 0 is the query point itself.
#[derive(Debug, Clone, Copy)]
pub struct Neighbourhood<'a> {
    /// Positions relative to the query point (so `positions[0] == [0, 0, 0]`), in f64.
    pub positions: &'a [V3],
    /// Oriented unit normals, in the same order (`normals[0]` is the query normal).
    pub normals: &'a [V3],
    /// The key of the query point's random stream ([`crate::core::rng::Rng::for_point`]): the
    /// engine passes [`crate::core::rng::position_key`] of its absolute coordinates, so that
    /// the stream depends on where the point is, not on its id or the order of the records.
    pub key: u64,
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
}

/// A value an estimator computes besides the curvature, written as a column by `--features`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtraColumn {
    /// The column name.
    pub name: &'static str,
    /// Its description (at most 32 bytes: a LAS extra-bytes description).
    pub description: &'static str,
    /// Whether the value is a component of a vector oriented by the input normal, so that it
    /// changes sign when the normal is flipped (`--orient propagate`).
    pub flips: bool,
    /// A bound on |value| (1 for a unit vector's component): a scaled-integer output stores
    /// the value as an i16 at bound / 32767.
    pub bound: f64,
}

/// Most extra values an estimator may declare ([`Estimator::extra_columns`]).
pub const MAX_EXTRA: usize = 4;

/// -x, but NaN (an undefined value) stays the very NaN it was, bit for bit (so that a flipped
/// result encodes to the same bytes as flipping the encoded one).
pub fn neg(x: f64) -> f64 {
    if x.is_nan() {
        x
    } else {
        -x
    }
}

impl Curvature {
    /// A result from its principal curvatures and directions `p`, with H = (k1 + k2)/2 and
    /// K = k1 k2 (algorithms.md 1.4), flagged UMBILIC when `p` is, for estimators that produce no
    /// separate H and K.
    pub fn from_principal(p: Principal) -> Self {
        Self::with_principal(0.5 * (p.k1 + p.k2), p.k1 * p.k2, p)
    }

    /// A result with its own H and K and the principal curvatures and directions `p`, flagged
    /// UMBILIC when `p` is.
    pub fn with_principal(h: f64, k: f64, p: Principal) -> Self {
        Curvature {
            h,
            k,
            k1: p.k1,
            k2: p.k2,
            d1: p.d1,
            d2: p.d2,
            flags: if p.umbilic { flags::UMBILIC } else { 0 },
        }
    }

    /// The result as it reads with the opposite normal: `H' = -H`, `K' = K`, `k1' = -k2`,
    /// `k2' = -k1` (k1 stays the smaller), `d1' = d2`, `d2' = d1` (so that `d1 x d2 = n` still
    /// holds). Flags are unchanged; NaN stays NaN. The one flip of `--orient propagate`.
    pub fn flipped(&self) -> Curvature {
        Curvature {
            h: neg(self.h),
            k: self.k,
            k1: neg(self.k2),
            k2: neg(self.k1),
            d1: self.d2,
            d2: self.d1,
            flags: self.flags,
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
        }
    }
}

/// Buffers an estimator reuses from one point to the next, owned by the caller (one per worker):
/// no estimator allocates per point once warm, and none keeps thread-local state.
#[derive(Default)]
pub struct Scratch {
    delaunay: cnc_delaunay::Buffers,
    vcm: vcm::Buffers,
}

/// A curvature estimator.
pub trait Estimator: Sync + Send {
    /// The estimator's command-line name, e.g. `cnc-avg-hexagram`.
    fn name(&self) -> &'static str;
    /// The values this estimator computes besides the curvature (written by `--features`), at
    /// most [`MAX_EXTRA`]; none for most estimators.
    fn extra_columns(&self) -> &'static [ExtraColumn] {
        &[]
    }
    /// Estimates the curvature at `nb.positions[0]`, with `scratch` for its buffers.
    fn estimate(&self, nb: &Neighbourhood<'_>, scratch: &mut Scratch) -> Curvature;
    /// [`Estimator::estimate`], also writing the extra values (one per [`extra_columns`], in
    /// that order) to `extra`; values it cannot compute are left as they are (NaN).
    ///
    /// [`extra_columns`]: Estimator::extra_columns
    fn estimate_extra(
        &self,
        nb: &Neighbourhood<'_>,
        scratch: &mut Scratch,
        extra: &mut [f64],
    ) -> Curvature {
        let _ = extra;
        self.estimate(nb, scratch)
    }
}

/// Parameters shared by the estimator family constructors (each uses what it needs).
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorParams {
    /// Seed for randomised estimators; each point's stream is derived from (seed, the point's
    /// [`Neighbourhood::key`], a hash of its position).
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

/// The estimators, by their command-line names (`--estimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorKind {
    /// CNC-Avg-Hexagram (default): L = 2 averaged hexagram triangles (algorithms.md 4.6).
    CncAvgHexagram,
    /// CNC-Hexagram: the hexagram's two triangles (algorithms.md 4.7).
    CncHexagram,
    /// CNC-Uniform: L random triangles per point, seeded per point (algorithms.md 4.8).
    CncUniform,
    /// CNC-Delaunay: local Delaunay umbrellas (algorithms.md 4.9).
    CncDelaunay,
    /// APSS: algebraic sphere fit (algorithms.md 6.3).
    Apss,
    /// ASO: the algebraic shape operator (algorithms.md 6.4).
    Aso,
    /// WME: least-squares Weingarten map (algorithms.md 7).
    Wme,
    /// Osculating jet fit, degree 2 (algorithms.md 8).
    Jet,
    /// VCM: Voronoi covariance measure, unsigned (algorithms.md 5).
    Vcm,
}

impl EstimatorKind {
    /// Every estimator, default first.
    pub const ALL: [EstimatorKind; 9] = [
        EstimatorKind::CncAvgHexagram,
        EstimatorKind::CncHexagram,
        EstimatorKind::CncUniform,
        EstimatorKind::CncDelaunay,
        EstimatorKind::Apss,
        EstimatorKind::Aso,
        EstimatorKind::Wme,
        EstimatorKind::Jet,
        EstimatorKind::Vcm,
    ];

    /// The command-line name, e.g. `cnc-avg-hexagram`.
    pub fn name(self) -> &'static str {
        match self {
            EstimatorKind::CncAvgHexagram => "cnc-avg-hexagram",
            EstimatorKind::CncHexagram => "cnc-hexagram",
            EstimatorKind::CncUniform => "cnc-uniform",
            EstimatorKind::CncDelaunay => "cnc-delaunay",
            EstimatorKind::Apss => "apss",
            EstimatorKind::Aso => "aso",
            EstimatorKind::Wme => "wme",
            EstimatorKind::Jet => "jet",
            EstimatorKind::Vcm => "vcm",
        }
    }

    /// One line for `--help`.
    pub fn summary(self) -> &'static str {
        match self {
            EstimatorKind::CncAvgHexagram => "corrected normal current, two averaged hexagram triangles: the most accurate CNC variant (default)",
            EstimatorKind::CncHexagram => "corrected normal current on the hexagram's two triangles",
            EstimatorKind::CncUniform => "corrected normal current on --triangles random triangles per point (seeded per point by --seed)",
            EstimatorKind::CncDelaunay => "corrected normal current on local Delaunay umbrellas",
            EstimatorKind::Apss => "algebraic point set surface: sphere fit, mean curvature only (k1 = k2 = H)",
            EstimatorKind::Aso => "algebraic shape operator: full curvature tensor of the APSS sphere field",
            EstimatorKind::Wme => "Weingarten map estimate by least squares on the normals",
            EstimatorKind::Jet => "osculating jet (a height-field polynomial of --jet-degree, 2 by default), the classical baseline",
            EstimatorKind::Vcm => "Voronoi covariance measure: unsigned curvature magnitudes; --features adds a sharp-edge score",
        }
    }

    /// The estimator called `name`, if there is one.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Builds the estimator with `params`.
    pub fn build(self, params: &EstimatorParams) -> Box<dyn Estimator> {
        match self {
            EstimatorKind::CncAvgHexagram => Box::new(cnc::CncAvgHexagram),
            EstimatorKind::CncHexagram => Box::new(cnc::CncHexagram),
            EstimatorKind::CncUniform => Box::new(cnc::CncUniform {
                triangles: params.triangles,
                seed: params.seed,
            }),
            EstimatorKind::CncDelaunay => Box::new(cnc_delaunay::CncDelaunay),
            EstimatorKind::Apss => Box::new(apss::Apss),
            EstimatorKind::Aso => Box::new(aso::Aso),
            EstimatorKind::Wme => Box::new(wme::Wme),
            EstimatorKind::Vcm => Box::new(vcm::Vcm),
            EstimatorKind::Jet => Box::new(jet::Jet {
                degree: params.jet_degree,
            }),
        }
    }
}

impl std::fmt::Display for EstimatorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::{cross, normalize, scale};

    #[test]
    fn flipping_curvature_twice_is_the_identity() {
        let n = [0.0, 0.0, 1.0];
        let c = Curvature {
            h: 1.5,
            k: 2.0,
            k1: 1.0,
            k2: 2.0,
            d1: [1.0, 0.0, 0.0],
            d2: [0.0, 1.0, 0.0],
            flags: 16,
        };
        let f = c.flipped();
        assert_eq!((f.h, f.k, f.k1, f.k2), (-1.5, 2.0, -2.0, -1.0));
        assert!(f.k1 <= f.k2);
        assert_eq!(normalize(cross(f.d1, f.d2)), Some(scale(n, -1.0)));
        assert_eq!(f.flipped(), c);
        // An undefined result keeps its very NaNs.
        let u = Curvature::undefined(4);
        assert_eq!(u.flipped().h.to_bits(), u.h.to_bits());
    }
}
