use super::*;
use crate::core::geometry::{add, dot, norm, scale, sub};
use crate::core::neighbors::{KnnScratch, NeighbourIndex};
use crate::core::normals::pca_normal;
use crate::core::rng::Rng;

/// Fibonacci sphere of radius `r` around `c` with exact outward normals.
fn sphere(n: usize, r: f64, c: V3) -> (Vec<V3>, Vec<V3>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let u = [s * t.cos(), s * t.sin(), z];
            (add(c, scale(u, r)), u)
        })
        .unzip()
}

/// A torus (R, r) in the xy plane with exact outward normals, on a jittered grid.
fn torus(nu: usize, nv: usize, big: f64, small: f64) -> (Vec<V3>, Vec<V3>) {
    let mut rng = Rng::new(7);
    let tau = std::f64::consts::TAU;
    let mut p = Vec::new();
    let mut n = Vec::new();
    for a in 0..nu {
        for b in 0..nv {
            let u = (a as f64 + 0.3 * rng.uniform()) * tau / nu as f64;
            let v = (b as f64 + 0.3 * rng.uniform()) * tau / nv as f64;
            let dir = [v.cos() * u.cos(), v.cos() * u.sin(), v.sin()];
            let ring = [big * u.cos(), big * u.sin(), 0.0];
            p.push(add(ring, scale(dir, small)));
            n.push(dir);
        }
    }
    (p, n)
}

fn knn_lists(xyz: &[V3], k: usize) -> Vec<Vec<u32>> {
    let ids: Vec<u64> = (0..xyz.len() as u64).collect();
    let index = NeighbourIndex::build(xyz, &ids, k).expect("index");
    let mut s = KnnScratch::default();
    (0..xyz.len())
        .map(|i| {
            let mut out = Vec::new();
            index.knn(i, k, &mut s, &mut out);
            out
        })
        .collect()
}

/// PCA normals with random signs (PCA's own signs are arbitrary already; randomise anyway).
fn scrambled_pca(xyz: &[V3], knn: &[Vec<u32>], seed: u64) -> Vec<Option<V3>> {
    let mut rng = Rng::new(seed);
    knn.iter()
        .map(|l| {
            pca_normal(xyz, l).map(|n| {
                if rng.uniform() < 0.5 {
                    scale(n, -1.0)
                } else {
                    n
                }
            })
        })
        .collect()
}

fn wrong(normals: &[Option<V3>], truth: &[V3]) -> usize {
    normals
        .iter()
        .zip(truth)
        .filter(|(n, t)| n.is_some_and(|n| dot(n, **t) < 0.0))
        .count()
}

#[test]
fn outward_is_exact_on_a_sphere_and_ties_are_deterministic() {
    let c = [500_000.0, 4_000_000.0, 100.0];
    let (p, n) = sphere(2000, 3.0, c);
    for (pi, ni) in p.iter().zip(&n) {
        assert_eq!(orient_outward(scale(*ni, -1.0), *pi, c), *ni);
        assert_eq!(orient_outward(*ni, *pi, c), *ni);
    }
    // Orthogonal: first non-zero component made positive, as normals::orient does.
    assert_eq!(
        orient_outward([0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0; 3]),
        [-0.0, 1.0, -0.0]
    );
    assert_eq!(
        orient_outward([0.0, -1.0, 0.0], [0.0; 3], [0.0; 3]),
        [-0.0, 1.0, -0.0]
    );
}

