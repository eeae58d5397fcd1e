//! `tilecurv raster` against an independent reading: every GeoTIFF read back by rasterio
//! (GDAL), its CRS, transform and no-data value checked and every cell compared with numpy's
//! binning of the point file's column as laspy reads it (`scripts/raster_check.py`), for every
//! statistic; and the rasters' bytes unchanged by the points' order, the file's offsets and the
//! memory budget (which decides whether the binning spills sorted runs to disk).

use std::path::Path;
use std::process::Command;

use crate::common::{listing, process, root, s, shared, tilecurv, under_ci};
use crate::offsets::regrid;

/// rasterio and laspy are importable: a failure under CI=true, else a loud skip.
fn rasterio_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import rasterio, laspy, lazrs"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(
            !under_ci(),
            "python3 with rasterio, laspy and lazrs is required under CI=true"
        );
        eprintln!("SKIPPED: raster check (python3 -c 'import rasterio, laspy, lazrs' failed)");
    }
    ok
}

/// `tilecurv raster` with `args`, which must succeed.
fn raster(args: &[&str]) {
    let out = tilecurv(&[&["raster", "-q"], args].concat());
    assert!(
        out.status.success(),
        "raster {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The bytes of the GeoTIFF of `name` in the raster directory `dir`.
fn tif(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(format!("{name}.tif"))).expect("raster")
}

/// `scripts/raster_check.py` on `points` and the rasters in `dir`, which must pass; returns
/// its report.
fn check(points: &Path, dir: &Path, cell: f64, stat: &str, columns: &str) -> String {
    check_with(points, dir, (cell, stat, columns), &[])
}

/// [`check`] with more arguments to the script.
fn check_with(points: &Path, dir: &Path, what: (f64, &str, &str), more: &[&str]) -> String {
    let (cell, stat, columns) = what;
    let out = Command::new("python3")
        .arg(root().join("scripts/raster_check.py"))
        .args([points, dir])
        .args(more)
        .args([
            "--cell",
            &format!("{cell:?}"),
            "--stat",
            stat,
            "--columns",
            columns,
        ])
        .output()
        .expect("python3 runs");
    let report = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "raster check failed for {stat} {columns}: {report}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    report
}

/// A real survey (GeoTIFF keys, metres) with its curvature and terrain columns: every statistic
/// of every column equals numpy's binning, cell for cell, in the survey's EPSG code.
#[test]
fn rasters_equal_an_independent_binning_for_every_statistic() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    if !rasterio_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("topo.laz");
    process(
        &input,
        &out,
        &["--columns", "H,K,k1,k2,terrain", "-k", "20"],
    );
    let all = "H,K,k1,k2,ProfileCurvature,TangentialCurvature,PlanCurvature,ShapeIndex,Curvedness";
    let r = dir.path().join("default");
    raster(&[s(&out), "--cell", "2m", "-o", s(&r)]);
    let report = check(&out, &r, 2.0, "mean", all);
    assert!(report.contains("crs 2949"), "{report}");
    for stat in ["mean", "median", "min", "max", "count"] {
        let r = dir.path().join(stat);
        let cols = "H,Slope,Aspect,z";
        raster(&[
            s(&out),
            "--cell",
            "1.5",
            "--stat",
            stat,
            "--columns",
            cols,
            "-o",
            s(&r),
        ]);
        check(&out, &r, 1.5, stat, cols);
    }
}

/// A LAS 1.4 file in US survey feet with a WKT CRS: the cell is converted to file units and the
/// WKT becomes the EPSG code GDAL finds for it.
#[test]
fn a_wkt_crs_in_feet_becomes_its_epsg_code() {
    let Some(input) = shared("las/test1_4.las") else {
        return;
    };
    if !rasterio_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("t.las");
    process(&input, &out, &["--columns", "H,K", "-k", "10"]);
    let r = dir.path().join("r");
    raster(&[s(&out), "--cell", "3m", "-o", s(&r)]);
    let report = check(&out, &r, 3.0 / (1200.0 / 3937.0), "mean", "H,K");
    assert!(!report.contains("crs None"), "{report}");
}

