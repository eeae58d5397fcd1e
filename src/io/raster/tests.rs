//! The rasterizer's two ways of tallying give the same rasters; what its summary says.

use super::*;
use crate::core::rng::Rng;

/// The rasters are the same bytes whether the integer columns are tallied as the points
/// come (dense points), with the table spilled or not, or kept with the points and
/// tallied at the end (sparse points): GeoTIFFs and PNGs, for each statistic.
#[test]
fn tallies_as_points_come_or_at_the_end_give_the_same_rasters() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let column = |name: &str, integers| RasterColumn {
        name: name.into(),
        unit: String::new(),
        signed: true,
        angle: false,
        scale: None,
        integers,
    };
    let columns = vec![
        column(
            "A",
            Some(Integers {
                scale: 1e-3,
                offset: 0.0,
            }),
        ),
        column("B", None),
        column(
            "C",
            Some(Integers {
                scale: -0.5,
                offset: 3.0,
            }),
        ),
    ];
    let crs = geokeys::raster_crs(std::iter::empty(), false);
    for stat in [Stat::Mean, Stat::Min, Stat::Max, Stat::Count] {
        // (area, budget, whether tallied as the points come)
        let runs = [
            (Some(1.0), 1u64 << 30, true),
            (Some(1.0), 1 << 16, true),
            (Some(1e9), 1 << 30, false),
        ];
        let mut first: Option<Vec<Vec<u8>>> = None;
        for (i, (area, budget, dense)) in runs.into_iter().enumerate() {
            let dir = tmp.path().join(format!("{stat}{i}"));
            let request = RasterRequest {
                cell: 1.0,
                unit: "m".into(),
                stat,
                dir: dir.clone(),
                columns: columns.clone(),
            };
            let mut r = Rasterizer::new(request, &dir.join(".runs"), budget, (6000, area));
            assert_eq!(r.sums.is_some(), dense);
            let mut rng = Rng::new(7);
            for p in 0..6000 {
                let (x, y) = (rng.uniform() * 60.0 - 7.0, rng.uniform() * 40.0 + 3.0);
                let int = |rng: &mut Rng| match rng.uniform() < 0.1 {
                    true => UNDEFINED,
                    false => (rng.uniform() * 4e9 - 2e9) as i64,
                };
                let a = int(&mut rng);
                let c = -int(&mut rng).clamp(-30_000, 30_000);
                let b = if p % 7 == 0 {
                    f32::NAN
                } else {
                    rng.uniform() as f32
                };
                let z = Rasterizer::z_integer(rng.uniform() * 10.0);
                r.push(x, y, (&[b], &[a, c, z]), &|| "test".into())
                    .expect("push");
            }
            r.finish(&crs, &AtomicBool::new(false)).expect("finish");
            let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
                .expect("dir")
                .map(|e| e.expect("entry").path())
                .collect();
            names.sort();
            assert_eq!(names.len(), 8, "{names:?}");
            let bytes: Vec<Vec<u8>> = names
                .iter()
                .map(|p| std::fs::read(p).expect("read"))
                .collect();
            match &first {
                None => first = Some(bytes),
                Some(f) => assert!(*f == bytes, "{stat}: run {i} differs"),
            }
        }
    }
}

/// Cell sizes print to six significant digits with their unit (a metre in feet is not 16
/// digits long, nor 1e300 three hundred), and a grid under a quarter filled is warned about.
#[test]
fn cell_sizes_read_and_sparse_grids_are_warned_about() {
    let summary = |cell: f64, unit: &str, cells: u64| RasterSummary {
        grid: CellGrid {
            cell,
            west: 0,
            north: 0,
            width: 10,
            height: 10,
        },
        unit: unit.into(),
        points: 500,
        cells,
        files: Vec::new(),
    };
    assert_eq!(summary(1.0 / 0.3048, "ft", 50).cell_text(), "3.28084 ft");
    assert_eq!(summary(1e300, "m", 50).cell_text(), "1e300 m");
    assert_eq!(summary(0.25, "unit", 50).cell_text(), "0.25 file units");
    assert_eq!(summary(1.0, "unit", 50).cell_text(), "1 file unit");
    assert_eq!(summary(2.0, "m", 25).sparse_warning(), None);
    let w = summary(2.0, "m", 24).sparse_warning().expect("a warning");
    assert!(
        w.starts_with("only 24 of the 10x10 cells (24.0%) hold a point: cells of 2 m "),
        "{w}"
    );
    // 1 of 14600x10 cells is 0.000685%: two significant digits, not "0.0%".
    let mut tiny = summary(2.0, "m", 1);
    tiny.grid.width = 14600;
    let w = tiny.sparse_warning().expect("a warning");
    assert!(
        w.starts_with("only 1 of the 14600x10 cells (0.00068%) hold a point"),
        "{w}"
    );
}

/// GeoTIFFs in the rasters' directory that the run did not write (an earlier run's) are named
/// in a warning; the run's own files, and files of other kinds, are not.
#[test]
fn other_runs_rasters_are_warned_about() {
    let dir = tempfile::tempdir().expect("temp dir");
    let ours = ["H.tif", "H.png", "PointCount.tif"].map(|f| dir.path().join(f));
    for f in ours
        .iter()
        .chain(&[dir.path().join("Old.tif"), dir.path().join("notes.txt")])
    {
        std::fs::write(f, b"x").expect("file");
    }
    let s = RasterSummary {
        grid: CellGrid {
            cell: 1.0,
            west: 0,
            north: 0,
            width: 2,
            height: 2,
        },
        unit: "m".into(),
        points: 4,
        cells: 4,
        files: ours.to_vec(),
    };
    let w = s.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("also holds Old.tif, which this run did not write"),
        "{}",
        w[0]
    );
    std::fs::remove_file(dir.path().join("Old.tif")).expect("removed");
    assert!(s.warnings().is_empty());
}
