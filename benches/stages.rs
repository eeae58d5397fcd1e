//! Per-stage cost of the curvature phase on one tile of a real file, single thread: where the
//! time of `tilecurv process` goes per point, and the engine's k-NN against kiddo's k-d tree
//! (the crate tilecurv's neighbours were first built on, and the usual baseline) on the same
//! points.
//!
//! Usage: `cargo bench --bench stages -- [FILE] [--tile METRES] [-k K] [--repeat N]`
//! (default FILE: data/Haystack_Rock.las, the sample that ships; tile 50, K 30, repeat 3).
//! Takes the points of a `--tile`-wide square at the centre of FILE (file units), orders them
//! along a Morton curve as a loaded tile is, and times, per point: the engine's k-NN (index
//! build included, queries in the index's cell order as the engine's tasks make them), kiddo
//! `nearest_n` on tile-local f32 coordinates (no exact re-ranking, so a lower bound on what a
//! kiddo-based engine costs), PCA normals, the default estimator with its neighbourhood gather,
//! and the terrain values of its results (`--columns terrain`: slope, aspect, profile,
//! tangential and plan curvature, shape index, curvedness): what computing them costs, without
//! carrying them through the result files to the output. Best of `--repeat` runs of each stage.

use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::time::Instant;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use tilecurv::core::compute::NeighbourhoodBuf;
use tilecurv::core::estimate::{EstimatorKind, EstimatorParams};
use tilecurv::core::geometry::sub;
use tilecurv::core::neighbors::{KnnScratch, NeighbourIndex};
use tilecurv::core::normals::{orient, pca_normal, Orientation};
use tilecurv::core::plan::Rect;
use tilecurv::core::terrain::TerrainValues;
use tilecurv::core::tile::TilePoints;
use tilecurv::io::source::open;

struct Args {
    file: PathBuf,
    tile: f64,
    k: usize,
    repeat: usize,
}

fn args() -> Args {
    let mut a = Args {
        file: PathBuf::from("data/Haystack_Rock.las"),
        tile: 50.0,
        k: 30,
        repeat: 3,
    };
    let mut it = std::env::args().skip(1);
    while let Some(s) = it.next() {
        let mut value = |name: &str| -> String {
            it.next()
                .unwrap_or_else(|| panic!("stages: {name} needs a value"))
        };
        match s.as_str() {
            "--tile" => a.tile = value("--tile").parse().expect("--tile: a number"),
            "-k" => a.k = value("-k").parse().expect("-k: an integer"),
            "--repeat" => a.repeat = value("--repeat").parse().expect("--repeat: an integer"),
            "--bench" => {}
            f => a.file = PathBuf::from(f),
        }
    }
    a
}

/// The points of the `size`-wide square at the centre of the file, Morton ordered.
fn load(a: &Args) -> TilePoints {
    let src = open(&a.file).unwrap_or_else(|e| panic!("stages: {e}"));
    let [lo, hi] = src.bounds().unwrap_or_else(|e| panic!("stages: {e}"));
    let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    let h = 0.5 * a.tile;
    let region = Rect {
        min: [c[0] - h, c[1] - h],
        max: [c[0] + h, c[1] + h],
    };
    let mut t = TilePoints {
        region,
        ..Default::default()
    };
    let rl = src.record_length();
    src.for_each_chunk(1 << 20, &mut |first, recs| {
        for (i, r) in recs.chunks_exact(rl).enumerate() {
            let p = src.decode(first + i as u64, r);
            if region.contains(p.xyz[0], p.xyz[1]) {
                t.xyz.push(p.xyz);
                t.ids.push(p.id);
                t.file_normals.push(None);
            }
        }
        Ok(())
    })
    .unwrap_or_else(|e| panic!("stages: {e}"));
    t.n_core = t.xyz.len();
    t.morton_order();
    t
}

