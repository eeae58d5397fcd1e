//! Tests of the exact k-NN against brute force, on both backends.

use super::*;

/// Brute force: self first, then by (distance, x, y, z, id).
fn brute(xyz: &[V3], ids: &[u64], i: usize, k: usize) -> Vec<u32> {
    let mut v: Vec<(f64, [f64; 3], u64, u32)> = (0..xyz.len())
        .filter(|&j| j != i)
        .map(|j| {
            let d = sub(xyz[j], xyz[i]);
            let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            (d2, xyz[j], ids[j], j as u32)
        })
        .collect();
    v.sort_by(|a, b| {
        let pos = |p: &[f64; 3]| p.map(|c| c + 0.0);
        a.0.total_cmp(&b.0)
            .then(pos(&a.1)[0].total_cmp(&pos(&b.1)[0]))
            .then(pos(&a.1)[1].total_cmp(&pos(&b.1)[1]))
            .then(pos(&a.1)[2].total_cmp(&pos(&b.1)[2]))
            .then(a.2.cmp(&b.2))
    });
    std::iter::once(i as u32)
        .chain(v.into_iter().take(k - 1).map(|t| t.3))
        .collect()
}

fn check_both_backends(xyz: &[V3], ids: &[u64], ks: &[usize]) {
    let (lo, hi) = bounds(xyz);
    let mut scratch = KnnScratch::default();
    let mut out = Vec::new();
    for &k in ks {
        let ranks = position_ranks(xyz, ids);
        let dups = Duplicates::find(xyz, &ranks, k);
        let tree = NeighbourIndex::build_tree(xyz, ranks, dups, lo, hi).expect("tree");
        let index = NeighbourIndex::build(xyz, ids, k).expect("index");
        for i in 0..xyz.len() {
            let want = brute(xyz, ids, i, k);
            index.knn(i, k, &mut scratch, &mut out);
            assert_eq!(out, want, "auto backend, point {i} k {k}");
            tree.knn(i, k, &mut scratch, &mut out);
            assert_eq!(out, want, "tree backend, point {i} k {k}");
        }
    }
}

/// An n x n lattice of spacing `step` in the plane z = origin[2] from `origin`, in (gx, gy)
/// order, each node repeated `copies(gx, gy)` times (exact duplicates, adjacent).
fn lattice(
    origin: V3,
    n: usize,
    step: f64,
    mut copies: impl FnMut(usize, usize) -> usize,
) -> Vec<V3> {
    let mut xyz = Vec::new();
    for gx in 0..n {
        for gy in 0..n {
            let p = [
                origin[0] + gx as f64 * step,
                origin[1] + gy as f64 * step,
                origin[2],
            ];
            xyz.extend(std::iter::repeat_n(p, copies(gx, gy)));
        }
    }
    xyz
}

#[test]
fn matches_brute_force_with_duplicates_and_utm_offsets() {
    // A grid with exact duplicates and many equal distances, far from the origin (UTM-like).
    let mut rng = crate::core::rng::Rng::new(12345);
    let mut xyz = lattice([500_000.0, 5_000_000.0, 100.0], 20, 0.5, |_, _| {
        1 + (rng.next_u64() >> 61 == 0) as usize
    });
    // A few isolated points far away (sparse shells) and a tree-like vertical column.
    xyz.push([500_030.0, 5_000_030.0, 100.0]);
    xyz.push([499_990.0, 5_000_002.0, 140.0]);
    for h in 0..15 {
        xyz.push([500_004.0, 5_000_004.0, 100.5 + h as f64 * 0.7]);
    }
    // Ids deliberately not in storage order.
    let ids: Vec<u64> = (0..xyz.len() as u64)
        .map(|i| (i * 7919) % 100_003)
        .collect();
    assert!(matches!(
        NeighbourIndex::build(&xyz, &ids, 8).map(|x| x.backend),
        Some(Backend::Grid(_))
    ));
    check_both_backends(&xyz, &ids, &[1, 5, 8, 9, 13, 30, 70, 130]);
}

/// Large groups of exact duplicates are answered without a search, with
/// the same neighbours as brute force (the group's first members in position-rank order),
/// beside groups too small for the shortcut and a lattice around them.
#[test]
fn duplicate_groups_match_brute_force() {
    let mut xyz = lattice([500_000.0, 4_100_000.0, 50.0], 12, 0.25, |_, _| 1);
    xyz.extend(vec![[500_001.0, 4_100_001.0, 50.0]; 200]);
    xyz.extend(vec![[500_002.0, 4_100_000.5, 50.25]; 40]);
    xyz.extend(vec![[500_000.5, 4_100_002.0, 50.0]; 3]);
    let ids: Vec<u64> = (0..xyz.len() as u64).map(|i| (i * 7919) % 10_007).collect();
    check_both_backends(&xyz, &ids, &[5, 30, 41, 60, 100, 250]);
}

