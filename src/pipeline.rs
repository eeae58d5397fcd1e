//! The run: scan the input into buckets, plan the tiles, push them through a bounded pipeline
//! (loader -> compute -> result writer, in scoped threads joined by crossbeam channels, one
//! rayon pool for the per-point work), then assemble the output. The first error cancels the
//! run; the work directory is removed whatever happens.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crossbeam_channel::bounded;

use crate::assemble::assemble;
use crate::bucket::Buckets;
use crate::columns::ColumnSet;
use crate::compute::{compute_tile, ComputeParams, PointResult};
use crate::config::{ColumnType, Config};
use crate::crs::UnitSource;
use crate::error::{Error, Result};
use crate::estimate::flags;
use crate::normals::Orientation;
use crate::plan::{plan, TileGrid, TileKey, TileSpec};
use crate::progress::Reporter;

use crate::tile::{load_tile, TilePoints};

/// What a finished run reports.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Points written.
    pub points: u64,
    /// Points whose curvature is undefined (flag in `flags::UNDEFINED`).
    pub undefined: u64,
    /// Tiles processed.
    pub tiles: usize,
    /// Points recomputed with a wider halo after verification.
    pub retried: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// Removes the work directory when dropped, so no run leaves one behind.
struct WorkDir(PathBuf);

