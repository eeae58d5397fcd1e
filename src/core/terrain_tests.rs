//! Tests of terrain.rs: the shape-operator route against Florinsky's closed forms, and the
//! simple shapes of algorithms.md 10.4.

use super::*;
use crate::core::estimate::{flags, Curvature};
use crate::core::rng::Rng;
use crate::core::surface::height_field_curvature;

/// The estimator-side input of a height field's point: the upward normal and the exact
/// curvature (principal directions from the level set, algorithms.md 13.3).
fn exact(p: f64, q: f64, r: f64, s: f64, t: f64) -> (V3, Curvature) {
    let w = (1.0 + p * p + q * q).sqrt();
    let c = height_field_curvature(p, q, r, s, t);
    let (d1, d2) = c.directions.unwrap_or(([0.0; 3], [0.0; 3]));
    let curvature = Curvature {
        h: c.h,
        k: c.k,
        k1: c.k1,
        k2: c.k2,
        d1,
        d2,
        flags: 0,
    };
    ([-p / w, -q / w, 1.0 / w], curvature)
}

fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!(
        (a.is_nan() && b.is_nan()) || (a - b).abs() <= tol * (1.0 + b.abs()),
        "{what}: {a} against {b}"
    );
}

fn same(a: &TerrainValues, b: &TerrainValues, tol: f64) {
    close(a.profile, b.profile, tol, "profile");
    close(a.tangential, b.tangential, tol, "tangential");
    close(a.plan, b.plan, tol, "plan");
    close(a.shape_index, b.shape_index, tol, "shape index");
    close(a.curvedness, b.curvedness, tol, "curvedness");
    close(a.slope_deg, b.slope_deg, tol, "slope");
    close(a.aspect_deg, b.aspect_deg, tol, "aspect");
    assert_eq!(a.flags, b.flags);
}

#[test]
fn the_shape_operator_route_matches_the_closed_forms() {
    let mut rng = Rng::new(27);
    let mut u = |a: f64| a * (2.0 * rng.uniform() - 1.0);
    for _ in 0..2000 {
        let (p, q, r, s, t) = (u(1.5), u(1.5), u(0.3), u(0.3), u(0.3));
        let (n, c) = exact(p, q, r, s, t);
        let want = TerrainValues::from_derivatives(p, q, r, s, t);
        let got = TerrainValues::of(n, &c);
        if want.slope_deg < 2.0 * FLAT_SLOPE_DEG {
            continue;
        }
        same(&got, &want, 1e-9);
        close(
            got.profile + got.tangential,
            2.0 * c.h,
            1e-9,
            "kv + kh = 2H",
        );
    }
}

#[test]
fn a_flipped_normal_gives_the_same_values() {
    let (n, c) = exact(0.3, -0.2, 0.05, -0.02, 0.01);
    let up = TerrainValues::of(n, &c);
    let down = TerrainValues::of(n.map(|v| -v), &c.flipped());
    assert_eq!(up, down);
}

#[test]
fn a_sphere_seen_from_above() {
    // z = sqrt(R^2 - x^2 - y^2): profile = tangential = 1/R, plan = 1/rho, a dome.
    let radius: f64 = 10.0;
    for &(x, y) in &[(3.0f64, 0.0f64), (-2.0, 5.0), (4.0, 4.0), (0.5, -7.0)] {
        let f: f64 = (radius * radius - x * x - y * y).sqrt();
        let f3 = f * f * f;
        let (p, q) = (-x / f, -y / f);
        let (r, s, t) = (
            -(radius * radius - y * y) / f3,
            -x * y / f3,
            -(radius * radius - x * x) / f3,
        );
        let v = TerrainValues::from_derivatives(p, q, r, s, t);
        close(v.profile, 1.0 / radius, 1e-12, "profile");
        close(v.tangential, 1.0 / radius, 1e-12, "tangential");
        close(v.plan, 1.0 / x.hypot(y), 1e-12, "plan");
        // An umbilic: M = sqrt(H^2 - K) carries the rounding of H^2 - K, about 1e-8 of H.
        close(v.shape_index, 1.0, 1e-7, "shape index");
        close(v.curvedness, 1.0 / radius, 1e-12, "curvedness");
        // Downslope points away from the top: the azimuth of (x, y).
        close(v.aspect_deg, azimuth_deg(x.atan2(y)), 1e-12, "aspect");
        let (n, c) = exact(p, q, r, s, t);
        let got = TerrainValues::of(n, &c);
        close(
            got.profile,
            1.0 / radius,
            1e-9,
            "profile from k1, k2, d1, d2",
        );
        close(
            got.tangential,
            1.0 / radius,
            1e-9,
            "tangential from k1, k2, d1, d2",
        );
    }
}