/// The same points shuffled, on moved offsets, as LAZ, and binned through sorted runs on disk
/// (a 2 MiB budget) give the same GeoTIFF bytes.
#[test]
fn rasters_do_not_depend_on_order_offsets_or_memory() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    if !rasterio_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("topo.las");
    // Floats: laspy's copy keeps NaN, but drops a scaled column's declared no-data value.
    process(
        &input,
        &out,
        &["--columns", "H,K,terrain", "-k", "20", "--f32"],
    );
    let moved = dir.path().join("moved.laz");
    if !regrid(&out, &moved, [1234, -567, 89], &["--shuffle", "3"]) {
        return;
    }
    let cols = "H,ProfileCurvature,Aspect";
    let runs = [
        (out.as_path(), "base", "2G"),
        (moved.as_path(), "moved", "2G"),
        (out.as_path(), "spilled", "2M"),
    ];
    for (points, name, memory) in runs {
        let r = dir.path().join(name);
        raster(&[
            s(points),
            "--cell",
            "1m",
            "--columns",
            cols,
            "--memory",
            memory,
            "-o",
            s(&r),
        ]);
    }
    for name in ["H", "ProfileCurvature", "Aspect", "PointCount"] {
        let file = |d: &str| tif(&dir.path().join(d), name);
        let base = file("base");
        assert!(base.len() > 1000, "{name}");
        assert!(
            base == file("moved"),
            "{name}: shuffled, moved copy differs"
        );
        assert!(base == file("spilled"), "{name}: spilled binning differs");
    }
}

/// The scaled columns' rasters, whose cells tally integers in a table that spills to run files
/// past the budget, are the same bytes for the points in another order and binned within 2 MiB
/// (the table spilled many times) or 2 GiB; `process --raster` gives them too.
#[test]
fn tallied_rasters_do_not_depend_on_order_or_memory() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    if !rasterio_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let shuffled = dir.path().join("shuffled.las");
    if !regrid(&input, &shuffled, [0, 0, 0], &["--shuffle", "5"]) {
        return;
    }
    let args = ["--columns", "H,K,terrain", "-k", "20"];
    let out = dir.path().join("topo.las");
    let beside = dir.path().join("beside");
    let raster_args = ["--raster", "1m", "--raster-dir", s(&beside)];
    process(&input, &out, &[&args[..], &raster_args].concat());
    let out_shuffled = dir.path().join("shuffled_out.las");
    process(&shuffled, &out_shuffled, &args);
    let cols = "H,K,ProfileCurvature,PlanCurvature,ShapeIndex,Slope";
    let runs = [
        (out.as_path(), "base", "2G"),
        (out_shuffled.as_path(), "shuffled", "2G"),
        (out.as_path(), "spilled", "2M"),
    ];
    for (points, name, memory) in runs {
        let r = dir.path().join(name);
        let common = ["--cell", "1m", "--memory", memory, "-o", s(&r)];
        raster(&[&[s(points), "--columns", cols][..], &common].concat());
    }
    check(&out, &dir.path().join("base"), 1.0, "mean", cols);
    for name in cols.split(',').chain(["PointCount"]) {
        let file = |d: &str| tif(&dir.path().join(d), name);
        let base = file("base");
        assert!(base.len() > 1000, "{name}");
        assert!(base == file("shuffled"), "{name}: shuffled points differ");
        assert!(base == file("spilled"), "{name}: spilled tallies differ");
        if name != "Slope" {
            assert!(
                base == tif(&beside, name),
                "{name}: process --raster differs"
            );
        }
    }
}

/// The run directory a killed raster run of this host left beside the rasters is removed by
/// the next run; another host's is left alone (its run may be alive there).
#[test]
fn a_killed_runs_scratch_is_swept() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("topo.las");
    process(&input, &out, &["--columns", "H", "-k", "10"]);
    let r = dir.path().join("r");
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").expect("hostname");
    let dead = r.join(format!(
        ".raster-runs.tilecurv-{}-2147483646.tmp",
        host.trim()
    ));
    let other = r.join(".raster-runs.tilecurv-elsewhere-12.tmp");
    for d in [&dead, &other] {
        std::fs::create_dir_all(d).expect("fake leftover");
        std::fs::write(d.join("run1.bin"), [0u8; 64]).expect("fake run");
    }
    raster(&[s(&out), "--cell", "5m", "-o", s(&r)]);
    assert!(!dead.exists(), "the killed run's directory was not swept");
    assert!(other.exists(), "another host's directory was removed");
    assert!(r.join("H.tif").exists());
}

