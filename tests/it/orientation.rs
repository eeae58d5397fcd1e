//! Orientation of PCA normals on real scans, against reference normals: the file's own oriented
//! normals of `kitten.xyz`, and the vertex normals of `bun_zipper.ply` computed from its faces
//! (area-weighted face normals summed per vertex). PCA normals over k = 16 neighbours (the point
//! itself included) are oriented by each mode, in memory and, for propagation, also tiled (2 x 2
//! tiles with a halo, per-tile propagation, tile signs from the halo votes), and the normals
//! disagreeing in sign with the reference (`<n, n_ref> < 0`) are counted. The table is printed
//! (`cargo test --release orientation -- --nocapture`).

use std::path::Path;

use tilecurv::core::geometry::{add, cross, dot, normalize, scale, sub, V3};
use tilecurv::core::neighbors::{KnnScratch, NeighbourIndex};
use tilecurv::core::normals::{orient, pca_normal, Orientation};
use tilecurv::core::orient::{
    orient_outward, orient_tile, patch_signs, propagate, votes_from_shared, Centroid, Seed,
};
use tilecurv::io::source::open;

use crate::common::shared;

/// Neighbours per PCA normal, the point itself included.
const K: usize = 16;

/// Coordinates and file normals of every point, with the library's reader.
fn points(path: &Path) -> (Vec<V3>, Vec<Option<V3>>) {
    let src = open(path).expect("readable input");
    let rl = src.record_length();
    let (mut xyz, mut nrm) = (Vec::new(), Vec::new());
    src.for_each_chunk(100_000, &mut |first, recs| {
        for (i, r) in recs.chunks_exact(rl).enumerate() {
            let p = src.decode(first + i as u64, r);
            xyz.push(p.xyz);
            nrm.push(p.normal.and_then(normalize));
        }
        Ok(())
    })
    .expect("decodes");
    (xyz, nrm)
}

/// Vertex normals of an ASCII PLY mesh from its faces (the library's reader skips faces):
/// area-weighted face normals (the cross products) summed per vertex, then normalised; None
/// for a vertex in no face (or whose faces cancel).
fn vertex_normals(path: &Path, xyz: &[V3]) -> Vec<Option<V3>> {
    let text = std::fs::read_to_string(path).expect("read PLY");
    let (header, body) = text.split_once("end_header\n").expect("PLY header");
    assert!(header.contains("format ascii"), "ASCII PLY expected");
    let count = |name: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {name} ")))
            .and_then(|n| n.trim().parse().ok())
            .unwrap_or_else(|| panic!("no element {name}"))
    };
    let (nv, nf) = (count("vertex"), count("face"));
    assert_eq!(nv, xyz.len());
    assert!(
        header.find("element vertex") < header.find("element face"),
        "vertices come first"
    );
    let mut sum = vec![[0.0; 3]; nv];
    let mut faces = 0;
    for line in body.lines().skip(nv).take(nf) {
        let v: Vec<usize> = line
            .split_whitespace()
            .map(|t| t.parse().expect("index"))
            .collect();
        assert_eq!(v.len(), v[0] + 1, "face line {line:?}");
        // Fan triangulation of a polygon.
        for t in 1..v[0] - 1 {
            let (a, b, c) = (v[1], v[1 + t], v[2 + t]);
            let n = cross(sub(xyz[b], xyz[a]), sub(xyz[c], xyz[a]));
            for i in [a, b, c] {
                sum[i] = add(sum[i], n);
            }
        }
        faces += 1;
    }
    assert_eq!(faces, nf, "face count");
    sum.into_iter().map(normalize).collect()
}

fn knn_lists(xyz: &[V3], ids: &[u64]) -> Vec<Vec<u32>> {
    let index = NeighbourIndex::build(xyz, ids, K).expect("index");
    let mut s = KnnScratch::default();
    (0..xyz.len())
        .map(|i| {
            let mut l = Vec::with_capacity(K);
            index.knn(i, K, &mut s, &mut l);
            l
        })
        .collect()
}

fn pca(xyz: &[V3], knn: &[Vec<u32>]) -> Vec<Option<V3>> {
    knn.iter().map(|l| pca_normal(xyz, l)).collect()
}

