//! Every name in a work directory, in one place. The layout:
//!
//! ```text
//! <work>/
//!   lock                      flock of the run that owns the directory (process, plan); its pid
//!   manifest.txt              fingerprint of the inputs and options, the same in words, and the
//!                             options as `param key=value` lines every stage rebuilds the run from
//!   tasks.txt                 the task layout: bucket tasks (input ranges) and tile tasks
//!   buckets/t<task>/          one directory per bucket task, renamed into place when complete:
//!     b_<x>_<y>.zst           the points of tile (x, y) this task scanned (zstd frames)
//!     buckets.done            the task's scan statistics; its presence marks the task complete
//!   results/
//!     tile_<x>_<y>.res        one finished tile's results, sorted by point id (the journal)
//!     tile_<x>_<y>.ori        its orientation sidecar (`--orient propagate` only)
//!     run_<n>.res             merge runs of assemble past its fan-in (removed after use)
//!   log/                      the Slurm recipe's task logs (scripts/slurm/submit.sh), which
//!                             tilecurv never writes but counts as the directory's own
//! ```
//!
//! Every file is written durably (`io::durable`): under `.<name>.tilecurv-<host>-<pid>.tmp`
//! beside its final name, then renamed. A tile is done if and only if its result file is whole
//! (and, with `--orient propagate`, its sidecar, renamed first, is there); a bucket task if and
//! only if its directory holds `buckets.done`. The version of these formats is
//! [`super::FORMAT_VERSION`], in every manifest.

use std::path::{Path, PathBuf};

use crate::core::plan::TileKey;

/// The manifest.
pub(crate) const MANIFEST: &str = "manifest.txt";
/// The lock file.
pub(crate) const LOCK: &str = "lock";
/// The task layout.
pub(crate) const TASKS: &str = "tasks.txt";
/// The directory of the bucket tasks.
pub(crate) const BUCKETS: &str = "buckets";
/// The directory of the tile results.
pub(crate) const RESULTS: &str = "results";
/// The directory where the Slurm recipe (scripts/slurm/submit.sh) puts its task logs by
/// default: part of the work directory, cleared with its stale work.
pub(crate) const LOGS: &str = "log";
/// The file that marks a bucket task's directory complete, with its statistics.
pub(crate) const BUCKETS_DONE: &str = "buckets.done";
/// The file in the buckets directory that says the bucket files were deleted once every tile
/// was done: the statistics remain, the points are gone.
pub(crate) const BUCKETS_RELEASED: &str = "frames.released";

/// The directory of bucket task `task` in the buckets directory `buckets`.
pub(crate) fn bucket_task_dir(buckets: &Path, task: usize) -> PathBuf {
    buckets.join(format!("t{task}"))
}

/// The bucket file of a tile in a bucket task's directory.
pub(crate) fn bucket_file(task_dir: &Path, key: TileKey) -> PathBuf {
    task_dir.join(format!("b_{}_{}.zst", key.0, key.1))
}

/// The result file of a tile in the results directory.
pub(crate) fn tile_result(results: &Path, key: TileKey) -> PathBuf {
    results.join(format!("tile_{}_{}.res", key.0, key.1))
}

/// The orientation sidecar of a tile in the results directory.
pub(crate) fn tile_orientation(results: &Path, key: TileKey) -> PathBuf {
    results.join(format!("tile_{}_{}.ori", key.0, key.1))
}

/// Merge run `n` of assemble in the results directory.
pub(crate) fn merge_run(results: &Path, n: usize) -> PathBuf {
    results.join(format!("run_{n}.res"))
}

/// The default work directory of an output: `.<name>.tilecurv` beside it.
pub fn default_path(output: &Path) -> PathBuf {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let dir = output
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    dir.join(format!(".{name}.tilecurv"))
}