/// Bad requests are usage errors naming what to do, and leave no directory behind.
#[test]
fn a_missing_column_is_a_usage_error_that_leaves_nothing() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let r = dir.path().join("r");
    let out = tilecurv(&["raster", s(&input), "--cell", "1m", "-o", s(&r)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no curvature column") && err.contains("tilecurv process"),
        "{err}"
    );
    let out = tilecurv(&[
        "raster",
        s(&input),
        "--cell",
        "1m",
        "--columns",
        "H",
        "-o",
        s(&r),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no column \"H\"") && err.contains("intensity"),
        "{err}"
    );
    assert!(!r.exists(), "the refused runs made {}", r.display());
}

/// `process --raster` bins each point as its output is written: its rasters are those
/// `tilecurv raster` makes of the output, byte for byte, and its quick looks are PNGs.
#[test]
fn process_rasters_equal_the_rasters_of_its_output() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("topo.laz");
    let r = dir.path().join("beside");
    // z is a field of the input, the others new columns.
    let cols = "H,K,ProfileCurvature,PlanCurvature,ShapeIndex,z";
    let args = [
        "--columns",
        "H,K,terrain",
        "-k",
        "20",
        "--raster",
        "2m",
        "--raster-dir",
        s(&r),
    ];
    process(
        &input,
        &out,
        &[&args[..], &["--raster-columns", cols]].concat(),
    );
    let again = dir.path().join("again");
    raster(&[s(&out), "--cell", "2m", "-o", s(&again)]);
    let again_z = dir.path().join("again_z");
    raster(&[s(&out), "--cell", "2m", "--columns", "z", "-o", s(&again_z)]);
    let names = [
        "H",
        "K",
        "ProfileCurvature",
        "PlanCurvature",
        "ShapeIndex",
        "PointCount",
        "z",
    ];
    for name in names {
        let other = if name == "z" { &again_z } else { &again };
        assert!(
            tif(&r, name) == tif(other, name),
            "{name}: process --raster differs from raster"
        );
        let png = std::fs::read(r.join(format!("{name}.png"))).expect("quick look");
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name}.png");
    }
    assert!(!r.join("Curvedness.tif").exists(), "a column not asked for");
    let leftovers: Vec<_> = std::fs::read_dir(&r)
        .expect("dir")
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "scratch left: {leftovers:?}");
}

