//! The library's error type. Every variant carries what a user needs to act: the file, the byte
//! offset or point index, what was expected, and a hint. Exit codes are decided from
//! [`Error::exit_class`] in the binary; nothing here prints.

use std::path::PathBuf;

/// Which class of failure an error belongs to; the CLI maps each to a documented exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitClass {
    /// The command line or configuration is wrong (exit 2).
    Usage,
    /// An input file is unreadable, malformed or unsupported (exit 3).
    BadInput,
    /// The output or the work directory could not be written or read, or a limit of the
    /// machine (disk space, file size, open files, memory) stopped the run (exit 4).
    Output,
    /// The run was stopped by a signal (exit 130).
    Interrupted,
    /// A stage found tasks of an earlier stage not done (exit 5).
    Incomplete,
    /// A bug or an unexpected internal state (exit 1).
    Internal,
}

/// Errors of the tilecurv library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A configuration value is invalid.
    #[error("{0}")]
    Usage(String),

    /// An input file is malformed or unsupported.
    #[error("{path}: {what}{}", offset.map(|o| format!(" (at byte offset {o})")).unwrap_or_default())]
    BadInput {
        /// The input file.
        path: PathBuf,
        /// Byte offset in the file where the problem was found, if known.
        offset: Option<u64>,
        /// What is wrong and what to do.
        what: String,
    },

    /// Reading an input file failed at the operating-system level (made by
    /// [`Error::read_input`], which keeps a lack of resources out of it).
    #[error("{path}: cannot read: {source}")]
    ReadIo {
        /// The input file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },

    /// Reading failed for a reason that is not the input's: a file of the work directory
    /// (tilecurv's own) is unreadable, or opening any file hit a limit (too many open files).
    #[error("{path}: cannot read: {source}{hint}")]
    ReadFailed {
        /// The file being read.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
        /// What to do.
        hint: &'static str,
    },

    /// Writing the output or the work directory failed.
    #[error("{path}: cannot write: {source}{hint}")]
    WriteIo {
        /// The file or directory being written.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
        /// A hint on what to do (may be empty).
        hint: &'static str,
    },

    /// The machine refused the run something it needs (a thread), not because of any file.
    #[error("{0}")]
    Resource(String),

    /// Tasks of an earlier stage are not done yet (a cluster run): nothing was written.
    #[error("{stage} tasks not done: {tasks}; {hint}")]
    TasksMissing {
        /// The stage whose tasks are missing (`bucket`, `run-tile`).
        stage: &'static str,
        /// The missing task indices, in Slurm `--array=` syntax.
        tasks: String,
        /// What to run.
        hint: String,
    },

    /// The run was interrupted by a signal before it finished.
    #[error("interrupted: no output was written")]
    Interrupted,

    /// An internal invariant was violated (a bug: please report it).
    #[error("internal error: {0} (this is a bug in tilecurv; please report it)")]
    Internal(String),
}

impl Error {
    /// The class of this error, for the exit code.
    pub fn exit_class(&self) -> ExitClass {
        match self {
            Error::Usage(_) => ExitClass::Usage,
            Error::BadInput { .. } | Error::ReadIo { .. } => ExitClass::BadInput,
            Error::WriteIo { .. } | Error::ReadFailed { .. } | Error::Resource(_) => {
                ExitClass::Output
            }
            Error::TasksMissing { .. } => ExitClass::Incomplete,
            Error::Interrupted => ExitClass::Interrupted,
            Error::Internal(_) => ExitClass::Internal,
        }
    }

    /// A bad-input error at a byte offset.
    pub fn bad_input(path: &std::path::Path, offset: Option<u64>, what: impl Into<String>) -> Self {
        Error::BadInput {
            path: path.to_path_buf(),
            offset,
            what: what.into(),
        }
    }

    /// A write error on `path`, with a standard hint for the common causes.
    pub fn write(path: &std::path::Path, source: std::io::Error) -> Self {
        let hint = match source.kind() {
            std::io::ErrorKind::PermissionDenied => " (check the directory's permissions)",
            std::io::ErrorKind::NotFound => " (does the output directory exist?)",
            _ => match source.raw_os_error() {
                Some(libc::ENOSPC) | Some(libc::EDQUOT) => {
                    " (no space left there: free space, or put the output or the work directory (--work-dir) elsewhere, then run the same command again: a run of process resumes from its finished tiles)"
                }
                Some(libc::EFBIG) => {
                    " (the file outgrew the file-size limit: raise `ulimit -f`, or write to a file system that takes larger files, then run the same command again: a run of process resumes from its finished tiles)"
                }
                _ => resource_hint(&source).unwrap_or(""),
            },
        };
        Error::WriteIo {
            path: path.to_path_buf(),
            source,
            hint,
        }
    }

    /// A read error on the input file `path`: bad input ([`Error::ReadIo`]), unless the
    /// process lacked a resource to read it (too many open files, memory), which is not the
    /// input's fault ([`Error::ReadFailed`], exit 4).
    pub fn read_input(path: &std::path::Path, source: std::io::Error) -> Self {
        match resource_hint(&source) {
            Some(hint) => Error::ReadFailed {
                path: path.to_path_buf(),
                source,
                hint,
            },
            None => Error::ReadIo {
                path: path.to_path_buf(),
                source,
            },
        }
    }

    /// A read error on `path`, a file of the work directory: never bad input (the user's
    /// files are fine), exit 4 with what to do.
    pub fn read_work(path: &std::path::Path, source: std::io::Error) -> Self {
        let hint = resource_hint(&source).unwrap_or(match source.kind() {
            std::io::ErrorKind::NotFound => {
                " (a file of the work directory went missing during the run: is another program cleaning it? Run the same command again)"
            }
            _ => " (a file of the work directory is unreadable: check the directory, or delete it to start over)",
        });
        Error::ReadFailed {
            path: path.to_path_buf(),
            source,
            hint,
        }
    }

    /// A file of the work directory (tilecurv's own) that is damaged, truncated or of another
    /// version of tilecurv: never bad input, exit 4, with what to do. `what` says what is
    /// wrong with it.
    pub fn damaged_work(path: &std::path::Path, what: &str) -> Self {
        Error::ReadFailed {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, what.to_string()),
            hint: " (a file of the work directory is damaged or was written by another version of tilecurv: delete the work directory and run again)",
        }
    }
}

/// The hint for an error that says the process ran out of a resource, not that a file is bad:
/// too many open files (EMFILE for the process, ENFILE for the system) or no memory.
fn resource_hint(e: &std::io::Error) -> Option<&'static str> {
    match e.raw_os_error() {
        Some(libc::EMFILE) => Some(
            " (too many open files: raise the limit, e.g. `ulimit -n 4096`, then run the same command again: a run of process resumes from its finished tiles)",
        ),
        Some(libc::ENFILE) => Some(
            " (the system's table of open files is full: close other programs or raise fs.file-max, then run the same command again: a run of process resumes from its finished tiles)",
        ),
        Some(libc::ENOMEM) => Some(
            " (out of memory: lower --memory, or raise `ulimit -v` or the memory limit, then run the same command again: a run of process resumes from its finished tiles)",
        ),
        _ => None,
    }
}

/// Result alias for the library.
pub type Result<T> = std::result::Result<T, Error>;
