//! Re-running on an output: tilecurv's own columns, known from the input's
//! provenance record, are replaced (the output is the one a run on the original file gives),
//! with a warning; any other name clash is refused before any work, also by `--dry-run`; a
//! tilecurv PLY output given back is refused for now. Layouts are read back with laspy.

use std::path::{Path, PathBuf};

use crate::common::{
    column_bytes, generate_terrain, laspy_available, process, provenance_texts, records,
    run_process, s, tilecurv_as_given, COLUMNS,
};
use crate::interop::laspy;

/// The truth columns of a generated terrain.
const TRUTH: [&str; 4] = ["TrueH", "TrueK", "Truek1", "Truek2"];

/// A generated terrain of 20,000 points in `dir`.
fn terrain(dir: &Path) -> PathBuf {
    let t = dir.join("terrain.las");
    generate_terrain(&t, "20000", 7, 10.0);
    t
}

/// The extra dimensions of each LAS/LAZ file as laspy reads them, after checking that no
/// dimension name repeats, none is an "undocumented extra bytes" filler and the file has
/// exactly one extra-bytes record.
fn laspy_extra_names(files: &[&Path]) -> Vec<Vec<String>> {
    let check = r#"
import sys, collections, laspy
for path in sys.argv[1:]:
    f = laspy.read(path)
    names = list(f.point_format.dimension_names)
    twice = [n for n, c in collections.Counter(n.lower() for n in names).items() if c > 1]
    assert not twice, (path, twice)
    assert not any("undocumented" in n.lower() for n in names), (path, names)
    eb = [v for v in list(f.header.vlrs) + list(f.header.evlrs or []) if v.user_id == "LASF_Spec" and v.record_id == 4]
    assert len(eb) == 1, (path, len(eb))
    print(",".join(f.point_format.extra_dimension_names))
"#;
    laspy(check, files)
        .lines()
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

/// `names` as owned strings.
fn strings(names: &[&str]) -> Vec<String> {
    names.iter().map(|n| n.to_string()).collect()
}

/// Asserts that processing `input` into `output` with `args` is refused before any work, and
/// so is the `--dry-run`: exit 3, a message holding every one of `words`, no scan, no note of
/// replaced columns, no output, no work directory.
fn assert_refused(input: &Path, output: &Path, args: &[&str], words: &[&str]) {
    for dry in [&[][..], &["--dry-run"]] {
        let out = run_process(input, output, &[args, dry].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{dry:?}: {err}");
        for w in words {
            assert!(err.contains(w), "{w:?} not in: {err}");
        }
        assert!(!err.contains("scan:"), "refused before the scan: {err}");
        assert!(!err.contains("replacing"), "nothing replaced: {err}");
        assert!(!output.exists(), "no output");
        let name = output.file_name().expect("a file name").to_string_lossy();
        let work = output.with_file_name(format!(".{name}.tilecurv"));
        assert!(!work.exists(), "no work directory");
    }
}

/// A tilecurv output processed again with the same options (LAS and LAZ, with and without
/// `--ignore-file-normals`, which changes nothing since its normals are not the file's) gives
/// the first output's records byte for byte (every base field, the truth columns and every new
/// column, each once), with a warning naming the replaced columns and the run that wrote them,
/// also from `--dry-run`; the output keeps the earlier provenance records before its own.
#[test]
fn a_rerun_replaces_the_previous_columns_bit_for_bit() {
    let dir = tempfile::tempdir().expect("temp dir");
    let t = terrain(dir.path());
    let note = "replacing NormalX, NormalY, NormalZ, H, K, k1, k2, CurvatureFlags, the columns of an earlier run (tilecurv ";
    let mut written = Vec::new();
    for ext in ["las", "laz"] {
        let once = dir.path().join(format!("once.{ext}"));
        process(&t, &once, &[]);
        let (first, first_records) = records(&once);
        for extra in [&["-q"][..], &["-q", "--ignore-file-normals"][..]] {
            let twice = dir.path().join(format!("twice{}.{ext}", extra.len()));
            let out = run_process(&once, &twice, extra);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{err}");
            assert_eq!(err.matches(note).count(), 1, "one note: {err}");
            let run = format!("{note}{} on terrain.las", env!("CARGO_PKG_VERSION"));
            assert!(err.contains(&run), "{err}");
            let (second, second_records) = records(&twice);
            assert_eq!(second.extra, first.extra, "{ext} {extra:?}");
            assert!(
                second_records == first_records,
                "{ext} {extra:?}: records differ"
            );
            written.push(twice);
        }
        let dry = run_process(
            &once,
            &dir.path().join(format!("dry.{ext}")),
            &["--dry-run"],
        );
        let err = String::from_utf8_lossy(&dry.stderr);
        assert!(dry.status.success() && err.contains(note), "{err}");
    }
    let texts = provenance_texts(&written[0]);
    assert_eq!(texts.len(), 3, "{texts:?}");
    assert!(texts[0].contains("generate terrain"), "{}", texts[0]);
    assert!(texts[1].contains("\ninputs=terrain.las\n"), "{}", texts[1]);
    assert!(texts[2].contains("\ninputs=once.las\n"), "{}", texts[2]);
    if !laspy_available() {
        return;
    }
    let paths: Vec<&Path> = written.iter().map(PathBuf::as_path).collect();
    let want = strings(&[&TRUTH[..], &COLUMNS[..]].concat());
    for (names, path) in laspy_extra_names(&paths).into_iter().zip(&paths) {
        assert_eq!(names, want, "{}", path.display());
    }
}

/// A re-run with other `--columns` drops every column of the previous run, not only those it
/// writes again; the columns it does write equal the first run's, and a third run with the
/// first run's columns (the tests' [`crate::common::ALL_CURVATURE`]) gives its records again.
#[test]
fn a_rerun_with_other_columns_drops_all_the_previous_ones() {
    let dir = tempfile::tempdir().expect("temp dir");
    let t = terrain(dir.path());
    let once = dir.path().join("once.las");
    let some = dir.path().join("some.las");
    let thrice = dir.path().join("thrice.las");
    process(&t, &once, &[]);
    process(&once, &some, &["--columns", "H,flags"]);
    let (s, _) = records(&some);
    let names: Vec<&str> = s.extra.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, [&TRUTH[..], &["H", "CurvatureFlags"][..]].concat());
    for c in ["H", "CurvatureFlags"] {
        assert!(column_bytes(&some, c) == column_bytes(&once, c), "{c}");
    }
    process(&some, &thrice, &[]);
    assert!(records(&thrice).1 == records(&once).1, "records differ");
    if laspy_available() {
        let names = laspy_extra_names(&[&some, &thrice]);
        assert_eq!(
            names[0],
            strings(&[&TRUTH[..], &["H", "CurvatureFlags"]].concat())
        );
        assert_eq!(names[1], strings(&[&TRUTH[..], &COLUMNS[..]].concat()));
    }
}

/// The common case, with the real defaults (no `--columns`): a re-run on a default output
/// replaces H, K and CurvatureFlags, says so, and writes the first run's records again.
#[test]
fn a_default_rerun_on_a_default_output_gives_the_same_records() {
    let dir = tempfile::tempdir().expect("temp dir");
    let t = terrain(dir.path());
    let (once, twice) = (dir.path().join("once.laz"), dir.path().join("twice.laz"));
    let run = |input: &Path, output: &Path| {
        let o = tilecurv_as_given(&["process", s(input), "-o", s(output), "-q"]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        err
    };
    run(&t, &once);
    let err = run(&once, &twice);
    assert!(err.contains("replacing H, K, CurvatureFlags"), "{err}");
    let (src, _) = records(&twice);
    let names: Vec<&str> = src.extra.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(
        names,
        [&TRUTH[..], &["H", "K", "CurvatureFlags"][..]].concat()
    );
    assert!(records(&twice).1 == records(&once).1, "records differ");
}

/// Writes `input` again as `output` with laspy, with an f64 extra dimension `name` (all 0.5)
/// added after the others; every VLR is kept.
fn add_dimension(input: &Path, output: &Path, name: &str) {
    let code = r#"
import sys, laspy, numpy as np
f = laspy.read(sys.argv[1])
f.add_extra_dim(laspy.ExtraBytesParams(name=sys.argv[3], type=np.float64))
f[sys.argv[3]] = np.full(len(f.points), 0.5)
f.write(sys.argv[2])
print("ok")
"#;
    assert_eq!(laspy(code, &[input, output, Path::new(name)]).trim(), "ok");
}

/// A column named like a new one that is not tilecurv's is refused before any work, also by
/// `--dry-run` (exit 3), naming the file and the column and saying what to do: a file that no
/// tilecurv run wrote (laspy adds `H` to a generated terrain), and a column a tilecurv
/// output's provenance record does not list (laspy adds `d1x` to one: refused with
/// `--directions`; without it, kept while the previous run's columns are replaced).
#[test]
fn a_foreign_column_named_like_a_new_one_is_refused_before_any_work() {
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let t = terrain(dir.path());
    let foreign = dir.path().join("foreign.las");
    add_dimension(&t, &foreign, "H");
    let out = dir.path().join("out.las");
    let words = [
        "foreign.las",
        "extra dimension named \"H\"",
        "no provenance record of a tilecurv run",
        "--columns normals,K,k1,k2,flags",
    ];
    assert_refused(&foreign, &out, &[], &words);
    // With the real default columns the advice is what a user can type; with H alone asked
    // for, there is nothing to leave out.
    for (columns, advice) in [
        (None, "leave the new one out with --columns K,flags"),
        (Some("H"), "the new column is the only one asked for"),
    ] {
        let mut args = vec!["process", s(&foreign), "-o", s(&out), "-q"];
        args.extend(columns.map(|c| ["--columns", c]).iter().flatten());
        let o = tilecurv_as_given(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{err}");
        assert!(err.contains(advice), "{err}");
        assert!(!out.exists());
    }
    let once = dir.path().join("once.las");
    let marked = dir.path().join("marked.las");
    process(&t, &once, &[]);
    add_dimension(&once, &marked, "d1x");
    let words = [
        "marked.las",
        "extra dimension named \"d1x\"",
        "provenance record does not list it",
        "--columns normals,H,K,k1,k2,flags",
    ];
    assert_refused(&marked, &out, &["--directions"], &words);
    process(&marked, &out, &[]);
    let names = laspy_extra_names(&[&out]);
    assert_eq!(
        names[0],
        strings(&[&TRUTH[..], &["d1x"], &COLUMNS[..]].concat())
    );
    assert!(column_bytes(&out, "H") == column_bytes(&once, "H"));
}

/// A tilecurv PLY output given back as input is refused before any work ("not supported
/// yet"), and so is a PLY output whose new columns' PLY names an input property has.
#[test]
fn ply_outputs_and_ply_name_clashes_are_refused_before_any_work() {
    let dir = tempfile::tempdir().expect("temp dir");
    let t = terrain(dir.path());
    let ply = dir.path().join("once.ply");
    process(&t, &ply, &[]);
    let out = dir.path().join("out.las");
    let run = format!(
        "tilecurv {} (inputs terrain.las)",
        env!("CARGO_PKG_VERSION")
    );
    let words = ["once.ply", "not supported yet", run.as_str()];
    assert_refused(&ply, &out, &[], &words);
    let mut text = String::from("ply\nformat ascii 1.0\nelement vertex 400\n");
    text += "property float x\nproperty float y\nproperty float z\nproperty float scalar_H\nend_header\n";
    for i in 0..400 {
        let (x, y) = ((i % 20) as f64, (i / 20) as f64);
        text += &format!("{x} {y} {} 1\n", (x * x + y * y) / 100.0);
    }
    let foreign = dir.path().join("foreign.ply");
    std::fs::write(&foreign, text).expect("writes the PLY");
    let out = dir.path().join("out.ply");
    let words = [
        "foreign.ply",
        "property named \"scalar_H\"",
        "--columns normals,K,k1,k2,flags",
    ];
    assert_refused(&foreign, &out, &[], &words);
    process(&foreign, &dir.path().join("out.las"), &[]);
}
