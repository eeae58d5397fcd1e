//! The test kit checked against its closed forms (algorithms.md 13): the oracle of the
//! estimator tests must itself be right.

use crate::kit::synthetic::*;
use crate::kit::testkit;
use std::f64::consts::{PI, TAU};
use tilecurv::core::geometry::{cross, dot, norm, normalize, sub, FieldDerivatives, SurfacePoint};
use tilecurv::core::rng::Rng;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// The reference table of algorithms.md 13.5 (6 significant digits quoted there).
#[test]
fn goursat_reference_values() {
    let face = goursat_curvature([8.39355, 0.0, 0.0]).unwrap();
    assert!(
        close(face.h, -0.106990, 2e-6) && close(face.k, 0.0114469, 2e-7),
        "{face:?}"
    );
    assert!(face.directions.is_none() || close(face.k1, face.k2, 1e-6));
    let corner = goursat_curvature([8.24466; 3]).unwrap();
    assert!(
        close(corner.h, 0.344849, 2e-6) && close(corner.k, 0.118921, 2e-6),
        "{corner:?}"
    );
    assert!(close(corner.k1, 0.344849, 2e-6) && close(corner.k2, 0.344849, 2e-6));
    let edge = goursat_curvature([8.28312, -8.28312, 0.0]).unwrap();
    assert!(
        close(edge.k1, -0.0806645, 2e-6) && close(edge.k2, 0.417431, 2e-6),
        "{edge:?}"
    );
    assert!(close(edge.h, 0.168383, 2e-6) && close(edge.k, -0.0336718, 2e-6));
    // k1 (negative) runs along the edge (z), k2 across it.
    let (d1, d2) = edge.directions.unwrap();
    assert!(d1[2].abs() > 1.0 - 1e-9 && d2[2].abs() < 1e-9);
    // The quoted points lie on the surface (to the quoted digits).
    for p in [[8.39355, 0.0, 0.0], [8.24466; 3], [8.28312, 8.28312, 0.0]] {
        assert!(goursat_value(p).abs() < 1e-5 * norm(goursat_implicit(p).gradient));
    }
    assert!(close(norm(goursat_radial([1.0, 0.0, 0.0])), 8.393555, 1e-5));
}

/// K from the adjugate formula of algorithms.md 13.3 equals the product of the shape-operator
/// eigenvalues.
#[test]
fn implicit_matches_adjugate_formula() {
    let mut rng = Rng::new(3);
    for _ in 0..100 {
        let p = goursat_radial(unit_vector(&mut rng));
        let FieldDerivatives {
            gradient: g,
            hessian: h,
        } = goursat_implicit(p);
        let t = implicit_curvature(g, &h).unwrap();
        let adj = [cross(h[1], h[2]), cross(h[2], h[0]), cross(h[0], h[1])];
        let gag = dot(g, [dot(adj[0], g), dot(adj[1], g), dot(adj[2], g)]);
        let k = gag / dot(g, g).powi(2);
        let hs_g = [dot(h[0], g), dot(h[1], g), dot(h[2], g)];
        let hm =
            (dot(g, g) * (h[0][0] + h[1][1] + h[2][2]) - dot(g, hs_g)) / (2.0 * norm(g).powi(3));
        assert!(
            close(t.k, k, 1e-12) && close(t.h, hm, 1e-12),
            "{t:?} {k} {hm}"
        );
        assert!(t.k1 <= t.k2);
    }
}

/// Implicit and parametric torus (algorithms.md 13.4) agree, including directions, and match the
/// quoted values at the equators.
#[test]
fn torus_implicit_equals_parametric() {
    let (big_r, r) = (6.0, 2.0);
    for i in 0..37 {
        for j in 0..5 {
            let (theta, phi) = (i as f64 * 0.17 - 3.1, j as f64 * 1.3);
            let SurfacePoint {
                position: p,
                normal: n,
            } = torus_point(big_r, r, theta, phi);
            let FieldDerivatives {
                gradient: g,
                hessian: h,
            } = torus_implicit(big_r, r, p);
            assert!(dot(normalize(g).unwrap(), n) > 1.0 - 1e-12);
            let a = implicit_curvature(g, &h).unwrap();
            let b = torus_curvature(big_r, r, theta, phi);
            for (x, y) in [(a.k1, b.k1), (a.k2, b.k2), (a.h, b.h), (a.k, b.k)] {
                assert!(close(x, y, 1e-12), "theta {theta}: {a:?} {b:?}");
            }
            let ((a1, a2), (b1, b2)) = (a.directions.unwrap(), b.directions.unwrap());
            assert!(dot(a1, b1).abs() > 1.0 - 1e-9 && dot(a2, b2).abs() > 1.0 - 1e-9);
            let c = torus_curvature_at(big_r, r, p);
            assert!(close(c.h, b.h, 1e-12));
        }
    }
    let outer = torus_curvature(6.0, 2.0, 0.0, 0.0);
    let inner = torus_curvature(6.0, 2.0, PI, 0.0);
    assert!(close(outer.k1, 0.125, 1e-15) && close(outer.k2, 0.5, 1e-15));
    assert!(
        close(inner.k1, -0.25, 1e-15)
            && close(inner.h, 0.125, 1e-15)
            && close(inner.k, -0.125, 1e-15)
    );
}

