//! The work directory of a run and its format: where buckets and per-tile results live between
//! the stages, and the unit of resumption. `names` spells every file in it and describes the
//! layout. A run that owns the directory (`process`, `plan`) holds its lock, an exclusive
//! `flock` on `lock` (one run per work directory); the cluster stages attach without it. The
//! manifest ([`manifest`]) fingerprints the inputs and every option that changes the output,
//! so stale work is discarded, never mixed in. The bucket store (`buckets/`, [`bucket`]) and
//! the result store (`results/`, [`results`], [`ResultStore`]) are reached through
//! [`WorkDir`]; no other module joins a path inside the directory.

pub(crate) mod bucket;
pub(crate) mod manifest;
pub(crate) mod names;
pub(crate) mod results;

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::core::plan::TileSpec;
use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::durable::{sweep_dead_temps, temp_of, write_durably};
pub use names::default_path;
use names::{BUCKETS, BUCKETS_DONE, BUCKETS_RELEASED, LOCK, LOGS, MANIFEST, RESULTS, TASKS};

/// The version of the work directory's file formats (bucket frames, result files, the task
/// layout), in every manifest and its fingerprint: work left by a tilecurv that wrote other
/// formats is discarded by `process` and refused by the cluster stages, never misread. Each
/// binary file also starts with its own magic and version. 5: bucket tasks are ranges of
/// points of the inputs, no longer ranges of inputs.
pub(crate) const FORMAT_VERSION: u32 = 5;

/// What was found in the work directory when a run started.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Resume {
    /// Nothing: a fresh start.
    Fresh,
    /// Work from the same inputs and parameters: finished steps are reused.
    Resumed,
    /// Work from other inputs or parameters: it was discarded.
    Discarded,
}

/// A work directory attached to by a cluster stage, with its manifest.
pub(crate) struct Attached {
    /// The directory.
    pub(crate) work: WorkDir,
    /// The inputs and options the manifest holds.
    pub(crate) planned: manifest::Planned,
    /// The manifest's text, to compare with the run rebuilt from it.
    pub(crate) manifest: String,
}

