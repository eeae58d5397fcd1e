//! The cluster stages by hand, without a scheduler (scripts/slurm/cluster_test.sh runs them
//! through Slurm): plan, bucket tasks, every tile task, assemble give the bytes `process`
//! gives (and `assemble --raster` the rasters of `process --raster`); tasks run twice are harmless; assemble refuses with exit 5 and writes nothing while a
//! tile is missing; status counts and lists the tasks; a killed attempt's leftovers are swept.

use crate::common::{generate_terrain, s, stdout_of as run, tilecurv};

/// Runs the tile tasks `tasks` of the work directory `work`, each to success.
fn run_tiles(work: &std::path::Path, tasks: std::ops::Range<u64>) {
    for t in tasks {
        let task = t.to_string();
        run(&["run-tile", "--work", s(work), "--task", &task, "-q"], 0);
    }
}

#[test]
fn stages_by_hand_give_the_bytes_of_process() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, b) = (dir.path().join("a.las"), dir.path().join("b.laz"));
    generate_terrain(&a, "30k", 21, 10.0);
    generate_terrain(&b, "20k", 22, 6.0);
    let reference = dir.path().join("ref");
    let opts = ["--tile", "12m", "--orient", "propagate"];
    let mut args = vec!["process", s(&a), s(&b), "-q", "-o"];
    let refdir = format!("{}/", s(&reference));
    args.push(&refdir);
    args.extend(opts);
    args.extend(["--raster", "2m"]);
    run(&args, 0);

    let work = dir.path().join("w");
    let mut plan = vec![
        "plan",
        s(&a),
        s(&b),
        "--work",
        s(&work),
        "--tiles-per-task",
        "5",
        "-q",
    ];
    plan.extend(opts);
    let printed = run(&plan, 0);
    let last = printed.lines().last().expect("plan prints");
    let tasks: u64 = last
        .strip_prefix("tasks: ")
        .expect("tasks: N")
        .parse()
        .expect("N");
    assert!(printed.starts_with("bucket tasks: 2\n"), "{printed}");
    assert!(tasks > 2, "{printed}");
    // A leftover of a killed attempt of bucket task 1 on this host: swept by the next attempt.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").expect("hostname");
    let dead = work.join(format!(
        "buckets/.t1.tilecurv-{}-2147483646.tmp",
        host.trim()
    ));
    std::fs::create_dir_all(&dead).expect("fake leftover");
    assert_eq!(
        run(&["status", "--work", s(&work), "--missing"], 0).trim(),
        format!("0-{}", tasks - 1)
    );
    // Tile tasks before the buckets: exit 5, naming the bucket tasks.
    run(&["run-tile", "--work", s(&work), "--task", "0", "-q"], 5);
    for t in ["0", "1", "1"] {
        run(&["bucket", "--work", s(&work), "--task", t, "-q"], 0);
    }
    assert!(!dead.exists(), "the dead attempt's directory was not swept");
    run_tiles(&work, 0..tasks);
    // A task run again changes nothing.
    run(&["run-tile", "--work", s(&work), "--task", "1", "-q"], 0);
    assert_eq!(
        run(&["status", "--work", s(&work)], 0).trim(),
        format!("done {tasks} of {tasks} tasks")
    );
    let out = dir.path().join("out");
    let outdir = format!("{}/", s(&out));
    let assemble = ["assemble", "--work", s(&work), "-o", &outdir, "-q"];
    run(&[&assemble[..], &["--raster", "2m"]].concat(), 0);
    // The rasters of several outputs go to rasters/ beside them: one raster of the scene.
    for f in [
        "a.las",
        "b.laz",
        "rasters/H.tif",
        "rasters/K.tif",
        "rasters/PointCount.tif",
    ] {
        let (x, y) = (
            std::fs::read(out.join(f)).expect("output"),
            std::fs::read(reference.join(f)).expect("reference"),
        );
        assert!(x == y, "{f} differs from process's");
    }

    // One tile result lost: status names its task, assemble refuses and writes nothing.
    let results = work.join("results");
    let lost = std::fs::read_dir(&results)
        .expect("results")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "res"))
        .expect("a result file");
    std::fs::remove_file(&lost).expect("remove");
    let missing = run(&["status", "--work", s(&work), "--missing"], 0);
    assert!(missing.trim().parse::<u64>().is_ok(), "{missing}");
    let partial = dir.path().join("partial");
    let partial_dir = format!("{}/", s(&partial));
    let refused = tilecurv(&["assemble", "--work", s(&work), "-o", &partial_dir, "-q"]);
    assert_eq!(refused.status.code(), Some(5));
    let msg = String::from_utf8_lossy(&refused.stderr);
    assert!(
        msg.contains(&format!("run-tile tasks not done: {};", missing.trim())),
        "{msg}"
    );
    assert!(
        !partial.exists(),
        "assemble created its output while refusing"
    );
}

/// The outputs of several inputs take their file names, so `plan` refuses two inputs of one
/// name (which `assemble` would refuse after all the work) before it makes the work directory;
/// `assemble` makes a missing output folder, as `process` does, and writes `process`'s bytes.
#[test]
fn plan_refuses_one_name_twice_and_assemble_makes_the_output_folder() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, other) = (dir.path().join("a.las"), dir.path().join("sub/a.las"));
    generate_terrain(&a, "5k", 31, 5.0);
    std::fs::create_dir_all(other.parent().expect("sub")).expect("sub");
    std::fs::copy(&a, &other).expect("copy");
    let work = dir.path().join("w");
    let refused = tilecurv(&["plan", s(&a), s(&other), "--work", s(&work), "-q"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(err.contains("two inputs are named a.las"), "{err}");
    assert!(
        !work.exists(),
        "plan made its work directory while refusing"
    );

    let reference = dir.path().join("ref.las");
    run(&["process", s(&a), "-o", s(&reference), "-q"], 0);
    run(&["plan", s(&a), "--work", s(&work), "-q"], 0);
    run(&["bucket", "--work", s(&work), "--task", "0", "-q"], 0);
    let status = run(&["status", "--work", s(&work), "--missing"], 0);
    let last: u64 = (status.trim().rsplit('-').next())
        .and_then(|t| t.parse().ok())
        .expect("the tile tasks missing, as FIRST-LAST");
    run_tiles(&work, 0..last + 1);
    let out = dir.path().join("new/deeper/a.las");
    run(&["assemble", "--work", s(&work), "-o", s(&out), "-q"], 0);
    let (x, y) = (
        std::fs::read(&out).expect("output"),
        std::fs::read(&reference).expect("ref"),
    );
    assert!(x == y, "assemble's output differs from process's");
}
