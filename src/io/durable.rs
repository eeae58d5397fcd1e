//! Durable writing, for the work directory and the outputs alike: a file is written under a
//! temporary name beside its final one (the same directory, so that the rename is atomic),
//! synced, renamed, and its directory synced; readers see the old file or the new one, never a
//! part. Every temporary name has one form, `.<name>.tilecurv-<host>-<pid>.tmp`: hidden, naming
//! the file it becomes, and the host and process writing it, so that two processes writing the
//! same file (a task run twice, on two nodes of a cluster) never share one, and a rerun removes
//! those of killed processes of its own host ([`sweep_dead_temps`]) and no others.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `bytes` to `path` durably: a temporary name in the same directory, fsync, rename,
/// fsync of the directory. Readers see the old file or the new one, never a part.
pub(crate) fn write_durably(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = tmp_name(path);
    let mut f = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
    f.write_all(bytes)
        .and_then(|_| f.sync_all())
        .map_err(|e| Error::write(&tmp, e))?;
    drop(f);
    commit_file(&tmp, path)
}

/// The temporary name of `path` for this process: `.<name>.tilecurv-<host>-<pid>.tmp` beside
/// it.
pub(crate) fn tmp_name(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    path.with_file_name(format!(
        ".{name}.tilecurv-{}-{}.tmp",
        host_name(),
        std::process::id()
    ))
}

/// The file a temporary name of this host's process `pid` is for: `Some((name, pid))` for
/// `.<name>.tilecurv-<this host>-<pid>.tmp`; another host's temporaries are never judged
/// (their process may be alive there).
fn temp_of_this_host(entry: &str) -> Option<(&str, &str)> {
    let rest = entry.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (rest, pid) = rest.rsplit_once('-')?;
    let base = rest
        .strip_suffix(host_name().as_str())?
        .strip_suffix(".tilecurv-")?;
    (!base.is_empty()).then_some((base, pid))
}

/// The file a temporary name of any host is for: `Some(name)` for
/// `.<name>.tilecurv-<host>-<pid>.tmp` ([`tmp_name`]).
pub(crate) fn temp_of(entry: &str) -> Option<&str> {
    let rest = entry.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (base, _) = rest.rsplit_once(".tilecurv-")?;
    (!base.is_empty()).then_some(base)
}

/// Removes what killed processes of this host left in `dir` under temporary names
/// ([`tmp_name`]), all of them, or only those of the file `only`: result files, sidecars,
/// manifests, bucket task directories, outputs. Those of running processes (another task on
/// this node) and of other hosts are left alone; one that cannot be removed is left for the
/// next run.
pub(crate) fn sweep_dead_temps(dir: &Path, only: Option<&str>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let dead = temp_of_this_host(&name)
            .is_some_and(|(base, pid)| only.is_none_or(|o| o == base) && is_dead_process(pid));
        if dead {
            let p = e.path();
            let _ = if p.is_dir() {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            };
        }
    }
}

/// Whether `pid` (as written in a temporary name of this host) names a process that no longer
/// runs; this process, and anything that is not a pid, is never dead.
fn is_dead_process(pid: &str) -> bool {
    match pid.parse::<i32>() {
        Ok(pid) => pid != std::process::id() as i32 && !pid_alive(pid),
        Err(_) => false,
    }
}

/// Whether a process with this pid exists on this machine (a recycled pid counts as alive: its
/// temporaries are then left alone, never wrongly removed).
fn pid_alive(pid: i32) -> bool {
    if pid <= 0 {
        return true;
    }
    // SAFETY: kill with signal 0 sends nothing; it only asks whether the pid exists.
    unsafe {
        libc::kill(pid, 0) == 0
            || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
}

/// This machine's host name (`localhost` if it cannot be read), with path separators replaced.
pub(crate) fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most `len` bytes into the buffer we own.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr() as *mut libc::c_char, buf.len()) };
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let name = String::from_utf8_lossy(&buf[..end]).replace(['/', '\\'], "_");
    if r != 0 || name.is_empty() {
        "localhost".into()
    } else {
        name
    }
}

/// Renames a finished, synced temporary file over `path` and syncs the directory.
pub(crate) fn commit_file(tmp: &Path, path: &Path) -> Result<()> {
    std::fs::rename(tmp, path).map_err(|e| Error::write(path, e))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        sync_dir(dir);
    }
    Ok(())
}

