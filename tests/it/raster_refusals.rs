//! Rasters that would fail, or come out wrong, are refused before any point is read: for
//! `process --raster` before the curvature work, with exit 2, and the folder left as it was.

use std::path::Path;

use crate::common::{listing, s, shared, tilecurv};

/// Runs `args`, which must be refused with exit 2 before the curvature work (no `curvature:`
/// phase in the log) with a message holding every one of `says`; returns the message.
fn refused<A: AsRef<str>>(args: &[A], says: &[&str]) -> String {
    let args: Vec<&str> = args.iter().map(AsRef::as_ref).collect();
    let out = tilecurv(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(!err.contains("curvature:"), "refused after the work: {err}");
    for s in says {
        assert!(err.contains(s), "{args:?}: no {s:?} in {err}");
    }
    err
}

/// `tilecurv raster` of `z` in 2 m cells of the inputs `a` and `b` into `out`.
fn raster_z(a: &Path, b: &Path, out: &Path) -> Vec<String> {
    let args = [
        "raster",
        s(a),
        s(b),
        "--cell",
        "2m",
        "--columns",
        "z",
        "-o",
        s(out),
    ];
    args.map(String::from).to_vec()
}

/// A raster directory that is a file, or cannot be made, and an unknown raster column stop
/// `process` before its work; the folder keeps only what was there.
#[test]
fn process_refuses_bad_raster_requests_before_the_work() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("afile");
    std::fs::write(&file, b"x").expect("file");
    let out = dir.path().join("out.laz");
    let base = ["process", s(&input), "-o", s(&out), "--raster", "2m"];
    let run =
        |more: &[&str]| -> Vec<String> { base.iter().chain(more).map(|a| a.to_string()).collect() };
    refused(
        &run(&["--raster-dir", s(&file)]),
        &["exists and is not a directory", "--raster-dir"],
    );
    // With a trailing slash, which makes the file read as missing.
    refused(
        &run(&["--raster-dir", &format!("{}/", s(&file))]),
        &["exists and is not a directory", "--raster-dir"],
    );
    let under_file = file.join("r");
    refused(
        &run(&["--raster-dir", s(&under_file)]),
        &["is not a directory"],
    );
    refused(
        &run(&["--raster-columns", "Foo,H"]),
        &["--raster-columns Foo", "intensity"],
    );
    refused(
        &run(&["--columns", "normals"]),
        &["is a curvature column", "NormalX"],
    );
    assert_eq!(listing(dir.path()), ["afile"]);
}

/// Inputs in two CRSs make no raster (their points would land on another map) and no scene
/// (`process` without rasters: a neighbourhood would join two maps): `process` and `raster`
/// refuse them before reading a point; the same file twice is refused too.
#[test]
fn inputs_in_two_crss_or_named_twice_are_refused() {
    let (Some(topo), Some(hay)) = (
        shared("las/Topography.las"),
        shared("las/Haystack_Rock.las"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("multi");
    let err = refused(
        &[
            "process",
            s(&topo),
            s(&hay),
            "-o",
            &format!("{}/", out.display()),
            "--raster",
            "2m",
        ],
        &["in another CRS", "EPSG:3645", "EPSG:2949", "Reproject"],
    );
    assert!(err.contains("Haystack_Rock.las"), "{err}");
    let into = format!("{}/", out.display());
    let process_two = |a: &Path, b: &Path| ["process", s(a), s(b), "-o", &into].map(String::from);
    // Without rasters too: the curvature of one scene would take points of two maps.
    let says = ["in another CRS", "one scene", "process each file apart"];
    refused(&process_two(&topo, &hay), &says);
    // The same file under another name (a link) would count its points twice.
    let link = dir.path().join("link.las");
    std::os::unix::fs::symlink(&topo, &link).expect("symlink");
    refused(&process_two(&topo, &link), &["named twice", "link.las"]);
    // A hard link is the same file under another name too (made of a copy: a hard link
    // cannot cross from the shared data's file system).
    let copy = dir.path().join("copy.las");
    let hard = dir.path().join("hard.las");
    std::fs::copy(&topo, &copy).expect("copy");
    std::fs::hard_link(&copy, &hard).expect("hard link");
    refused(
        &process_two(&copy, &hard),
        &["hard.las is named twice (also as"],
    );
    std::fs::remove_file(&copy).expect("copy removed");
    std::fs::remove_file(&hard).expect("hard link removed");
    std::fs::remove_file(&link).expect("link removed");
    let r = dir.path().join("r");
    refused(&raster_z(&topo, &hay, &r), &["in another CRS"]);
    refused(&raster_z(&topo, &topo, &r), &["named twice"]);
    assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));
}