/// An open work directory.
pub(crate) struct WorkDir {
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
    pub(crate) fn open(path: &Path, manifest: &str) -> Result<Self> {
        check_own(path)?;
        std::fs::create_dir_all(path).map_err(|e| Error::write(path, e))?;
        let lock_file = take_lock(path)?;
        sweep_dead_temps(path, None);
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
            remove_own_entries(path, false)?;
            write_durably(&mpath, manifest.as_bytes())?;
        }
        Ok(WorkDir {
            path: path.to_path_buf(),
            resume,
            locked: true,
            _lock: Some(lock_file),
        })
    }

    /// The scratch directory of a dry run beside the work directory `path`, opened and locked
    /// as [`WorkDir::open`] does, once `path` is found fit to be a work directory.
    pub(crate) fn open_scratch(path: &Path, manifest: &str) -> Result<Self> {
        // Refused as the run would refuse it.
        check_own(path)?;
        WorkDir::open(&path.with_extension("dryrun"), manifest)
    }

    /// Attaches to the work directory a `plan` made at `path`, without its lock (tasks of one
    /// stage run at the same time, on any node), and returns it with what its manifest says.
    pub(crate) fn attach(path: &Path) -> Result<Attached> {
        let mpath = path.join(MANIFEST);
        let text = std::fs::read_to_string(&mpath).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => Error::Usage(format!(
                "{}: not a tilecurv work directory ({e}); run `tilecurv plan INPUTS... --work {}` first",
                path.display(),
                path.display()
            )),
            std::io::ErrorKind::InvalidData => manifest::damaged(&mpath, "it is not text"),
            _ => Error::read_work(&mpath, e),
        })?;
        let planned = manifest::parse(&mpath, &text)?;
        let work = WorkDir {
            path: path.to_path_buf(),
            resume: Resume::Resumed,
            locked: false,
            _lock: None,
        };
        Ok(Attached {
            work,
            planned,
            manifest: text,
        })
    }

    /// The directory.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// Records the task layout `text`; buckets made under another layout are discarded.
    pub(crate) fn set_task_layout(&self, text: &str) -> Result<()> {
        let tasks = self.path.join(TASKS);
        if std::fs::read_to_string(&tasks).ok().as_deref() == Some(text) {
            return Ok(());
        }
        let buckets = self.path.join(BUCKETS);
        if buckets.exists() {
            std::fs::remove_dir_all(&buckets).map_err(|e| Error::write(&buckets, e))?;
        }
        write_durably(&tasks, text.as_bytes())
    }

    /// The task layout's text as `plan` wrote it, parsed by `parse`; a missing layout asks for
    /// a new plan, one that does not parse is damaged work (exit 4).
    pub(crate) fn task_layout<T>(&self, parse: impl FnOnce(&str) -> Option<T>) -> Result<T> {
        let tasks = self.path.join(TASKS);
        let text = std::fs::read_to_string(&tasks).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => Error::Usage(format!(
                "{}: no task layout; run `tilecurv plan` again",
                tasks.display()
            )),
            _ => Error::read_work(&tasks, e),
        })?;
        parse(&text).ok_or_else(|| {
            Error::damaged_work(&tasks, "a damaged task layout; run `tilecurv plan` again")
        })
    }

    /// The directory of bucket task `task`.
    pub(crate) fn bucket_task_dir(&self, task: usize) -> PathBuf {
        names::bucket_task_dir(&self.path.join(BUCKETS), task)
    }

    /// The directories of bucket tasks `0..tasks`.
    pub(crate) fn bucket_task_dirs(&self, tasks: usize) -> Vec<PathBuf> {
        (0..tasks).map(|t| self.bucket_task_dir(t)).collect()
    }

    /// Makes the buckets directory ready for a scan: created, with the attempts of killed
    /// scans of this host removed (their frames are never reused).
    pub(crate) fn prepare_buckets(&self) -> Result<()> {
        let buckets = self.path.join(BUCKETS);
        std::fs::create_dir_all(&buckets).map_err(|e| Error::write(&buckets, e))?;
        sweep_dead_temps(&buckets, None);
        Ok(())
    }

    /// Deletes the bucket files of every bucket task, keeping each task's statistics (the
    /// tile plan): `process` calls it once every tile is done, so that the buckets' disk is
    /// free while the outputs are written (the merge's run files then take its place). The
    /// marker is made durable first: a run killed while the files go knows the points are
    /// gone ([`WorkDir::bucket_files_released`]). Best effort: a file left behind is removed
    /// with the directory.
    pub(crate) fn release_bucket_files(&self) {
        let buckets = self.path.join(BUCKETS);
        if write_durably(&buckets.join(BUCKETS_RELEASED), b"").is_err() {
            return;
        }
        for task in std::fs::read_dir(&buckets).into_iter().flatten().flatten() {
            if !task.path().is_dir() {
                continue;
            }
            for f in std::fs::read_dir(task.path())
                .into_iter()
                .flatten()
                .flatten()
            {
                if f.file_name() != BUCKETS_DONE {
                    let _ = std::fs::remove_file(f.path());
                }
            }
        }
    }

    /// Whether the bucket files were deleted after every tile was done
    /// ([`WorkDir::release_bucket_files`]): only the statistics remain.
    pub(crate) fn bucket_files_released(&self) -> bool {
        self.path.join(BUCKETS).join(BUCKETS_RELEASED).exists()
    }

    /// Deletes the buckets directory (released buckets, before a scan that makes them again).
    pub(crate) fn discard_buckets(&self) -> Result<()> {
        let buckets = self.path.join(BUCKETS);
        match std::fs::remove_dir_all(&buckets) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::write(&buckets, e)),
            _ => Ok(()),
        }
    }

    /// The result store, created if needed, with the half-written files of killed runs of this
    /// host removed.
    pub(crate) fn results(&self) -> Result<ResultStore> {
        let dir = self.path.join(RESULTS);
        std::fs::create_dir_all(&dir).map_err(|e| Error::write(&dir, e))?;
        sweep_dead_temps(&dir, None);
        Ok(ResultStore { dir })
    }

    /// Removes the directory (after a successful run): its own entries, then the directory if
    /// that leaves it empty. Nothing else in it is touched: [`check_own`] refused a directory
    /// holding anything else, and a file put there during the run stays, with the directory.
    pub(crate) fn remove(self) {
        let _ = remove_own_entries(&self.path, true);
        let _ = std::fs::remove_dir(&self.path);
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

/// The tile results of a work directory: which tiles are done, the journal that commits new
/// ones, and the files assemble merges.
pub(crate) struct ResultStore {
    dir: PathBuf,
}

impl ResultStore {
    /// Whether tile `t` is finished: its result file is complete (and, with `propagate`
    /// (`--orient propagate`), its orientation sidecar is there: it is renamed first).
    pub(crate) fn tile_done(&self, t: &TileSpec, cols: &ColumnSet, propagate: bool) -> bool {
        (!propagate || names::tile_orientation(&self.dir, t.key).exists())
            && results::is_complete(&names::tile_result(&self.dir, t.key), t.count, cols)
    }

    /// The tiles of `tiles` that are not finished ([`ResultStore::tile_done`]), in order.
    pub(crate) fn missing<'t>(
        &self,
        tiles: &'t [TileSpec],
        cols: &ColumnSet,
        propagate: bool,
    ) -> Vec<&'t TileSpec> {
        tiles
            .iter()
            .filter(|t| !self.tile_done(t, cols, propagate))
            .collect()
    }

    /// The journal that writes and commits finished tiles.
    pub(crate) fn journal(&self) -> results::Journal {
        results::Journal::new(&self.dir)
    }

    /// The result files of `tiles`, in order.
    pub(crate) fn files(&self, tiles: &[TileSpec]) -> Vec<PathBuf> {
        tiles
            .iter()
            .map(|t| names::tile_result(&self.dir, t.key))
            .collect()
    }

    /// The directory, for the merge's run files and the orientation sidecars.
    pub(crate) fn dir(&self) -> &Path {
        &self.dir
    }
}

