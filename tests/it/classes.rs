//! Class filters: points outside `--classes`, inside `--skip-classes` (the
//! noise classes 7 and 18 by default) or withheld with `--skip-withheld` are left out of every
//! neighbourhood and written with NaN values and flag 128. The independent truth: the selected
//! points' columns equal those of a run on a file holding only those points (written by laspy).

use std::path::Path;

use crate::common::{column_bytes, laspy_available, process, tilecurv};

/// Writes, from a generated terrain, `all` (10% of the points lifted 0.4 m as class 7 noise, 5%
/// of the rest withheld) and `subsets` (each a filter name and the file of its selected points).
fn classed_terrain(dir: &Path) {
    crate::common::generate_terrain(&dir.join("terrain.las"), "20000", 0, 10.0);
    let script = format!(
        r#"
import laspy, numpy as np
d = {dir:?}
f = laspy.read(d + "/terrain.las")
rng = np.random.default_rng(7)
n = len(f.points)
noise = rng.random(n) < 0.10
held = (~noise) & (rng.random(n) < 0.05)
cls = np.full(n, 2, dtype=np.uint8); cls[noise] = 7
f.classification = cls
f.z = np.asarray(f.z) + np.where(noise, 0.4, 0.0)
f.withheld = held.astype(np.uint8)
f.write(d + "/all.las")
for name, keep in [("default", ~noise), ("no_withheld", (~noise) & (~held)), ("noise", noise)]:
    g = laspy.LasData(f.header)
    g.points = f.points[keep]
    g.write(d + "/" + name + ".las")
    np.save(d + "/" + name + ".npy", np.nonzero(keep)[0])
"#,
        dir = dir.to_str().expect("utf-8"),
    );
    crate::interop::laspy(&script, &[]);
}

/// The indices saved by [`classed_terrain`] (numpy's .npy of int64).
fn indices(path: &Path) -> Vec<usize> {
    let b = std::fs::read(path).expect("npy");
    let header = u16::from_le_bytes([b[8], b[9]]) as usize;
    b[10 + header..]
        .chunks_exact(8)
        .map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes")) as usize)
        .collect()
}

/// The per-point raw bytes of column `name` in `out` (its size from the file: i16 normals,
/// i32 curvatures by default).
fn values(out: &Path, name: &str) -> Vec<Vec<u8>> {
    let bytes = column_bytes(out, name);
    let n = column_bytes(out, "CurvatureFlags").len();
    bytes
        .chunks_exact(bytes.len() / n)
        .map(|c| c.to_vec())
        .collect()
}

#[test]
fn filtered_points_are_left_out_of_every_neighbourhood() {
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    classed_terrain(dir.path());
    let all = dir.path().join("all.las");
    for (name, args) in [
        ("default", &[][..]),
        ("no_withheld", &["--skip-withheld"][..]),
        ("noise", &["--classes", "7", "--skip-classes", "none"][..]),
    ] {
        let out = dir.path().join(format!("out_all_{name}.las"));
        process(&all, &out, args);
        let sub_out = dir.path().join(format!("out_{name}.las"));
        // The subset holds only selected points; the noise subset is all class 7, which the
        // default would skip.
        let sub_args: &[&str] = if name == "noise" {
            &["--skip-classes", "none"]
        } else {
            &[]
        };
        process(&dir.path().join(format!("{name}.las")), &sub_out, sub_args);
        let keep = indices(&dir.path().join(format!("{name}.npy")));
        let flags = values(&out, "CurvatureFlags");
        let mut selected = vec![false; flags.len()];
        for &i in &keep {
            selected[i] = true;
        }
        for (i, f) in flags.iter().enumerate() {
            assert_eq!(
                f[0] & 128 != 0,
                !selected[i],
                "{name}: point {i} flags {}",
                f[0]
            );
        }
        for col in ["H", "K", "k1", "k2", "NormalX", "NormalZ", "CurvatureFlags"] {
            let (a, b) = (values(&out, col), values(&sub_out, col));
            assert_eq!(keep.len(), b.len());
            for (j, &i) in keep.iter().enumerate() {
                assert_eq!(a[i], b[j], "{name}: {col} of point {i}");
            }
            if col == "H" {
                let h = crate::common::column(&out, "H");
                for i in (0..a.len()).filter(|&i| !selected[i]) {
                    assert!(
                        h[i].is_nan(),
                        "{name}: point {i} not selected but H {}",
                        h[i]
                    );
                }
            }
        }
    }
    // With every class computed, the lifted noise bends the ground's curvature: the filter
    // is what made the columns above equal.
    let out = dir.path().join("out_everything.las");
    process(&all, &out, &["--skip-classes", "none"]);
    let keep = indices(&dir.path().join("default.npy"));
    let (a, b) = (
        values(&out, "H"),
        values(&dir.path().join("out_default.las"), "H"),
    );
    let differ = keep
        .iter()
        .enumerate()
        .filter(|(j, &i)| a[i] != b[*j])
        .count();
    assert!(
        differ > keep.len() / 4,
        "only {differ} of {} differ",
        keep.len()
    );
}

/// A class filter on an input without classes is a usage error naming the file.
#[test]
fn a_class_filter_needs_las_classes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let xyz = dir.path().join("p.xyz");
    std::fs::write(&xyz, "0 0 0\n1 0 0\n0 1 0\n1 1 1\n").expect("write");
    let out = dir.path().join("o.las");
    let r = tilecurv(&[
        "process",
        xyz.to_str().expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
        "--classes",
        "2",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("p.xyz") && err.contains("no LAS classes"),
        "{err}"
    );
    assert!(!out.exists());
}
