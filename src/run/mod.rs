//! The run: scan the inputs into buckets, plan the tiles, push the tiles not yet done through a
//! bounded pipeline (two tile drivers that load and compute -> result writer, in scoped threads
//! joined by a crossbeam channel, one rayon pool for the per-point work), then assemble one
//! output per input. The
//! work directory keeps buckets and finished tiles, so an interrupted run resumes where it
//! stopped; it is removed only after every output is written.

pub mod assemble;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crossbeam_channel::bounded;

use crate::config::{ColumnType, Config, OrientMode};
use crate::core::compute::{compute_tile, ComputeParams, PointResult, Shared, TileOutcome};
use crate::core::estimate::flags;
use crate::core::plan::{plan, ScanStats, TileGrid, TilePlan, TileSpec};
use crate::core::tile::{load_tile, split_parts, Part, TilePoints};
use crate::error::{Error, Result};
use crate::io::bucket::{Buckets, ScanInput, POINT_BYTES};
use crate::io::columns::ColumnSet;
use crate::io::crs::UnitSource;
use crate::io::results::{is_complete, tile_path, Merger, TileSidecar};
use crate::io::source::PointSource;
use crate::io::workdir::{Fingerprint, Resume, WorkDir};
use crate::progress::Reporter;
use crate::run::assemble::assemble;

/// What a finished run reports.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Points written.
    pub points: u64,
    /// Points whose curvature is undefined (flag in `flags::UNDEFINED`), among those computed
    /// in this run.
    pub undefined: u64,
    /// Tiles in the plan.
    pub tiles: usize,
    /// Tiles found finished from an earlier, interrupted run.
    pub tiles_resumed: usize,
    /// Points recomputed with a wider halo after verification.
    pub retried: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Bytes a loaded tile needs per point (coordinates, ids, neighbour list, normal, result), for
