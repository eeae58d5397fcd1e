//! What a run leaves in the folder it writes into: a dry run and a refused run (exit 2 or 3)
//! leave no folder they made, an output directory or the folders above an output alike; a run
//! that completes makes them.

use crate::common::{generate_terrain, listing, s, tilecurv};

/// `--dry-run` into `out/deeper/t.las` and into a new output directory of two inputs leaves
/// none of the folders its work directory needed; the plan line gives the tile in the CRS's
/// unit; a refused run into new folders leaves none either; the real run makes them.
#[test]
fn dry_and_refused_runs_leave_no_folder_they_made() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, b) = (dir.path().join("a.las"), dir.path().join("b.las"));
    generate_terrain(&a, "3k", 41, 5.0);
    generate_terrain(&b, "3k", 42, 5.0);
    let nested = dir.path().join("out/deeper/t.las");
    let outdir = format!("{}/", dir.path().join("both").display());
    for args in [
        vec!["process", s(&a), "-o", s(&nested), "--dry-run"],
        vec!["process", s(&a), s(&b), "-o", &outdir, "--dry-run"],
        vec!["process", s(&a), "-o", s(&nested), "--classes", "nine"],
    ] {
        let run = tilecurv(&args);
        let err = String::from_utf8_lossy(&run.stderr);
        let dry = args.contains(&"--dry-run");
        assert_eq!(
            run.status.code(),
            Some(if dry { 0 } else { 2 }),
            "{args:?}: {err}"
        );
        if dry {
            let plan = String::from_utf8_lossy(&run.stdout);
            assert!(plan.contains("tiles of 50 m;"), "{plan}");
        }
        assert_eq!(listing(dir.path()), ["a.las", "b.las"], "{args:?}");
    }
    let run = tilecurv(&["process", s(&a), "-o", s(&nested), "-q"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(listing(&dir.path().join("out/deeper")), ["t.las"]);
}

/// A folder holding anything but a work directory's own files is never taken for one: tilecurv
/// empties a stale work directory and removes it after a run, so `--work-dir .` beside the
/// input, a folder of the user's or `plan --work` into one is refused (exit 2) with every file
/// left as it was, by a dry run too; an output inside the work directory is refused before it
/// is written; a new folder is made and removed, and one left by a killed run is reused.
#[test]
fn a_folder_of_other_files_is_never_taken_for_a_work_directory() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("in.las");
    generate_terrain(&input, "3k", 43, 5.0);
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "field notes\n").expect("notes");
    let mine = dir.path().join("mine");
    std::fs::create_dir(&mine).expect("folder");
    std::fs::write(mine.join("keep.txt"), "mine\n").expect("keep");
    let bytes = std::fs::read(&input).expect("input");
    let out = dir.path().join("out.las");
    let here = s(dir.path());
    let (inner_out, inner_work) = (dir.path().join("w/out.las"), dir.path().join("w/../w"));
    let (foreign, inside) = ("not a tilecurv work directory", "is in the work directory");
    let (inp, outp, minep) = (s(&input), s(&out), s(&mine));
    let runs: [(Vec<&str>, &str); 5] = [
        // The output beside the input is in the work directory too: either refusal will do.
        (vec!["process", inp, "-o", outp, "--work-dir", here], ""),
        (
            vec!["process", inp, "-o", outp, "--work-dir", minep],
            foreign,
        ),
        (
            vec!["process", inp, "-o", outp, "--work-dir", minep, "--dry-run"],
            foreign,
        ),
        (vec!["plan", inp, "--work", minep], foreign),
        (
            vec![
                "process",
                inp,
                "-o",
                s(&inner_out),
                "--work-dir",
                s(&inner_work),
            ],
            inside,
        ),
    ];
    for (args, why) in &runs {
        let run = tilecurv(args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(why), "{args:?}: {err}");
        assert_eq!(
            listing(dir.path()),
            ["in.las", "mine", "notes.txt"],
            "{args:?}"
        );
        assert_eq!(listing(&mine), ["keep.txt"], "{args:?}");
        assert_eq!(std::fs::read(&input).expect("input"), bytes);
        assert_eq!(
            std::fs::read_to_string(&notes).expect("notes"),
            "field notes\n"
        );
    }
    // A new folder is the work directory, removed after the run.
    let work = dir.path().join("new_work");
    let run_into = |output: &std::path::Path| {
        let args = [
            "process",
            s(&input),
            "-o",
            s(output),
            "--work-dir",
            s(&work),
            "-q",
        ];
        let run = tilecurv(&args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{err}");
        assert!(!work.exists());
    };
    run_into(&out);
    // A work directory a killed run left (its manifest, another host's temporary) is reused.
    std::fs::create_dir(&work).expect("work");
    std::fs::write(work.join("manifest.txt"), "stale\n").expect("manifest");
    std::fs::write(work.join(".manifest.txt.tilecurv-elsewhere-1.tmp"), "x").expect("temp");
    let again = dir.path().join("again.las");
    run_into(&again);
    assert_eq!(
        std::fs::read(&again).expect("again"),
        std::fs::read(&out).expect("out")
    );
}
