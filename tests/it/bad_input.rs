//! Bad input gets a clear error naming the file (and the byte offset where it applies), a
//! documented non-zero exit code, never a panic, and never an output file or a leftover
//! temporary file.

use std::path::Path;

use crate::common::{root, s, tilecurv};

fn sample() -> Vec<u8> {
    std::fs::read(root().join("data/Haystack_Rock.las")).expect("shipped sample")
}

/// Runs on `bytes` written as `name`; asserts exit code `code`, that stderr contains every
/// `needles` string, and that the output directory holds nothing but the input afterwards.
fn expect_failure(name: &str, bytes: &[u8], code: i32, needles: &[&str]) {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join(name);
    std::fs::write(&input, bytes).expect("write input");
    let output = dir.path().join("out.laz");
    let out = tilecurv(&[
        "process",
        input.to_str().expect("utf-8"),
        "-o",
        output.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{name}: {err}");
    assert!(!err.contains("panicked"), "{name} panicked: {err}");
    for n in needles {
        assert!(err.contains(n), "{name}: expected {n:?} in: {err}");
    }
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(left.len(), 1, "{name}: files left behind: {left:?}");
    assert_eq!(
        std::fs::read(&input).expect("input still there"),
        bytes,
        "the input was modified"
    );
}

fn set(b: &mut [u8], at: usize, v: &[u8]) {
    b[at..at + v.len()].copy_from_slice(v);
}

#[test]
fn truncated_file() {
    let b = sample();
    expect_failure(
        "trunc.las",
        &b[..b.len() - 1000],
        3,
        &["trunc.las", "truncated", "21932 points"],
    );
}

#[test]
fn header_count_larger_than_file() {
    let mut b = sample();
    set(&mut b, 107, &30_000u32.to_le_bytes());
    expect_failure(
        "count.las",
        &b,
        3,
        &["count.las", "30000 points", "only 21932 whole points"],
    );
}

#[test]
fn unknown_point_format() {
    let mut b = sample();
    b[104] = 11;
    expect_failure(
        "fmt.las",
        &b,
        3,
        &[
            "fmt.las",
            "byte offset 104",
            "unknown point data record format 11",
        ],
    );
}

#[test]
fn zero_scale() {
    let mut b = sample();
    set(&mut b, 139, &0f64.to_le_bytes());
    expect_failure(
        "scale.las",
        &b,
        3,
        &["scale.las", "byte offset 139", "y scale factor is 0"],
    );
}

#[test]
fn empty_and_foreign_files() {
    expect_failure("empty.las", &[], 3, &["empty.las", "empty"]);
    expect_failure(
        "text.las",
        b"x y z\n1 2 3\n",
        3,
        &["text.las", "not a LAS/LAZ file"],
    );
    let b = sample();
    expect_failure(
        "hdr.las",
        &b[..200],
        3,
        &["hdr.las", "only 200 bytes", "truncated"],
    );
}

#[test]
fn corrupt_laz_is_an_error_not_a_panic() {
    let Some(laz) = crate::common::shared("las/autzen_trim.laz") else {
        return;
    };
    let mut b = std::fs::read(laz).expect("read");
    let n = b.len();
    b.truncate(n / 2);
    expect_failure("half.laz", &b, 3, &["half.laz"]);
}

#[test]
fn refuses_to_overwrite_the_input_and_bad_usage() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("in.las");
    std::fs::write(&input, sample()).expect("write");
    let p = input.to_str().expect("utf-8");
    let out = tilecurv(&["process", p, "-o", p]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("overwrite an input"));
    for args in [
        vec!["process", p, "-o", "x.txt"],
        vec!["process", p, "-o", "x.las", "--tile", "5 parsecs"],
        vec!["process", p, "-o", "x.las", "-k", "2"],
        vec!["process", p, "-o", "x.las", "--estimator", "magic"],
        vec!["process", p, "-o", "x.las", "--orient", "down"],
    ] {
        let out = tilecurv(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(!Path::new("x.las").exists());
    let missing = tilecurv(&["process", "/nonexistent/in.las", "-o", "x.las"]);
    assert_eq!(missing.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent/in.las"));
}

/// A closed stderr (`tilecurv ... 2>&1 | head -1`) never kills a run: messages are dropped, the
/// output is written and the exit code is 0 (it was 101, "failed printing to stderr").
#[test]
fn a_closed_stderr_does_not_stop_the_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    crate::common::generate_terrain(&input, "20k", 3, 10.0);
    let output = dir.path().join("out.las");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_tilecurv"))
        .args(["process", input.to_str().expect("utf-8"), "-o"])
        .arg(&output)
        .arg("--tile")
        .arg("10m")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("tilecurv starts");
    // Close the reading end at once: every write to stderr fails with EPIPE.
    drop(child.stderr.take());
    let status = child.wait().expect("tilecurv ends");
    assert_eq!(status.code(), Some(0), "exit {status:?}");
    let bytes = std::fs::metadata(&output).expect("the output exists").len();
    assert!(bytes > 20_000 * 20, "output of {bytes} bytes");
}

/// A directory given as an input is bad input (exit 3) that says it is a directory and how to
/// name its files, with a LAS name (it said "No such device", the mmap error) or without an
/// extension (it said "unsupported input format \"\"").
#[test]
fn a_directory_as_input_is_named_as_such() {
    let dir = tempfile::tempdir().expect("temp dir");
    let output = dir.path().join("out.las");
    for name in ["scans.las", "scans"] {
        let input = dir.path().join(name);
        std::fs::create_dir(&input).expect("a directory");
        let out = tilecurv(&["process", s(&input), "-o", s(&output)]);
        let msg = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{msg}");
        assert!(
            msg.contains("is a directory") && msg.contains("/*.laz"),
            "{msg}"
        );
        assert!(!output.exists());
    }
}

/// A cloud of one or two points: every point has fewer than 3 neighbours, so flag 1 (and flag
/// 2: no PCA normal) is set and H is NaN (only flag 2 was set).
#[test]
fn points_with_fewer_than_three_neighbours_get_flag_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    for n in [1usize, 2] {
        let input = dir.path().join(format!("p{n}.las"));
        let pts: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 0.5 * i as f64, 1.0]).collect();
        crate::common::write_las(&input, &pts, None, 0.001);
        let out = dir.path().join(format!("o{n}.las"));
        crate::common::process(&input, &out, &[]);
        let f = crate::common::column(&out, "CurvatureFlags");
        assert_eq!(f, vec![3.0; n], "{n} points");
        assert!(crate::common::column(&out, "H").iter().all(|h| h.is_nan()));
    }
}

