//! The estimator study (docs/study.md): the protocol of the CNC paper's section 6
//! (algorithms.md 14.1) run on every estimator of this crate, accuracy and single-thread time
//! per point.
//!
//! Protocol (full mode):
//! * shapes: goursat and torus (R = 6, r = 2), sampled i.i.d. uniform in area by
//!   [`sample_goursat`] / [`sample_torus`] (the paper uses Lloyd-relaxed clouds; its files only go
//!   to 75k points, so the samplers replace them here);
//! * N in {10k, 25k, 50k, 100k}; position noise sigma_p and normal noise sigma_n each in
//!   {0, 0.1, 0.2} ([`Cloud::add_noise`]: Gaussian per coordinate, normals renormalised): the full
//!   product, 72 clouds;
//! * the same K = 50 for every estimator (the query point included), and a "window" series with
//!   K = 100 and 200 at N = 50k for the estimators that use a large window well;
//! * every estimator of [`EstimatorKind::ALL`] with its default parameters, plus `jet-d4` (the degree 4 jet of
//!   the paper's JetFitting baseline; the tool's `jet` is degree 2);
//! * the truth is the closed form at the clean sample point (before the position noise);
//! * errors: RMS and max of H, K, k1, k2 ([`evaluate`], the crate's one error function), and
//!   the RMS angle of the k1 direction where k2 - k1 >= 0.1;
//! * time: k-NN first ([`knn_brute`], timed separately per point), then the neighbourhoods are
//!   gathered (positions relative to the query point, untimed) and only the `estimate` calls
//!   are timed, single thread. Times are the thread's CPU time (`CLOCK_THREAD_CPUTIME_ID`), so
//!   that other processes on a shared machine do not inflate them; the wall time is recorded
//!   too. The normals are given (exact or noisy), so no normal estimation is timed: end to end
//!   per point here is k-NN + curvature.
//! * a "lloyd" series runs the CNC authors' Lloyd-relaxed clouds (`../shared/data/reference`,
//!   N = 10k to 75k, read with [`read_pts`]) without noise and at sigma_p = sigma_n = 0.1, to
//!   relate the i.i.d. samples to the paper's blue-noise sampling (skipped when absent);
//! * slow estimators (`cnc-delaunay`, `vcm`) run on a fixed subset: every (N / subset)-th point
//!   of the i.i.d. sample, i.e. a uniform random subset (`--subset`, default 1000).
//!
//! Usage: `cargo bench --bench study -- [--quick] [--csv PATH] [--subset N] [--only a,b]`.
//! CSV rows go to PATH (default stdout), progress to stderr. `--quick` runs N = 10k, three
//! noise levels, the 25k Lloyd clouds and a 200-point subset for the slow estimators, in well
//! under two minutes.

#[path = "../tests/kit/mod.rs"]
mod kit;

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use kit::synthetic::{
    evaluate, goursat_curvature, knn_brute, read_pts, sample_goursat, sample_torus,
    torus_curvature_at, Cloud, ErrorStats, TrueCurvature,
};
use tilecurv::core::estimate::{
    Curvature, Estimator, EstimatorKind, EstimatorParams, Neighbourhood, Scratch,
};
use tilecurv::core::geometry::{sub, V3};

/// Torus radii of the paper (algorithms.md 13.4).
const TORUS_R: (f64, f64) = (6.0, 2.0);
/// Seed of the samplers (the same for every N: the clouds are independent samples anyway).
const SAMPLE_SEED: u64 = 2023;
/// Seed of the noise.
const NOISE_SEED: u64 = 7;
/// The common K of the study.
const K: usize = 50;
/// Estimators too slow to run on every point.
const SLOW: &[&str] = &["cnc-delaunay", "vcm"];
/// Estimators of the large-window series.
const WINDOW_ESTIMATORS: &[&str] = &["cnc-avg-hexagram", "aso", "apss", "wme", "jet", "jet-d4"];
/// Points gathered per timed batch.
const BATCH: usize = 256;

/// A test surface with closed-form curvature.
#[derive(Debug, Clone, Copy)]
enum Shape {
    Goursat,
    Torus,
}

