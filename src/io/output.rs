//! What every output writer shares: the [`PointSink`] trait (records in, a complete file or
//! nothing out) and the atomic-output steps: a [`TempFile`] beside the output (`temp_path`),
//! removed on every path that does not [`TempFile::commit`] it. It imports no writer, so that
//! the writers (`las::writer`, `ply`) can use it while `sink` picks among them.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::workdir::{host_name, is_dead_process};

/// An output being written: records in, a complete file (or nothing) out.
pub trait PointSink {
    /// Appends whole output records (input record + new columns), in file order.
    fn write_points(&mut self, records: &[u8]) -> Result<()>;
    /// Completes the file and renames it over the output; on failure the temporary file is
    /// removed.
    fn finish(self: Box<Self>) -> Result<()>;
    /// Removes the temporary file (after a failure or an interruption).
    fn abandon(self: Box<Self>);
}

/// The temporary file an output is written to: hidden, beside the output (the same file
/// system, so that the final rename is atomic), named after the output, this host and this
/// process: `.<name>.tilecurv-<host>-<pid>.tmp` (outputs may be on a file system that other
/// nodes share, where pids alone would collide and could not be judged dead).
fn temp_path(output: &Path) -> PathBuf {
    output.with_file_name(format!(
        "{}{}-{}.tmp",
        temp_prefix(output),
        host_name(),
        std::process::id()
    ))
}

/// What every temporary name of `output` starts with: `.<name>.tilecurv-`.
fn temp_prefix(output: &Path) -> String {
    let file_name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    format!(".{file_name}.tilecurv-")
}

/// Removes the temporary files of `output` that killed processes of this host left beside it
/// (a run killed while writing leaves its temporary file). Those of running processes and of
/// other hosts are left alone; one that cannot be removed is left for the next run.
pub fn sweep_dead_temps(output: &Path) {
    let dir = output
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = format!("{}{}-", temp_prefix(output), host_name());
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let pid = name
            .strip_prefix(&prefix)
            .and_then(|rest| rest.strip_suffix(".tmp"));
        if pid.is_some_and(is_dead_process) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// The temporary file of an output while it is written. Dropping it removes the file: a writer
/// that fails anywhere (a write, the final flush, the sync, the rename), is abandoned, or is
/// dropped unfinished leaves nothing beside the output. Only [`TempFile::commit`] keeps it, as
/// the output.
#[derive(Debug)]
pub struct TempFile {
    path: PathBuf,
    output: PathBuf,
    /// Set once the rename succeeded: the file is the output now.
    committed: bool,
}

impl TempFile {
    /// Creates the temporary file of `output` (`temp_path`), empty, after removing those of
    /// killed runs ([`sweep_dead_temps`]); write errors are to name the output
    /// ([`TempFile::error`]).
    pub fn create(output: &Path) -> Result<(Self, File)> {
        sweep_dead_temps(output);
        let path = temp_path(output);
        let file = File::create(&path).map_err(|e| Error::write(output, e))?;
        let tmp = TempFile {
            path,
            output: output.to_path_buf(),
            committed: false,
        };
        Ok((tmp, file))
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The output it becomes.
    pub fn output(&self) -> &Path {
        &self.output
    }

    /// A write error of this output: it names the output (the temporary file is removed
    /// anyway), with the standard hint.
    pub fn error(&self, e: std::io::Error) -> Error {
        Error::write(&self.output, e)
    }

    /// Makes the completely written `file` the output: syncs it, renames it over the output and
    /// syncs the directory so that the rename is durable. On failure the temporary file is
    /// removed.
    pub fn commit(mut self, file: File) -> Result<()> {
        file.sync_all().map_err(|e| self.error(e))?;
        drop(file);
        crate::io::workdir::commit_file(&self.path, &self.output)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// What is left in `dir` besides `keep`.
    fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
        std::fs::read_dir(dir)
            .expect("lists")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !keep.contains(&n.as_str()))
            .collect()
    }

    #[test]
    fn a_temp_file_is_removed_unless_committed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("o.las");
        let (tmp, mut f) = TempFile::create(&out).expect("creates");
        f.write_all(b"x").expect("writes");
        drop(tmp);
        assert!(leftovers(dir.path(), &[]).is_empty());
        let (tmp, mut f) = TempFile::create(&out).expect("creates");
        f.write_all(b"y").expect("writes");
        tmp.commit(f).expect("commits");
        assert_eq!(std::fs::read(&out).expect("output"), b"y");
        assert_eq!(leftovers(dir.path(), &[]), ["o.las"]);
    }

    #[test]
    fn temp_files_of_dead_processes_of_this_host_are_swept() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("o.las");
        let host = host_name();
        let names = [
            format!(".o.las.tilecurv-{host}-2147483646.tmp"),
            format!(".o.las.tilecurv-{host}-{}.tmp", std::process::id()),
            ".o.las.tilecurv-other-node-2147483646.tmp".to_string(),
            format!(".o2.las.tilecurv-{host}-2147483646.tmp"),
        ];
        for n in &names {
            std::fs::write(dir.path().join(n), b"x").expect("plants");
        }
        sweep_dead_temps(&out);
        let mut left = leftovers(dir.path(), &[]);
        left.sort();
        let mut kept = names[1..].to_vec();
        kept.sort();
        assert_eq!(left, kept);
    }

    #[test]
    fn a_failed_rename_leaves_no_temp_file() {
        // A non-empty directory where the output goes: the rename fails.
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("o.las");
        std::fs::create_dir_all(out.join("x")).expect("blocking directory");
        let (tmp, f) = TempFile::create(&out).expect("creates");
        let e = tmp.commit(f).expect_err("the rename fails");
        assert!(
            matches!(&e, Error::WriteIo { path, .. } if path == &out),
            "{e}"
        );
        assert_eq!(leftovers(dir.path(), &[]), ["o.las"]);
    }
}
