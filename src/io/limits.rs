//! The process's resource limits as the operating system states them: open files (raised to
//! the hard limit at start, as batch tools do, and the descriptors in use) and memory (the
//! address-space limit and the cgroup's memory limit, which `run::limits` fits the budget to).

/// Raises the soft limit on open files to the hard limit (a run opens up to
/// [`MAX_FAN_IN`](crate::io::results::MAX_FAN_IN) result files at once when it merges them);
/// a limit that cannot be raised is left as it is, and the merge fits itself to it.
pub fn raise_open_files() {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit and setrlimit only read or write the struct passed.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) == 0 && lim.rlim_cur < lim.rlim_max {
            let raised = libc::rlimit {
                rlim_cur: lim.rlim_max,
                rlim_max: lim.rlim_max,
            };
            libc::setrlimit(libc::RLIMIT_NOFILE, &raised);
        }
    }
}

/// The soft limit on open files, if it can be read (`RLIM_INFINITY` is `u64::MAX`).
pub fn open_files_limit() -> Option<u64> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit only writes the struct passed.
    (unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } == 0).then_some(lim.rlim_cur)
}

/// The file descriptors this process has open now (Linux: `/proc/self/fd`, less the one the
/// listing itself holds); None where that cannot be read.
pub fn open_descriptors() -> Option<u64> {
    let n = std::fs::read_dir("/proc/self/fd").ok()?.count() as u64;
    Some(n.saturating_sub(1))
}