impl Shape {
    fn name(self) -> &'static str {
        match self {
            Shape::Goursat => "goursat",
            Shape::Torus => "torus",
        }
    }

    /// The clean cloud of a case: sampled, or the reference Lloyd file (None if absent).
    fn cloud(self, n: usize, lloyd: bool) -> Option<Cloud> {
        if !lloyd {
            return Some(match self {
                Shape::Goursat => sample_goursat(n, SAMPLE_SEED),
                Shape::Torus => sample_torus(n, TORUS_R.0, TORUS_R.1, SAMPLE_SEED),
            });
        }
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/reference")
            .join(self.name())
            .join(format!("{}_{n:06}.pts", self.name()));
        match read_pts(&path) {
            Ok(c) => Some(c),
            Err(e) => {
                eprintln!("SKIPPED: {} unavailable ({e})", path.display());
                None
            }
        }
    }

    fn truth(self, p: V3) -> Option<TrueCurvature> {
        match self {
            Shape::Goursat => goursat_curvature(p),
            Shape::Torus => Some(torus_curvature_at(TORUS_R.0, TORUS_R.1, p)),
        }
    }
}

/// One estimator under study.
struct Entry {
    label: &'static str,
    est: Box<dyn Estimator>,
    slow: bool,
}

/// Every estimator of [`EstimatorKind::ALL`] with default parameters, then `jet-d4`.
fn entries(only: &Option<Vec<String>>) -> Vec<Entry> {
    let default = EstimatorParams::default();
    let d4 = EstimatorParams {
        jet_degree: 4,
        ..EstimatorParams::default()
    };
    let mut v: Vec<Entry> = EstimatorKind::ALL
        .into_iter()
        .map(|kind| (kind.name(), kind, &default))
        .chain(std::iter::once(("jet-d4", EstimatorKind::Jet, &d4)))
        .map(|(label, kind, params)| Entry {
            label,
            est: kind.build(params),
            slow: SLOW.contains(&kind.name()),
        })
        .collect();
    if let Some(only) = only {
        v.retain(|e| only.iter().any(|o| o == e.label));
    }
    v
}

/// One cloud of the study: which K values and estimators to run on it.
struct Case {
    series: &'static str,
    /// The reference Lloyd cloud instead of an i.i.d. sample.
    lloyd: bool,
    shape: Shape,
    n: usize,
    sigma_p: f64,
    sigma_n: f64,
    ks: Vec<usize>,
    /// None: every estimator.
    estimators: Option<&'static [&'static str]>,
}

/// The cases of a run.
fn plan(quick: bool) -> Vec<Case> {
    let (sizes, levels, window_n): (&[usize], &[f64], usize) = if quick {
        (&[10_000], &[0.0, 0.1, 0.2], 10_000)
    } else {
        (&[10_000, 25_000, 50_000, 100_000], &[0.0, 0.1, 0.2], 50_000)
    };
    let mut cases = Vec::new();
    for shape in [Shape::Goursat, Shape::Torus] {
        for &n in sizes {
            for &sigma_p in levels {
                for &sigma_n in levels {
                    // Quick mode: only the diagonal of the noise grid.
                    if quick && sigma_p != sigma_n {
                        continue;
                    }
                    cases.push(Case {
                        series: "grid",
                        lloyd: false,
                        shape,
                        n,
                        sigma_p,
                        sigma_n,
                        ks: vec![K],
                        estimators: None,
                    });
                }
            }
        }
        let window: &[(f64, f64)] = if quick {
            &[(0.2, 0.2)]
        } else {
            &[(0.1, 0.1), (0.2, 0.0), (0.0, 0.2), (0.2, 0.2)]
        };
        for &(sigma_p, sigma_n) in window {
            cases.push(Case {
                series: "window",
                lloyd: false,
                shape,
                n: window_n,
                sigma_p,
                sigma_n,
                ks: if quick { vec![200] } else { vec![100, 200] },
                estimators: Some(WINDOW_ESTIMATORS),
            });
        }
        let lloyd_sizes: &[usize] = if quick {
            &[25_000]
        } else {
            &[10_000, 25_000, 50_000, 75_000]
        };
        for &n in lloyd_sizes {
            for sigma in [0.0, 0.1] {
                cases.push(Case {
                    series: "lloyd",
                    lloyd: true,
                    shape,
                    n,
                    sigma_p: sigma,
                    sigma_n: sigma,
                    ks: vec![K],
                    estimators: None,
                });
            }
        }
    }
    cases
}

