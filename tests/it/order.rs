//! Results depend on the point set alone, not on the order of the records:
//! the same points written in another order give every point bit-identical columns. The cloud
//! is made to hold ties: a lattice at a 1 cm scale with a height field rounded to the
//! centimetre (many neighbours at exactly equal distances, at the K-th place too), a patch of
//! random points snapped to the centimetre, and exact duplicates (pairs and triples). A second
//! file holds the same records under a fixed permutation; both are processed under the default
//! settings, with `-k auto` (its ScaleK and ScaleFlags too), with `--orient propagate`, and
//! with the randomised `cnc-uniform` and the tie-breaking `cnc-delaunay` estimators, over
//! several tiles and two threads.
//!
//! Like invariance.rs, this uses only the `tilecurv` binary and the files it writes.

use std::path::Path;

use crate::common::{column_bytes, process, write_las, COLUMNS};

/// The test cloud: a 0.5 m lattice over 60 m x 60 m with a gentle height field rounded to the
/// centimetre, a patch of random points snapped to the centimetre, points stacked above
/// lattice points, and exact duplicates of about 3 % of the points (some twice). UTM-sized
/// coordinates.
fn cloud() -> Vec<[f64; 3]> {
    let mut rng = tilecurv::core::rng::Rng::new(2024);
    let cm = |v: f64| (v * 100.0).round() / 100.0;
    let height = |x: f64, y: f64| 1.5 * (x / 9.0).sin() * (y / 7.0).cos() + 0.01 * x;
    let mut xyz = Vec::new();
    for i in 0..120 {
        for j in 0..120 {
            let (x, y) = (i as f64 * 0.5, j as f64 * 0.5);
            xyz.push([x, y, cm(height(x, y))]);
        }
    }
    for _ in 0..4000 {
        let (x, y) = (
            cm(20.0 + 20.0 * rng.uniform()),
            cm(20.0 + 20.0 * rng.uniform()),
        );
        xyz.push([x, y, cm(height(x, y))]);
    }
    // Vegetation: points above lattice points, at the same x and y (distinct points that only
    // their height tells apart, so they share their tile's Morton key).
    for _ in 0..300 {
        let p = xyz[rng.below(120 * 120)];
        for _ in 0..1 + rng.below(3) {
            xyz.push([p[0], p[1], cm(p[2] + 0.5 + 2.5 * rng.uniform())]);
        }
    }
    let n = xyz.len();
    for _ in 0..n / 30 {
        let p = xyz[rng.below(n)];
        xyz.push(p);
        if rng.below(4) == 0 {
            xyz.push(p);
        }
    }
    xyz.iter()
        .map(|p| [500_000.0 + p[0], 4_000_000.0 + p[1], 100.0 + p[2]])
        .collect()
}

/// A fixed permutation of `0..n` (Fisher-Yates): record `j` of the shuffled file is record
/// `perm[j]` of the original.
fn permutation(n: usize) -> Vec<usize> {
    let mut rng = tilecurv::core::rng::Rng::new(77);
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        perm.swap(i, rng.below(i + 1));
    }
    perm
}

/// Points of the shuffled output whose `name` column differs from the original output's at the
/// same point (record `j` of `shuffled` against record `perm[j]` of `original`).
fn differing(original: &Path, shuffled: &Path, name: &str, perm: &[usize]) -> Vec<usize> {
    let (a, b) = (column_bytes(original, name), column_bytes(shuffled, name));
    assert_eq!(a.len(), b.len(), "column {name}: sizes differ");
    let size = a.len() / perm.len();
    (0..perm.len())
        .filter(|&j| b[j * size..(j + 1) * size] != a[perm[j] * size..(perm[j] + 1) * size])
        .collect()
}

#[test]
fn shuffled_records_give_identical_columns() {
    let dir = tempfile::tempdir().expect("temp dir");
    let xyz = cloud();
    let perm = permutation(xyz.len());
    let shuffled: Vec<[f64; 3]> = perm.iter().map(|&i| xyz[i]).collect();
    let (a, b) = (dir.path().join("a.las"), dir.path().join("b.las"));
    write_las(&a, &xyz, None, 0.01);
    write_las(&b, &shuffled, None, 0.01);

    let directions = ["d1x", "d1y", "d1z", "d2x", "d2y", "d2z"];
    let common = ["--tile", "20", "--threads", "2", "--directions"];
    let cases: [(&str, &[&str]); 5] = [
        ("default", &[]),
        ("auto", &["-k", "auto"]),
        ("propagate", &["--orient", "propagate"]),
        (
            "cnc-uniform",
            &["--estimator", "cnc-uniform", "--seed", "5"],
        ),
        ("cnc-delaunay", &["--estimator", "cnc-delaunay"]),
    ];
    let mut report = Vec::new();
    for (name, extra) in cases {
        let args: Vec<&str> = common.iter().chain(extra).copied().collect();
        let (oa, ob) = (
            dir.path().join(format!("{name}_a.las")),
            dir.path().join(format!("{name}_b.las")),
        );
        process(&a, &oa, &args);
        process(&b, &ob, &args);
        let scale: &[&str] = match name {
            "auto" => &["ScaleK", "ScaleFlags"],
            _ => &[],
        };
        let mut bad: Vec<usize> = COLUMNS
            .iter()
            .chain(&directions)
            .chain(scale)
            .flat_map(|c| differing(&oa, &ob, c, &perm))
            .collect();
        bad.sort_unstable();
        bad.dedup();
        if !bad.is_empty() {
            let first = bad[0];
            report.push(format!(
                "{name}: {} of {} points differ (first: shuffled record {first}, original \
                 record {}, at {:?})",
                bad.len(),
                xyz.len(),
                perm[first],
                xyz[perm[first]]
            ));
        }
    }
    assert!(
        report.is_empty(),
        "results depend on the order of the records:\n{}",
        report.join("\n")
    );
}
