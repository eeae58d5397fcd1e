//! Tiling is invisible: every output column is bit-identical whatever the tile size, the thread
//! count, the read chunk size or the memory budget (spilled buckets, quadtree parts), on real
//! files (LAS and LAZ input) when the shared data is present, and always on terrain the tests
//! generate themselves (`tilecurv generate terrain`, LAS and LAZ twins), where LAS versus LAZ
//! input and output and a run killed and resumed are checked too.
//!
//! These tests use only the `tilecurv` binary and the files it writes, so that they do not
//! depend on the library's internals.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{
    column, column_bytes, finished_tiles, median, process, records, s, shared, tilecurv, COLUMNS,
};

fn assert_same_columns(a: &std::path::Path, b: &std::path::Path) {
    for name in COLUMNS {
        assert!(
            column_bytes(a, name) == column_bytes(b, name),
            "column {name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn tiles_threads_and_chunks_do_not_change_results() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (file, tiles) in [
        ("las/Topography.las", ["5m", "20m", "100000m"]),
        ("las/autzen_trim.laz", ["5m", "20m", "100000m"]),
    ] {
        let Some(input) = shared(file) else { continue };
        let reference = dir.path().join("ref.las");
        process(&input, &reference, &["--tile", tiles[2], "--threads", "1"]);
        for tile in tiles {
            for threads in ["1", "2"] {
                for chunk in ["1000000", "4099"] {
                    if (tile, threads, chunk) == (tiles[2], "1", "1000000") {
                        continue;
                    }
                    let out = dir.path().join(format!("t{tile}_{threads}_{chunk}.las"));
                    process(
                        &input,
                        &out,
                        &["--tile", tile, "--threads", threads, "--chunk-size", chunk],
                    );
                    assert_same_columns(&reference, &out);
                    std::fs::remove_file(&out).expect("cleanup");
                }
            }
        }
        // A small memory budget: buckets spill to disk and the one big tile is computed in
        // quadtree parts.
        let out = dir.path().join("parts.las");
        process(&input, &out, &["--tile", tiles[2], "--memory", "64M"]);
        assert_same_columns(&reference, &out);
    }
}

// ---------------------------------------------------------------------------------------------
// On generated terrain: these never skip.

/// Points per square metre of the generated terrains. A K = 30 neighbourhood is then about 2 m
/// across, so that 5 m tiles are many and mostly halo, and one 100 km tile holds everything.
const DENSITY: f64 = 10.0;

/// Points of the terrains of the tile, thread, chunk and format matrix and of the resumed run:
/// a square of 110 m, 484 tiles of 5 m, 36 of 20 m, 9 of 50 m.
const POINTS: u64 = 120_000;

/// The reference run: one tile holding every point, one thread, and a budget under which that
/// tile is computed whole and in memory on any machine (the default budget depends on the
/// machine's memory).
const REFERENCE: [&str; 6] = ["--tile", "100000m", "--threads", "1", "--memory", "4G"];

/// Writes a noise-free generated terrain of `points` points at [`DENSITY`] (.las or .laz by the
/// extension: the same options give the same points in both).
fn generate(path: &Path, points: u64, seed: u64) {
    crate::common::generate_terrain(path, &points.to_string(), seed, DENSITY);
}

/// The arguments of `tilecurv process input -o output extra...` (not quiet: the tests read
/// the plan and the summary from stderr).
fn process_args<'a>(input: &'a Path, output: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["process", s(input), "-o", s(output)];
    args.extend_from_slice(extra);
    crate::common::with_test_columns(&args)
}

/// Runs `tilecurv process`, asserts success and returns its stderr.
fn run(input: &Path, output: &Path, extra: &[&str]) -> String {
    let args = process_args(input, output, extra);
    let out = tilecurv(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "tilecurv {args:?} failed: {err}");
    err
}

/// N of the "plan: N tiles" line.
fn planned_tiles(stderr: &str) -> usize {
    stderr
        .split("plan: ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no plan line in: {stderr}"))
}

/// N of the "(N resumed)" of the final summary line.
fn resumed_tiles(stderr: &str) -> usize {
    stderr
        .split(" resumed)")
        .next()
        .filter(|head| head.len() < stderr.len())
        .and_then(|head| head.rsplit('(').next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no \"(N resumed)\" in: {stderr}"))
}

/// Fewest tiles of `tile_m` metres over the square of `points` generated points: the square's
/// south-west corner (easting 500000, northing 4100000) is a multiple of every tile size used
/// here, so whole tiles fit floor(side / tile) times along each axis.
fn min_tiles(points: u64, tile_m: f64) -> usize {
    let side = (points as f64 / DENSITY).sqrt();
    ((side / tile_m).floor() as usize).pow(2).max(1)
}

/// The record length in the header of a LAS/LAZ file (bytes 105-106 in every LAS version; for
/// LAZ the length of a decompressed record).
fn record_length(path: &Path) -> usize {
    use std::io::Read;
    let mut h = [0u8; 107];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut h))
        .unwrap_or_else(|e| panic!("{}: no LAS header: {e}", path.display()));
    usize::from(u16::from_le_bytes([h[105], h[106]]))
}