/// A text input's points are binned from their own records (the sources' shared way of reading
/// a batch's coordinates, not the LAS one): `process --raster` on an XYZ file gives, byte for
/// byte, the rasters `tilecurv raster` makes of its LAS output.
#[test]
fn rasters_of_a_text_input_equal_those_of_its_output() {
    let Some(input) = shared("objects/kitten.xyz") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("kitten.las");
    let r = dir.path().join("beside");
    // A cell with a unit over a file without a CRS is taken in file units, with a warning.
    let run = tilecurv(&[
        "process",
        s(&input),
        "-o",
        s(&out),
        "--raster",
        "0.5m",
        "--raster-dir",
        s(&r),
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("--raster 0.5m is taken in file units"),
        "{err}"
    );
    let again = dir.path().join("again");
    raster(&[s(&out), "--cell", "0.5", "-o", s(&again)]);
    for name in ["H", "K", "PointCount"] {
        assert!(
            tif(&r, name) == tif(&again, name),
            "{name}: process --raster of the text input differs from raster of its output"
        );
    }
}

/// Every real survey of the shared data gives rasters that GDAL reads with the survey's CRS and
/// numpy's cell means, whatever its GeoTIFF text holds (padding NULs: autzen, bcts, hexbin;
/// Latin-1: the Norwegian survey), its point format or LAS version. The WKTs of autzen_trim_7
/// and las14_pdrf6 name no EPSG code, which GeoTIFF keys need, as the run warns: autzen's
/// reaches GDAL through each raster's sidecar (NAME.tif.aux.xml), which GDAL reads as the same
/// projection; las14_pdrf6's is malformed (it closes before its vertical CRS), so its rasters
/// have no CRS and no sidecar.
#[test]
fn every_real_survey_gives_rasters_gdal_reads() {
    if !rasterio_available() {
        return;
    }
    for name in crate::real_files::FILES {
        let Some(input) = shared(&format!("las/{name}")) else {
            return;
        };
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("out.laz");
        let run = tilecurv(&[
            "process",
            s(&input),
            "-o",
            s(&out),
            "--columns",
            "H",
            "-k",
            "10",
            "--raster",
            "8",
        ]);
        let log = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{name}: {log}");
        let no_code = ["autzen_trim_7.las", "las14_pdrf6.laz"].contains(&name);
        assert_eq!(log.contains("names no EPSG code"), no_code, "{name}: {log}");
        let no_crs = name == "las14_pdrf6.laz";
        assert_eq!(
            log.contains("GDAL cannot read it either"),
            no_crs,
            "{name}: {log}"
        );
        let more: &[&str] = if no_crs { &["--no-crs"] } else { &[] };
        let rasters = dir.path().join("out.rasters");
        let sidecars = (listing(&rasters).into_iter())
            .filter(|f| f.ends_with(".tif.aux.xml"))
            .count();
        assert_eq!(
            sidecars,
            if name == "autzen_trim_7.las" { 2 } else { 0 },
            "{name}"
        );
        let report = check_with(&out, &rasters, (8.0, "mean", "H"), more);
        eprintln!("{name}: {report}");
    }
}

/// A column named in another case is the file's column, and its raster carries the file's
/// spelling (`Z` makes `z.tif`, `h` makes `H.tif`), so that one column has one file name.
#[test]
fn rasters_take_the_files_spelling_of_a_column() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("t.las");
    process(&input, &out, &["--columns", "H", "-k", "10"]);
    let r = dir.path().join("r");
    raster(&[
        s(&out),
        "--cell",
        "5m",
        "--columns",
        "Z,h,INTENSITY",
        "-o",
        s(&r),
    ]);
    let names: Vec<String> = (listing(&r).into_iter())
        .filter(|n| n.ends_with(".tif"))
        .collect();
    assert_eq!(names, ["H.tif", "PointCount.tif", "intensity.tif", "z.tif"]);
}

/// A PLY output names its columns as CloudCompare loads them (`scalar_H`): rastered, they are
/// tilecurv's columns all the same, by default and by name, the same bytes as the rasters of a
/// PLY output with the LAS names (`--ply-las-names`).
#[test]
fn a_ply_outputs_columns_are_rastered_as_tilecurvs() {
    let Some(input) = shared("las/Topography.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let (cc, las) = (dir.path().join("cc.ply"), dir.path().join("las.ply"));
    let cols = ["--columns", "H,K,flags,slope", "-k", "10"];
    process(&input, &cc, &cols);
    process(&input, &las, &[&cols[..], &["--ply-las-names"]].concat());
    for (list, want) in [
        (None, vec!["H.tif", "K.tif", "PointCount.tif"]),
        (
            Some("Slope,H"),
            vec!["H.tif", "PointCount.tif", "Slope.tif"],
        ),
    ] {
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        for (points, to) in [(&cc, &a), (&las, &b)] {
            let mut args = vec![s(points), "--cell", "5", "-o", s(to)];
            args.extend(list.iter().flat_map(|l| ["--columns", *l]));
            raster(&args);
        }
        let names: Vec<String> = (listing(&a).into_iter())
            .filter(|n| n.ends_with(".tif"))
            .collect();
        assert_eq!(names, want);
        for n in &names {
            let stem = n.trim_end_matches(".tif");
            assert!(tif(&a, stem) == tif(&b, stem), "{n}");
        }
        std::fs::remove_dir_all(&a).expect("clean");
        std::fs::remove_dir_all(&b).expect("clean");
    }
}