/// Whether `name` is an entry of a work directory: one of its names ([`names`], the Slurm
/// recipe's logs included), a temporary of one ([`crate::io::durable::tmp_name`]), or a file
/// NFS keeps for one deleted while open (`.nfs` and hex digits, gone once it is closed).
fn is_own_entry(name: &str) -> bool {
    let own = |n: &str| [LOCK, MANIFEST, TASKS, BUCKETS, RESULTS, LOGS].contains(&n);
    own(name) || temp_of(name).is_some_and(own) || name.starts_with(".nfs")
}

/// Refuses a directory at `path` that holds anything but a work directory's own entries
/// ([`is_own_entry`]): tilecurv empties a work directory of stale work and removes it after a
/// successful run, so a folder of other files (`--work-dir .` beside the input, a home
/// directory) is never taken for one. A missing or empty directory, or a work directory, is
/// accepted.
fn check_own(path: &Path) -> Result<()> {
    match std::fs::metadata(path) {
        // Missing, or below a file: making it says why it cannot be made.
        Err(_) => return Ok(()),
        Ok(m) if !m.is_dir() => {
            return Err(Error::Usage(format!(
                "{}: the work directory is a file, not a folder; name a new or empty folder for it",
                path.display()
            )))
        }
        Ok(_) => {}
    }
    let entries = std::fs::read_dir(path).map_err(|e| Error::write(path, e))?;
    let mut foreign: Vec<String> = entries
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !is_own_entry(n))
        .collect();
    if foreign.is_empty() {
        return Ok(());
    }
    foreign.sort();
    let more = foreign.len().saturating_sub(3);
    foreign.truncate(3);
    let mut held = foreign.join(", ");
    if more > 0 {
        held.push_str(&format!(" and {more} more"));
    }
    Err(Error::Usage(format!(
        "{}: not a tilecurv work directory (it holds {held}): tilecurv empties its work directory of stale work and removes it when a run is done, so it must be a new or empty folder of its own; name one with --work-dir (`plan`: --work), or leave the default (.NAME.tilecurv beside the output)",
        path.display()
    )))
}