/// the budget; measured layout of `TilePoints` and `compute_tile`'s buffers, rounded up.
fn tile_point_bytes(k: usize) -> usize {
    300 + 4 * k
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// The output path of each input: the output itself for one input (or a file in it if it is a
/// directory), `<output dir>/<input file name>` for several.
pub fn output_paths(cfg: &Config) -> Result<Vec<PathBuf>> {
    let is_dir = cfg.output.is_dir() || cfg.output.as_os_str().to_string_lossy().ends_with('/');
    if cfg.inputs.len() == 1 && !is_dir {
        return Ok(vec![cfg.output.clone()]);
    }
    if !is_dir {
        return Err(Error::Usage(format!(
            "{}: with {} inputs the output must be a directory (one output per input, same file name); end it with / to create it",
            cfg.output.display(),
            cfg.inputs.len()
        )));
    }
    std::fs::create_dir_all(&cfg.output).map_err(|e| Error::write(&cfg.output, e))?;
    let mut outs: Vec<PathBuf> = Vec::new();
    for input in &cfg.inputs {
        let name = input
            .file_name()
            .ok_or_else(|| Error::Usage(format!("{}: not a file name", input.display())))?;
        let out = cfg.output.join(name);
        if outs.contains(&out) {
            return Err(Error::Usage(format!(
                "two inputs are named {}: their outputs would collide in {}",
                name.to_string_lossy(),
                cfg.output.display()
            )));
        }
        outs.push(out);
    }
    Ok(outs)
}

/// The manifest of a run: a fingerprint of the inputs (path, size, modification time, header)
/// and of every parameter that changes the output, then the same in words for a person.
fn manifest(cfg: &Config, sources: &[Box<dyn PointSource>], tile_size: f64) -> String {
    let mut fp = Fingerprint::default();
    let mut text = String::new();
    fp.text(env!("CARGO_PKG_VERSION"));
    for s in sources {
        let p = s.path();
        let meta = std::fs::metadata(p).ok();
        let size = meta.as_ref().map(|m| m.len()).unwrap_or(0);
        let mtime = meta
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let canon = p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
        fp.text(&canon.to_string_lossy())
            .text(&size.to_string())
            .text(&mtime.to_string())
            .text(&s.len().to_string());
        text.push_str(&format!(
            "input {} ({size} bytes, {} points)\n",
            canon.display(),
            s.len()
        ));
    }
    let params = format!(
        "estimator={} k={} params={:?} orientation={:?} ignore_file_normals={} directions={} features={} columns={:?} tile={} sample_faces={:?}",
        cfg.estimator,
        cfg.k,
        cfg.params,
        cfg.orientation,
        cfg.ignore_file_normals,
        cfg.directions,
        cfg.features,
        cfg.column_type,
        tile_size.to_bits(),
        cfg.sample_faces
    );
    fp.text(&params);
    format!(
        "tilecurv work directory, fingerprint {:016x}\n{text}{params}\n",
        fp.value()
    )
}

/// Runs `tilecurv process` as configured.
pub fn run(cfg: &Config, reporter: &dyn Reporter, cancel: &AtomicBool) -> Result<Summary> {
    let started = Instant::now();
    cfg.validate()?;
    let outputs = output_paths(cfg)?;
    for (input, output) in cfg.inputs.iter().zip(&outputs) {
        crate::io::sink::check_output_path(output)?;
        if same_file(input, output) || cfg.inputs.iter().any(|i| same_file(i, output)) {
            return Err(Error::Usage(format!(
                "{}: the output would overwrite an input; choose another output path",
                output.display()
            )));
        }
    }
    let sources = cfg
        .inputs
        .iter()
        .map(|p| match cfg.sample_faces {
            Some(n) => crate::io::source::open_sampled(p, n, cfg.params.seed),
            None => crate::io::source::open(p),
        })
        .collect::<Result<Vec<_>>>()?;

    // Units: every input must agree, the first one decides.
    let unit = sources[0].unit();
    for s in &sources[1..] {
        let u = s.unit();
        if u.unit().map(|u| u.metres) != unit.unit().map(|u| u.metres) {
            return Err(Error::Usage(format!(
                "{} and {} have different horizontal units ({:?} and {:?}); process them separately",
                sources[0].path().display(),
                s.path().display(),
                unit.unit().map(|u| u.symbol()),
                u.unit().map(|u| u.symbol())
            )));
        }
    }
    let (unit_name, metres) = match &unit {
        UnitSource::Wkt(u) | UnitSource::GeoTiff(u) => (u.symbol(), Some(u)),
        UnitSource::Unknown(why) => {
            if cfg.tile.has_unit() {
                reporter.warn(&format!(
                    "{}: {why}; --tile {} is taken in file units",
                    sources[0].path().display(),
                    cfg.tile
                ));
            }
            ("unit".to_string(), None)
        }
    };
    let tile_size = cfg.tile.in_file_units(metres);
    let with_normals = sources.iter().filter(|s| s.has_normals()).count();
    if with_normals != 0 && with_normals != sources.len() && !cfg.ignore_file_normals {
        return Err(Error::Usage(
            "some inputs have normals and others do not; process them separately (or use --ignore-file-normals)".into(),
        ));
    }
    let file_normals = with_normals > 0 && !cfg.ignore_file_normals;
    // Estimated normals are written as NormalX/Y/Z: an input that already has columns of those
    // names (a LAS file's normals) cannot take them.
    let named_normals = |s: &dyn PointSource| {
        s.properties()
            .iter()
            .any(|p| p.name.eq_ignore_ascii_case("NormalX"))
    };
    if cfg.ignore_file_normals {
        if let Some(s) = sources.iter().find(|s| named_normals(s.as_ref())) {
            return Err(Error::Usage(format!(
                "{}: --ignore-file-normals: the input already has NormalX/Y/Z columns, and the estimated normals cannot be written under the same names; drop the option to use the file's normals",
                s.path().display()
            )));
        }
    }
    let total: u64 = sources.iter().map(|s| s.len()).sum();
    for s in &sources {
        reporter.info(&format!(
            "{}: {} points, {}, unit {unit_name}; tile {} = {tile_size:.3} {unit_name}; normals {}",
            s.path().display(),
            s.len(),
            s.describe(),
            cfg.tile,
            if file_normals {
                "from the file (NormalX/Y/Z)"
            } else {
                "by PCA"
            },
        ));
    }
    let first_ids: Vec<u64> = sources
        .iter()
        .scan(0u64, |acc, s| {
            let f = *acc;
            *acc += s.len();
            Some(f)
        })
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()
        .map_err(|e| Error::Internal(format!("thread pool: {e}")))?;
    let estimator = crate::core::estimate::build(&cfg.estimator, &cfg.params)
        .ok_or_else(|| Error::Usage(format!("unknown estimator {:?}", cfg.estimator)))?;
    let cols = ColumnSet {
        ty: cfg.column_type,
        normals: !file_normals && !sources.iter().any(|s| named_normals(s.as_ref())),
        directions: cfg.directions,
        features: cfg.features,
        unit: unit_name.clone(),
    };
    // The orientation is resolved against the cloud's centroid once the scan has seen it.
    let params = ComputeParams {
        k: cfg.k,
        orientation: cfg.orientation.resolve([0.0; 3]),
        use_file_normals: file_normals,
        estimator: estimator.as_ref(),
        propagate: None,
    };
    let manifest = manifest(cfg, &sources, tile_size);
    let budget = cfg.memory_bytes as usize;
    let grid = TileGrid { size: tile_size };
    let work_path = cfg
        .work_dir
        .clone()
        .unwrap_or_else(|| crate::io::workdir::default_path(&outputs[0]));

    if cfg.dry_run {
        let dry = work_path.with_extension("dryrun");
        let wd = WorkDir::open(&dry, &manifest)?;
        let r = dry_run(
            cfg, &sources, &first_ids, grid, &wd, &pool, &params, reporter, cancel,
        );
        wd.remove();
        return r.map(|_| Summary {
            points: total,
            undefined: 0,
            tiles: 0,
            tiles_resumed: 0,
            retried: 0,
            seconds: started.elapsed().as_secs_f64(),
        });
    }

    let work = WorkDir::open(&work_path, &manifest)?;
    let r = run_in(
        cfg,
        reporter,
        cancel,
        &work,
        &sources,
        &outputs,
        &first_ids,
        grid,
        budget,
        &cols,
        &params,
        &pool,
        &unit_name,
        total,
        file_normals,
    );
    match &r {
        // Interrupted or out of disk: keep the work, the same command resumes.
        Err(Error::Interrupted) | Err(Error::WriteIo { .. }) => drop(work),
        // Done, or a failure that a rerun would repeat (bad input, a bug): nothing to keep.
        _ => work.remove(),
    }
    r.map(|(undefined, retried, tiles, tiles_resumed)| Summary {
        points: total,
        undefined,
        tiles,
        tiles_resumed,
        retried,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The part of [`run`] that uses the work directory.
#[allow(clippy::too_many_arguments)]
fn run_in(
    cfg: &Config,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
    work: &WorkDir,
    sources: &[Box<dyn PointSource>],
    outputs: &[PathBuf],
    first_ids: &[u64],
    grid: TileGrid,
    budget: usize,
    cols: &ColumnSet,
    params: &ComputeParams<'_>,
    pool: &rayon::ThreadPool,
    unit_name: &str,
    total: u64,
    file_normals: bool,
) -> Result<(u64, u64, usize, usize)> {
    let tile_size = grid.size;
    match work.resume {
        Resume::Fresh => {}
        Resume::Resumed => reporter.info(&format!("resuming the interrupted run in {}", work.path().display())),
        Resume::Discarded => reporter.warn(&format!(
            "{}: the work left there came from other inputs or parameters: discarded, starting over",
            work.path().display()
        )),
    }

    // Pass 1: scan into buckets (or reuse the buckets of an interrupted run).
    let spill_dir = work.path().join("buckets");
    let reopened = if work.resume == Resume::Resumed {
        Buckets::reopen(&spill_dir, grid)
    } else {
        None
    };
    let (buckets, stats) = match reopened {
        Some(b) => {
            reporter.info("reusing the buckets of the interrupted run");
            b
        }
        None => scan(
            sources,
            first_ids,
            grid,
            chunk_points(cfg, sources),
            budget * 2 / 5,
            &spill_dir,
            pool,
            reporter,
            cancel,
        )?,
    };
    let params = &ComputeParams {
        orientation: cfg.orientation.resolve(stats.centroid),
        propagate: (cfg.orientation == OrientMode::Propagate).then_some(stats.centroid),
        ..*params
    };
    let tplan = plan(&stats, tile_size, cfg.k);
    let results_dir = work.path().join("results");
    std::fs::create_dir_all(&results_dir).map_err(|e| Error::write(&results_dir, e))?;
    let todo: Vec<TileSpec> = tplan
        .tiles
        .iter()
        .filter(|t| !tile_done(&results_dir, t, cols, params.propagate.is_some()))
        .cloned()
        .collect();
    let resumed_tiles = tplan.tiles.len() - todo.len();
    let done_points: u64 = stats.count - todo.iter().map(|t| t.count).sum::<u64>();
    reporter.info(&format!(
        "plan: {} tiles of {tile_size:.3} {unit_name}{}; buckets {}",
        tplan.tiles.len(),
        if resumed_tiles > 0 {
            format!(", {resumed_tiles} already done")
        } else {
            String::new()
        },
        if buckets.spilled() {
            "spilled to the work directory"
        } else {
            "in memory"
        }
    ));

    // Memory: buckets in memory took up to 2/5 of the budget; spilled ones leave room for a
    // cache of decoded neighbours. Tiles in flight share the rest.
    let tile_budget = if buckets.spilled() {
        buckets.set_cache_budget(budget / 5);
        budget * 2 / 5
    } else {
        budget * 2 / 5
    };
    // Two parts in flight (one computing, one loaded); a tile whose core and halo would need
    // more than its share is computed in quadtree parts. Only the raw bucket of a tile (about
    // POINT_BYTES per point) must fit whole.
    let in_flight = 2;
    let per_part = tile_budget / in_flight;
    let max_core_points = (per_part / tile_point_bytes(cfg.k) * 2 / 3).max(1024);
    if let Some(t) = todo
        .iter()
        .find(|t| t.count as usize * POINT_BYTES > per_part)
    {
        reporter.warn(&format!(
            "tile {:?} holds {} points, whose raw bucket alone exceeds the {} MiB the budget leaves per tile; memory may exceed --memory: use a smaller --tile or a larger --memory",
            t.key,
            t.count,
            per_part >> 20
        ));
    }

    // Pass 2: the tiles not done yet.
    reporter.phase("curvature", stats.count);
    reporter.advance(done_points);
    let outcome = run_tiles(
        &todo,
        &tplan,
        &buckets,
        &grid,
        &results_dir,
        cols,
        params,
        pool,
        in_flight,
        max_core_points,
        reporter,
        cancel,
    );
    let (undefined, retried) = match outcome {
        Ok(v) => v,
        Err(e) => {
            if matches!(e, Error::Interrupted) {
                let done = tplan
                    .tiles
                    .iter()
                    .filter(|t| tile_done(&results_dir, t, cols, params.propagate.is_some()))
                    .count();
                reporter.warn(&format!(
                    "interrupted after {done} of {} tiles; the work is kept in {}",
                    tplan.tiles.len(),
                    work.path().display()
                ));
            }
            return Err(e);
        }
    };
    reporter.finish_phase();
    drop(buckets);

    // Pass 3: assemble each input in file order.
    let files: Vec<PathBuf> = tplan
        .tiles
        .iter()
        .map(|t| tile_path(&results_dir, t.key))
        .collect();
    let flips = match params.propagate {
        Some(_) => Some(resolve_orientation(&results_dir, &tplan, reporter)?),
        None => None,
    };
    let mut merger = Merger::open(&results_dir, &files, cols)?;
    reporter.phase("write", total);
    let provenance = provenance(cfg, unit_name, tile_size, file_normals);
    for ((source, output), first) in sources.iter().zip(outputs).zip(first_ids) {
        assemble(
            source.as_ref(),
            *first,
            &mut merger,
            flips.as_deref(),
            cols,
            output,
            &provenance,
            chunk_points(cfg, sources),
            reporter,
            cancel,
        )?;
    }
    reporter.finish_phase();
    Ok((undefined, retried, tplan.tiles.len(), resumed_tiles))
}

/// Whether a tile of the plan is finished: its result file is complete (and, with
/// `--orient propagate`, its orientation sidecar is there: it is renamed first).
fn tile_done(dir: &Path, t: &TileSpec, cols: &ColumnSet, propagate: bool) -> bool {
    (!propagate || crate::io::results::orientation_path(dir, t.key).exists())
        && is_complete(&tile_path(dir, t.key), t.count, cols)
}

/// `--orient propagate`, across tiles: reads every tile's patch anchors and shared normals,
/// turns the normals that two patches both oriented into votes, solves one sign per patch
/// (orient::patch_signs) and returns, per tile of the plan, which of its patches to flip.
fn resolve_orientation(
    dir: &Path,
    tplan: &TilePlan,
    reporter: &dyn Reporter,
) -> Result<Vec<Vec<bool>>> {
    let mut anchors = Vec::new();
    let mut shared = Vec::new();
    let mut offsets = Vec::with_capacity(tplan.tiles.len() + 1);
    offsets.push(0u32);
    for t in &tplan.tiles {
        let sc =
            crate::io::results::read_sidecar(&crate::io::results::orientation_path(dir, t.key))?;
        let base = *offsets.last().unwrap_or(&0);
        anchors.extend(sc.anchors.iter().map(|a| crate::core::orient::PatchAnchor {
            patch: base + a.patch,
            ..*a
        }));
        shared.extend(sc.shared.iter().map(|s| crate::core::orient::SharedNormal {
            patch: base + s.patch,
            ..*s
        }));
        offsets.push(base + sc.anchors.len() as u32);
    }
    let total = *offsets.last().unwrap_or(&0) as usize;
    let votes = crate::core::orient::votes_from_shared(&mut shared);
    let signs = crate::core::orient::patch_signs(total, &votes, &anchors);
    reporter.info(&format!(
        "orientation: {total} patches in {} tiles, {} shared normals voted, {} against the chosen signs, {} patches flipped",
        tplan.tiles.len(),
        signs.votes,
        signs.contradicted,
        signs.flip.iter().filter(|f| **f).count()
    ));
    Ok(offsets
        .windows(2)
        .map(|w| signs.flip[w[0] as usize..w[1] as usize].to_vec())
        .collect())
}

/// Points per read chunk: the user's choice, capped so that a chunk of raw records takes at
/// most 1/16 of the memory budget.
fn chunk_points(cfg: &Config, sources: &[Box<dyn PointSource>]) -> usize {
    let widest = sources
        .iter()
        .map(|s| s.record_length())
        .max()
        .unwrap_or(1)
        .max(1)
        + 64;
    cfg.chunk_points
        .min((cfg.memory_bytes as usize / 16 / widest).max(1024))
}

/// Points a tile loads: its core plus the halo ring at the same density.
fn estimated_loaded_points(t: &TileSpec, size: f64) -> usize {
    let ring = ((size + 2.0 * t.halo) / size).powi(2);
    (t.count as f64 * ring) as usize
}

#[allow(clippy::too_many_arguments)]
fn scan(
    sources: &[Box<dyn PointSource>],
    first_ids: &[u64],
    grid: TileGrid,
    chunk_points: usize,
    mem_budget: usize,
    spill_dir: &Path,
    pool: &rayon::ThreadPool,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<(Buckets, ScanStats)> {
    let total = sources.iter().map(|s| s.len()).sum();
    reporter.phase("scan", total);
    let inputs: Vec<ScanInput<'_>> = sources
        .iter()
        .zip(first_ids)
        .map(|(s, &first_id)| ScanInput {
            source: s.as_ref(),
            first_id,
        })
        .collect();
    let r = pool.install(|| {
        Buckets::scan(&inputs, grid, chunk_points, mem_budget, spill_dir, |n| {
            reporter.advance(n);
            if cancel.load(Ordering::Relaxed) {
                Err(Error::Interrupted)
            } else {
                Ok(())
            }
        })
    })?;
    reporter.finish_phase();
    Ok(r)
}

/// Runs `todo` with `in_flight` drivers and a result writer. Each driver takes the next tile,
/// loads it (part by part when it is too dense for its share of the budget) and computes it on
/// the shared rayon pool, so that one tile's loading and serial steps overlap another's parallel
/// ones; the writer journals each finished tile. Tiles finish in any order: each has its own
/// result file, and the parts of a tile stay with one driver, in order (patch numbering).
/// Returns (undefined points, retried points).
#[allow(clippy::too_many_arguments)]
fn run_tiles(
    todo: &[TileSpec],
    tplan: &TilePlan,
    buckets: &Buckets,
    grid: &TileGrid,
    results_dir: &Path,
    cols: &ColumnSet,
    params: &ComputeParams<'_>,
    pool: &rayon::ThreadPool,
    in_flight: usize,
    max_core_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<(u64, u64)> {
    type Finished = (TileSpec, Vec<PointResult>, Option<TileSidecar>);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let failure: std::sync::Mutex<Option<Error>> = std::sync::Mutex::new(None);
    let fail = |e: Error| {
        stop.store(true, Ordering::Relaxed);
        if let Ok(mut f) = failure.lock() {
            f.get_or_insert(e);
        }
    };
    let undefined = std::sync::atomic::AtomicU64::new(0);
    let retried = std::sync::atomic::AtomicU64::new(0);
    // One tile, all its parts: the results and the orientation sidecar.
    let tile = |spec: &TileSpec| -> Result<(Vec<PointResult>, TileSidecar)> {
        let whole = Part::whole(grid.rect(spec.key));
        let parts = if (spec.count as usize) <= max_core_points {
            vec![whole]
        } else {
            split_parts(&buckets.core(spec.key)?, whole, max_core_points)
        };
        let mut gathered = Vec::new();
        let mut sidecar = TileSidecar::default();
        for part in parts {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            let t = load_tile(buckets, spec.key, &part, spec.halo, None, &tplan.per_tile)?;
            let (mut results, again) = pool.install(|| {
                compute_verified(buckets, tplan, spec, &part, t, params, &mut sidecar)
            })?;
            retried.fetch_add(again, Ordering::Relaxed);
            undefined.fetch_add(
                results
                    .iter()
                    .filter(|r| r.curvature.flags & flags::UNDEFINED != 0)
                    .count() as u64,
                Ordering::Relaxed,
            );
            reporter.advance(results.len() as u64);
            gathered.append(&mut results);
        }
        Ok((gathered, sidecar))
    };
    std::thread::scope(|s| -> Result<(u64, u64)> {
        let (res_tx, res_rx) = bounded::<Finished>(1);
        let writer = s.spawn(move || -> Result<()> {
            let mut journal = crate::io::results::Journal::new(results_dir);
            for (spec, mut results, sidecar) in res_rx {
                journal.add(spec.key, spec.index, &mut results, sidecar.as_ref(), cols)?;
            }
            // Also after an interruption: the tiles finished so far become durable.
            journal.commit()
        });
        for _ in 0..in_flight.max(1) {
            let res_tx = res_tx.clone();
            let (next, stop, tile, fail) = (&next, &stop, &tile, &fail);
            s.spawn(move || loop {
                if stop.load(Ordering::Relaxed) {
                    return;
                }
                if cancel.load(Ordering::Relaxed) {
                    fail(Error::Interrupted);
                    return;
                }
                let Some(spec) = todo.get(next.fetch_add(1, Ordering::Relaxed)) else {
                    return;
                };
                match tile(spec) {
                    Ok((results, sidecar)) => {
                        let sidecar = params.propagate.map(|_| sidecar);
                        if res_tx.send((spec.clone(), results, sidecar)).is_err() {
                            // The writer failed; its error is reported below.
                            stop.store(true, Ordering::Relaxed);
                            return;
                        }
                    }
                    Err(e) => {
                        fail(e);
                        return;
                    }
                }
            });
        }
        drop(res_tx);
        let written = writer
            .join()
            .map_err(|_| Error::Internal("result writer panicked".into()))?;
        if let Some(e) = failure.lock().ok().and_then(|mut f| f.take()) {
            return Err(e);
        }
        written?;
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        Ok((
            undefined.load(Ordering::Relaxed),
            retried.load(Ordering::Relaxed),
        ))
    })
}

/// Computes a tile, recomputing with a doubled halo the core points whose neighbourhoods were
/// not verified complete, until none is left (the loaded region eventually covers the scene,
/// where every neighbourhood is complete). Returns the results and the number of retried points.
fn compute_verified(
    buckets: &Buckets,
    tplan: &TilePlan,
    spec: &TileSpec,
    part: &Part,
    tile: TilePoints,
    params: &ComputeParams<'_>,
    sidecar: &mut TileSidecar,
) -> Result<(Vec<PointResult>, u64)> {
    // With `--orient propagate` each pass numbers its patches after the tile's earlier ones
    // and reports their anchors and shared normals.
    let keep = |o: &mut TileOutcome, sidecar: &mut TileSidecar| {
        if let Some(or) = o.orientation.take() {
            sidecar.anchors.extend(or.anchors);
            sidecar.shared.extend(or.shared);
        }
    };
    let band = Shared::Band {
        rect: part.rect,
        width: spec.halo,
    };
    let mut outcome = compute_tile(
        &tile,
        &tplan.scene,
        params,
        sidecar.anchors.len() as u32,
        band,
    );
    keep(&mut outcome, sidecar);
    drop(tile);
    let mut results = std::mem::take(&mut outcome.done);
    let mut retry = outcome.retry;
    let mut halo = spec.halo;
    let mut retried = 0u64;
    while !retry.is_empty() {
        retried += retry.len() as u64;
        halo *= 2.0;
        let only: HashSet<u64> = retry.iter().copied().collect();
        let t = load_tile(buckets, spec.key, part, halo, Some(&only), &tplan.per_tile)?;
        let covers = t.region.covers(&tplan.scene);
        let mut o = compute_tile(
            &t,
            &tplan.scene,
            params,
            sidecar.anchors.len() as u32,
            Shared::All,
        );
        keep(&mut o, sidecar);
        results.append(&mut o.done);
        retry = o.retry;
        if covers && !retry.is_empty() {
            return Err(Error::Internal(format!(
                "tile {:?}: {} points unverified with the whole scene loaded",
                spec.key,
                retry.len()
            )));
        }
    }
    Ok((results, retried))
}

/// `--dry-run`: scans the inputs (a full read: the plan needs every point's tile), plans, times
/// the computation on the median tile, and prints the plan with its estimates.
#[allow(clippy::too_many_arguments)]
fn dry_run(
    cfg: &Config,
    sources: &[Box<dyn PointSource>],
    first_ids: &[u64],
    grid: TileGrid,
    wd: &WorkDir,
    pool: &rayon::ThreadPool,
    params: &ComputeParams<'_>,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let budget = cfg.memory_bytes as usize;
    let t0 = Instant::now();
    let (buckets, stats) = scan(
        sources,
        first_ids,
        grid,
        chunk_points(cfg, sources),
        budget * 2 / 5,
        &wd.path().join("buckets"),
        pool,
        reporter,
        cancel,
    )?;
    let scan_s = t0.elapsed().as_secs_f64();
    let params = &ComputeParams {
        orientation: cfg.orientation.resolve(stats.centroid),
        propagate: (cfg.orientation == OrientMode::Propagate).then_some(stats.centroid),
        ..*params
    };
    let tplan = plan(&stats, grid.size, cfg.k);
    let mut counts: Vec<u64> = tplan.tiles.iter().map(|t| t.count).collect();
    counts.sort_unstable();
    let median = counts[counts.len() / 2];
    let sample = tplan.tiles.iter().find(|t| t.count == median).cloned();
    let mut us_per_point = f64::NAN;
    let mut halo_factor = 1.0;
    if let Some(spec) = sample {
        let whole = Part::whole(grid.rect(spec.key));
        let t = load_tile(&buckets, spec.key, &whole, spec.halo, None, &tplan.per_tile)?;
        halo_factor = t.xyz.len() as f64 / t.n_core.max(1) as f64;
        let t1 = Instant::now();
        let (r, _) = pool.install(|| {
            compute_verified(
                &buckets,
                &tplan,
                &spec,
                &whole,
                t,
                params,
                &mut TileSidecar::default(),
            )
        })?;
        us_per_point = t1.elapsed().as_secs_f64() * 1e6 / r.len().max(1) as f64;
    }
    let n = stats.count as f64;
    let biggest = tplan
        .tiles
        .iter()
        .map(|t| estimated_loaded_points(t, grid.size))
        .max()
        .unwrap_or(0);
    let in_memory = stats.count as usize * POINT_BYTES <= budget * 2 / 5;
    let tiles_mem = (biggest * tile_point_bytes(cfg.k)).min(budget * 2 / 5) * 2;
    let peak = if in_memory {
        stats.count as usize * POINT_BYTES + tiles_mem
    } else {
        budget * 3 / 5 + tiles_mem / 2
    };
    let cols_bytes = 8 + 1 + 4 * (7 + 6 * cfg.directions as usize + 4 * cfg.features as usize);
    let disk = if in_memory { 0.0 } else { n * 45.0 } + n * cols_bytes as f64;
    let est = 2.0 * scan_s + n * us_per_point * 1e-6;
    println!("plan: {} points in {} tiles of {:.3} (file units); points per tile: min {}, median {median}, max {}", stats.count, tplan.tiles.len(), grid.size, counts[0], counts[counts.len() - 1]);
    println!(
        "halo: {:.1}% extra points loaded on the median tile",
        100.0 * (halo_factor - 1.0)
    );
    println!("memory: budget {} MiB; buckets {}; expected peak about {} MiB plus ~60 MiB for the program", budget >> 20, if in_memory { "in memory" } else { "spilled to disk" }, peak.min(budget) >> 20);
    println!(
        "work directory: {} (about {:.0} MiB at the peak)",
        crate::io::workdir::default_path(&cfg.output).display(),
        disk / (1 << 20) as f64
    );
    println!("time: scan {scan_s:.1} s; curvature {us_per_point:.2} us/point on the median tile with {} threads; estimated total {est:.0} s", cfg.threads);
    Ok(())
}

/// The provenance text stored in the output: tool version, estimator and every parameter.
fn provenance(cfg: &Config, unit: &str, tile_size: f64, file_normals: bool) -> String {
    let orientation = cfg.orientation.to_string();
    let inputs: Vec<String> = cfg
        .inputs
        .iter()
        .map(|p| {
            p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    format!(
        "tilecurv {}\ninputs={}\nestimator={}\nk={}\nseed={}\ntriangles={}\nnormals={}\norientation={orientation}\ntile={} ({tile_size} {unit})\ncolumns={}\ndirections={}\nfeatures={}\n{}sign=positive where the surface bends away from its normal; curvature in 1/{unit}\n",
        env!("CARGO_PKG_VERSION"),
        inputs.join(","),
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
        cfg.features,
        cfg.sample_faces
            .map(|n| format!("sample_faces={n} (points sampled on the mesh faces)\n"))
            .unwrap_or_default(),
    )
}