/// Two surveys of one place whose CRSs cannot be compared (autzen's user-defined GeoTIFF keys
/// and its LAS 1.4 copy's WKT without an EPSG code) are processed as one scene, with a warning
/// that names both CRSs; files in different units are refused with both units named.
#[test]
fn undecided_crss_are_warned_about_and_other_units_refused() {
    let (Some(keys), Some(wkt), Some(metres), Some(none)) = (
        shared("las/autzen_trim.las"),
        shared("las/autzen_trim_7.las"),
        shared("las/Megaplot.las"),
        shared("las/extrabytes.las"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = format!("{}/", dir.path().join("both").display());
    let run = tilecurv(&["process", s(&keys), s(&wkt), "-o", &out, "-k", "10"]);
    let log = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{log}");
    let warning = "has the CRS user-defined, from the input's GeoTIFF keys and";
    assert!(log.contains(warning), "{log}");
    assert!(
        log.contains(
            "NAD_1983_HARN_Lambert_Conformal_Conic (the input's WKT, which names no EPSG code)"
        ),
        "{log}"
    );
    assert_eq!(
        listing(&dir.path().join("both")),
        ["autzen_trim.las", "autzen_trim_7.las"]
    );
    let other = dir.path().join("other");
    let args = [
        "process",
        s(&metres),
        s(&none),
        "-o",
        &format!("{}/", other.display()),
    ];
    refused(
        &args,
        &["different horizontal units (m and no length unit)"],
    );
    assert!(!other.exists());
}

/// A grid that would be all but empty (a file without a CRS, 4,400 km from the other's points)
/// is refused by the declared bounds, with the grid's size and what to check; the file without
/// a CRS is warned about first.
#[test]
fn an_all_but_empty_grid_is_refused() {
    let (Some(topo), Some(other)) = (shared("las/Topography.las"), shared("las/extrabytes.las"))
    else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let r = dir.path().join("r");
    let err = refused(
        &raster_z(&topo, &other, &r),
        &["almost all empty", "share a CRS", "larger --cell"],
    );
    assert!(err.contains("has no CRS"), "{err}");
    assert!(!r.exists());
}

/// `process --raster-stat` without `--raster` is refused (it would be ignored), and `--stat`,
/// `tilecurv raster`'s name for it, is the same option: the rasters are byte for byte those of
/// `--raster-stat`.
#[test]
fn the_raster_statistic_needs_a_raster_and_answers_to_stat() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("t.laz");
    let alone = [
        "process",
        s(&input),
        "-o",
        s(&out),
        "--raster-stat",
        "median",
    ];
    let out_run = tilecurv(&alone);
    let err = String::from_utf8_lossy(&out_run.stderr);
    assert_eq!(out_run.status.code(), Some(2), "{err}");
    assert!(err.contains("--raster <CELL>"), "{err}");
    assert!(listing(dir.path()).is_empty());
    let mut rasters = Vec::new();
    // The third run takes the default, mean: the median must have been used, not ignored.
    for (i, option) in ["--raster-stat", "--stat", "--raster-stat"]
        .into_iter()
        .enumerate()
    {
        let out = dir.path().join(format!("t{i}.laz"));
        let run = tilecurv(&[
            "process",
            s(&input),
            "-o",
            s(&out),
            "-k",
            "10",
            "--raster",
            "5m",
            option,
            if i < 2 { "median" } else { "mean" },
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let h = std::fs::read(dir.path().join(format!("t{i}.rasters/H.tif"))).expect("H.tif");
        rasters.push(h);
    }
    assert!(rasters[0] == rasters[1], "--stat and --raster-stat differ");
    assert!(
        rasters[0] != rasters[2],
        "the median rasters equal the mean's"
    );
}

/// An ASCII PLY of a 20 x 20 grid (1 unit apart, z = 0) whose further float properties are
/// named `names` and hold the values `values` on every point.
fn ply_with(path: &Path, names: &[&str], values: &[f32]) {
    let mut t = String::from("ply\nformat ascii 1.0\nelement vertex 400\n");
    for p in ["x", "y", "z"].iter().chain(names) {
        t.push_str(&format!("property float {p}\n"));
    }
    t.push_str("end_header\n");
    for i in 0..400 {
        let v: Vec<String> = values.iter().map(f32::to_string).collect();
        t.push_str(&format!("{} {} 0 {}\n", i % 20, i / 20, v.join(" ")));
    }
    std::fs::write(path, t).expect("writes the PLY");
}

/// A column whose name cannot name its raster file (a path, the point count's file, another
/// column's file on a file system that ignores case) is refused before a point is read, and
/// nothing is written, beside the directory or in it; a column named exactly as asked is taken
/// over one whose name differs only in case.
#[test]
fn columns_that_cannot_name_their_raster_files_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let ply = dir.path().join("names.ply");
    ply_with(
        &ply,
        &["../evil", "PointCount", "h", "H"],
        &[1.0, 2.0, 7.0, 8.0],
    );
    let out = dir.path().join("r").join("");
    let run = |cols: &str| -> Vec<String> {
        [
            "raster",
            s(&ply),
            "--cell",
            "2",
            "--columns",
            cols,
            "-o",
            s(&out),
        ]
        .map(String::from)
        .to_vec()
    };
    refused(&run("../evil"), &["\"../evil\"", "path separator"]);
    refused(
        &run("z,PointCount"),
        &["\"PointCount\"", "holds the point count"],
    );
    refused(&run("H,h"), &["\"h\"", "H is rastered to the same file"]);
    assert_eq!(listing(dir.path()), ["names.ply"]);
    // H (8), not h (7): its raster is that of a file where H is the only such column.
    let only = dir.path().join("only.ply");
    ply_with(&only, &["H"], &[8.0]);
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (input, to) in [(&ply, &a), (&only, &b)] {
        let o = tilecurv(&[
            "raster",
            s(input),
            "--cell",
            "2",
            "--columns",
            "H",
            "-o",
            s(to),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let read = |d: &Path| std::fs::read(d.join("H.tif")).expect("H.tif");
    assert!(read(&a) == read(&b), "the raster of H is not that of H");
}