impl Drop for WorkDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `tilecurv process` as configured.
pub fn run(cfg: &Config, reporter: &dyn Reporter, cancel: &AtomicBool) -> Result<Summary> {
    let started = Instant::now();
    cfg.validate()?;
    if same_file(&cfg.input, &cfg.output) {
        return Err(Error::Usage(format!(
            "{}: the output would overwrite the input; choose another output path",
            cfg.output.display()
        )));
    }
    crate::sink::check_output_path(&cfg.output)?;
    let source = crate::source::open(&cfg.input)?;
    let unit = source.unit();
    let (unit_name, metres) = match &unit {
        UnitSource::Wkt(u) | UnitSource::GeoTiff(u) => (u.symbol(), Some(u)),
        UnitSource::Unknown(why) => {
            if cfg.tile.has_unit() {
                reporter.warn(&format!(
                    "{}: {why}; --tile {} is taken in file units",
                    cfg.input.display(),
                    cfg.tile
                ));
            }
            ("unit".to_string(), None)
        }
    };
    let tile_size = cfg.tile.in_file_units(metres);
    let use_file_normals = source.has_normals() && !cfg.ignore_file_normals;
    reporter.info(&format!(
        "{}: {} points, {}, unit {unit_name}; tile {} = {tile_size:.3} {unit_name}; normals {}",
        cfg.input.display(),
        source.len(),
        source.describe(),
        cfg.tile,
        if use_file_normals {
            "from the file (NormalX/Y/Z)"
        } else {
            "by PCA"
        },
    ));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()
        .map_err(|e| Error::Internal(format!("thread pool: {e}")))?;
    let estimator = crate::estimate::build(&cfg.estimator, &cfg.params)
        .ok_or_else(|| Error::Usage(format!("unknown estimator {:?}", cfg.estimator)))?;
    if source.has_normals() && cfg.ignore_file_normals {
        return Err(Error::Usage(format!(
            "{}: --ignore-file-normals: the input already has NormalX/Y/Z columns, and the estimated normals cannot be written under the same names; drop the option to use the file's normals",
            cfg.input.display()
        )));
    }
    let cols = ColumnSet {
        ty: cfg.column_type,
        normals: !source.has_normals(),
        directions: cfg.directions,
        unit: unit_name.clone(),
    };

    // Pass 1: scan into buckets.
    reporter.phase("scan", source.len());
    let grid = TileGrid { size: tile_size };
    let (buckets, stats) = pool.install(|| {
        Buckets::scan(source.as_ref(), grid, cfg.chunk_points, |n| {
            reporter.advance(n);
            if cancel.load(Ordering::Relaxed) {
                Err(Error::Interrupted)
            } else {
                Ok(())
            }
        })
    })?;
    reporter.finish_phase();
    let tplan = plan(&stats, tile_size, cfg.k);
    reporter.info(&format!(
        "plan: {} tiles of {tile_size:.3} {unit_name}",
        tplan.tiles.len()
    ));

    let work = WorkDir(make_work_dir(cfg)?);
    let params = ComputeParams {
        k: cfg.k,
        orientation: cfg.orientation,
        use_file_normals,
        estimator: estimator.as_ref(),
    };

    // Pass 2: tiles through the pipeline.
    reporter.phase("curvature", source.len());
    let (result_files, undefined, retried) =
        std::thread::scope(|s| -> Result<(Vec<PathBuf>, u64, u64)> {
            let (tile_tx, tile_rx) = bounded::<(TileSpec, TilePoints)>(2);
            let (res_tx, res_rx) = bounded::<(TileKey, Vec<PointResult>)>(2);
            let (buckets, grid, tplan) = (&buckets, &grid, &tplan);
            let loader = s.spawn(move || {
                for spec in &tplan.tiles {
                    if cancel.load(Ordering::Relaxed) {
                        return;
                    }
                    let t = load_tile(buckets, grid, spec.key, spec.halo, None);
                    if tile_tx.send((spec.clone(), t)).is_err() {
                        return; // the compute stage stopped
                    }
                }
            });
            let writer = s.spawn(|| -> Result<Vec<PathBuf>> {
                let mut files = Vec::new();
                for (key, mut results) in res_rx {
                    files.push(crate::results::write_tile(
                        &work.0,
                        key,
                        &mut results,
                        &cols,
                    )?);
                }
                Ok(files)
            });
            let mut undefined = 0u64;
            let mut retried = 0u64;
            let mut failure = None;
            for (spec, tile) in tile_rx.iter() {
                if cancel.load(Ordering::Relaxed) {
                    failure = Some(Error::Interrupted);
                    break;
                }
                let (results, again) = pool.install(|| {
                    compute_verified(buckets, grid, &tplan.scene, &spec, tile, &params)
                });
                retried += again;
                undefined += results
                    .iter()
                    .filter(|r| r.curvature.flags & flags::UNDEFINED != 0)
                    .count() as u64;
                reporter.advance(results.len() as u64);
                if res_tx.send((spec.key, results)).is_err() {
                    break; // the writer failed; its error is reported below
                }
            }
            drop(tile_rx);
            drop(res_tx);
            let _ = loader.join();
            let files = writer
                .join()
                .map_err(|_| Error::Internal("result writer panicked".into()))?;
            if let Some(e) = failure {
                return Err(e);
            }
            Ok((files?, undefined, retried))
        })?;
    reporter.finish_phase();
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Interrupted);
    }

    // Pass 3: assemble in file order.
    reporter.phase("write", source.len());
    let provenance = provenance(cfg, &unit_name, tile_size, use_file_normals);
    assemble(
        source.as_ref(),
        &result_files,
        &cols,
        &cfg.output,
        &provenance,
        cfg.chunk_points,
        reporter,
        cancel,
    )?;
    reporter.finish_phase();
    drop(work);
    Ok(Summary {
        points: source.len(),
        undefined,
        tiles: tplan.tiles.len(),
        retried,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Computes a tile, recomputing with a doubled halo the core points whose neighbourhoods were
/// not verified complete, until none is left (the loaded region eventually covers the scene,
/// where every neighbourhood is complete). Returns the results and the number of retried points.
fn compute_verified(
    buckets: &Buckets,
    grid: &TileGrid,
    scene: &crate::plan::Rect,
    spec: &TileSpec,
    tile: TilePoints,
    params: &ComputeParams<'_>,
) -> (Vec<PointResult>, u64) {
    let mut outcome = compute_tile(&tile, scene, params);
    let mut results = std::mem::take(&mut outcome.done);
    let mut retry = outcome.retry;
    let mut halo = spec.halo;
    let mut retried = 0u64;
    while !retry.is_empty() {
        retried += retry.len() as u64;
        halo *= 2.0;
        let only: HashSet<u64> = retry.iter().copied().collect();
        let t = load_tile(buckets, grid, spec.key, halo, Some(&only));
        let covers = t.region.covers(scene);
        let mut o = compute_tile(&t, scene, params);
        results.append(&mut o.done);
        retry = o.retry;
        debug_assert!(
            !covers || retry.is_empty(),
            "a region covering the scene must verify"
        );
    }
    (results, retried)
}

fn make_work_dir(cfg: &Config) -> Result<PathBuf> {
    let base = match &cfg.work_dir {
        Some(d) => d.clone(),
        None => cfg
            .output
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from(".")),
    };
    let name = cfg
        .output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let dir = base.join(format!(".{name}.tilecurv-work-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| Error::write(&dir, e))?;
    Ok(dir)
}

/// The provenance text stored in the output: tool version, estimator and every parameter.
fn provenance(cfg: &Config, unit: &str, tile_size: f64, file_normals: bool) -> String {
    let orientation = match cfg.orientation {
        Orientation::Up => "up".to_string(),
        Orientation::Viewpoint(v) => format!("viewpoint:{},{},{}", v[0], v[1], v[2]),
    };
    let input = cfg
        .input
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!(
        "tilecurv {}\ninput={input}\nestimator={}\nk={}\nseed={}\ntriangles={}\nnormals={}\norientation={orientation}\ntile={} ({tile_size} {unit})\ncolumns={}\ndirections={}\nsign=positive where the surface bends away from its normal; curvature in 1/{unit}\n",
        env!("CARGO_PKG_VERSION"),
        cfg.estimator,
        cfg.k,
        cfg.params.seed,
        cfg.params.triangles,
        if file_normals { "file" } else { "pca" },
        cfg.tile,
        match cfg.column_type {
            ColumnType::F32 => "f32",
            ColumnType::F64 => "f64",
        },
        cfg.directions,
    )
}
