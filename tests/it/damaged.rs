//! Damaged work is exit 4, naming the damaged file and saying to delete the work directory,
//! wherever the damage is found: the manifest, the task layout, a bucket file. A result file
//! with garbage in it, or another tile's in its place, fails its check as a cut one does: the
//! tile is not done, and running its task again heals the work (a point in two whole result
//! files, which that check cannot see, is damaged work too:
//! `io::workdir::results::tests::a_point_in_two_result_files_is_damaged_work`). Never
//! "internal error" (exit 1), never a panic.

use std::path::{Path, PathBuf};

use crate::common::{generate_terrain, s, tilecurv};

/// Runs `tilecurv args`; returns (exit code, stderr).
fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = tilecurv(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    (out.status.code(), err)
}

/// A planned work directory of a 20k-point terrain in 3-tile tasks, its buckets scanned;
/// returns it and the number of tile tasks.
fn planned(dir: &Path) -> (PathBuf, usize) {
    std::fs::create_dir_all(dir).expect("case folder");
    let input = dir.join("t.las");
    generate_terrain(&input, "20k", 5, 10.0);
    let work = dir.join("w");
    let plan = [
        "plan",
        s(&input),
        "--work",
        s(&work),
        "--tile",
        "15m",
        "--tiles-per-task",
        "3",
        "-q",
    ];
    let out = tilecurv(&plan);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout).into_owned();
    let n: usize = printed
        .lines()
        .last()
        .and_then(|l| l.strip_prefix("tasks: "))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("plan prints `tasks: N`: {printed}"));
    let (code, err) = run(&["bucket", "--work", s(&work), "--task", "0", "-q"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(n >= 3, "{printed}");
    (work, n)
}

/// Runs every tile task; returns the first failure's (code, stderr), if any.
fn run_tiles(work: &Path, tasks: usize) -> Option<(Option<i32>, String)> {
    (0..tasks)
        .map(|t| {
            run(&[
                "run-tile",
                "--work",
                s(work),
                "--task",
                &t.to_string(),
                "-q",
            ])
        })
        .find(|(code, _)| *code != Some(0))
}

fn files(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("list")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    v.sort();
    v
}

/// Exit 4, naming `needle` (the file) and the remedy.
fn assert_damaged(what: &str, got: Option<(Option<i32>, String)>, needle: &str) {
    let (code, err) = got.unwrap_or_else(|| panic!("{what}: the damage went unnoticed"));
    assert_eq!(code, Some(4), "{what}: {err}");
    assert!(
        err.contains(needle) && err.contains("delete the work directory"),
        "{what}: expected {needle:?} and the remedy in: {err}"
    );
}

#[test]
fn damaged_work_is_exit_4_naming_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");

    // The manifest: a parameter line that no option takes.
    let (work, tasks) = planned(&dir.path().join("m"));
    let manifest = work.join("manifest.txt");
    let text = std::fs::read_to_string(&manifest).expect("manifest");
    std::fs::write(&manifest, text.replacen("param k=", "param k=banana", 1)).expect("write");
    assert_damaged("manifest", run_tiles(&work, tasks), "manifest");

    // The task layout cut in half.
    let (work, tasks) = planned(&dir.path().join("t"));
    let layout = work.join("tasks.txt");
    let text = std::fs::read(&layout).expect("tasks");
    std::fs::write(&layout, &text[..text.len() / 2]).expect("write");
    assert_damaged("task layout", run_tiles(&work, tasks), "tasks.txt");

    // A bucket file with garbage in the middle of its frames.
    let (work, tasks) = planned(&dir.path().join("b"));
    let buckets = files(&work.join("buckets/t0"), "zst");
    let bucket = buckets
        .iter()
        .max_by_key(|p| p.metadata().map_or(0, |m| m.len()))
        .expect("a bucket");
    let mut bytes = std::fs::read(bucket).expect("bucket");
    let mid = bytes.len() / 2;
    bytes[mid..mid + 64].fill(0x5a);
    std::fs::write(bucket, &bytes).expect("write");
    let name = bucket
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    assert_damaged("bucket file", run_tiles(&work, tasks), &name);

    // A result file with garbage in its frames, or another tile's copied over it, fails its
    // check as a cut one does: the tile is not done. Assemble refuses (exit 5) naming the task
    // to run again, nothing written, and the rerun heals the work.
    for case in ["garbled", "swapped"] {
        let (work, tasks) = planned(&dir.path().join(case));
        assert!(run_tiles(&work, tasks).is_none(), "{case}: the tiles run");
        let results = files(&work.join("results"), "res");
        assert!(results.len() >= 2, "{results:?}");
        if case == "garbled" {
            let mut bytes = std::fs::read(&results[0]).expect("result");
            let mid = bytes.len() / 2;
            bytes[mid..mid + 64].fill(0x5a);
            std::fs::write(&results[0], &bytes).expect("write");
        } else {
            std::fs::copy(&results[1], &results[0]).expect("copy");
        }
        let out = dir.path().join(format!("{case}.las"));
        let assemble = ["assemble", "--work", s(&work), "-o", s(&out), "-q"];
        let (code, err) = run(&assemble);
        assert_eq!(code, Some(5), "{case}: {err}");
        assert!(
            err.contains("tiles have no result") && !out.exists(),
            "{case}: {err}"
        );
        assert!(run_tiles(&work, tasks).is_none(), "{case}: the tiles rerun");
        let (code, err) = run(&assemble);
        assert_eq!(code, Some(0), "{case}: {err}");
    }
}