/// Empties the work directory `dir` of its own entries ([`is_own_entry`]; the lock only with
/// `lock`), leaving anything else.
fn remove_own_entries(dir: &Path, lock: bool) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::write(dir, e))?;
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !is_own_entry(&name) || name.starts_with(".nfs") || (name == LOCK && !lock) {
            continue;
        }
        let p = e.path();
        // The entry's own type: a link named like an entry is removed, not followed.
        let r = if e.file_type().is_ok_and(|t| t.is_dir()) {
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
    fn stale_work_is_discarded_and_matching_work_resumed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let wd = dir.path().join("w");
        let w = WorkDir::open(&wd, "fp 1\n").expect("open");
        assert_eq!(w.resume, Resume::Fresh);
        std::fs::create_dir(wd.join(RESULTS)).expect("results");
        std::fs::write(wd.join(RESULTS).join("tile_0_0.res"), b"x").expect("write");
        drop(w);
        let w = WorkDir::open(&wd, "fp 1\n").expect("open");
        assert_eq!(w.resume, Resume::Resumed);
        assert!(wd.join(RESULTS).join("tile_0_0.res").exists());
        drop(w);
        let w = WorkDir::open(&wd, "fp 2\n").expect("open");
        assert_eq!(w.resume, Resume::Discarded);
        assert!(!wd.join(RESULTS).exists());
        drop(w);
        // A lock file left by a run that died (here naming pid 1) holds no lock: taken over.
        std::fs::write(wd.join(LOCK), "1\n").expect("write lock");
        let w = WorkDir::open(&wd, "fp 2\n").expect("open");
        w.remove();
        assert!(!wd.exists());
    }

    /// A folder of other files is refused untouched; what appears in a work directory during
    /// a run stays when the run removes its own entries, and so does the directory then.
    #[test]
    fn only_a_work_directorys_own_entries_are_ever_removed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let wd = dir.path().join("w");
        std::fs::create_dir(&wd).expect("dir");
        std::fs::write(wd.join("survey.las"), b"points").expect("write");
        let refused = WorkDir::open(&wd, "fp 1\n");
        assert!(matches!(&refused, Err(Error::Usage(m)) if m.contains("it holds survey.las")));
        assert_eq!(
            std::fs::read(wd.join("survey.las")).expect("kept"),
            b"points"
        );
        std::fs::remove_file(wd.join("survey.las")).expect("remove");
        std::fs::write(wd.join(".nfs000000001"), b"").expect("nfs");
        let w = WorkDir::open(&wd, "fp 1\n").expect("an empty folder is accepted");
        w.results().expect("results");
        std::fs::write(wd.join("later.txt"), b"mine").expect("write");
        w.remove();
        let mut left: Vec<_> = std::fs::read_dir(&wd)
            .expect("kept")
            .map(|e| e.expect("entry").file_name())
            .collect();
        left.sort();
        assert_eq!(left, [".nfs000000001", "later.txt"]);
        assert_eq!(temp_of(".results.tilecurv-node-7-42.tmp"), Some("results"));
        assert_eq!(temp_of(".tilecurv-node-42.tmp"), None);
    }

    #[test]
    fn a_held_lock_is_never_taken_even_when_its_file_reads_empty() {
        // A second run that reads the lock file between the first run's create and its write
        // sees no pid: the flock, not the file's text, decides.
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