/// Height-field curvature equals the explicit Monge formulas of algorithms.md 13.2 and the table
/// of algorithms.md 13.1.
#[test]
fn height_field_matches_monge_formulas() {
    let mut rng = Rng::new(5);
    for _ in 0..200 {
        let v: Vec<f64> = (0..5).map(|_| 4.0 * rng.uniform() - 2.0).collect();
        let (hx, hy, hxx, hxy, hyy) = (v[0], v[1], v[2], v[3], v[4]);
        let t = height_field_curvature(hx, hy, hxx, hxy, hyy);
        let w = 1.0 + hx * hx + hy * hy;
        let k = (hxx * hyy - hxy * hxy) / (w * w);
        let h = -((1.0 + hy * hy) * hxx - 2.0 * hx * hy * hxy + (1.0 + hx * hx) * hyy)
            / (2.0 * w.powf(1.5));
        assert!(
            close(t.k, k, 1e-12) && close(t.h, h, 1e-12),
            "{t:?} {h} {k}"
        );
        let disc = (h * h - k).max(0.0).sqrt();
        assert!(close(t.k1, h - disc, 1e-7) && close(t.k2, h + disc, 1e-7));
    }
    let s = Saddle.jet(0.0, 0.0).curvature();
    assert_eq!((s.k1, s.k2, s.h, s.k), (-1.0, 1.0, 0.0, -1.0));
    let (d1, d2) = s.directions.unwrap();
    assert!(d1[0].abs() > 1.0 - 1e-12 && d2[1].abs() > 1.0 - 1e-12);
    let a = 0.5;
    let p = Paraboloid { a };
    assert_eq!(p.jet(0.0, 0.0).curvature().h, -2.0 * a);
    let rho: f64 = 0.7;
    let t = p.jet(rho, 0.0).curvature();
    let q = 1.0 + 4.0 * a * a * rho * rho;
    assert!(
        close(t.k1, -2.0 * a / q.sqrt(), 1e-12) && close(t.k2, -2.0 * a / q.powf(1.5), 1e-12),
        "{t:?}"
    );
    assert!(close(
        t.h,
        -a * (2.0 + 4.0 * a * a * rho * rho) / q.powf(1.5),
        1e-12
    ));
    assert!(close(t.k, 4.0 * a * a / (q * q), 1e-12));
    // k1 (the parallel) is along y at (rho, 0).
    assert!(t.directions.unwrap().0[1].abs() > 1.0 - 1e-12);
}

#[test]
fn simple_shapes_table() {
    assert_eq!(
        sphere_curvature(2.0),
        TrueCurvature {
            k1: 0.5,
            k2: 0.5,
            h: 0.5,
            k: 0.25,
            directions: None
        }
    );
    let c = cylinder_curvature(2.0, [0.0, 2.0, 1.0]);
    assert_eq!((c.k1, c.k2, c.h, c.k), (0.0, 0.5, 0.25, 0.0));
    assert_eq!(c.directions.unwrap().1, [-1.0, 0.0, 0.0]);
    assert_eq!(plane_curvature().h, 0.0);
    let sph = implicit_curvature(
        [0.0, 0.0, 4.0],
        &[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]],
    )
    .unwrap();
    assert!(close(sph.h, 0.5, 1e-15) && close(sph.k, 0.25, 1e-15) && sph.directions.is_none());
    assert!(implicit_curvature([0.0; 3], &[[1.0; 3]; 3]).is_none());
}

