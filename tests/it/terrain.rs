//! The terrain columns (algorithms.md 10) against closed forms: a generated terrain whose
//! truth `generate terrain --terrain-truth` writes from the surface's derivatives p, q, r, s, t
//! (Florinsky's formulas, not the shape operator the columns come from), and the simple shapes
//! of algorithms.md 10.4 seen from above: a sphere (profile = tangential = 1/R, plan = 1/rho,
//! shape index 1), a horizontal cylinder off its crest (profile 1/R, tangential 0, shape index
//! 1/2) and z = xy along y = 0 (profile = tangential = 0).

use std::path::Path;

use crate::common::{column, process, tilecurv_as_given, write_las};
use crate::kit::synthetic::{sample_height_field, HeightField, HeightJet};
use tilecurv::core::terrain::TerrainValues;

/// The median of `v` (NaN when empty).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The points of `out` whose TerrainFlags are 0 and that `keep` selects, with the named columns.
fn defined(out: &Path, names: &[&str], keep: impl Fn(usize) -> bool) -> Vec<Vec<f64>> {
    let flags = column(out, "TerrainFlags");
    let cols: Vec<Vec<f64>> = names.iter().map(|c| column(out, c)).collect();
    let rows: Vec<usize> = (0..flags.len())
        .filter(|&i| flags[i] == 0.0 && keep(i))
        .collect();
    cols.iter()
        .map(|c| rows.iter().map(|&i| c[i]).collect())
        .collect()
}

#[test]
fn generated_terrain_matches_florinskys_closed_forms() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    let gen = tilecurv_as_given(&[
        "generate",
        "terrain",
        "--points",
        "150k",
        "--density",
        "8",
        "--seed",
        "5",
        "--terrain-truth",
        "-q",
        "-o",
        input.to_str().expect("utf-8"),
    ]);
    assert!(
        gen.status.success(),
        "{}",
        String::from_utf8_lossy(&gen.stderr)
    );
    let out = dir.path().join("out.las");
    process(
        &input,
        &out,
        &["-k", "30", "--columns", "k1,k2,flags,terrain"],
    );
    let slope = column(&out, "TrueSlope");
    // Where the closed form is well conditioned and the estimate is defined: slope above 3
    // degrees, as the comparison with WhiteboxTools.
    let steep = |i: usize| slope[i] > 3.0;
    let names = [
        "ProfileCurvature",
        "TangentialCurvature",
        "PlanCurvature",
        "ShapeIndex",
        "Curvedness",
        "Slope",
        "Aspect",
    ];
    let truth: Vec<String> = names.iter().map(|n| format!("True{n}")).collect();
    let mut all: Vec<&str> = names.to_vec();
    all.extend(truth.iter().map(String::as_str));
    let c = defined(&out, &all, steep);
    assert!(c[0].len() > 50_000, "{} steep defined points", c[0].len());
    // Median |error| / median |truth|. Measured: profile 0.071, tangential 0.057, plan 0.058,
    // curvedness 0.034 (the numpy figures at -k 30 on a like terrain: 0.049-0.054); the
    // bounds leave 40% for another seed.
    let rel = |j: usize| {
        let e: Vec<f64> = c[j]
            .iter()
            .zip(&c[j + 7])
            .map(|(v, t)| (v - t).abs())
            .collect();
        median(e) / median(c[j + 7].iter().map(|t| t.abs()).collect())
    };
    let abs = |j: usize, period: f64| {
        median(
            c[j].iter()
                .zip(&c[j + 7])
                .map(|(v, t)| {
                    let d = (v - t).abs();
                    if period > 0.0 {
                        d.min(period - d)
                    } else {
                        d
                    }
                })
                .collect(),
        )
    };
    let (kv, kh, kp, cv) = (rel(0), rel(1), rel(2), rel(4));
    let (si, slope_err, aspect_err) = (abs(3, 0.0), abs(5, 0.0), abs(6, 360.0));
    eprintln!("terrain -k 30, median relative error: profile {kv:.3} tangential {kh:.3} plan {kp:.3} curvedness {cv:.3}; median absolute: shape index {si:.4} slope {slope_err:.4} deg aspect {aspect_err:.3} deg");
    assert!(
        kv < 0.1 && kh < 0.08 && kp < 0.08,
        "profile {kv} tangential {kh} plan {kp}"
    );
    assert!(cv < 0.05, "curvedness {cv}");
    // Measured 0.017 (the issue: 0.031 per point at -k 30).
    assert!(si < 0.03, "shape index {si}");
    // A normal off by e radians moves the slope by e and the aspect by e / sin(slope).
    assert!(
        slope_err < 0.03 && aspect_err < 0.2,
        "slope {slope_err} aspect {aspect_err}"
    );

    // The flat flag: exactly the points under 0.1 degree, and their slope-line columns no-data.
    let (flags, est_slope, profile) = (
        column(&out, "TerrainFlags"),
        column(&out, "Slope"),
        column(&out, "ProfileCurvature"),
    );
    for i in 0..flags.len() {
        let flat = flags[i] as u8 & 1 != 0;
        // Slope is stored at 90/32767 degrees: within 0.0014 of the value compared with 0.1.
        let s = est_slope[i];
        assert!(
            (s > 0.1 - 0.0014 || flat) && (s < 0.1 + 0.0014 || !flat),
            "point {i}: slope {s}, flags {}",
            flags[i]
        );
        // No-data exactly where the slope line (1) or the curvature (2) is undefined.
        let undefined = flags[i] as u8 & 3 != 0;
        assert_eq!(
            undefined,
            profile[i].is_nan(),
            "point {i}: flags {}",
            flags[i]
        );
    }
    // Profile + tangential = k1 + k2 (algorithms.md 10.2), to the quantisation of the columns.
    let (k1, k2, kh_all) = (
        column(&out, "k1"),
        column(&out, "k2"),
        column(&out, "TangentialCurvature"),
    );
    let step = (1..k1.len())
        .map(|i| (k1[i] - k1[i - 1]).abs())
        .filter(|d| *d > 0.0)
        .fold(1.0, f64::min);
    for i in (0..flags.len()).filter(|&i| flags[i] == 0.0) {
        let gap = (profile[i] + kh_all[i] - k1[i] - k2[i]).abs();
        assert!(
            gap <= 2.0 * step + 1e-12,
            "point {i}: profile + tangential - k1 - k2 = {gap}"
        );
    }
}