/// Every input point is in the output, in input order, with its whole input record (all
/// original fields and extra bytes, the truth columns included) as the start of its output
/// record, the new columns after it.
fn assert_keeps_input_records(input: &Path, output: &Path) {
    let (il, ol) = (record_length(input), record_length(output));
    let ((_, a), (_, b)) = (records(input), records(output));
    assert!(
        ol > il,
        "{}: records of {ol} bytes do not extend the input's {il}",
        output.display()
    );
    assert_eq!(a.len() % il, 0);
    assert_eq!(b.len() % ol, 0);
    assert_eq!(
        a.len() / il,
        b.len() / ol,
        "{}: point count differs from the input's",
        output.display()
    );
    let bad = a
        .chunks_exact(il)
        .zip(b.chunks_exact(ol))
        .position(|(x, y)| y[..il] != *x);
    assert!(
        bad.is_none(),
        "{}: point {bad:?} lost its original fields",
        output.display()
    );
}

/// `out` holds the same points as `reference`: every added column bit for bit and the whole
/// decoded point records (the original fields too), whatever the containers (LAS or LAZ). The
/// files themselves differ: the provenance VLR records the options.
fn assert_same_output(reference: &Path, out: &Path) {
    assert_same_columns(reference, out);
    assert!(
        records(reference).1 == records(out).1,
        "the point records of {} differ from {}'s",
        out.display(),
        reference.display()
    );
}

/// The curvature is the terrain's, not merely the same in two runs that could be equally
/// broken: the median |H - TrueH| is under a quarter of the median |TrueH|. A zero, sign-flipped
/// or misscaled H gives a ratio near 1, near 2 or far off; a correct one about 0.1 here (outofcore.rs
/// `terrain_curvature_matches_its_closed_form` bounds the error tightly).
fn assert_near_truth(out: &Path) {
    let (h, truth) = (column(out, "H"), column(out, "TrueH"));
    let err = median(h.iter().zip(&truth).map(|(a, b)| (a - b).abs()).collect());
    let scale = median(truth.iter().map(|t| t.abs()).collect());
    eprintln!(
        "{}: median |H - TrueH| {err:.2e} 1/m, median |TrueH| {scale:.2e} 1/m, ratio {:.3}",
        out.display(),
        err / scale
    );
    assert!(
        scale > 1e-4,
        "the terrain is curved: median |TrueH| {scale}"
    );
    assert!(
        err < 0.25 * scale,
        "median |H - TrueH| {err} is not small against median |TrueH| {scale}"
    );
}

#[test]
fn generated_terrain_tiles_threads_chunks_and_formats_do_not_change_results() {
    let dir = tempfile::tempdir().expect("temp dir");
    let las = dir.path().join("t.las");
    let laz = dir.path().join("t.laz");
    generate(&las, POINTS, 11);
    generate(&laz, POINTS, 11);
    assert!(
        records(&las).1 == records(&laz).1,
        "the .laz twin holds the .las file's point records"
    );

    let reference = dir.path().join("ref.las");
    let err = run(&las, &reference, &REFERENCE);
    assert_eq!(planned_tiles(&err), 1, "the reference is one tile: {err}");
    assert_keeps_input_records(&las, &reference);
    assert_near_truth(&reference);

    // Tile size, threads and read chunk (4099: a prime, so chunks end anywhere in the grid),
    // each varied against the reference: 20 m and 50 m tiles under every combination, 5 m tiles
    // (many, mostly halo, but slower: 484 result files to commit) under two.
    let cases = [
        ("5m", "1", "1000000"),
        ("5m", "2", "4099"),
        ("20m", "1", "1000000"),
        ("20m", "1", "4099"),
        ("20m", "2", "1000000"),
        ("20m", "2", "4099"),
        ("50m", "1", "1000000"),
        ("50m", "1", "4099"),
        ("50m", "2", "1000000"),
        ("50m", "2", "4099"),
    ];
    for (tile, threads, chunk) in cases {
        let out = dir.path().join(format!("t{tile}_{threads}_{chunk}.las"));
        let err = run(
            &las,
            &out,
            &["--tile", tile, "--threads", threads, "--chunk-size", chunk],
        );
        let tile_m: f64 = tile.trim_end_matches('m').parse().expect("metres");
        let tiles = planned_tiles(&err);
        assert!(
            tiles >= min_tiles(POINTS, tile_m),
            "--tile {tile}: {tiles} tiles, at least {} expected: {err}",
            min_tiles(POINTS, tile_m)
        );
        assert_same_output(&reference, &out);
        std::fs::remove_file(&out).expect("cleanup");
    }

    // LAZ input against LAS input and LAZ output against LAS output under the reference's
    // options, then both at once with small tiles, two threads and small chunks (which end
    // inside the LAZ chunks of 50000 points).
    let small = ["--tile", "10m", "--threads", "2", "--chunk-size", "4099"];
    for (input, name, extra) in [
        (&laz, "laz_in.las", &REFERENCE[..]),
        (&las, "laz_out.laz", &REFERENCE[..]),
        (&laz, "laz_in_out_small.laz", &small[..]),
    ] {
        let out = dir.path().join(name);
        let err = run(input, &out, extra);
        let tiles = planned_tiles(&err);
        if extra == small {
            assert!(tiles >= min_tiles(POINTS, 10.0), "{tiles} tiles: {err}");
        } else {
            assert_eq!(tiles, 1, "{err}");
        }
        assert_same_output(&reference, &out);
        std::fs::remove_file(&out).expect("cleanup");
    }
}