/// Wall-clock and thread CPU time together.
#[derive(Debug, Clone, Copy, Default)]
struct Times {
    wall: Duration,
    cpu: Duration,
}

/// A running measurement of [`Times`].
struct Stopwatch {
    wall: Instant,
    cpu: Duration,
}

/// The calling thread's CPU time.
fn thread_cpu() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime only writes the timespec it is given.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

impl Stopwatch {
    fn start() -> Self {
        Stopwatch {
            wall: Instant::now(),
            cpu: thread_cpu(),
        }
    }

    fn stop(&self) -> Times {
        Times {
            wall: self.wall.elapsed(),
            cpu: thread_cpu().saturating_sub(self.cpu),
        }
    }
}

impl std::ops::AddAssign for Times {
    fn add_assign(&mut self, o: Times) {
        self.wall += o.wall;
        self.cpu += o.cpu;
    }
}

/// Microseconds per item of a duration.
fn us_per(d: Duration, items: usize) -> f64 {
    d.as_secs_f64() * 1e6 / items.max(1) as f64
}

/// Replays stored results, so that [`evaluate`] scores exactly the values that were timed
/// (`run_timed` passes the point's index as the key).
struct Replay<'a> {
    results: &'a [Curvature],
}

impl Estimator for Replay<'_> {
    fn name(&self) -> &'static str {
        "replay"
    }

    fn estimate(&self, nb: &Neighbourhood<'_>, _: &mut Scratch) -> Curvature {
        self.results[nb.key as usize]
    }
}

/// Runs `est` at the points `selected` of `cloud` (neighbours `knn`), timing only the
/// `estimate` calls. Returns the results by point index (undefined where not selected) and
/// the total estimation times.
fn run_timed(
    est: &dyn Estimator,
    cloud: &Cloud,
    knn: &[Vec<usize>],
    selected: &[usize],
) -> (Vec<Curvature>, Times) {
    let mut results = vec![Curvature::undefined(0); cloud.len()];
    let (mut pos, mut nrm, mut ends) = (Vec::new(), Vec::new(), Vec::new());
    let mut total = Times::default();
    let mut scratch = Scratch::default();
    for batch in selected.chunks(BATCH) {
        pos.clear();
        nrm.clear();
        ends.clear();
        for &i in batch {
            let q = cloud.positions[i];
            for &j in &knn[i] {
                pos.push(sub(cloud.positions[j], q));
                nrm.push(cloud.normals[j]);
            }
            ends.push(pos.len());
        }
        let t = Stopwatch::start();
        let mut start = 0;
        for (&i, &end) in batch.iter().zip(&ends) {
            results[i] = est.estimate(
                &Neighbourhood {
                    positions: &pos[start..end],
                    normals: &nrm[start..end],
                    key: i as u64,
                },
                &mut scratch,
            );
            start = end;
        }
        total += t.stop();
    }
    (results, total)
}

/// Command-line options.
struct Options {
    quick: bool,
    csv: Option<PathBuf>,
    subset: Option<usize>,
    only: Option<Vec<String>>,
}

fn options() -> Options {
    let mut o = Options {
        quick: false,
        csv: None,
        subset: None,
        only: None,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => o.quick = true,
            "--csv" => o.csv = Some(args.next().expect("--csv PATH").into()),
            "--subset" => {
                let v = args.next().expect("--subset N");
                o.subset = Some(v.parse().expect("--subset takes a point count"));
            }
            "--only" => {
                let v = args.next().expect("--only NAME,NAME");
                o.only = Some(v.split(',').map(str::to_string).collect());
            }
            // cargo bench passes --bench to harness = false targets.
            "--bench" => {}
            other => panic!(
                "unknown argument {other:?}; usage: study [--quick] [--csv PATH] [--subset N] [--only a,b]"
            ),
        }
    }
    o
}

