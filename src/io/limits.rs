//! The process's resource limits as the operating system states them: open files (raised to
//! the hard limit at start, as batch tools do, and the descriptors in use) and memory (the
//! address-space limit and the cgroup's memory limit, which `run::limits` fits the budget to).

/// Raises the soft limit on open files to the hard limit (a run opens up to
/// [`MAX_FAN_IN`](crate::io::workdir::results::MAX_FAN_IN) result files at once when it merges them,
/// as its memory budget allows);
/// a limit that cannot be raised is left as it is, and the merge fits itself to it.
pub(crate) fn raise_open_files() {
    if let Some(lim) = current(Limit::OpenFiles).filter(|l| l.rlim_cur < l.rlim_max) {
        let raised = libc::rlimit {
            rlim_cur: lim.rlim_max,
            rlim_max: lim.rlim_max,
        };
        // SAFETY: setrlimit only reads the struct passed.
        unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) };
    }
}

/// The soft limit on open files, if it can be read (`RLIM_INFINITY` is `u64::MAX`).
pub(crate) fn open_files_limit() -> Option<u64> {
    current(Limit::OpenFiles).map(|l| l.rlim_cur)
}

/// The file descriptors this process has open now (Linux: `/proc/self/fd`, less the one the
/// listing itself holds); None where that cannot be read.
pub(crate) fn open_descriptors() -> Option<u64> {
    let n = std::fs::read_dir("/proc/self/fd").ok()?.count() as u64;
    Some(n.saturating_sub(1))
}

/// The address-space limit (`RLIMIT_AS`, `ulimit -v`) in bytes; None when unlimited. Every
/// mapping counts against it: the memory-mapped inputs, thread stacks, the allocator's arenas.
pub(crate) fn address_space_limit() -> Option<u64> {
    current(Limit::AddressSpace)
        .map(|l| l.rlim_cur)
        .filter(|&cur| cur != libc::RLIM_INFINITY)
}

/// The limits read here.
#[derive(Clone, Copy)]
enum Limit {
    OpenFiles,
    AddressSpace,
}

/// The soft and hard values of a limit, if getrlimit answers. A match of calls rather than a
/// resource argument: the resource's type differs between C libraries (glibc: unsigned).
fn current(which: Limit) -> Option<libc::rlimit> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit only writes the struct passed.
    let r = unsafe {
        match which {
            Limit::OpenFiles => libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim),
            Limit::AddressSpace => libc::getrlimit(libc::RLIMIT_AS, &mut lim),
        }
    };
    (r == 0).then_some(lim)
}

/// Caps the allocator's arenas (glibc). Under an address-space limit, one: glibc reserves 64 MiB
/// of address space for each further arena, which counts against `ulimit -v` though it is never
/// used (one arena costs a few percent of speed). Otherwise two a core instead of glibc's eight
/// a core: with that many, each of a run's threads (workers, tile drivers, the result writer,
/// the merge) keeps an arena of its own, whose freed buffers the others do not reuse, and the
/// resident memory outgrows the budget (a 2M-point terrain at `--memory 64M`, 2 cores: peak
/// 94-108 MiB with glibc's cap, 63-77 MiB in six runs of seven with two arenas a core, 89 in
/// the seventh; the CPU time of 14 runs interleaved at the default budget: glibc's cap took
/// 1.014 of it, median, within the runs' scatter of 0.04). Call before any thread starts.
/// Elsewhere (other C libraries) nothing changes.
pub(crate) fn fit_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let arenas = match address_space_limit() {
            Some(_) => 1,
            None => std::thread::available_parallelism().map_or(2, |n| 2 * n.get()),
        };
        let arenas = libc::c_int::try_from(arenas).unwrap_or(libc::c_int::MAX);
        // SAFETY: mallopt only sets an allocator parameter; no thread allocates yet.
        unsafe {
            libc::mallopt(libc::M_ARENA_MAX, arenas);
        }
    }
}

/// A cgroup's memory limit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct MemoryLimit {
    /// The limit in bytes.
    pub(crate) bytes: u64,
    /// The file that sets it.
    pub(crate) file: std::path::PathBuf,
}

/// The memory limit of this process's cgroup in bytes and the file that sets it: the lowest
/// `memory.max` (cgroup v2) or `memory.limit_in_bytes` (v1) from its cgroup up to the root of
/// the mounted hierarchy; None when there is none (or no cgroup file system).
pub(crate) fn cgroup_memory_limit() -> Option<MemoryLimit> {
    let cgroup = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let mountinfo = std::fs::read_to_string("/proc/self/mountinfo").ok()?;
    cgroup_limit(&cgroup, &mountinfo, &|p| std::fs::read_to_string(p).ok())
}

