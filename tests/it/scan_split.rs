//! One input scanned by several bucket tasks (`plan --points-per-scan-task`): a LAS input split
//! between records and a LAZ input split between its compressed chunks give, through the
//! cluster stages, the bytes `process` gives; other formats stay one task; 0 is a usage error.

use std::path::Path;

use crate::common::{generate_terrain, run_stages, s, stdout_of, tilecurv};

/// Runs `tilecurv args`, asserts it succeeds, returns stdout.
fn ok(args: &[&str]) -> String {
    stdout_of(args, 0)
}

/// The number after `prefix` on a line of `printed`.
fn count(printed: &str, prefix: &str) -> u64 {
    printed
        .lines()
        .find_map(|l| l.strip_prefix(prefix))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no `{prefix}N` in {printed:?}"))
}

/// The first point of every bucket task but the first, from the layout `plan` wrote.
fn cuts(work: &Path) -> Vec<u64> {
    let text = std::fs::read_to_string(work.join("tasks.txt")).expect("task layout");
    text.lines()
        .filter_map(|l| l.strip_prefix("bucket_task "))
        .skip(1)
        .map(|r| {
            let start = r.split_once(':').and_then(|(_, p)| p.split_once(".."));
            start
                .expect("input:first..end")
                .0
                .parse()
                .expect("a number")
        })
        .collect()
}

/// Plans `input` with `per_task` points per scan task, runs every stage by hand (the bucket
/// tasks in reverse order) and returns the bucket tasks, the cuts between them and the
/// output's bytes.
fn split_run(input: &Path, dir: &Path, per_task: &str, opts: &[&str]) -> (u64, Vec<u64>, Vec<u8>) {
    let work = dir.join("w");
    let mut plan = vec!["plan", s(input), "--work", s(&work), "-q"];
    plan.extend(["--points-per-scan-task", per_task, "--tiles-per-task", "4"]);
    plan.extend(opts);
    let printed = ok(&plan);
    let (buckets, tiles) = (
        count(&printed, "bucket tasks: "),
        count(&printed, "tasks: "),
    );
    let name = input.file_name().expect("file name");
    let out = dir.join("out").join(name);
    std::fs::create_dir_all(dir.join("out")).expect("output directory");
    run_stages(&work, buckets, tiles, s(&out));
    let bytes = std::fs::read(&out).expect("assembled output");
    (buckets, cuts(&work), bytes)
}

#[test]
fn a_las_and_a_laz_input_split_over_scan_tasks_give_the_bytes_of_process() {
    let dir = tempfile::tempdir().expect("temp dir");
    let opts = ["--tile", "12m", "--orient", "propagate"];
    for (name, seed) in [("one.las", 31), ("one.laz", 32)] {
        let case = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir_all(&case).expect("case dir");
        let input = case.join(name);
        generate_terrain(&input, "130k", seed, 10.0);
        let reference = case.join("ref").join(name);
        let mut process = vec!["process", s(&input), "-q", "-o", s(&reference)];
        process.extend(opts);
        ok(&process);

        let (buckets, cuts, bytes) = split_run(&input, &case, "40k", &opts);
        if name.ends_with(".las") {
            // ceil(130k / 40k) = 4 tasks, cut at floor(i * 130000 / 4).
            assert_eq!(cuts, [32_500, 65_000, 97_500], "{name}");
        } else {
            // Only at chunk starts: the ones nearest 32.5k, 65k and 97.5k.
            assert_eq!(cuts, [50_000, 100_000], "{name}");
        }
        assert_eq!(buckets, cuts.len() as u64 + 1, "{name}");
        let want = std::fs::read(&reference).expect("process output");
        assert!(
            bytes == want,
            "{name}: the split scan's output differs from process's"
        );
    }
}

#[test]
fn other_formats_stay_one_scan_task_and_zero_is_a_usage_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let xyz = dir.path().join("grid.xyz");
    let text: String = (0..400)
        .map(|i| format!("{} {} {}\n", i % 20, i / 20, ((i % 20) as f64 * 0.1).sin()))
        .collect();
    std::fs::write(&xyz, text).expect("write xyz");
    let work = dir.path().join("w");
    let printed = ok(&[
        "plan",
        s(&xyz),
        "--work",
        s(&work),
        "--points-per-scan-task",
        "100",
        "-q",
    ]);
    assert_eq!(count(&printed, "bucket tasks: "), 1, "{printed}");

    let las = dir.path().join("a.las");
    generate_terrain(&las, "5k", 3, 10.0);
    let zero = dir.path().join("zero");
    let out = tilecurv(&[
        "plan",
        s(&las),
        "--work",
        s(&zero),
        "--points-per-scan-task",
        "0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--points-per-scan-task"), "{err}");
    assert!(!zero.exists(), "a refused plan made its work directory");
}