/// z = sqrt(R^2 - x^2 - y^2): the top of a sphere.
struct Dome(f64);

impl HeightField for Dome {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        let r2 = self.0 * self.0;
        let f = (r2 - x * x - y * y).sqrt();
        let f3 = f * f * f;
        HeightJet {
            h: f,
            hx: -x / f,
            hy: -y / f,
            hxx: -(r2 - y * y) / f3,
            hxy: -x * y / f3,
            hyy: -(r2 - x * x) / f3,
        }
    }
}

/// z = sqrt(R^2 - x^2): a horizontal cylinder with its axis along y.
struct Barrel(f64);

impl HeightField for Barrel {
    fn jet(&self, x: f64, _y: f64) -> HeightJet {
        let r2 = self.0 * self.0;
        let f = (r2 - x * x).sqrt();
        HeightJet {
            h: f,
            hx: -x / f,
            hy: 0.0,
            hxx: -r2 / (f * f * f),
            hxy: 0.0,
            hyy: 0.0,
        }
    }
}

/// z = x y.
struct Monkey;

impl HeightField for Monkey {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        HeightJet {
            h: x * y,
            hx: y,
            hy: x,
            hxx: 0.0,
            hxy: 1.0,
            hyy: 0.0,
        }
    }
}

/// Samples `f` on a jittered 141 x 141 grid over [-w, w]^2 with its exact normals in the file,
/// runs `process -k 30 --columns terrain`, and returns x, y and the chosen columns of the
/// points at least 0.2 w inside the edge.
fn run_shape(f: &impl HeightField, w: f64, names: &[&str]) -> (Vec<[f64; 2]>, Vec<Vec<f64>>) {
    let dir = tempfile::tempdir().expect("temp dir");
    let cloud = sample_height_field(f, w, 141, 0.5, 3);
    let input = dir.path().join("shape.las");
    write_las(&input, &cloud.positions, Some(&cloud.normals), 1e-6);
    let out = dir.path().join("shape_out.las");
    process(&input, &out, &["-k", "30", "--columns", "terrain"]);
    let inside = |i: usize| cloud.positions[i][..2].iter().all(|c| c.abs() < 0.8 * w);
    let flags = column(&out, "TerrainFlags");
    let rows: Vec<usize> = (0..flags.len())
        .filter(|&i| inside(i) && flags[i] == 0.0)
        .collect();
    let cols = names
        .iter()
        .map(|n| {
            let c = column(&out, n);
            rows.iter().map(|&i| c[i]).collect()
        })
        .collect();
    (
        rows.iter()
            .map(|&i| [cloud.positions[i][0], cloud.positions[i][1]])
            .collect(),
        cols,
    )
}