#[test]
fn centroid_streams_and_merges() {
    let pts: Vec<V3> = (0..10)
        .map(|i| [600_000.0 + i as f64, 5_000_000.0 - i as f64, 0.5 * i as f64])
        .collect();
    let mut all = Centroid::default();
    pts.iter().for_each(|p| all.add(*p));
    let (mut a, mut b) = (Centroid::default(), Centroid::default());
    pts[..3].iter().for_each(|p| a.add(*p));
    pts[3..].iter().for_each(|p| b.add(*p));
    a.merge(&b);
    let want = [600_004.5, 4_999_995.5, 2.25];
    for c in [all.get().expect("points"), a.get().expect("points")] {
        assert!(norm(sub(c, want)) < 1e-9, "{c:?}");
    }
    // Any split and any order give the same bits.
    assert_eq!(a, all);
    let mut rev = Centroid::default();
    pts.iter().rev().for_each(|p| rev.add(*p));
    assert_eq!(rev.get(), all.get());
    assert_eq!(Centroid::default().get(), None);
}

#[test]
fn propagation_orients_a_sphere_outward() {
    let (p, truth) = sphere(3000, 1.0, [10.0, -20.0, 5.0]);
    let knn = knn_lists(&p, 12);
    let mut normals = scrambled_pca(&p, &knn, 1);
    assert!(wrong(&normals, &truth) > 1000);
    let prop = propagate(&p, &knn, &normals, Seed::Outward);
    assert_eq!(prop.components.len(), 1);
    assert_eq!(prop.components[0].size, 3000);
    prop.apply(&mut normals);
    assert_eq!(wrong(&normals, &truth), 0);
}

#[test]
fn propagation_orients_a_torus_and_each_of_two_objects() {
    let (mut p, mut truth) = torus(120, 40, 3.0, 1.0);
    // A second object, a sphere far away: its own component and seed.
    let (ps, ns) = sphere(800, 0.5, [20.0, 0.0, 0.0]);
    p.extend(ps);
    truth.extend(ns);
    let knn = knn_lists(&p, 10);
    let mut normals = scrambled_pca(&p, &knn, 2);
    let prop = propagate(&p, &knn, &normals, Seed::Outward);
    assert_eq!(prop.components.len(), 2);
    assert_eq!(prop.components[0].size, 4800);
    assert_eq!(prop.component[4800], 1);
    prop.apply(&mut normals);
    assert_eq!(wrong(&normals, &truth), 0);
    // Deterministic.
    assert_eq!(
        prop,
        propagate(&p, &knn, &scrambled_pca(&p, &knn, 2), Seed::Outward)
    );
}

#[test]
fn seeds_tied_in_distance_go_by_position_not_by_index() {
    // The surface of a lattice cube around its centre: its 8 corners are equally far from
    // it. In any order of the points the seed is the same corner (the smallest position), and
    // so is the anchor, whatever the ids.
    let mut p = Vec::new();
    for i in 0..9 {
        for j in 0..9 {
            for k in 0..9 {
                if [i, j, k].iter().any(|&c| c == 0 || c == 8) {
                    p.push([i as f64 * 0.25, j as f64 * 0.25, k as f64 * 0.25]);
                }
            }
        }
    }
    let centre = [1.0, 1.0, 1.0];
    let seed_of = |p: &[V3]| {
        let knn = knn_lists(p, 10);
        let normals = scrambled_pca(p, &knn, 4);
        let prop = propagate(p, &knn, &normals, Seed::OutwardFrom(centre));
        assert_eq!(prop.components.len(), 1);
        let ids: Vec<u64> = (0..p.len() as u64).rev().collect();
        let a = prop.anchor(0, 0, p, &ids);
        assert_eq!(a.pos, p[prop.components[0].seed as usize]);
        (a.pos, a.dist2)
    };
    let first = seed_of(&p);
    assert_eq!(first, ([0.0; 3], 3.0));
    p.reverse();
    assert_eq!(seed_of(&p), first);
    let mut rng = Rng::new(9);
    for i in (1..p.len()).rev() {
        p.swap(i, rng.below(i + 1));
    }
    assert_eq!(seed_of(&p), first);
}