/// Syncs a directory so that a rename in it survives a power loss. A directory that cannot be
/// opened for syncing (some network file systems) is not an error.
pub(crate) fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Flushes `files` (all in `dir`'s file system) to disk: one `syncfs` of that file system where
/// the OS has it (an fsync costs milliseconds, and runs write thousands of files), else an
/// fsync per file.
pub(crate) fn sync_files<'a>(dir: &Path, files: impl IntoIterator<Item = &'a Path>) -> Result<()> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        if let Ok(d) = File::open(dir) {
            // SAFETY: syncfs only reads the descriptor, which stays open for the call.
            if unsafe { libc::syncfs(d.as_raw_fd()) } == 0 {
                return Ok(());
            }
        }
    }
    let _ = dir;
    for f in files {
        File::open(f)
            .and_then(|h| h.sync_all())
            .map_err(|e| Error::write(f, e))?;
    }
    Ok(())
}

/// The temporary file of an output while it is written. Dropping it removes the file: a writer
/// that fails anywhere (a write, the final flush, the sync, the rename), is abandoned, or is
/// dropped unfinished leaves nothing beside the output. Only [`TempFile::commit`] keeps it, as
/// the output.
#[derive(Debug)]
pub(crate) struct TempFile {
    path: PathBuf,
    output: PathBuf,
    /// Set once the rename succeeded: the file is the output now.
    committed: bool,
}

impl TempFile {
    /// Creates the temporary file of `output` ([`tmp_name`]), empty, after removing those of
    /// killed runs ([`sweep_dead_temps`]); write errors are to name the output
    /// ([`TempFile::error`]).
    pub(crate) fn create(output: &Path) -> Result<(Self, File)> {
        let dir = output
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = output.file_name().map(|n| n.to_string_lossy().into_owned());
        sweep_dead_temps(dir, Some(name.as_deref().unwrap_or("output")));
        let path = tmp_name(output);
        let file = File::create(&path).map_err(|e| Error::write(output, e))?;
        let tmp = TempFile {
            path,
            output: output.to_path_buf(),
            committed: false,
        };
        Ok((tmp, file))
    }

    /// Its path.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// The output it becomes.
    pub(crate) fn output(&self) -> &Path {
        &self.output
    }

    /// A write error of this output: it names the output (the temporary file is removed
    /// anyway), with the standard hint.
    pub(crate) fn error(&self, e: std::io::Error) -> Error {
        Error::write(&self.output, e)
    }

    /// Makes the completely written `file` the output: syncs it, renames it over the output and
    /// syncs the directory so that the rename is durable. On failure the temporary file is
    /// removed.
    pub(crate) fn commit(self, file: File) -> Result<()> {
        self.ready(file)?.commit()
    }

    /// Syncs the completely written `file`, which [`Ready::commit`] then makes the output: so
    /// that several outputs appear together, or none of them. On failure the temporary file is
    /// removed.
    pub(crate) fn ready(self, file: File) -> Result<Ready> {
        file.sync_all().map_err(|e| self.error(e))?;
        drop(file);
        Ok(Ready(self))
    }
}

/// A complete, synced temporary file ([`TempFile::ready`]) not yet renamed over its output.
/// Dropping it removes the file.
#[derive(Debug)]
pub(crate) struct Ready(TempFile);

impl Ready {
    /// Renames the file over its output and syncs the directory. On failure the temporary file
    /// is removed.
    pub(crate) fn commit(mut self) -> Result<()> {
        commit_file(&self.0.path, &self.0.output)?;
        self.0.committed = true;
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

    /// Whether `name` is the temporary name of a file, left by a process of this host that no
    /// longer runs.
    fn is_dead_temp(name: &str) -> bool {
        temp_of_this_host(name).is_some_and(|(_, pid)| is_dead_process(pid))
    }

    #[test]
    fn dead_temps_are_recognised_only_on_this_host() {
        let host = host_name();
        // A pid past any pid_max is dead; this process is alive; other hosts are never judged.
        assert!(is_dead_temp(&format!(".t3.tilecurv-{host}-2147483646.tmp")));
        assert!(is_dead_temp(&format!(
            ".tile_1_-2.res.tilecurv-{host}-2147483646.tmp"
        )));
        assert!(!is_dead_temp(&format!(
            ".t3.tilecurv-{host}-{}.tmp",
            std::process::id()
        )));
        assert!(!is_dead_temp(".t3.tilecurv-some-other-node-2147483646.tmp"));
        assert!(!is_dead_temp(&format!(".t3.tilecurv-{host}-x.tmp")));
        assert!(!is_dead_temp(&format!("..tilecurv-{host}-2147483646.tmp")));
        assert!(!is_dead_temp("t3"));
    }
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
        sweep_dead_temps(dir.path(), Some("o.las"));
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
