//! The work directory of a run: where buckets and per-tile results live between passes, and the
//! unit of resumption. Its name is derived from the output, so the same command finds it again
//! after a crash. It holds a lock file (one run per work directory), a manifest with the
//! fingerprint of the inputs and of every parameter that changes the result (stale work is
//! discarded, never mixed in), and the durable-write helper used for everything in it, whose
//! temporary names say which host and process wrote them, so that a rerun can remove those of
//! killed processes ([`sweep_dead_temps`]).

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The version of the work directory's file formats (bucket frames, result files), in every
/// manifest and its fingerprint: work left by a tilecurv that wrote other formats is discarded
/// by `process` and refused by the cluster stages, never misread. Each file also starts with
/// its own magic and version.
pub const FORMAT_VERSION: u32 = 2;

/// File name of the manifest inside the work directory.
const MANIFEST: &str = "manifest.txt";
/// File name of the lock inside the work directory.
const LOCK: &str = "lock";

/// 64-bit FNV-1a: a fixed, documented hash (unlike `DefaultHasher`, which may change between
/// Rust releases), for fingerprints that must survive a rebuild of the tool.
#[derive(Debug, Clone, Copy)]
pub struct Fingerprint(u64);

impl Default for Fingerprint {
    fn default() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
}

impl Fingerprint {
    /// Feeds bytes.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        for &c in b {
            self.0 ^= c as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        // A separator, so that ("ab", "c") and ("a", "bc") differ.
        self.0 ^= 0xff;
        self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        self
    }

    /// Feeds a string.
    pub fn text(&mut self, s: &str) -> &mut Self {
        self.bytes(s.as_bytes())
    }

    /// The hash value.
    pub fn value(&self) -> u64 {
        self.0
    }
}

/// Writes `bytes` to `path` durably: a temporary name in the same directory, fsync, rename,
/// fsync of the directory. Readers see the old file or the new one, never a part.
pub fn write_durably(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = tmp_name(path);
    let mut f = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
    f.write_all(bytes)
        .and_then(|_| f.sync_all())
        .map_err(|e| Error::write(&tmp, e))?;
    drop(f);
    commit_file(&tmp, path)
}

/// The temporary name used for `path` while this process writes it: `<name>.tmp.<host>.<pid>`
/// beside it (the same directory, so the final rename is atomic), unique to the attempt, so that
/// two processes writing the same file (a task run twice, on two nodes of a cluster) never share
/// a temporary file.
pub fn tmp_name(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{name}.tmp.{}.{}", host_name(), std::process::id()))
}

/// Whether `name` is a temporary name ([`tmp_name`]) left by a process of this host that is no
/// longer running: its file can go. Another host's temporaries are never judged (their process
/// may be alive there).
pub fn is_dead_temp(name: &str) -> bool {
    let Some((rest, pid)) = name.rsplit_once('.') else {
        return false;
    };
    rest.strip_suffix(&format!(".tmp.{}", host_name()))
        .is_some_and(|base| !base.is_empty() && is_dead_process(pid))
}

/// Whether `pid` (as written in a temporary name of this host) names a process that no longer
/// runs; this process, and anything that is not a pid, is never dead.
pub fn is_dead_process(pid: &str) -> bool {
    match pid.parse::<i32>() {
        Ok(pid) => pid != std::process::id() as i32 && !pid_alive(pid),
        Err(_) => false,
    }
}

