//! Tests of compute.rs.

use super::*;

/// Parameters with upward PCA normals, no extra values, no propagation.
fn params(
    estimator: &dyn crate::core::estimate::Estimator,
    k: usize,
    radius: Option<f64>,
    ladder: Option<crate::core::scale::Ladder>,
) -> ComputeParams<'_> {
    ComputeParams {
        k,
        radius,
        orientation: Orientation::Up,
        use_file_normals: false,
        estimator,
        extra: 0,
        propagate: None,
        ladder,
        terrain: false,
    }
}

/// A 40 x 40 patch of the paraboloid z = (x^2 + y^2) / 2 (|H| = 1 at the apex), loaded as a
/// whole scene.
fn paraboloid() -> (TilePoints, Rect) {
    let mut t = TilePoints {
        xyz: Vec::new(),
        ids: Vec::new(),
        file_normals: Vec::new(),
        n_core: 0,
        region: Rect {
            min: [f64::NEG_INFINITY; 2],
            max: [f64::INFINITY; 2],
        },
    };
    for i in 0..1600u64 {
        let (x, y) = ((i % 40) as f64 * 0.01 - 0.2, (i / 40) as f64 * 0.01 - 0.2);
        t.xyz.push([x, y, 0.5 * (x * x + y * y)]);
        t.ids.push(i);
        t.file_normals.push(None);
    }
    t.n_core = t.xyz.len();
    let scene = Rect {
        min: [-0.2; 2],
        max: [0.2; 2],
    };
    (t, scene)
}

/// Flag 64 follows the geometric bound on a unit sphere (exact outward normals): up to
/// reach 1.4 the estimate is within 11% and never flagged; at reach 1.9 (most of the
/// sphere) CNC's H is 25% high, H r > 2, and the flag catches it. The rule itself on set
/// values: radius of curvature 0.4 is flagged exactly when r > 0.8.
#[test]
fn sharper_than_the_neighbourhood_is_the_sphere_bound() {
    let est = crate::core::estimate::EstimatorKind::CncAvgHexagram.build(&Default::default());
    let mut buf = NeighbourhoodBuf::with_capacity(400);
    let q = [0.0, 0.0, 1.0];
    let mut xyz = vec![q];
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 1..400 {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / 400.0;
        let (s, a) = ((1.0 - z * z).sqrt(), golden * i as f64);
        xyz.push([s * a.cos(), s * a.sin(), z]);
    }
    let outward: Vec<Option<V3>> = xyz.iter().map(|p| Some(*p)).collect();
    let dist = |j: u32| crate::core::geometry::norm(sub(xyz[j as usize], q));
    for reach in [0.3, 1.0, 1.4, 1.9] {
        let list: Vec<u32> = (0..xyz.len() as u32)
            .filter(|&j| dist(j) <= reach)
            .collect();
        let r = list.iter().map(|&j| dist(j)).fold(0.0, f64::max);
        let c = buf.estimate(est.as_ref(), &xyz, &outward, 0, &list, &mut []);
        let flagged = c.flags & flags::SHARPER_THAN_NEIGHBOURHOOD != 0;
        if reach < 1.5 {
            assert!((c.h - 1.0).abs() < 0.11, "reach {reach}: H {}", c.h);
            assert!(!flagged, "reach {reach}");
        } else {
            assert!(c.h * r > 2.0 && flagged, "reach {reach}: H {} r {r}", c.h);
        }
        let tight = Curvature {
            h: 2.5,
            k1: 2.5,
            k2: 2.5,
            k: 6.25,
            ..c
        };
        assert_eq!(sharper_than(&tight, r), r > 0.8, "reach {reach}");
    }
    assert!(
        !sharper_than(&Curvature::undefined(0), 10.0),
        "NaN values are never flagged"
    );
}

/// A set cancel flag stops the pass with `Cancelled` (no partial results); a clear one
/// computes every point, H near -1 at the apex (normals up point into the bowl, like inward
/// normals on a sphere, so H = -1/r by the convention of algorithms.md 1.1, 13.1).
#[test]
fn a_set_cancel_flag_stops_the_pass() {
    let (t, scene) = paraboloid();
    let est = crate::core::estimate::EstimatorKind::CncAvgHexagram.build(&Default::default());
    let p = params(est.as_ref(), 30, None, None);
    let mut bufs = TileBuffers::default();
    let all = Shared::All;
    let stop = AtomicBool::new(true);
    assert_eq!(
        compute_tile(&t, &scene, &p, 0, all, &mut bufs, &stop).err(),
        Some(Cancelled)
    );
    let go = AtomicBool::new(false);
    let out = compute_tile(&t, &scene, &p, 0, all, &mut bufs, &go).expect("not cancelled");
    assert_eq!(out.done.len(), t.xyz.len());
    let h = apex_h(&out);
    assert!((h + 1.0).abs() < 0.05, "H {h}");
}

