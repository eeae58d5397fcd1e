//! `tilecurv raster`: runs `run::raster` and prints what it wrote.

use super::args::RasterArgs;
use super::{fail, reporter, CANCEL};
use crate::progress::{say, Reporter};
use crate::run::raster::{raster, RasterJob};

/// Runs `tilecurv raster`.
pub(super) fn run(a: RasterArgs) -> Result<i32, i32> {
    let exec = a.exec.options();
    let reporter = reporter(a.exec.quiet(), exec.progress_json.as_deref())?;
    let job = RasterJob {
        inputs: a.inputs,
        cell: a.cell,
        columns: a.columns.map(|c| c.0),
        stat: a.stat,
        dir: a.output,
    };
    let started = std::time::Instant::now();
    let s = raster(
        &job,
        exec.memory_bytes,
        exec.chunk_points,
        &reporter,
        &CANCEL,
    )
    .map_err(|e| fail(&e))?;
    for w in s.warnings() {
        reporter.warn(&w);
    }
    if !a.exec.quiet() {
        say!(
            "done: {} points in {} of {}x{} cells of {} ({} files) in {:.1} s -> {}",
            s.points,
            s.cells,
            s.grid.width,
            s.grid.height,
            s.cell_text(),
            s.files.len(),
            started.elapsed().as_secs_f64(),
            job.dir.display()
        );
    }
    Ok(super::exit::OK)
}