/// Removes what killed processes of this host left in `dir` under temporary names
/// ([`is_dead_temp`]): result files, sidecars, manifests, bucket task directories. Those of
/// running processes (another task on this node) and of other hosts are left alone; a file
/// that cannot be removed is left for the next run.
pub fn sweep_dead_temps(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        if is_dead_temp(&e.file_name().to_string_lossy()) {
            let p = e.path();
            let _ = if p.is_dir() {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            };
        }
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
pub fn host_name() -> String {
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
pub fn commit_file(tmp: &Path, path: &Path) -> Result<()> {
    std::fs::rename(tmp, path).map_err(|e| Error::write(path, e))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        sync_dir(dir);
    }
    Ok(())
}

/// Syncs a directory so that a rename in it survives a power loss. A directory that cannot be
/// opened for syncing (some network file systems) is not an error.
pub fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Flushes `files` (all in `dir`'s file system) to disk: one `syncfs` of that file system where
/// the OS has it (an fsync costs milliseconds, and runs write thousands of files), else an
/// fsync per file.
pub fn sync_files<'a>(dir: &Path, files: impl IntoIterator<Item = &'a Path>) -> Result<()> {
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

/// What was found in the work directory when a run started.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Resume {
    /// Nothing: a fresh start.
    Fresh,
    /// Work from the same inputs and parameters: finished steps are reused.
    Resumed,
    /// Work from other inputs or parameters: it was discarded.
    Discarded,
}

/// An open, locked work directory.
pub struct WorkDir {
    path: PathBuf,
    /// What was found there.
    pub resume: Resume,
    /// Whether this process holds the directory's lock (`process`, `plan`); the cluster stages
    /// attach without it.
    locked: bool,
    /// The open lock file, whose `flock` is the lock: the kernel releases it when the process
    /// ends, however it ends.
    _lock: Option<File>,
}

/// File name of the task layout inside the work directory (written by `plan`).
pub const TASKS: &str = "tasks.txt";

/// The default work directory for an output: `.<name>.tilecurv` beside it.
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

/// Takes the lock of the work directory at `path`: an exclusive `flock` on its lock file, then
/// our pid written in it (for the message a second run prints). Two runs can never both hold
/// it: the kernel decides, not the file's contents (a pid file read between another run's
/// create and write read as empty, pid 0, and both runs went on), and a run that died, even by
/// `kill -9`, holds nothing. The lock file is removed on drop, so the lock is re-checked to be
/// on the file the path names now.
fn take_lock(path: &Path) -> Result<File> {
    use std::io::Read;
    use std::os::unix::fs::MetadataExt;
    use std::os::unix::io::AsRawFd;
    let lock = path.join(LOCK);
    loop {
        let mut f = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&lock)
            .map_err(|e| Error::write(&lock, e))?;
        // SAFETY: flock on a file descriptor this function owns; no memory is involved.
        if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::WouldBlock {
                return Err(Error::write(&lock, e));
            }
            let mut holder = String::new();
            let _ = f.read_to_string(&mut holder);
            let holder = match holder.trim() {
                "" => "starting".to_string(),
                pid => format!("process {pid}"),
            };
            return Err(Error::Usage(format!(
                "{}: another tilecurv run ({holder}) is using this work directory; wait for it, or use --work-dir",
                path.display()
            )));
        }
        let same = match (f.metadata(), std::fs::metadata(&lock)) {
            (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
            _ => false,
        };
        if !same {
            continue; // the holder removed the file between our open and our lock
        }
        f.set_len(0).map_err(|e| Error::write(&lock, e))?;
        writeln!(f, "{}", std::process::id()).map_err(|e| Error::write(&lock, e))?;
        return Ok(f);
    }
}

impl WorkDir {
    /// Opens (creating it if needed) and locks the work directory at `path`, compares its
    /// manifest with `manifest` (whose first line is the fingerprint), and discards stale work.
    pub fn open(path: &Path, manifest: &str) -> Result<Self> {
        std::fs::create_dir_all(path).map_err(|e| Error::write(path, e))?;
        let lock_file = take_lock(path)?;
        sweep_dead_temps(path);
        let mpath = path.join(MANIFEST);
        // Only a manifest that is not there, or not text, means no work to keep: one that
        // cannot be read now (too many open files) must not discard the work.
        let resume = match std::fs::read_to_string(&mpath) {
            Ok(old) if old == manifest => Resume::Resumed,
            Ok(_) => Resume::Discarded,
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => Resume::Discarded,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Resume::Fresh,
            Err(e) => return Err(Error::read_work(&mpath, e)),
        };
        if resume != Resume::Resumed {
            clear_except_lock(path)?;
            write_durably(&mpath, manifest.as_bytes())?;
        }
        Ok(WorkDir {
            path: path.to_path_buf(),
            resume,
            locked: true,
            _lock: Some(lock_file),
        })
    }