/// The largest |v - want(x, y)| over the points.
fn worst(xy: &[[f64; 2]], v: &[f64], want: impl Fn([f64; 2]) -> f64) -> f64 {
    xy.iter()
        .zip(v)
        .map(|(p, v)| (v - want(*p)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_sphere_seen_from_above() {
    let r = 5.0;
    let (xy, c) = run_shape(
        &Dome(r),
        2.0,
        &[
            "ProfileCurvature",
            "TangentialCurvature",
            "PlanCurvature",
            "ShapeIndex",
        ],
    );
    assert!(xy.len() > 10_000);
    // Exact normals on a sphere: CNC is exact up to the averaging of Avg-Hexagram (13.8) and
    // the 1e-6 coordinates; 1% of 1/R.
    let (kv, kh) = (
        worst(&xy, &c[0], |_| 1.0 / r),
        worst(&xy, &c[1], |_| 1.0 / r),
    );
    let off_top: Vec<usize> = (0..xy.len())
        .filter(|&i| xy[i][0].hypot(xy[i][1]) > 0.5)
        .collect();
    let kp = off_top
        .iter()
        .map(|&i| (c[2][i] * xy[i][0].hypot(xy[i][1]) - 1.0).abs())
        .fold(0.0, f64::max);
    let si = worst(&xy, &c[3], |_| 1.0);
    eprintln!("sphere R=5 from above: worst profile {kv:.2e} tangential {kh:.2e} (1/R = 0.2), plan x rho - 1 {kp:.2e}, shape index {si:.2e}");
    // Measured 2.5e-3 and 3.7e-3, against |k| ~ 1 there.
    assert!(kv < 0.006 && kh < 0.006, "profile {kv} tangential {kh}");
    assert!(kp < 0.01, "plan curvature off 1/rho by {kp} relative");
    assert!(si < 0.05, "shape index off 1 by {si}");
}

#[test]
fn a_horizontal_cylinder_off_its_crest() {
    let r = 3.0;
    let (xy, c) = run_shape(
        &Barrel(r),
        2.0,
        &[
            "ProfileCurvature",
            "TangentialCurvature",
            "ShapeIndex",
            "Aspect",
        ],
    );
    let off: Vec<usize> = (0..xy.len()).filter(|&i| xy[i][0].abs() > 0.3).collect();
    assert!(off.len() > 8_000);
    let pick = |j: usize| off.iter().map(|&i| c[j][i]).collect::<Vec<f64>>();
    let pts: Vec<[f64; 2]> = off.iter().map(|&i| xy[i]).collect();
    let (kv, kh, si) = (
        worst(&pts, &pick(0), |_| 1.0 / r),
        worst(&pts, &pick(1), |_| 0.0),
        worst(&pts, &pick(2), |_| 0.5),
    );
    let aspect = worst(&pts, &pick(3), |p| if p[0] > 0.0 { 90.0 } else { 270.0 });
    eprintln!("cylinder R=3 off the crest: worst profile {kv:.2e} (1/R = 0.333), tangential {kh:.2e}, shape index {si:.2e}, aspect {aspect:.2e} deg");
    assert!(kv < 0.004 && kh < 0.004, "profile {kv} tangential {kh}");
    assert!(si < 0.01, "shape index off 1/2 by {si}");
    assert!(aspect < 0.05, "aspect off east/west by {aspect} degrees");
}

#[test]
fn a_saddle_along_its_straight_line() {
    let (xy, c) = run_shape(&Monkey, 1.0, &["ProfileCurvature", "TangentialCurvature"]);
    let line: Vec<usize> = (0..xy.len())
        .filter(|&i| xy[i][1].abs() < 0.01 && xy[i][0].abs() > 0.2)
        .collect();
    assert!(line.len() > 50, "{} points near y = 0", line.len());
    // The closed forms at each point (near, not on, the line y = 0).
    let truth = |i: usize| TerrainValues::from_derivatives(xy[i][1], xy[i][0], 0.0, 1.0, 0.0);
    let kv = line
        .iter()
        .map(|&i| (c[0][i] - truth(i).profile).abs())
        .fold(0.0, f64::max);
    let kh = line
        .iter()
        .map(|&i| (c[1][i] - truth(i).tangential).abs())
        .fold(0.0, f64::max);
    let near = line
        .iter()
        .map(|&i| truth(i).profile.abs())
        .fold(0.0, f64::max);
    eprintln!("z = xy near y = 0: worst profile error {kv:.2e}, tangential {kh:.2e} (their closed forms reach {near:.2e} there; k = -+1/(1 + x^2))");
    assert!(kv < 0.04 && kh < 0.04, "profile {kv} tangential {kh}");
}