#[test]
fn generated_terrain_memory_budget_does_not_change_results() {
    // 1M points: their bucket entries (32 bytes a point and the columns' growth, over 32 MB)
    // exceed the share of a 64M budget kept for buckets in memory (2/5, 26.8 MB), so buckets
    // spill to the work directory. With one tile holding everything, the tile's raw bucket
    // alone exceeds its share of the budget, so it is computed in quadtree parts.
    let points = 1_000_000;
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    generate(&input, points, 12);
    let reference = dir.path().join("ref.las");
    let err = run(&input, &reference, &REFERENCE);
    assert!(
        err.contains("buckets in memory"),
        "the reference keeps its buckets in memory: {err}"
    );

    let small_tiles = dir.path().join("small_tiles.las");
    let err = run(
        &input,
        &small_tiles,
        &["--tile", "10m", "--memory", "64M", "--threads", "2"],
    );
    assert!(
        err.contains("buckets spilled to the work directory"),
        "1M points must spill with a 64M budget: {err}"
    );
    assert!(planned_tiles(&err) >= min_tiles(points, 10.0), "{err}");
    assert_same_output(&reference, &small_tiles);
    std::fs::remove_file(&small_tiles).expect("cleanup");

    let parts = dir.path().join("parts.las");
    let err = run(
        &input,
        &parts,
        &["--tile", "100000m", "--memory", "64M", "--threads", "2"],
    );
    assert!(
        err.contains("buckets spilled to the work directory"),
        "1M points must spill with a 64M budget: {err}"
    );
    assert_eq!(planned_tiles(&err), 1, "{err}");
    assert!(
        err.contains(&format!(
            "holds {points} points, whose raw bucket alone exceeds"
        )),
        "the one tile is too large for its share of a 64M budget, so it is computed in parts: {err}"
    );
    assert_same_output(&reference, &parts);
}

#[test]
fn generated_terrain_killed_run_resumes_to_the_reference() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    generate(&input, POINTS, 13);
    let reference = dir.path().join("ref.las");
    process(&input, &reference, &REFERENCE);

    // 484 tiles of 5 m on one thread: finished tiles are committed in batches (of 256, or
    // every 2 s), so the first one appears well before the end.
    let out = dir.path().join("resumed.las");
    let work: PathBuf = dir.path().join("work");
    let extra = ["--tile", "5m", "--threads", "1", "--work-dir", s(&work)];
    let log = dir.path().join("killed_stderr.txt");
    let mut child = Command::new(env!("CARGO_BIN_EXE_tilecurv"))
        .args(process_args(&input, &out, &extra))
        .stdout(Stdio::null())
        .stderr(Stdio::from(File::create(&log).expect("stderr file")))
        .spawn()
        .expect("tilecurv starts");
    let started = Instant::now();
    while finished_tiles(&work) == 0 {
        if let Some(status) = child.try_wait().expect("wait") {
            panic!(
                "the run ended ({status}) before a tile was finished: {}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
        }
        if started.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("no tile finished within 2 minutes");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    // SAFETY: kill(2) on our own child's pid, which has not been reaped yet.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGKILL) };
    assert_eq!(r, 0, "kill(SIGKILL) failed");
    let status = child.wait().expect("wait");
    let killed_err = std::fs::read_to_string(&log).expect("stderr of the killed run");
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(
            status.signal(),
            Some(libc::SIGKILL),
            "the run was killed, it did not finish first: {killed_err}"
        );
    }
    assert!(!out.exists(), "the killed run left an output");
    let tiles = planned_tiles(&killed_err);
    let done = finished_tiles(&work);
    assert!(
        tiles >= min_tiles(POINTS, 5.0),
        "{tiles} tiles: {killed_err}"
    );
    assert!(
        done >= 1 && done < tiles,
        "{done} of {tiles} tiles finished at the kill"
    );

    let err = run(&input, &out, &extra);
    assert!(
        err.contains("resuming the interrupted run"),
        "the rerun resumes: {err}"
    );
    assert_eq!(
        resumed_tiles(&err),
        done,
        "the rerun reuses exactly the {done} finished tiles: {err}"
    );
    eprintln!("killed after {done} of {tiles} tiles; the rerun resumed them");
    assert_same_output(&reference, &out);
    assert_keeps_input_records(&input, &out);
    assert!(
        !work.exists(),
        "the work directory is removed after success"
    );
}