/// Best wall time of `repeat` runs of `f`, in microseconds per point.
fn best(repeat: usize, n: usize, mut f: impl FnMut()) -> f64 {
    (0..repeat.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e6 / n as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let a = args();
    let t = load(&a);
    let n = t.xyz.len();
    assert!(
        n > a.k,
        "stages: only {n} points in the tile; give a bigger --tile"
    );
    eprintln!(
        "stages: {} — {n} points in a {} unit tile, k = {}, 1 thread, best of {}",
        a.file.display(),
        a.tile,
        a.k,
        a.repeat
    );
    let k = a.k;
    let mut lists = vec![0u32; n * k];
    let knn = best(a.repeat, n, || {
        let index = NeighbourIndex::build(&t.xyz, &t.ids, k).expect("index");
        let mut s = KnnScratch::default();
        let mut out = Vec::with_capacity(k);
        // In the index's query order, as the engine's k-NN tasks query (core::compute).
        let mut order: Vec<(u64, usize)> = (0..n).map(|i| (index.query_key(i), i)).collect();
        order.sort_unstable();
        for &(_, i) in &order {
            index.knn(i, k, &mut s, &mut out);
            lists[i * k..(i + 1) * k].copy_from_slice(&out);
        }
    });
    let origin = t.xyz[0];
    let local: Vec<[f32; 3]> = t
        .xyz
        .iter()
        .map(|p| sub(*p, origin).map(|c| c as f32))
        .collect();
    let mut checksum = 0u64;
    let kiddo = best(a.repeat, n, || {
        let tree: ImmutableKdTree<f32, 3> =
            ImmutableKdTree::new_from_slice(&local).expect("kiddo tree");
        for q in &local {
            let nn = tree
                .query(q)
                .nearest_n::<SquaredEuclidean<f32>>(NonZeroUsize::new(k).expect("k > 0"))
                .execute();
            checksum = checksum.wrapping_add(nn[k - 1].item as u64);
        }
    });
    let mut normals = vec![None; n];
    let pca = best(a.repeat, n, || {
        for (i, nrm) in normals.iter_mut().enumerate() {
            *nrm = pca_normal(&t.xyz, &lists[i * k..(i + 1) * k])
                .map(|v| orient(v, t.xyz[i], Orientation::Up));
        }
    });
    let estimator = EstimatorKind::CncAvgHexagram.build(&EstimatorParams::default());
    let mut buf = NeighbourhoodBuf::with_capacity(k);
    let mut h_sum = 0.0;
    let est = best(a.repeat, n, || {
        for i in 0..n {
            let c = buf.estimate(
                estimator.as_ref(),
                &t.xyz,
                &normals,
                i,
                &lists[i * k..(i + 1) * k],
                &mut [],
            );
            if c.h.is_finite() {
                h_sum += c.h;
            }
        }
    });
    // Outside the timed loop, so that the estimator's stage stores nothing more than before.
    let curvatures: Vec<_> = (0..n)
        .map(|i| {
            let list = &lists[i * k..(i + 1) * k];
            buf.estimate(estimator.as_ref(), &t.xyz, &normals, i, list, &mut [])
        })
        .collect();
    let mut slope_sum = 0.0;
    // Point by point in the tile's order, as the tiles stage computes them (there right after
    // each point's estimate).
    let terrain = best(a.repeat, n, || {
        for (nrm, c) in normals.iter().zip(&curvatures) {
            if let Some(nrm) = nrm {
                let v = TerrainValues::of(*nrm, c);
                if v.slope_deg.is_finite() {
                    slope_sum += v.slope_deg;
                }
            }
        }
    });
    // The sums read by black_box: a stage whose results nobody reads could be optimised away.
    std::hint::black_box([h_sum, checksum as f64, slope_sum]);
    println!("stage                        us/point");
    println!("k-NN (tilecurv, exact)       {knn:8.3}");
    println!(
        "k-NN (kiddo nearest_n, f32)  {kiddo:8.3}   ratio kiddo/tilecurv {:.2}",
        kiddo / knn
    );
    println!("PCA normals                  {pca:8.3}");
    println!("cnc-avg-hexagram             {est:8.3}");
    println!(
        "sum                          {:8.3}   = {:.0} points/s per core",
        knn + pca + est,
        1e6 / (knn + pca + est)
    );
    println!(
        "terrain values               {terrain:8.3}   {:.1}% of the sum",
        100.0 * terrain / (knn + pca + est)
    );
}
