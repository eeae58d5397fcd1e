//! Results depend on the points, not on how a LAS file stores them: the same points on the
//! same grid, written with offsets that differ by whole steps, in another record order, in
//! point format 0, 1, 3 or 6, as LAS, LAZ or COPC, give every point bit-identical columns
//! (`--f64`, so no quantisation hides a last-bit difference). The copies are written by laspy
//! (`scripts/regrid.py`), an independent writer. Before `core::grid`, a shift by whole steps
//! changed every point's H in its last bits on the shipped sample.

use std::path::Path;
use std::process::Command;

use crate::common::{
    column_bytes, laspy_available, process, records, root, shared, under_ci, COLUMNS,
};

/// Writes `input`'s points to `output` with offsets moved by `steps` and the options `more` of
/// `scripts/regrid.py`. False (a loud skip) when laspy is missing outside CI.
pub(crate) fn regrid(input: &Path, output: &Path, steps: [i64; 3], more: &[&str]) -> bool {
    let steps = steps.map(|s| s.to_string());
    let out = Command::new("python3")
        .arg(root().join("scripts/regrid.py"))
        .args([input, output])
        .arg("--steps")
        .args(&steps)
        .args(more)
        .output()
        .expect("python3 runs");
    if !out.status.success() {
        let why = String::from_utf8_lossy(&out.stderr);
        if under_ci() {
            panic!("scripts/regrid.py failed under CI=true (laspy, lazrs, copclib): {why}");
        }
        eprintln!("SKIPPED: scripts/regrid.py failed: {why}");
        return false;
    }
    true
}

/// Every point of a tilecurv output as (its index on the grid counted from the origin, the
/// bytes of its columns `names`), sorted: what must not depend on how the file stores it.
fn keyed(path: &Path, names: &[&str]) -> Vec<([i64; 3], Vec<u8>)> {
    let (src, all) = records(path);
    let h = &src.header;
    let n = h.point_count as usize;
    let steps: Vec<i64> = (0..3)
        .map(|a| (h.offset[a] / h.scale[a]).round() as i64)
        .collect();
    let columns: Vec<Vec<u8>> = names.iter().map(|c| column_bytes(path, c)).collect();
    let mut v: Vec<([i64; 3], Vec<u8>)> = all
        .chunks_exact(h.record_length as usize)
        .enumerate()
        .map(|(i, rec)| {
            let q = |a: usize| {
                i32::from_le_bytes(rec[4 * a..4 * a + 4].try_into().expect("4 bytes")) as i64
            };
            let key = [0, 1, 2].map(|a| q(a) + steps[a]);
            let bytes = columns
                .iter()
                .flat_map(|c| {
                    let size = c.len() / n;
                    c[i * size..(i + 1) * size].to_vec()
                })
                .collect();
            (key, bytes)
        })
        .collect();
    v.sort();
    v
}

/// Processes `original` and each copy with `args`, and names the copies whose points differ.
fn compare(dir: &Path, original: &Path, copies: &[&Path], args: &[&str]) -> Vec<String> {
    let out = |p: &Path| {
        dir.join(format!(
            "{}_out.las",
            p.file_name().expect("name").to_string_lossy()
        ))
    };
    process(original, &out(original), args);
    let want = keyed(&out(original), &COLUMNS);
    let mut report = Vec::new();
    for copy in copies {
        process(copy, &out(copy), args);
        let got = keyed(&out(copy), &COLUMNS);
        assert_eq!(got.len(), want.len(), "{}: point count", copy.display());
        let keys_differ = got.iter().zip(&want).filter(|(a, b)| a.0 != b.0).count();
        assert_eq!(keys_differ, 0, "{}: not the same points", copy.display());
        let bad = got.iter().zip(&want).filter(|(a, b)| a.1 != b.1).count();
        if bad > 0 {
            report.push(format!(
                "{} {args:?}: {bad} of {} points differ from {}",
                copy.display(),
                want.len(),
                original.display()
            ));
        }
    }
    report
}

/// The shipped sample (point format 0, LAS): shifted offsets; shifted, shuffled, format 6,
/// LAZ; shifted, format 6, COPC. Default estimator and `-k auto`, over tiles and threads.
#[test]
fn the_sample_stored_any_way_on_its_grid_gives_identical_columns() {
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let original = root().join("data/Haystack_Rock.las");
    let (shift, shuffled, copc) = (
        d.join("shift.las"),
        d.join("shuffled.laz"),
        d.join("c.copc.laz"),
    );
    let made = regrid(&original, &shift, [12_345, -6_789, 321], &[])
        && regrid(
            &original,
            &shuffled,
            [-777, 1_000, -50],
            &["--shuffle", "3", "--format", "6"],
        )
        && regrid(&original, &copc, [5, 5, 5], &["--format", "6", "--copc"]);
    if !made {
        return;
    }
    let copies = [shift.as_path(), shuffled.as_path(), copc.as_path()];
    let mut report = Vec::new();
    for args in [
        &["--f64", "--tile", "20", "--threads", "2"][..],
        &["--f64", "-k", "auto"],
    ] {
        report.extend(compare(d, &original, &copies, args));
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// A real LAZ survey (autzen_trim.laz, point format 3): shifted and shuffled as point format 1
/// LAZ, and shifted as point format 6 LAZ.
#[test]
fn a_laz_survey_stored_any_way_on_its_grid_gives_identical_columns() {
    let Some(original) = shared("las/autzen_trim.laz") else {
        return;
    };
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let (one, six) = (d.join("f1.laz"), d.join("f6.laz"));
    let made = regrid(
        &original,
        &one,
        [99_999, -12, 7],
        &["--shuffle", "9", "--format", "1"],
    ) && regrid(&original, &six, [-4_242, 31_337, -1], &["--format", "6"]);
    if !made {
        return;
    }
    let report = compare(d, &original, &[&one, &six], &["--f64", "--threads", "2"]);
    assert!(report.is_empty(), "{}", report.join("\n"));
}
