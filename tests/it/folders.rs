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