#[test]
fn anchors_tied_in_distance_go_by_position() {
    // Two patches whose votes agree, with anchors equally far from the centre that disagree
    // (one says inward, one outward): the anchor at the smaller position decides, whatever
    // the ids.
    let vote = PatchVote {
        a: 0,
        b: 1,
        agree: 10,
        disagree: 0,
    };
    let anchor = |patch, x, id, outward| PatchAnchor {
        patch,
        dist2: 4.0,
        pos: [x, 0.0, 0.0],
        id,
        outward,
    };
    let anchors = [anchor(0, 2.0, 1, false), anchor(1, -2.0, 9, true)];
    let s = patch_signs(2, &[vote], &anchors);
    assert_eq!(
        s.flip,
        vec![false, false],
        "patch 1's anchor (x = -2) decides"
    );
    let swapped = [anchor(0, 2.0, 9, false), anchor(1, -2.0, 1, true)];
    assert_eq!(patch_signs(2, &[vote], &swapped), s);
}

#[test]
fn propagation_skips_points_without_normals() {
    let (p, truth) = sphere(1000, 1.0, [0.0; 3]);
    let knn = knn_lists(&p, 10);
    let mut normals = scrambled_pca(&p, &knn, 3);
    for i in (0..1000).step_by(7) {
        normals[i] = None;
    }
    // Lists may be missing at the end (halo points without lists).
    let prop = propagate(&p, &knn[..900], &normals, Seed::OutwardFrom([0.0; 3]));
    assert_eq!(prop.component[7], Propagation::NONE);
    assert!(!prop.flip[7]);
    prop.apply(&mut normals);
    assert!(normals[7].is_none());
    assert_eq!(wrong(&normals, &truth), 0);
    // Nothing at all.
    let none = propagate(&p, &knn, &vec![None; 1000], Seed::Outward);
    assert!(none.components.is_empty());
}

/// The tiled scheme end to end on a sphere cut into 4 tiles (quadrants in x/y) with a halo:
/// independent propagation per tile, tiles 1 and 2 then flipped wholesale (as a tile whose
/// local seed lies might come out), votes from the overlap, one sign per tile.
#[test]
fn tiles_agree_through_their_halos() {
    let centre = [1.0, 2.0, 3.0];
    let (p, truth) = sphere(4000, 1.0, centre);
    let ids: Vec<u64> = (0..p.len() as u64).map(|i| i * 3 + 1).collect();
    let halo = 0.25;
    let mut shared = Vec::new();
    let mut anchors = Vec::new();
    // Per tile: (global index, oriented normal, patch) of its core points.
    let mut results: Vec<(usize, V3, u32)> = Vec::new();
    let mut next_patch = 0u32;
    for t in 0..4 {
        let pos = [t & 1 == 1, t & 2 == 2];
        // Inside the quadrant along axis a (0 belongs to the positive side), and distance
        // outside it.
        let inside = |q: &V3, a: usize| (q[a] - centre[a] >= 0.0) == pos[a];
        let out = |q: &V3, a: usize| {
            if inside(q, a) {
                0.0
            } else {
                (q[a] - centre[a]).abs()
            }
        };
        let in_core = |q: &V3| inside(q, 0) && inside(q, 1);
        let in_halo = |q: &V3| !in_core(q) && out(q, 0) <= halo && out(q, 1) <= halo;
        let mut local: Vec<usize> = (0..p.len()).filter(|&i| in_core(&p[i])).collect();
        let n_core = local.len();
        local.extend((0..p.len()).filter(|&i| in_halo(&p[i])));
        let lxyz: Vec<V3> = local.iter().map(|&i| p[i]).collect();
        let lids: Vec<u64> = local.iter().map(|&i| ids[i]).collect();
        let knn = knn_lists(&lxyz, 10);
        let mut normals = scrambled_pca(&lxyz, &knn, 10 + t as u64);
        let prop = propagate(&lxyz, &knn, &normals, Seed::OutwardFrom(centre));
        prop.apply(&mut normals);
        if t == 1 || t == 2 {
            normals
                .iter_mut()
                .flatten()
                .for_each(|n| *n = scale(*n, -1.0));
        }
        let base = next_patch;
        next_patch += prop.components.len() as u32;
        for c in 0..prop.components.len() {
            let mut a = prop.anchor(c, base + c as u32, &lxyz, &lids);
            let s = prop.components[c].seed as usize;
            a.outward = normals[s].is_some_and(|n| dot(n, sub(lxyz[s], centre)) >= 0.0);
            anchors.push(a);
        }
        for (l, &g) in local.iter().enumerate() {
            let (Some(n), c) = (normals[l], prop.component[l]) else {
                continue;
            };
            let near_edge =
                (p[g][0] - centre[0]).abs() <= halo || (p[g][1] - centre[1]).abs() <= halo;
            if l >= n_core || near_edge {
                shared.push(SharedNormal {
                    id: ids[g],
                    patch: base + c,
                    normal: n,
                });
            }
            if l < n_core {
                results.push((g, n, base + c));
            }
        }
    }
    // One component per tile here.
    assert_eq!(next_patch, 4);
    let votes = votes_from_shared(&mut shared);
    assert!(votes.len() >= 4, "{votes:?}");
    let signs = patch_signs(4, &votes, &anchors);
    assert_eq!(signs.contradicted, 0, "{votes:?}");
    assert_eq!(signs.flip, vec![false, true, true, false]);
    assert_eq!(results.len(), 4000);
    for &(g, n, patch) in &results {
        let n = if signs.flip[patch as usize] {
            scale(n, -1.0)
        } else {
            n
        };
        assert!(dot(n, truth[g]) > 0.0, "point {g}");
    }
}