#[test]
fn position_ranks_follow_cmp_point() {
    // Negative and positive coordinates, -0 and +0 (one value), duplicates (by id).
    let xyz = [
        [1.0, 2.0, 3.0],
        [-0.0, 5.0, 1.0],
        [0.0, 5.0, 1.0],
        [-1.5, 0.0, 0.0],
        [1.0, 2.0, 3.0],
        [1.0, -2.0, 9.0],
        [1.0, 2.0, -3.0],
        [-1e-300, 7.0, 7.0],
    ];
    let ids = [7, 3, 1, 9, 2, 5, 4, 8];
    let r = position_ranks(&xyz, &ids);
    for i in 0..xyz.len() {
        for j in 0..xyz.len() {
            let want = crate::core::point::cmp_point((&xyz[i], ids[i]), (&xyz[j], ids[j]));
            assert_eq!(r[i].cmp(&r[j]), want, "points {i} and {j}");
        }
    }
    assert_eq!(
        r[2].cmp(&r[1]),
        Ordering::Less,
        "-0 and +0 are one value: by id"
    );
}

#[test]
fn ties_are_broken_by_position_whatever_the_order_and_ids() {
    // A 1 cm lattice on a plane (every ring of neighbours at exactly
    // equal distances, so ties at the k-th place are the rule) with exact duplicates, once
    // in lattice order with ids in that order, once shuffled with other ids. Every point's
    // neighbours must be the same positions in the same order: ties go by position, and by
    // id only between duplicates, whose positions are the same.
    let xyz = lattice([600_000.0, 5_000_000.0, 10.0], 24, 0.01, |gx, gy| {
        match ((gx * 7 + gy * 3) % 11 == 0, gx % 3 == 0) {
            (true, true) => 3,
            (true, false) => 2,
            _ => 1,
        }
    });
    let n = xyz.len();
    let ids: Vec<u64> = (0..n as u64).collect();
    let mut rng = crate::core::rng::Rng::new(31);
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        perm.swap(i, rng.below(i + 1));
    }
    let shuffled: Vec<V3> = perm.iter().map(|&i| xyz[i]).collect();
    let other_ids: Vec<u64> = (0..n as u64).map(|i| (i * 7919 + 13) % 100_003).collect();
    let mut s = KnnScratch::default();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut ties = 0;
    for k in [5, 9, 13, 21] {
        let ia = NeighbourIndex::build(&xyz, &ids, k).expect("index");
        let ib = NeighbourIndex::build(&shuffled, &other_ids, k).expect("index");
        for (j, &i) in perm.iter().enumerate() {
            ia.knn(i, k, &mut s, &mut a);
            ib.knn(j, k, &mut s, &mut b);
            let pa: Vec<V3> = a.iter().map(|&l| xyz[l as usize]).collect();
            let pb: Vec<V3> = b.iter().map(|&l| shuffled[l as usize]).collect();
            assert_eq!(pa, pb, "point {i} k {k}: neighbours depend on the order");
            // A tie at the k-th place: the first point left out is as near as the last in.
            let d = |p: V3| sub(p, xyz[i]).map(|c| c * c).iter().sum::<f64>();
            let last = d(pa[k - 1]);
            let first_out = brute(&xyz, &ids, i, k + 1)[k];
            ties += (d(xyz[first_out as usize]) == last) as usize;
        }
    }
    assert!(
        ties > 1000,
        "only {ties} ties at the k-th place: the test tests nothing"
    );
    check_both_backends(&shuffled, &other_ids, &[5, 13]);
}