/// Propagation through 2 x 2 tiles split at the centroid's x and y, each loading its core plus
/// a halo of width `halo`, as the engine would run it: k-NN and PCA within the tile's loaded
/// points, `orient_tile`, votes from the points two tiles share, one sign per patch.
/// Also returns a summary of the patches and votes.
fn tiled_propagation(xyz: &[V3], centre: V3, halo: f64) -> (Vec<Option<V3>>, String) {
    let mut out = vec![None; xyz.len()];
    let mut shared_normals = Vec::new();
    let mut anchors = Vec::new();
    // Per tile: (global index, oriented normal, patch) of its core points.
    let mut results = Vec::new();
    let mut next_patch = 0;
    for t in 0..4 {
        let pos = [t & 1 == 1, t & 2 == 2];
        let inside = |q: &V3, a: usize| (q[a] - centre[a] >= 0.0) == pos[a];
        let gap = |q: &V3, a: usize| {
            if inside(q, a) {
                0.0
            } else {
                (q[a] - centre[a]).abs()
            }
        };
        let core = |q: &V3| inside(q, 0) && inside(q, 1);
        let mut local: Vec<usize> = (0..xyz.len()).filter(|&i| core(&xyz[i])).collect();
        let n_core = local.len();
        local.extend(
            (0..xyz.len())
                .filter(|&i| !core(&xyz[i]) && gap(&xyz[i], 0) <= halo && gap(&xyz[i], 1) <= halo),
        );
        let lxyz: Vec<V3> = local.iter().map(|&i| xyz[i]).collect();
        let lids: Vec<u64> = local.iter().map(|&i| i as u64).collect();
        let knn = knn_lists(&lxyz, &lids);
        let mut normals = pca(&lxyz, &knn);
        let near_edge =
            |q: &V3| (q[0] - centre[0]).abs() <= halo || (q[1] - centre[1]).abs() <= halo;
        let tile = orient_tile(&lxyz, &lids, &knn, &mut normals, centre, next_patch, |i| {
            i >= n_core || near_edge(&lxyz[i])
        });
        next_patch += tile.n_patches();
        anchors.extend_from_slice(&tile.anchors);
        shared_normals.extend_from_slice(&tile.shared);
        for (l, &g) in local.iter().enumerate().take(n_core) {
            if let (Some(n), Some(p)) = (normals[l], tile.patch(l)) {
                results.push((g, n, p));
            }
        }
    }
    let votes = votes_from_shared(&mut shared_normals);
    let signs = patch_signs(next_patch as usize, &votes, &anchors);
    let summary = format!(
        "2x2 tiles: {next_patch} patches, {} halo votes, {} contradicted",
        signs.votes, signs.contradicted
    );
    for (g, n, p) in results {
        out[g] = Some(if signs.flip[p as usize] {
            scale(n, -1.0)
        } else {
            n
        });
    }
    (out, summary)
}

/// Normals that disagree with the reference, over the points where both are defined.
fn disagreements(normals: &[Option<V3>], reference: &[Option<V3>]) -> (usize, usize) {
    let both = normals
        .iter()
        .zip(reference)
        .filter_map(|(n, r)| Some(dot((*n)?, (*r)?)));
    both.fold((0, 0), |(bad, all), d| (bad + (d < 0.0) as usize, all + 1))
}

