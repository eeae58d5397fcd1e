//! `--radius R` neighbourhoods: the points within R, at most -k of them. The
//! curvature follows the generated terrain's closed form, the output is bit-identical whatever
//! the tile size and thread count (the halo is verified against R), a radius that is not a
//! positive length is a usage error, and a radius with a unit on a file without CRS is warned
//! about as --tile is.

use std::path::Path;

use crate::common::{
    column, column_bytes, generate_terrain, median, process, run_stages, stdout_of, COLUMNS,
};

/// Points per square metre of the terrain: 1.5 m holds about 70 points, 3 m about 280.
const DENSITY: f64 = 10.0;

/// The median |H - TrueH| over the median |TrueH| of a terrain output.
fn h_error(out: &Path) -> f64 {
    let (h, truth) = (column(out, "H"), column(out, "TrueH"));
    let err = median(h.iter().zip(&truth).map(|(a, b)| (a - b).abs()).collect());
    let scale = median(truth.iter().map(|t| t.abs()).collect());
    assert!(
        scale > 1e-4,
        "the terrain is curved: median |TrueH| {scale}"
    );
    err / scale
}

fn assert_same_columns(a: &Path, b: &Path, what: &str) {
    for name in COLUMNS {
        assert!(
            column_bytes(a, name) == column_bytes(b, name),
            "{what}: column {name} differs"
        );
    }
}

/// On 40k points of generated terrain: with --radius 1.5m (under the default cap of 100) and
/// with --radius 3m -k 40 (the cap is what binds), H is near the closed form, and every column
/// is bit-identical between one tile on one thread and 5 m or 20 m tiles on two threads (5 m
/// tiles are mostly halo: 2R = 6 m reaches past the next tile).
#[test]
fn radius_neighbourhoods_follow_the_truth_and_ignore_tiling() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    generate_terrain(&input, "40000", 15, DENSITY);
    let one = ["--tile", "100000m", "--threads", "1", "--memory", "4G"];
    let knn = dir.path().join("knn.las");
    process(&input, &knn, &one);
    let knn_error = h_error(&knn);
    for (radius, cap) in [("1.5m", None), ("3m", Some("40"))] {
        let mut opts = vec!["--radius", radius];
        if let Some(c) = cap {
            opts.extend(["-k", c]);
        }
        let reference = dir.path().join(format!("r{radius}.las"));
        process(&input, &reference, &[&one[..], &opts[..]].concat());
        let error = h_error(&reference);
        eprintln!(
            "--radius {radius} (cap {cap:?}): median |H - TrueH| / median |TrueH| = {error:.3} (-k 30: {knn_error:.3})"
        );
        assert!(error < 0.25, "--radius {radius}: ratio {error}");
        assert!(
            column_bytes(&reference, "H") != column_bytes(&knn, "H"),
            "--radius {radius} changed nothing"
        );
        for tile in ["5m", "20m"] {
            let out = dir.path().join(format!("r{radius}_{tile}.las"));
            let args = [&["--tile", tile, "--threads", "2"][..], &opts[..]].concat();
            process(&input, &out, &args);
            assert_same_columns(
                &reference,
                &out,
                &format!("--radius {radius} --tile {tile}"),
            );
        }
    }
}

/// A radius holding no other point leaves every point with fewer than 3 neighbours: flagged
/// FEW_NEIGHBOURS (1), H undefined.
#[test]
fn a_radius_below_the_spacing_flags_few_neighbours() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    generate_terrain(&input, "2000", 3, 1.0);
    let out = dir.path().join("o.las");
    process(&input, &out, &["--radius", "0.01m"]);
    let flags = column(&out, "CurvatureFlags");
    let few = flags.iter().filter(|&&f| (f as u8) & 1 != 0).count();
    assert!(
        few > flags.len() * 9 / 10,
        "{few} of {} flagged",
        flags.len()
    );
    assert!(column(&out, "H").iter().filter(|h| h.is_nan()).count() >= few);
}

/// A radius that is zero, negative or not a length is refused with the usage exit code and
/// no output; a radius with a unit on a file without CRS is taken in file units with a
/// warning, as --tile is.
#[test]
fn radius_usage_errors_and_unit_warning() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("plain.las");
    let xyz: Vec<[f64; 3]> = (0..900)
        .map(|i| {
            let (x, y) = ((i % 30) as f64 * 0.2, (i / 30) as f64 * 0.2);
            [x, y, 0.05 * (x * x + y * y)]
        })
        .collect();
    crate::common::write_las(&input, &xyz, None, 0.001);
    let output = dir.path().join("out.las");
    let run = |extra: &[&str]| crate::common::run_process(&input, &output, extra);
    for bad in [
        "--radius=0",
        "--radius=-1m",
        "--radius=0m",
        "--radius=2parsecs",
    ] {
        let out = run(&[bad]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("radius"), "{bad}: {err}");
        assert!(!output.exists(), "{bad}: an output was written");
    }
    let out = run(&["--radius", "1m"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("--radius 1m is taken in file units"), "{err}");
}

/// The cluster stages rebuild --radius (and its cap) from the work directory's manifest:
/// plan, bucket, every tile task and assemble give the bytes `process` gives.
#[test]
fn cluster_stages_keep_the_radius() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("a.las");
    generate_terrain(&input, "20000", 4, DENSITY);
    let s = |p: &Path| p.to_str().expect("utf-8 path").to_string();
    let ok = |args: &[&str]| stdout_of(args, 0);
    let opts = ["--tile", "12m", "--radius", "2m", "-k", "60"];
    let (refdir, outdir) = (dir.path().join("ref/"), dir.path().join("out/"));
    let refs = format!("{}/", s(&refdir));
    ok(&[&["process", &s(&input), "-q", "-o", &refs][..], &opts[..]].concat());
    let work = s(&dir.path().join("w"));
    let printed = ok(&[&["plan", &s(&input), "--work", &work, "-q"][..], &opts[..]].concat());
    let tasks: u64 = printed
        .lines()
        .last()
        .and_then(|l| l.strip_prefix("tasks: "))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("plan prints tasks: N: {printed}"));
    run_stages(Path::new(&work), 1, tasks, &format!("{}/", s(&outdir)));
    let (x, y) = (
        std::fs::read(outdir.join("a.las")).expect("output"),
        std::fs::read(refdir.join("a.las")).expect("reference"),
    );
    assert!(x == y, "the stages' output differs from process's");
    let provenance = ok(&["info", &s(&outdir.join("a.las"))]);
    assert!(
        provenance.contains("radius=2m") && provenance.contains("k=60"),
        "{provenance}"
    );
}
