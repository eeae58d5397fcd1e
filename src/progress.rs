//! Progress and log messages. The engine reports through the [`Reporter`] trait; this module
//! holds the only implementation that knows indicatif: a bar with phase, points/s and ETA on a
//! terminal, plain periodic lines on stderr otherwise, nothing but warnings with `quiet`.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// `eprintln!` that never panics: a closed or broken stderr (`2>&1 | head -1`) drops the line
/// instead of killing the run (messages never stop a run).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}
pub(crate) use say;

/// `println!` that never panics: a command's result on a closed stdout is dropped, and the
/// command still exits with its own code.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}
pub(crate) use out;

/// Receives progress and messages from a run. Implementations must be cheap to call often.
pub trait Reporter: Sync {
    /// A new phase starts, with `total` units of work (points).
    fn phase(&self, name: &str, total: u64);
    /// `n` more units of the current phase are done.
    fn advance(&self, n: u64);
    /// The current phase is over.
    fn finish_phase(&self);
    /// An informational message (suppressed by `--quiet`).
    fn info(&self, msg: &str);
    /// A warning (always shown).
    fn warn(&self, msg: &str);
}

/// A reporter that ignores everything (for tests and library use).
pub struct Silent;

impl Reporter for Silent {
    fn phase(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish_phase(&self) {}
    fn info(&self, _: &str) {}
    fn warn(&self, _: &str) {}
}

struct Phase {
    name: String,
    total: u64,
    started: Instant,
    last_line: Instant,
}

/// The terminal reporter: indicatif bar on a TTY, plain lines every few seconds otherwise, and
/// optionally JSON lines to a file.
pub struct TermReporter {
    quiet: bool,
    json: Option<Mutex<std::fs::File>>,
    bar: Option<ProgressBar>,
    done: AtomicU64,
    phase: Mutex<Option<Phase>>,
    line_every: Duration,
}

impl TermReporter {
    /// A reporter writing to stderr; `quiet` keeps only warnings. With `json`, one JSON line per
    /// progress step and per phase is appended to that file.
    pub fn new(quiet: bool, json: Option<&std::path::Path>) -> crate::error::Result<Self> {
        let json = match json {
            Some(p) => Some(Mutex::new(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)
                    .map_err(|e| crate::error::Error::write(p, e))?,
            )),
            None => None,
        };
        let tty = std::io::stderr().is_terminal() && !quiet;
        let bar = tty.then(|| {
            let b = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
            b.set_style(
                ProgressStyle::with_template("{prefix:>10} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} pts {per_sec} ETA {eta}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        Ok(TermReporter {
            quiet,
            json,
            bar,
            done: AtomicU64::new(0),
            phase: Mutex::new(None),
            line_every: Duration::from_secs(10),
        })
    }

    fn json_line(&self, event: &str, p: &Phase, done: u64) {
        let Some(j) = &self.json else { return };
        let elapsed = p.started.elapsed();
        let r = rate(done, elapsed);
        let eta = if r > 0.0 {
            format!("{:.1}", p.total.saturating_sub(done) as f64 / r)
        } else {
            "null".into()
        };
        let line = format!(
            "{{\"event\":\"{event}\",\"phase\":\"{}\",\"done\":{done},\"total\":{},\"elapsed_s\":{:.3},\"points_per_s\":{r:.0},\"eta_s\":{eta}}}\n",
            p.name,
            p.total,
            elapsed.as_secs_f64()
        );
        if let Ok(mut f) = j.lock() {
            let _ = std::io::Write::write_all(&mut *f, line.as_bytes());
        }
    }

    fn line(&self, msg: &str) {
        match &self.bar {
            Some(b) => b.println(msg),
            None => say!("{msg}"),
        }
    }
}

fn rate(n: u64, d: Duration) -> f64 {
    n as f64 / d.as_secs_f64().max(1e-9)
}

impl Reporter for TermReporter {
    fn phase(&self, name: &str, total: u64) {
        self.done.store(0, Ordering::Relaxed);
        if let Some(b) = &self.bar {
            b.reset();
            b.set_length(total);
            b.set_prefix(name.to_string());
        }
        if let Ok(mut guard) = self.phase.lock() {
            let p = Phase {
                name: name.into(),
                total,
                started: Instant::now(),
                last_line: Instant::now(),
            };
            self.json_line("phase_start", &p, 0);
            *guard = Some(p);
        }
    }

    fn advance(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        if let Some(b) = &self.bar {
            b.inc(n);
        }
        let Ok(mut guard) = self.phase.lock() else {
            return;
        };
        let Some(p) = guard.as_mut() else { return };
        self.json_line("progress", p, done);
        if self.bar.is_some() || self.quiet || p.last_line.elapsed() < self.line_every {
            return;
        }
        p.last_line = Instant::now();
        let r = rate(done, p.started.elapsed());
        let eta = if r > 0.0 {
            p.total.saturating_sub(done) as f64 / r
        } else {
            f64::NAN
        };
        say!(
            "{}: {done}/{} points ({:.1}%), {r:.0} points/s, ETA {eta:.0} s",
            p.name,
            p.total,
            100.0 * done as f64 / p.total.max(1) as f64
        );
    }

    fn finish_phase(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
        let Ok(mut guard) = self.phase.lock() else {
            return;
        };
        let Some(p) = guard.take() else { return };
        self.json_line("phase_end", &p, self.done.load(Ordering::Relaxed));
        if !self.quiet {
            let t = p.started.elapsed();
            self.line(&format!(
                "{}: {} points in {:.1} s ({:.0} points/s)",
                p.name,
                p.total,
                t.as_secs_f64(),
                rate(p.total, t)
            ));
        }
    }

    fn info(&self, msg: &str) {
        if !self.quiet {
            self.line(msg);
        }
    }

    fn warn(&self, msg: &str) {
        self.line(&format!("warning: {msg}"));
    }
}