#[test]
fn patch_signs_follow_the_strongest_votes_and_the_farthest_anchor() {
    let v = |a, b, agree, disagree| PatchVote {
        a,
        b,
        agree,
        disagree,
    };
    // 0-1 agree, 1-2 disagree strongly, 0-2 weakly agree (contradiction: loses), 3 alone,
    // 4-5 tied (no information: separate groups).
    let votes = [v(0, 1, 50, 0), v(2, 1, 1, 40), v(0, 2, 3, 1), v(4, 5, 2, 2)];
    let anchor = |patch, dist2, outward| PatchAnchor {
        patch,
        dist2,
        pos: [patch as f64, 0.0, 0.0],
        id: patch as u64,
        outward,
    };
    // Patch 2's anchor is the farthest and says it is inward: 2 flips, 1 and 0 do not.
    let anchors = [
        anchor(0, 1.0, false),
        anchor(2, 4.0, false),
        anchor(3, 9.0, false),
        anchor(5, 1.0, true),
    ];
    let s = patch_signs(6, &votes, &anchors);
    assert_eq!(s.flip, vec![false, false, true, true, false, false]);
    assert_eq!(s.votes, 50 + 41 + 4 + 4);
    // 0-2: flips differ, so its 3 agreeing votes are contradicted; 1-2: its 1; 4-5: 2.
    assert_eq!(s.contradicted, 3 + 1 + 2);
    // Order of votes and anchors does not matter.
    let mut rv = votes.to_vec();
    rv.reverse();
    let mut ra = anchors.to_vec();
    ra.reverse();
    assert_eq!(patch_signs(6, &rv, &ra), s);
    // Out-of-range patches are ignored.
    assert_eq!(patch_signs(1, &votes, &anchors).flip, vec![true]);
}

#[test]
fn global_patches_pack_and_unpack() {
    let p = GlobalPatch::new(7, 3);
    assert_eq!(p.0, (7 << 32) | 3);
    assert_eq!(p.parts(), Some((7, 3)));
    assert_eq!(GlobalPatch::new(7, u32::MAX), GlobalPatch::NONE);
    assert_eq!(GlobalPatch::NONE.parts(), None);
}