/// An OFF header whose face or edge count is negative or not a number, and a PLY element that
/// declares a property twice, are bad input naming the line (both were accepted: the OFF count
/// was ignored, the PLY property's second copy shadowed the first).
#[test]
fn malformed_off_counts_and_duplicated_ply_properties_are_refused() {
    let off = |counts: &str| format!("OFF\n{counts}\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expect_failure(
        "neg.off",
        off("3 -1 0").as_bytes(),
        3,
        &["line 2", "face count is \"-1\""],
    );
    expect_failure(
        "edge.off",
        off("3 1 x").as_bytes(),
        3,
        &["edge count is \"x\""],
    );
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nproperty float x\nend_header\n0 0 0 5\n1 0 0 5\n0 1 0 5\n";
    expect_failure(
        "dup.ply",
        ply.as_bytes(),
        3,
        &["header line 7", "property \"x\" twice"],
    );
}

/// A run of several inputs refused during the scan (exit 3: the second input's coordinates are
/// not finite) leaves the folder as it was: no output directory it made, no work directory.
#[test]
fn a_refused_run_removes_the_output_directory_it_made() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = dir.path().join("a.las");
    std::fs::write(&good, sample()).expect("write");
    let mut b = sample();
    set(&mut b, 131, &1e306f64.to_le_bytes());
    set(&mut b, 155, &0f64.to_le_bytes());
    let bad = dir.path().join("b.las");
    std::fs::write(&bad, &b).expect("write");
    let out = dir.path().join("out");
    let r = tilecurv(&[
        "process",
        good.to_str().expect("utf-8"),
        bad.to_str().expect("utf-8"),
        "-o",
        &format!("{}/", out.display()),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(err.contains("b.las") && err.contains("not finite"), "{err}");
    let mut left: Vec<String> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a.las", "b.las"], "{err}");
}
