//! What every output writer shares: the [`PointSink`] trait (records in, a complete file or
//! nothing out) and the atomic-output steps, [`temp_path`] and [`commit`]. It imports no writer,
//! so that the writers (`las::writer`, `ply`) can use it while `sink` picks among them.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// An output being written: records in, a complete file (or nothing) out.
pub trait PointSink {
    /// Appends whole output records (input record + new columns), in file order.
    fn write_points(&mut self, records: &[u8]) -> Result<()>;
    /// Completes the file and renames it over the output.
    fn finish(self: Box<Self>) -> Result<()>;
    /// Removes the temporary file (after a failure or an interruption).
    fn abandon(self: Box<Self>);
}

/// The temporary file an output is written to: hidden, beside the output (the same file
/// system, so that the final rename is atomic), named after the output and this process.
pub fn temp_path(output: &Path) -> PathBuf {
    let file_name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    output.with_file_name(format!(".{file_name}.tilecurv-{}.tmp", std::process::id()))
}

/// Makes a completely written temporary file the output: syncs it, renames it over the output
/// and syncs the directory so that the rename is durable.
pub fn commit(file: File, tmp: &Path, output: &Path) -> Result<()> {
    file.sync_all().map_err(|e| Error::write(tmp, e))?;
    drop(file);
    crate::io::workdir::commit_file(tmp, output)
}
