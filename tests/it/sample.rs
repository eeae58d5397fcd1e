//! The shipped sample (data/Haystack_Rock.las, aerial LIDAR) gives a plausible result: normals
//! point up, curvature is finite on at least 99% of the points, and the undefined ones say so.

use crate::common::{column, process, root};

#[test]
fn haystack_rock_is_plausible() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("hay.laz");
    process(&root().join("data/Haystack_Rock.las"), &out, &[]);
    let nz = column(&out, "NormalZ");
    let h = column(&out, "H");
    let k = column(&out, "K");
    let flags = column(&out, "CurvatureFlags");
    let n = h.len() as f64;
    let defined = nz.iter().filter(|v| v.is_finite()).count();
    assert!(
        nz.iter().filter(|v| v.is_finite()).all(|&z| z >= 0.0),
        "--orient up gives upward normals"
    );
    let finite = h
        .iter()
        .zip(&k)
        .filter(|(h, k)| h.is_finite() && k.is_finite())
        .count() as f64;
    assert!(
        finite / n >= 0.99,
        "finite curvature on {:.2}% of the points",
        100.0 * finite / n
    );
    assert!(defined as f64 / n >= 0.99);
    for (i, (&hv, &f)) in h.iter().zip(&flags).enumerate() {
        assert_eq!(
            hv.is_nan(),
            (f as u8) & 7 != 0,
            "point {i}: NaN exactly when flagged undefined"
        );
    }
}