#[test]
fn samplers_are_on_surface_seeded_and_uniform() {
    let s = sample_sphere(1000, 2.0, 1);
    assert_eq!(s, sample_sphere(1000, 2.0, 1));
    assert_ne!(s, sample_sphere(1000, 2.0, 2));
    assert!(s
        .positions
        .iter()
        .zip(&s.normals)
        .all(|(p, n)| close(norm(*p), 2.0, 1e-12) && close(dot(*p, *n), 2.0, 1e-12)));
    let t = sample_torus(20000, 6.0, 2.0, 1);
    let mut outer = 0;
    for (p, n) in t.positions.iter().zip(&t.normals) {
        let g = torus_implicit(6.0, 2.0, *p).gradient;
        assert!(dot(normalize(g).unwrap(), *n) > 1.0 - 1e-12);
        outer += usize::from(p[0].hypot(p[1]) > 6.0);
    }
    // Area fraction of the outer half (cos theta > 0): (pi R + 2 r)/(2 pi R) = 0.6061;
    // binomial standard deviation 0.0035, bound ~4 of them.
    let frac = outer as f64 / 20000.0;
    assert!(close(frac, (PI * 6.0 + 4.0) / (TAU * 6.0), 0.014), "{frac}");
    let g = sample_goursat(2000, 1);
    for (p, n) in g.positions.iter().zip(&g.normals) {
        assert!(goursat_value(*p).abs() < 1e-9 && close(norm(*n), 1.0, 1e-12));
        assert!(dot(*p, *p) / dot(normalize(*p).unwrap(), *n) < GOURSAT_DENSITY_BOUND);
    }
    let h = sample_height_field(&Saddle, 1.0, 11, 0.0, 0);
    assert_eq!(h.len(), 121);
    assert_eq!(h.positions[0], [-1.0, -1.0, 0.0]);
    let c = sample_cylinder(100, 1.0, 4.0, 3);
    assert!(c
        .positions
        .iter()
        .all(|p| close(p[0].hypot(p[1]), 1.0, 1e-12) && p[2].abs() <= 2.0));
}

#[test]
fn noise_changes_positions_and_keeps_unit_normals() {
    let mut s = sample_sphere(2000, 1.0, 4);
    let clean = s.clone();
    s.add_noise(0.1, 0.1, 9);
    let mut var = 0.0;
    for (a, b) in s.positions.iter().zip(&clean.positions) {
        let d = sub(*a, *b);
        var += dot(d, d);
    }
    // Expected 3 sigma^2 = 0.03 per point; 6000 squared deviates give ~2% relative error.
    assert!(close(var / 2000.0, 0.03, 0.003), "{}", var / 2000.0);
    assert!(s.normals.iter().all(|n| close(norm(*n), 1.0, 1e-12)));
}

/// The grid k-NN equals a plain brute force, including tie order and duplicates.
#[test]
fn knn_matches_brute_force() {
    let mut pts = sample_torus(800, 6.0, 2.0, 2).positions;
    pts.extend(sample_height_field(&Saddle, 1.0, 8, 0.0, 0).positions);
    pts.push(pts[3]);
    pts.push(pts[3]);
    for k in [1, 7, 30] {
        let knn = knn_brute(&pts, k);
        for (i, row) in knn.iter().enumerate() {
            let mut all: Vec<(f64, usize)> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| (dot(sub(pts[j], pts[i]), sub(pts[j], pts[i])), j))
                .collect();
            all.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let want: Vec<usize> = std::iter::once(i)
                .chain(all.iter().take(k - 1).map(|x| x.1))
                .collect();
            assert_eq!(row, &want, "point {i} k {k}");
        }
    }
    assert_eq!(knn_brute(&pts[..2], 5)[1], vec![1, 0]);
    assert!(knn_brute(&[], 5).is_empty());
}

/// Every registered name builds an estimator reporting that name, and the estimators run
/// on a small sphere cap.
#[test]
fn all_names_build() {
    use tilecurv::core::estimate::EstimatorKind;
    let params = tilecurv::core::estimate::EstimatorParams::default();
    let (pos, nrm) = testkit::sphere_cap(1.0, 30);
    for kind in EstimatorKind::ALL {
        let name = kind.name();
        let est = kind.build(&params);
        assert_eq!(est.name(), name);
        assert_eq!(EstimatorKind::from_name(name), Some(kind));
        let c = testkit::run(&*est, &pos, &nrm);
        testkit::assert_valid(&c, name);
        // VCM magnitudes are strongly biased on random samples (see estimate/vcm.rs).
        let tol = if name == "vcm" { 1.0 } else { 0.1 };
        assert!((c.h - 1.0).abs() < tol, "{name}: {c:?}");
    }
    assert!(EstimatorKind::from_name("no-such").is_none());
}

#[test]
fn rotation_is_orthonormal() {
    let m = rotation([1.0, 2.0, 3.0], 0.7);
    for a in 0..3 {
        for b in 0..3 {
            let d = (0..3).map(|k| m[k][a] * m[k][b]).sum::<f64>();
            assert!(close(d, if a == b { 1.0 } else { 0.0 }, 1e-14));
        }
    }
    let z = rotation([0.0, 0.0, 1.0], PI / 2.0);
    let v = [
        dot(z[0], [1.0, 0.0, 0.0]),
        dot(z[1], [1.0, 0.0, 0.0]),
        dot(z[2], [1.0, 0.0, 0.0]),
    ];
    assert!(close(v[1], 1.0, 1e-15) && close(v[0], 0.0, 1e-15));
}