/// Every mode on one cloud: (mode, disagreeing, compared).
fn table(name: &str, xyz: &[V3], reference: &[Option<V3>]) -> Vec<(&'static str, usize, usize)> {
    let ids: Vec<u64> = (0..xyz.len() as u64).collect();
    let knn = knn_lists(xyz, &ids);
    let raw = pca(xyz, &knn);
    let mut c = Centroid::default();
    xyz.iter().for_each(|p| c.add(*p));
    let centre = c.get().expect("points");
    let (mut lo, mut hi) = (xyz[0], xyz[0]);
    for p in xyz {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let diag = sub(hi, lo);
    // A scanner above and in front of the object, a diagonal away from the box's top corner.
    let viewpoint = add(hi, diag);
    let by = |f: &dyn Fn(V3, V3) -> V3| -> Vec<Option<V3>> {
        raw.iter()
            .zip(xyz)
            .map(|(n, p)| n.map(|n| f(n, *p)))
            .collect()
    };
    let up = by(&|n, p| orient(n, p, Orientation::Up));
    let view = by(&|n, p| orient(n, p, Orientation::Viewpoint(viewpoint)));
    let outward = by(&|n, p| orient_outward(n, p, centre));
    let mut propagated = raw.clone();
    propagate(xyz, &knn, &raw, Seed::Outward).apply(&mut propagated);
    let halo = 0.05 * dot(diag, diag).sqrt();
    let (tiled, summary) = tiled_propagation(xyz, centre, halo);
    let rows = vec![
        ("up", up),
        ("viewpoint", view),
        ("outward", outward),
        ("propagate", propagated),
        ("propagate 2x2 tiles", tiled),
    ];
    eprintln!(
        "{name}: {} points, {} reference normals, {} PCA normals, k = {K}, viewpoint {viewpoint:?}, \
         tile halo {halo:.4}",
        xyz.len(),
        reference.iter().flatten().count(),
        raw.iter().flatten().count(),
    );
    let rows = rows
        .into_iter()
        .map(|(mode, n)| {
            let (bad, all) = disagreements(&n, reference);
            eprintln!(
                "  {mode:<20} {bad:>6} / {all} disagree ({:.2} %)",
                100.0 * bad as f64 / all as f64
            );
            (mode, bad, all)
        })
        .collect::<Vec<_>>();
    eprintln!("  {summary}");
    rows
}

fn rate(rows: &[(&str, usize, usize)], mode: &str) -> f64 {
    let r = rows.iter().find(|r| r.0 == mode).expect("mode");
    r.1 as f64 / r.2 as f64
}

#[test]
fn kitten_orientation_against_its_own_normals() {
    let Some(path) = shared("objects/kitten.xyz") else {
        return;
    };
    let (xyz, reference) = points(&path);
    assert!(reference.iter().all(Option::is_some), "kitten has normals");
    let rows = table("kitten.xyz", &xyz, &reference);
    assert!(rows.iter().all(|r| r.2 > 5000), "{rows:?}");
    assert!(rate(&rows, "propagate") < 0.01, "{rows:?}");
    assert!(rate(&rows, "propagate 2x2 tiles") < 0.01, "{rows:?}");
    assert!(rate(&rows, "up") > 0.2, "{rows:?}");
    assert!(
        rate(&rows, "propagate") < rate(&rows, "up") / 10.0,
        "{rows:?}"
    );
}

#[test]
fn bunny_orientation_against_mesh_vertex_normals() {
    let Some(path) = shared("objects/bun_zipper.ply") else {
        return;
    };
    let (xyz, _) = points(&path);
    let reference = vertex_normals(&path, &xyz);
    let rows = table("bun_zipper.ply", &xyz, &reference);
    // 1,113 vertices are in no face: no reference there.
    assert!(rows.iter().all(|r| r.2 > 34_000), "{rows:?}");
    assert!(rate(&rows, "propagate") < 0.01, "{rows:?}");
    assert!(rate(&rows, "propagate 2x2 tiles") < 0.01, "{rows:?}");
    assert!(rate(&rows, "up") > 0.2, "{rows:?}");
    assert!(
        rate(&rows, "propagate") < rate(&rows, "up") / 10.0,
        "{rows:?}"
    );
    assert!(
        rate(&rows, "propagate") < rate(&rows, "outward"),
        "{rows:?}"
    );
}

/// Sign disagreements of the NormalX/Y/Z columns of a tilecurv PLY output with `reference`.
fn output_disagreements(out: &Path, reference: &[Option<V3>]) -> (usize, usize) {
    let t = crate::common::read_ply(out);
    let (x, y, z) = (t.col("NormalX"), t.col("NormalY"), t.col("NormalZ"));
    let normals: Vec<Option<V3>> = (0..x.len())
        .map(|i| Some([x[i], y[i], z[i]]).filter(|n| n[0].is_finite()))
        .collect();
    disagreements(&normals, reference)
}

/// The same modes through the binary and the tiled engine: `--orient propagate` on the bunny
/// cut into ~30 tiles (halos reconcile the tiles' signs) agrees with the mesh normals as well
/// as the in-memory propagation does, and the curvature follows the orientation (the bunny's
/// body is convex: outward normals give a positive median H).
#[test]
fn cli_orientation_modes_on_the_bunny_in_tiles() {
    let Some(path) = shared("objects/bun_zipper.ply") else {
        return;
    };
    let (xyz, _) = points(&path);
    let reference = vertex_normals(&path, &xyz);
    let dir = tempfile::tempdir().expect("temp dir");
    let mut rates = Vec::new();
    for mode in ["up", "outward", "propagate"] {
        let out = dir.path().join(format!("{mode}.ply"));
        // The bunny is ~0.15 units wide: 0.03-unit tiles give about 30 tiles.
        crate::common::process(
            &path,
            &out,
            &["--orient", mode, "--tile", "0.03", "-k", "16"],
        );
        let (bad, all) = output_disagreements(&out, &reference);
        eprintln!("bun_zipper.ply through the CLI, --orient {mode}, 0.03 tiles: {bad} of {all} normals disagree");
        rates.push(bad as f64 / all as f64);
        if mode == "propagate" {
            let mut h: Vec<f64> = crate::common::read_ply(&out)
                .col("H")
                .into_iter()
                .filter(|v| v.is_finite())
                .collect();
            h.sort_by(f64::total_cmp);
            assert!(
                h[h.len() / 2] > 0.0,
                "median H {} with outward-consistent normals",
                h[h.len() / 2]
            );
        }
    }
    assert!(rates[2] < 0.01, "propagate: {rates:?}");
    assert!(rates[0] > 0.2 && rates[2] < rates[1], "{rates:?}");
}
