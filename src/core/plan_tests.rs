//! Tests of the tile plan and the memory plan.

use super::*;

/// A part of the size `core_points_per_part` allows loads, with its halo ring, at most the
/// points its share holds; a narrow halo keeps the plain cap, and the floor is 1024.
#[test]
fn a_part_and_its_halo_fit_the_tile_share() {
    let m = MemoryPlan::new(128 << 20, 320, 5, 2);
    let loadable = (m.per_tile_bytes / m.tile_point_bytes) as f64;
    for (halo, density) in [(7.0, 8.0), (3.0, 8.0), (20.0, 1.0), (1.0, 200.0)] {
        let n = m.core_points_per_part(halo, density);
        let side = (n as f64 / density).sqrt();
        let loaded = n as f64 * (1.0 + 2.0 * halo / side).powi(2);
        assert!(
            loaded <= loadable * (1.0 + 1e-9) || n == 1024,
            "halo {halo}, density {density}: {n} core points load {loaded} > {loadable}"
        );
        assert!(n <= m.max_core_points);
    }
    let k30 = MemoryPlan::new(128 << 20, 30, 1, 2);
    assert_eq!(k30.core_points_per_part(1.5, 8.0), k30.max_core_points);
    assert_eq!(m.core_points_per_part(1e6, 8.0), 1024);
    assert_eq!(m.core_points_per_part(2.0, 0.0), m.max_core_points);
}

#[test]
fn budgets_are_lowered_to_fit_a_limit_or_refused() {
    const M: u64 = 1 << 20;
    assert_eq!(fit_budget(256 * M, 1024 * M, 200 * M), BudgetFit::Fits);
    assert_eq!(
        fit_budget(4096 * M, 1024 * M, 200 * M + 5),
        BudgetFit::Lowered(823 * M)
    );
    assert_eq!(
        fit_budget(4096 * M, 264 * M, 200 * M),
        BudgetFit::Lowered(64 * M)
    );
    assert_eq!(
        fit_budget(4096 * M, 263 * M, 200 * M),
        BudgetFit::TooSmall(264 * M)
    );
    assert_eq!(
        fit_budget(4096 * M, 10 * M, 200 * M),
        BudgetFit::TooSmall(264 * M)
    );
}

#[test]
fn keys_partition_and_open_sides() {
    let g = TileGrid { size: 10.0 };
    assert_eq!(g.key(-0.0001, 9.9999), (-1, 0));
    assert_eq!(g.key(10.0, 0.0), (1, 0));
    let r = g.rect((0, 0));
    assert!(r.contains(0.0, 0.0) && r.contains(10.0, 10.0));
    let scene = Rect {
        min: [0.0, -100.0],
        max: [100.0, 100.0],
    };
    // The x = 0 side is the scene's edge: only the other three sides count.
    assert_eq!(r.distance_to_open_side(1.0, 3.0, &scene), 3.0);
    assert_eq!(r.grown(5.0).distance_to_open_side(1.0, 3.0, &scene), 8.0);
    let all = Rect {
        min: [-1.0, -200.0],
        max: [200.0, 200.0],
    };
    assert!(all.distance_to_open_side(1.0, 3.0, &scene).is_infinite());
}

#[test]
fn keys_are_total_and_holds_says_when_they_are_exact() {
    let g = TileGrid { size: 50.0 };
    assert_eq!(g.key(125.0, -0.5), (2, -1));
    for v in [1e300, f64::INFINITY, -1e21, f64::NAN] {
        let (x, y) = g.key(v, v);
        assert!(x.abs() <= MAX_TILE_KEY && y.abs() <= MAX_TILE_KEY, "{v}");
        let r = g.rect((x, y));
        assert!(r.max[0] > r.min[0], "{v}");
        assert!(!g.holds(v, 0.0), "{v}");
    }
    assert!(g.holds(5e12, -5e12));
    assert!(!computable([0.0, f64::NAN, 0.0]) && computable([1e7, 5e6, -400.0]));
}