#[test]
fn a_horizontal_cylinder_off_its_crest() {
    // z = sqrt(R^2 - x^2), axis along y: profile 1/R, tangential 0, shape index 1/2.
    let radius: f64 = 4.0;
    for &x in &[1.0f64, -2.5, 3.0] {
        let f: f64 = (radius * radius - x * x).sqrt();
        let (p, r) = (-x / f, -radius * radius / (f * f * f));
        let want = TerrainValues::from_derivatives(p, 0.0, r, 0.0, 0.0);
        close(want.profile, 1.0 / radius, 1e-12, "profile");
        close(want.tangential, 0.0, 1e-12, "tangential");
        close(want.shape_index, 0.5, 1e-12, "shape index");
        close(
            want.aspect_deg,
            if x > 0.0 { 90.0 } else { 270.0 },
            1e-12,
            "aspect",
        );
        let (n, c) = exact(p, 0.0, r, 0.0, 0.0);
        same(&TerrainValues::of(n, &c), &want, 1e-9);
    }
}

#[test]
fn a_saddle_along_its_straight_line() {
    // z = xy at (x0, 0): p = 0, q = x0, s = 1: profile = tangential = 0 (the slope line and
    // the contour are the surface's asymptotic directions there).
    for &x0 in &[0.5, -1.0, 2.0] {
        let want = TerrainValues::from_derivatives(0.0, x0, 0.0, 1.0, 0.0);
        close(want.profile, 0.0, 1e-12, "profile");
        close(want.tangential, 0.0, 1e-12, "tangential");
        close(want.shape_index, 0.0, 1e-12, "shape index");
        let (n, c) = exact(0.0, x0, 0.0, 1.0, 0.0);
        let got = TerrainValues::of(n, &c);
        close(got.profile, 0.0, 1e-9, "profile");
        close(got.tangential, 0.0, 1e-9, "tangential");
    }
}

#[test]
fn a_level_point_is_flat_and_an_undefined_curvature_says_so() {
    let (n, c) = exact(0.0, 0.0, -0.1, 0.0, -0.2);
    let v = TerrainValues::of(n, &c);
    assert_eq!(v.flags, terrain_flags::FLAT);
    assert_eq!(v.slope_deg, 0.0);
    assert!(v.profile.is_nan() && v.tangential.is_nan() && v.plan.is_nan());
    assert!(v.aspect_deg.is_nan());
    // k = (0.1, 0.2): H = 0.15, M = 0.05.
    close(
        v.shape_index,
        (2.0 / std::f64::consts::PI) * 3.0f64.atan(),
        1e-12,
        "si",
    );
    let w = TerrainValues::from_derivatives(0.0, 0.0, -0.1, 0.0, -0.2);
    same(&v, &w, 1e-12);

    let undefined = Curvature::undefined(flags::DEGENERATE);
    let v = TerrainValues::of([0.6, 0.0, 0.8], &undefined);
    assert_eq!(v.flags, terrain_flags::NO_CURVATURE);
    close(v.slope_deg, 0.75f64.atan().to_degrees(), 1e-12, "slope");
    close(v.aspect_deg, 90.0, 1e-12, "aspect of a slope falling east");
    assert!(v.profile.is_nan() && v.curvedness.is_nan() && v.shape_index.is_nan());
    let v = TerrainValues::of([f64::NAN; 3], &undefined);
    assert_eq!(
        v.flags,
        terrain_flags::NO_NORMAL | terrain_flags::NO_CURVATURE
    );
    assert!(v.slope_deg.is_nan());
}

#[test]
fn a_plane_has_no_shape_index() {
    let v = TerrainValues::from_derivatives(0.2, 0.1, 0.0, 0.0, 0.0);
    assert_eq!(v.flags, terrain_flags::PLANAR);
    assert!(v.shape_index.is_nan());
    assert_eq!(v.profile, 0.0);
    let (n, c) = exact(0.2, 0.1, 0.0, 0.0, 0.0);
    same(&TerrainValues::of(n, &c), &v, 1e-12);
}
