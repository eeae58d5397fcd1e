//! `--dry-run`: the real stages on a scratch work directory, stopped after one tile. Scans the
//! inputs (the plan needs every point's tile), plans, computes the median tile with the same
//! code as a run, and prints the plan with its estimates of memory, disk and time; then removes
//! the scratch directory. Nothing is written beside the output.

use crate::progress::out;
use std::path::Path;
use std::time::Instant;

use crate::core::compute::TileBuffers;
use crate::core::plan::TileSpec;
use crate::core::point::BUCKET_POINT_BYTES;
use crate::core::tasks::TaskLayout;
use crate::core::tile::Part;
use crate::error::Result;
use crate::io::workdir::bucket::load_tile;
use crate::io::workdir::results::estimated_point_bytes;
use crate::io::workdir::WorkDir;
use crate::run::bucket::bucket_all;
use crate::run::spec::RunSpec;
use crate::run::tiles::TileJob;
use crate::run::{Exec, Run};

/// Runs the dry run for `spec`, whose real work directory would be `work_path`.
pub(crate) fn dry_run(spec: RunSpec, exec: &Exec<'_>, work_path: &Path) -> Result<()> {
    let scratch = WorkDir::open_scratch(work_path, &spec.manifest())?;
    let layout = TaskLayout::single(&spec.input_points());
    let run = Run {
        spec,
        work: scratch,
        layout,
    };
    let r = estimate(&run, exec, work_path);
    run.work.remove();
    r
}

/// Points a tile loads: its core plus the halo ring at the same density.
fn estimated_loaded_points(t: &TileSpec, size: f64) -> usize {
    let ring = ((size + 2.0 * t.halo) / size).powi(2);
    (t.count as f64 * ring) as usize
}

fn estimate(run: &Run, exec: &Exec<'_>, work_path: &Path) -> Result<()> {
    let spec = &run.spec;
    let t0 = Instant::now();
    let scan = bucket_all(run, exec)?;
    let scan_s = t0.elapsed().as_secs_f64();
    let params = spec.compute_params(&scan.stats);
    let tplan = spec.tile_plan(&scan.stats);
    let mut counts: Vec<u64> = tplan.tiles.iter().map(|t| t.count).collect();
    counts.sort_unstable();
    let median = counts[counts.len() / 2];
    let mut us_per_point = f64::NAN;
    let mut halo_factor = 1.0;
    if let Some(sample) = tplan.tiles.iter().find(|t| t.count == median) {
        let whole = Part::whole(spec.grid.rect(sample.key));
        let t = load_tile(
            &scan.buckets,
            sample.key,
            &whole,
            sample.halo,
            None,
            &tplan.per_tile,
        )?;
        halo_factor = t.xyz.len() as f64 / t.n_core.max(1) as f64;
        drop(t);
        let job = TileJob {
            buckets: &scan.buckets,
            plan: &tplan,
            params: &params,
            memory: exec.memory,
        };
        let t1 = Instant::now();
        let t = job.compute(sample, exec, &exec.pool, &mut TileBuffers::default())?;
        us_per_point = t1.elapsed().as_secs_f64() * 1e6 / t.results.len().max(1) as f64;
    }
    let n = scan.stats.count as f64;
    let m = &exec.memory;
    let biggest = tplan
        .tiles
        .iter()
        .map(|t| estimated_loaded_points(t, spec.grid.size))
        .max()
        .unwrap_or(0);
    let buckets_bytes = scan.stats.count as usize * BUCKET_POINT_BYTES;
    let in_memory = buckets_bytes <= m.buckets_bytes;
    let tiles_mem = (biggest * m.tile_point_bytes).min(m.per_tile_bytes) * m.tiles_in_flight;
    let peak = if in_memory {
        buckets_bytes + tiles_mem
    } else {
        m.bucket_cache_bytes + tiles_mem
    };
    // Spilled buckets of LAS input take about 5 bytes a point (integer coordinates, zstd; raw
    // f64 float inputs up to 25).
    let bucket_bytes = if in_memory { 0.0 } else { 5.0 };
    let result_bytes = estimated_point_bytes(&spec.cols);
    let disk = n * (bucket_bytes + result_bytes);
    let est = 2.0 * scan_s + n * us_per_point * 1e-6;
    // The tile's edge in the CRS unit ("50 m"; "file units" without one).
    let edge = crate::io::raster::length_text(spec.grid.size, &spec.cols.unit);
    out!(
        "plan: {} points in {} tiles of {edge}; points per tile: min {}, median {median}, max {}",
        scan.stats.count,
        tplan.tiles.len(),
        counts[0],
        counts[counts.len() - 1]
    );
    out!(
        "halo: {:.1}% extra points loaded on the median tile",
        100.0 * (halo_factor - 1.0)
    );
    out!("memory: budget {} MiB; buckets {}; expected peak about {} MiB plus ~60 MiB for the program", m.budget_bytes >> 20, if in_memory { "in memory" } else { "spilled to disk" }, peak.min(m.budget_bytes) >> 20);
    out!(
        "work directory: {} (about {:.0} MiB at the peak)",
        work_path.display(),
        disk / (1 << 20) as f64
    );
    out!("time: scan {scan_s:.1} s; curvature {us_per_point:.2} us/point on the median tile with {} threads; estimated total {est:.0} s", exec.pool.current_num_threads());
    Ok(())
}