/// The verification of radius lists, on the paraboloid loaded as a region whose sides are all
/// open (a wider scene): a list cut at R = 0.04 (50 points within it, under the cap of 200) is
/// complete only when R is inside the region, so a point is computed only when it and its
/// neighbours (up to R nearer a side) are at least R from every side, and retried otherwise;
/// with R = 0.1 and a cap of 30 that binds (its 30th neighbour at about 0.03), the 30 nearest
/// only need to be inside, as for -k. The apex's H is the paraboloid's either way.
#[test]
fn radius_lists_are_verified_against_the_loaded_region() {
    let (mut t, _) = paraboloid();
    t.region = Rect {
        min: [-0.2; 2],
        max: [0.19; 2],
    };
    let scene = Rect {
        min: [-1.0; 2],
        max: [1.0; 2],
    };
    let est = crate::core::estimate::EstimatorKind::CncAvgHexagram.build(&Default::default());
    let mut bufs = TileBuffers::default();
    let go = AtomicBool::new(false);
    for (radius, cap, done_from, retried_below) in
        [(0.04, 200, 0.085, 0.075), (0.1, 30, 0.07, 0.025)]
    {
        let p = params(est.as_ref(), cap, Some(radius), None);
        let out = compute_tile(&t, &scene, &p, 0, Shared::All, &mut bufs, &go).expect("runs");
        assert_eq!(out.done.len() + out.retry.len(), t.xyz.len());
        let done: std::collections::HashSet<u64> = out.done.iter().map(|r| r.id).collect();
        for (i, q) in t.xyz.iter().enumerate() {
            let room = t.region.distance_to_open_side(q[0], q[1], &scene);
            let id = t.ids[i];
            if room >= done_from {
                assert!(
                    done.contains(&id),
                    "R {radius}: point {i} room {room} not done"
                );
            }
            if room <= retried_below {
                assert!(
                    !done.contains(&id),
                    "R {radius}: point {i} room {room} done"
                );
            }
        }
        let h = apex_h(&out);
        assert!((h + 1.0).abs() < 0.05, "R {radius}: H {h}");
    }
}

/// H at the paraboloid's apex (grid point 20, 20 of [`paraboloid`]): -1 by the sign convention
/// of algorithms.md 1.1, normals up pointing into the bowl.
fn apex_h(out: &TileOutcome) -> f64 {
    out.done
        .iter()
        .find(|r| r.id == 20 * 40 + 20)
        .map(|r| r.curvature.h)
        .expect("the apex is computed")
}

/// `-k auto` on the paraboloid: loaded whole, every point is computed at a rung of the ladder
/// and the apex's H is the paraboloid's; loaded as a region with an open side, the points it
/// computes are bit-identical to the whole load's (verification covers the lists of the 64
/// nearest and their neighbours' normal prefixes), the points near the open side are retried,
/// and the points far from it are done.
#[test]
fn auto_scale_results_do_not_depend_on_the_loaded_region() {
    let (whole, scene) = paraboloid();
    let est = crate::core::estimate::EstimatorKind::CncAvgHexagram.build(&Default::default());
    let ladder = crate::core::scale::Ladder { min: 16, max: 128 };
    let p = params(est.as_ref(), ladder.max, None, Some(ladder));
    let (mut bufs, go) = (TileBuffers::default(), AtomicBool::new(false));
    let full = compute_tile(&whole, &scene, &p, 0, Shared::All, &mut bufs, &go).expect("runs");
    assert_eq!(full.done.len(), whole.xyz.len());
    assert!(full.retry.is_empty());
    assert!(full
        .done
        .iter()
        .all(|r| [16, 32, 64, 128].contains(&r.scale)));
    let h = apex_h(&full);
    assert!((h + 1.0).abs() < 0.05, "H {h}");

    let mut open = whole.clone();
    open.region = Rect {
        min: [-0.2; 2],
        max: [0.19, 0.2],
    };
    // The scene goes on past x = 0.19 only: that is the one open side.
    let wider = Rect {
        min: [-0.2; 2],
        max: [1.0, 0.2],
    };
    let part = compute_tile(&open, &wider, &p, 0, Shared::All, &mut bufs, &go).expect("runs");
    assert_eq!(part.done.len() + part.retry.len(), whole.xyz.len());
    let counts = (part.done.len(), part.retry.len());
    assert!(counts.1 > 0 && counts.0 > whole.xyz.len() / 3, "{counts:?}");
    for r in &part.done {
        let same = format!("{r:?}") == format!("{:?}", full.done[r.id as usize]);
        assert!(same, "point {}", r.id);
    }
    // r_128 is about 0.064 here (10^4 points per unit area): a point within it of the open
    // side x = 0.19 is never done; one farther than 0.3 always is (the reach is r_64 + r_128
    // + r_64 inside, up to 1.4 times that at the patch's closed edges, where neighbourhoods
    // are half discs).
    for &id in &part.retry {
        let x = whole.xyz[id as usize][0];
        assert!(x > 0.19 - 0.3, "point {id} at x {x} retried");
    }
    for r in &part.done {
        assert!(
            whole.xyz[r.id as usize][0] < 0.19 - 0.06,
            "point {} done",
            r.id
        );
    }
}