/// CSV columns. Errors are absolute (1/unit, 1/unit^2 for K); `evaluated` counts the scored
/// points including `undefined` ones (NaN results, excluded from the errors); `us_per_point` is
/// thread CPU time of the curvature step, `wall_us_per_point` its wall time; the `knn_` columns
/// are the same for the k-NN of the whole cloud.
const HEADER: &str = "series,shape,n,sigma_p,sigma_n,k,estimator,evaluated,undefined,\
h_rms,h_max,k_rms,k_max,k1_rms,k1_max,k2_rms,k2_max,d1_rms_deg,us_per_point,wall_us_per_point,\
knn_us_per_point,knn_wall_us_per_point";

fn main() {
    let o = options();
    let subset = o.subset.unwrap_or(if o.quick { 200 } else { 1000 });
    let entries = entries(&o.only);
    let mut out: Box<dyn Write> = match &o.csv {
        Some(p) => {
            if let Some(dir) = p.parent() {
                std::fs::create_dir_all(dir).expect("create the CSV directory");
            }
            Box::new(std::fs::File::create(p).expect("create the CSV file"))
        }
        None => Box::new(std::io::stdout()),
    };
    writeln!(out, "{HEADER}").expect("write CSV");
    let started = Instant::now();
    let cases = plan(o.quick);
    for (ci, case) in cases.iter().enumerate() {
        let Some(clean) = case.shape.cloud(case.n, case.lloyd) else {
            continue;
        };
        let truth: Vec<Option<TrueCurvature>> = clean
            .positions
            .iter()
            .map(|&p| case.shape.truth(p))
            .collect();
        let mut cloud = clean;
        if case.sigma_p > 0.0 || case.sigma_n > 0.0 {
            cloud.add_noise(case.sigma_p, case.sigma_n, NOISE_SEED);
        }
        let all: Vec<usize> = (0..cloud.len()).collect();
        let stride = (cloud.len() / subset.max(1)).max(1);
        let some: Vec<usize> = all
            .iter()
            .copied()
            .filter(|i| i.is_multiple_of(stride))
            .collect();
        for &k in &case.ks {
            let t = Stopwatch::start();
            let knn = knn_brute(&cloud.positions, k);
            let knn_time = t.stop();
            for e in &entries {
                if case.estimators.is_some_and(|only| !only.contains(&e.label)) {
                    continue;
                }
                let selected = if e.slow { &some } else { &all };
                let (results, time) = run_timed(&*e.est, &cloud, &knn, selected);
                let chosen = |i: usize| {
                    if e.slow && !i.is_multiple_of(stride) {
                        None
                    } else {
                        truth[i]
                    }
                };
                let s: ErrorStats =
                    evaluate(&Replay { results: &results }, &cloud, &knn, chosen, 0.1);
                writeln!(
                    out,
                    "{},{},{},{},{},{},{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.4},{:.4},{:.4},{:.4},{:.4}",
                    case.series,
                    case.shape.name(),
                    cloud.len(),
                    case.sigma_p,
                    case.sigma_n,
                    k,
                    e.label,
                    s.h.count() + s.undefined,
                    s.undefined,
                    s.h.rms,
                    s.h.max,
                    s.k.rms,
                    s.k.max,
                    s.k1.rms,
                    s.k1.max,
                    s.k2.rms,
                    s.k2.max,
                    s.d1_deg.rms,
                    us_per(time.cpu, selected.len()),
                    us_per(time.wall, selected.len()),
                    us_per(knn_time.cpu, cloud.len()),
                    us_per(knn_time.wall, cloud.len()),
                )
                .expect("write CSV");
                out.flush().expect("flush CSV");
            }
        }
        eprintln!(
            "[{:>3}/{}] {:>6} {} N={} sigma=({}, {}) K={:?} done at {:.0} s",
            ci + 1,
            cases.len(),
            case.series,
            case.shape.name(),
            case.n,
            case.sigma_p,
            case.sigma_n,
            case.ks,
            started.elapsed().as_secs_f64()
        );
    }
}