    /// Attaches to the work directory a `plan` made at `path`, without its lock (tasks of one
    /// stage run at the same time, on any node), and returns it with its manifest.
    pub fn attach(path: &Path) -> Result<(Self, String)> {
        let mpath = path.join(MANIFEST);
        let manifest = std::fs::read_to_string(&mpath).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound | std::io::ErrorKind::InvalidData => {
                Error::Usage(format!(
                    "{}: not a tilecurv work directory ({e}); run `tilecurv plan INPUTS... --work {}` first",
                    path.display(),
                    path.display()
                ))
            }
            _ => Error::read_work(&mpath, e),
        })?;
        Ok((
            WorkDir {
                path: path.to_path_buf(),
                resume: Resume::Resumed,
                locked: false,
                _lock: None,
            },
            manifest,
        ))
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Removes the whole directory (after a successful run).
    pub fn remove(self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

impl Drop for WorkDir {
    /// Releases the lock; the work stays for a resumed run unless `remove` was called.
    fn drop(&mut self) {
        if self.locked {
            let _ = std::fs::remove_file(self.path.join(LOCK));
        }
    }
}

fn clear_except_lock(dir: &Path) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::write(dir, e))?;
    for e in entries.flatten() {
        if e.file_name() == LOCK {
            continue;
        }
        let p = e.path();
        let r = if p.is_dir() {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
        r.map_err(|e| Error::write(&p, e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_reference_values() {
        // FNV-1a 64 of "a" is 0xaf63dc4c8601ec8c; ours adds a separator byte after each field.
        let mut f = Fingerprint::default();
        f.0 ^= b'a' as u64;
        f.0 = f.0.wrapping_mul(0x0000_0100_0000_01b3);
        assert_eq!(f.0, 0xaf63_dc4c_8601_ec8c);
        let mut a = Fingerprint::default();
        let mut b = Fingerprint::default();
        assert_ne!(
            a.text("ab").text("c").value(),
            b.text("a").text("bc").value()
        );
    }

    #[test]
    fn dead_temps_are_recognised_only_on_this_host() {
        let host = host_name();
        // A pid past any pid_max is dead; this process is alive; other hosts are never judged.
        assert!(is_dead_temp(&format!("t3.tmp.{host}.2147483646")));
        assert!(is_dead_temp(&format!(
            "tile_1_-2.res.tmp.{host}.2147483646"
        )));
        assert!(!is_dead_temp(&format!(
            "t3.tmp.{host}.{}",
            std::process::id()
        )));
        assert!(!is_dead_temp("t3.tmp.some-other-node.2147483646"));
        assert!(!is_dead_temp(&format!("t3.tmp.{host}.x")));
        assert!(!is_dead_temp(&format!(".tmp.{host}.2147483646")));
        assert!(!is_dead_temp("t3"));
    }

    #[test]
    fn stale_work_is_discarded_and_matching_work_resumed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let wd = dir.path().join("w");
        let w = WorkDir::open(&wd, "fp 1\n").expect("open");
        assert_eq!(w.resume, Resume::Fresh);
        std::fs::write(wd.join("tile_0_0.res"), b"x").expect("write");
        drop(w);
        let w = WorkDir::open(&wd, "fp 1\n").expect("open");
        assert_eq!(w.resume, Resume::Resumed);
        assert!(wd.join("tile_0_0.res").exists());
        drop(w);
        let w = WorkDir::open(&wd, "fp 2\n").expect("open");
        assert_eq!(w.resume, Resume::Discarded);
        assert!(!wd.join("tile_0_0.res").exists());
        drop(w);
        // A lock file left by a run that died (here naming pid 1) holds no lock: taken over.
        std::fs::write(wd.join(LOCK), "1\n").expect("write lock");
        let w = WorkDir::open(&wd, "fp 2\n").expect("open");
        w.remove();
        assert!(!wd.exists());
    }

    #[test]
    fn a_held_lock_is_never_taken_even_when_its_file_reads_empty() {
        // A second run that reads the lock file between the first run's create and its write
        // sees pid 0: it must not take the lock too.
        let dir = tempfile::tempdir().expect("temp dir");
        let wd = dir.path().join("w");
        let first = WorkDir::open(&wd, "fp 1\n").expect("open");
        std::fs::write(wd.join(LOCK), "").expect("empty the lock file");
        let second = WorkDir::open(&wd, "fp 1\n");
        assert!(
            matches!(&second, Err(Error::Usage(m)) if m.contains("another tilecurv run")),
            "a second open of a held work directory must fail"
        );
        drop(first);
        let again = WorkDir::open(&wd, "fp 1\n").expect("free once the first run is done");
        drop(again);
    }
}