#[test]
fn memory_plan_shares_the_budget() {
    // One per thread, at least 2, while each keeps 32 MiB: 1 GiB * 2/5 holds 12 of them.
    for (threads, budget, want) in [(1, 1 << 30, 2), (2, 1 << 30, 2), (8, 1 << 30, 8)]
        .into_iter()
        .chain([(16, 1 << 30, 12), (16, 64 << 20, 2), (4, 4 << 30, 4)])
    {
        let m = MemoryPlan::new(budget, 30, 1, threads);
        assert_eq!(m.tiles_in_flight, want, "{threads} threads, {budget} bytes");
        assert!(m.per_tile_bytes >= MIN_TILE_SHARE || want == 2);
        // Buckets during the scan and the tiles in flight after it never exceed the budget.
        assert!(m.buckets_bytes + m.bucket_cache_bytes <= m.budget_bytes);
        assert!(m.bucket_cache_bytes + m.tiles_in_flight * m.per_tile_bytes <= m.budget_bytes);
        assert!(m.max_core_points * m.tile_point_bytes <= m.per_tile_bytes);
    }
    let m = MemoryPlan::new(1 << 30, 30, 1, 2);
    assert_eq!(m.tile_point_bytes, 420);
    // A 2000-byte record: 1 GiB / 16 / 2064 = 32513 points per chunk at most.
    assert_eq!(m.chunk_points(1_000_000, 2000), 32_513);
    assert_eq!(m.chunk_points(500, 2000), 500);
    assert_eq!(
        MemoryPlan::new(64 << 20, 30, 1, 2).chunk_points(1 << 20, 1 << 20),
        1024
    );
}

/// The i64 shortcut of `Centroid::add` gives the sum's definition, round(c * 2^32) as an
/// i128, on both sides of the i64 range and at UTM magnitudes.
#[test]
fn centroid_sums_are_the_rounded_units() {
    let edge = 2f64.powi(31);
    for c in [
        0.3e-9,
        -2.5 / CENTROID_UNITS,
        5_123_456.789,
        -712_345.25,
        edge - 1e-6,
        -edge,
        edge,
        edge * 3.0,
        -1e20,
        1e30,
    ] {
        let mut m = Centroid::default();
        m.add([c, -c, 0.0]);
        let want = |c: f64| (c * CENTROID_UNITS).round() as i128;
        assert_eq!(m.sum, [want(c), want(-c), 0], "{c}");
    }
}

#[test]
fn halo_grows_with_k_and_shrinks_with_density() {
    assert!(initial_halo(1000, 10.0, 30) > initial_halo(4000, 10.0, 30));
    let h = initial_halo(10_000, 100.0, 30);
    // density 1 pt/unit^2: r_k = sqrt(30/pi) = 3.09, halo = 9.27
    assert!((h - 3.0 * (30.0 / std::f64::consts::PI).sqrt()).abs() < 1e-12);
}

/// With --radius the halo is twice the radius (and a margin) unless the cap binds first.
#[test]
fn a_radius_halo_covers_twice_the_radius_or_the_capped_k() {
    let h30 = initial_halo(10_000, 100.0, 30); // 9.27 units
    assert_eq!(initial_halo_within(10_000, 100.0, 30, None), h30);
    assert_eq!(initial_halo_within(10_000, 100.0, 30, Some(2.0)), 4.1);
    assert_eq!(initial_halo_within(10_000, 100.0, 30, Some(20.0)), h30);
}

#[test]
fn a_sliver_tile_takes_the_halo_of_its_dense_neighbour() {
    // Tile (1, 0) holds 2 points at the scene's edge next to 10,000 in tile (0, 0); tile
    // (5, 5) stands alone with 2 points.
    let per_tile: BTreeMap<TileKey, u64> = [((0, 0), 10_000), ((1, 0), 2), ((5, 5), 2)]
        .into_iter()
        .collect();
    let stats = ScanStats {
        count: 10_004,
        min: [0.0; 3],
        max: [600.0, 600.0, 1.0],
        per_tile,
        centroid: Centroid::default(),
    };
    let p = plan(&stats, 100.0, 30, None);
    let halo = |key| p.tiles.iter().find(|t| t.key == key).map(|t| t.halo);
    let dense = initial_halo(10_000, 100.0, 30); // 9.27 units
    assert_eq!(halo((0, 0)), Some(dense));
    assert_eq!(halo((1, 0)), Some(dense));
    // Alone, a sparse tile keeps the halo its own density asks for (655 units).
    assert_eq!(halo((5, 5)), Some(initial_halo(2, 100.0, 30)));
    assert!(initial_halo(2, 100.0, 30) > 600.0);
}