/// [`cgroup_memory_limit`] from the text of `/proc/self/cgroup` and `/proc/self/mountinfo`,
/// reading the limit files with `read`.
fn cgroup_limit(
    cgroup: &str,
    mountinfo: &str,
    read: &dyn Fn(&std::path::Path) -> Option<String>,
) -> Option<MemoryLimit> {
    use std::path::PathBuf;
    // Mount points: (fstype is cgroup2, or cgroup with the memory controller) -> (root, point).
    let mut v2 = None;
    let mut v1 = None;
    for line in mountinfo.lines() {
        let Some((mount, fs)) = line.split_once(" - ") else {
            continue;
        };
        let m: Vec<&str> = mount.split(' ').collect();
        let f: Vec<&str> = fs.split(' ').collect();
        let (Some(root), Some(point), Some(ty)) = (m.get(3), m.get(4), f.first()) else {
            continue;
        };
        let at = (root.to_string(), PathBuf::from(point));
        match *ty {
            "cgroup2" => v2 = v2.or(Some(at)),
            "cgroup"
                if f.get(2)
                    .is_some_and(|o| o.split(',').any(|o| o == "memory")) =>
            {
                v1 = v1.or(Some(at))
            }
            _ => {}
        }
    }
    // This process's path in each hierarchy: "0::/path" (v2), "N:...memory...:/path" (v1).
    let mut lowest: Option<MemoryLimit> = None;
    for line in cgroup.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(id), Some(ctrl), Some(path)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let (mount, file) = if id == "0" && ctrl.is_empty() {
            (&v2, "memory.max")
        } else if ctrl.split(',').any(|c| c == "memory") {
            (&v1, "memory.limit_in_bytes")
        } else {
            continue;
        };
        let Some((root, point)) = mount else {
            continue;
        };
        // The mount shows the hierarchy from `root` down (a container's namespace).
        let rel = path.strip_prefix(root.as_str()).unwrap_or(path);
        let mut dir = point.join(rel.trim_start_matches('/'));
        loop {
            let f = dir.join(file);
            // "max" (v2) or a page-rounded 2^63 (v1) mean no limit.
            if let Some(v) = read(&f).and_then(|t| t.trim().parse::<u64>().ok()) {
                if v < 1 << 62 && lowest.as_ref().is_none_or(|l| v < l.bytes) {
                    lowest = Some(MemoryLimit { bytes: v, file: f });
                }
            }
            if dir == *point || !dir.pop() || !dir.starts_with(point) {
                break;
            }
        }
    }
    lowest
}

/// Gives the memory the allocator holds free back to the system (glibc: `malloc_trim`, over
/// every arena), between phases: the tile phase's buffers, freed in the worker threads' arenas,
/// would otherwise stay resident through the write phase and add to its own (30M points,
/// `--memory 128M`: peak anonymous memory 182 -> 122 MiB, the write phase 179 -> 99 MiB).
/// Elsewhere nothing happens.
pub(crate) fn return_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free pages of the allocator's own heaps.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::path::{Path, PathBuf};

    fn reader(files: &[(&str, &str)]) -> impl Fn(&Path) -> Option<String> {
        let m: HashMap<PathBuf, String> = files
            .iter()
            .map(|(p, t)| (PathBuf::from(p), t.to_string()))
            .collect();
        move |p| m.get(p).cloned()
    }

    #[test]
    fn the_lowest_cgroup_limit_along_the_path_is_found() {
        let mountinfo = "\
31 23 0:28 / /sys/fs/cgroup rw,relatime - tmpfs tmpfs rw,mode=755
35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory
41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw
";
        // v1: the job's limit is below its parent's; "unlimited" is 2^63 rounded to pages.
        let v1 = reader(&[
            (
                "/sys/fs/cgroup/memory/slurm/job1/memory.limit_in_bytes",
                "1073741824\n",
            ),
            (
                "/sys/fs/cgroup/memory/slurm/memory.limit_in_bytes",
                "4294967296\n",
            ),
            (
                "/sys/fs/cgroup/memory/memory.limit_in_bytes",
                "9223372036854771712\n",
            ),
        ]);
        assert_eq!(
            cgroup_limit("4:memory:/slurm/job1\n0::/\n", mountinfo, &v1),
            Some(MemoryLimit {
                bytes: 1 << 30,
                file: PathBuf::from("/sys/fs/cgroup/memory/slurm/job1/memory.limit_in_bytes")
            })
        );
        // v2 alone (a container with its own namespace: the mount's root is the cgroup).
        let v2 = "50 40 0:30 / /sys/fs/cgroup rw - cgroup2 cgroup2 rw\n";
        let files = reader(&[
            ("/sys/fs/cgroup/user.slice/memory.max", "max\n"),
            (
                "/sys/fs/cgroup/user.slice/run.scope/memory.max",
                "536870912\n",
            ),
        ]);
        assert_eq!(
            cgroup_limit("0::/user.slice/run.scope\n", v2, &files).map(|l| l.bytes),
            Some(512 << 20)
        );
        assert_eq!(cgroup_limit("0::/\n", v2, &reader(&[])), None);
        assert_eq!(cgroup_limit("0::/x\n", "", &files), None);
    }
}