#[test]
fn block_path_is_exact_on_terrain_with_vegetation() {
    // A bumpy surface at UTM offsets with a vegetated patch (points spread in z), snapped to
    // a 1 cm lattice so that equal distances (ties broken by position) occur.
    let mut rng = crate::core::rng::Rng::new(4242);
    let mut unit = || rng.uniform();
    let mut xyz = Vec::new();
    for _ in 0..6000 {
        let (x, y) = (40.0 * unit(), 40.0 * unit());
        let mut z = 3.0 * (x / 7.0).sin() * (y / 5.0).cos();
        if x < 12.0 && y < 12.0 && unit() < 0.5 {
            z += 15.0 * unit(); // canopy
        }
        let snap = |v: f64| (v * 100.0).round() / 100.0;
        xyz.push([500_000.0 + snap(x), 4_000_000.0 + snap(y), 120.0 + snap(z)]);
    }
    let ids: Vec<u64> = (0..xyz.len() as u64)
        .map(|i| (i * 104_729) % 7919)
        .collect();
    for k in [2, 10, 30, 31, 64] {
        let index = NeighbourIndex::build(&xyz, &ids, k).expect("index");
        let Backend::Grid(g) = &index.backend else {
            panic!("a surface gets the grid");
        };
        let mut s = KnnScratch::default();
        let mut out = Vec::new();
        let mut by_block = 0;
        for i in 0..xyz.len() {
            let want = brute(&xyz, &ids, i, k);
            if index.grid_block_knn(g, i, k - 1, &mut s).is_ok() {
                by_block += 1;
                let got: Vec<u32> = std::iter::once(i as u32)
                    .chain(s.exact[..k - 1].iter().map(|r| r.2))
                    .collect();
                assert_eq!(got, want, "block path, point {i} k {k}");
            }
            index.knn(i, k, &mut s, &mut out);
            assert_eq!(out, want, "point {i} k {k}");
        }
        // The fast path must carry most queries; the canopy sends some to the seeded shell
        // search, which the equality above checked too.
        assert!(
            by_block * 10 > xyz.len() * 8,
            "k {k}: {by_block} by the block"
        );
        assert!(
            by_block < xyz.len(),
            "k {k}: no query reached the shell search"
        );
    }
}

#[test]
fn a_scratch_reused_with_another_index_stays_exact() {
    // Two clouds whose grids have the same cell indices at different places: a block
    // cached for the first must not answer for the second.
    let mut rng = crate::core::rng::Rng::new(5);
    let a: Vec<V3> = (0..3000)
        .map(|_| {
            [
                30.0 * rng.uniform(),
                30.0 * rng.uniform(),
                0.1 * rng.uniform(),
            ]
        })
        .collect();
    let b: Vec<V3> = a.iter().map(|p| [p[1], p[0], p[2] + 0.05]).collect();
    let ids: Vec<u64> = (0..a.len() as u64).collect();
    let (ia, ib) = (
        NeighbourIndex::build(&a, &ids, 20).expect("index"),
        NeighbourIndex::build(&b, &ids, 20).expect("index"),
    );
    let mut s = KnnScratch::default();
    let mut out = Vec::new();
    for i in (0..a.len()).step_by(7) {
        ia.knn(i, 20, &mut s, &mut out);
        assert_eq!(out, brute(&a, &ids, i, 20), "first cloud, point {i}");
        ib.knn(i, 20, &mut s, &mut out);
        assert_eq!(out, brute(&b, &ids, i, 20), "second cloud, point {i}");
    }
}

#[test]
fn uneven_density_uses_the_tree_and_stays_exact() {
    // 2000 points in a 1 cm blob and 200 spread over 100 m: no single cell size fits.
    let mut xyz = Vec::new();
    let mut rng = crate::core::rng::Rng::new(99);
    let mut unit = || rng.uniform();
    for _ in 0..2000 {
        xyz.push([0.01 * unit(), 0.01 * unit(), 0.01 * unit()]);
    }
    for _ in 0..200 {
        xyz.push([100.0 * unit(), 100.0 * unit(), unit()]);
    }
    let ids: Vec<u64> = (0..xyz.len() as u64).collect();
    assert!(matches!(
        NeighbourIndex::build(&xyz, &ids, 10).map(|x| x.backend),
        Some(Backend::Tree { .. })
    ));
    check_both_backends(&xyz, &ids, &[10]);
}

#[test]
fn degenerate_extents_stay_exact() {
    // A zero x/y area (a facade, a vertical line, one spot) and extents far below any cell
    // size still give a grid of at least one column, and exact answers.
    let mut rng = crate::core::rng::Rng::new(7);
    let mut unit = || rng.uniform();
    let facade: Vec<V3> = (0..900)
        .map(|_| [5.0, 10.0 * unit(), 10.0 * unit()])
        .collect();
    let line: Vec<V3> = (0..300).map(|i| [3.0, 4.0, i as f64 * 0.01]).collect();
    let spot: Vec<V3> = vec![[1.0, 2.0, 3.0]; 40];
    let tiny: Vec<V3> = (0..200)
        .map(|i| [(i % 20) as f64 * 1e-300, (i / 20) as f64 * 1e-300, 0.0])
        .collect();
    for (name, xyz) in [
        ("facade", facade),
        ("line", line),
        ("spot", spot),
        ("tiny", tiny),
    ] {
        let ids: Vec<u64> = (0..xyz.len() as u64).collect();
        assert!(NeighbourIndex::build(&xyz, &ids, 10).is_some(), "{name}");
        check_both_backends(&xyz, &ids, &[1, 10]);
    }
}
