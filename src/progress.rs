//! Progress and log messages. The engine reports through the [`Reporter`] trait; this module
//! holds the only implementation that knows indicatif: a bar with phase, points/s and ETA on a
//! terminal, plain periodic lines on stderr otherwise, nothing but warnings with `quiet`.

use std::io::{IsTerminal, Write as _};
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
    /// `n` units of the current phase were done before it started (a resumed run's finished
    /// tiles): done, but not part of the phase's rate.
    fn resumed(&self, n: u64) {
        self.advance(n);
    }
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
    /// Units done before the phase started ([`Reporter::resumed`]).
    resumed: u64,
    started: Instant,
    last_line: Instant,
}

/// The share of a default run's wall time each phase takes (the seconds of each phase of a run
/// on 20M generated terrain points on 2 cores: docs/performance.md): the later phases' time is
/// estimated from the current phase's rate with these weights, for one ETA for the run.
const PHASE_WEIGHTS: [(&str, f64); 3] = [("scan", 8.0), ("curvature", 33.8), ("write", 5.9)];

/// Seconds left in the whole run, from phase `p` with `done` of its points done: none until the
/// phase is 1% and 2 s in (a rate from its first moments is noise). The rate is that of the
/// points done in the phase, not of those it resumed.
fn run_eta(p: &Phase, done: u64) -> Option<f64> {
    let elapsed = p.started.elapsed().as_secs_f64();
    let worked = done.saturating_sub(p.resumed) as f64;
    let f = done as f64 / p.total.max(1) as f64;
    if worked < 0.01 * p.total as f64 || elapsed < 2.0 {
        return None;
    }
    // The phase's time at this rate as if none had been resumed: the later phases scale with it.
    let phase_total = elapsed * p.total as f64 / worked;
    let at = PHASE_WEIGHTS.iter().position(|(n, _)| *n == p.name);
    let later: f64 = at
        .map(|i| PHASE_WEIGHTS[i + 1..].iter().map(|w| w.1).sum::<f64>() / PHASE_WEIGHTS[i].1)
        .unwrap_or(0.0);
    Some(phase_total * (1.0 - f) + phase_total * later)
}

/// A rate for people: `591k points/s`, `1.21M points/s` (indicatif's has four decimals).
pub fn human_rate(r: f64) -> String {
    match r {
        r if r >= 1e6 => format!("{:.2}M points/s", r / 1e6),
        r if r >= 1e4 => format!("{:.0}k points/s", r / 1e3),
        r => format!("{r:.0} points/s"),
    }
}

/// A duration for people: `45 s`, `12 min 5 s`, `2 h 3 min`.
fn human_secs(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    match s {
        s if s < 60 => format!("{s} s"),
        s if s < 3600 => format!("{} min {} s", s / 60, s % 60),
        s => format!("{} h {} min", s / 3600, s % 3600 / 60),
    }
}

/// A JSON string literal.
pub fn json_str(v: &str) -> String {
    let mut o = String::from("\"");
    for c in v.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            '\n' => o.push_str("\\n"),
            c if (c as u32) < 0x20 => o.push_str(&format!("\\u{:04x}", c as u32)),
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

/// The terminal reporter: indicatif bar on a TTY, plain lines every few seconds otherwise, and
/// optionally JSON lines to a file.
pub struct TermReporter {
    quiet: bool,
    json: Option<Mutex<Box<dyn std::io::Write + Send>>>,
    bar: Option<ProgressBar>,
    done: AtomicU64,
    phase: Mutex<Option<Phase>>,
    line_every: Duration,
}

impl TermReporter {
    /// A reporter writing to stderr; `quiet` keeps only warnings. With `json`, one JSON line per
    /// progress step and per phase is appended to that file (`-`: standard output).
    pub fn new(quiet: bool, json: Option<&std::path::Path>) -> crate::error::Result<Self> {
        let json: Option<Box<dyn std::io::Write + Send>> = match json {
            Some(p) if p.as_os_str() == "-" => Some(Box::new(std::io::stdout())),
            Some(p) => Some(Box::new(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)
                    .map_err(|e| crate::error::Error::write(p, e))?,
            )),
            None => None,
        };
        Ok(Self::with_json_writer(quiet, json))
    }

    /// [`TermReporter::new`] with the JSON lines written to `json` (the Python package hands
    /// them to a callback).
    pub fn with_json_writer(quiet: bool, json: Option<Box<dyn std::io::Write + Send>>) -> Self {
        let json = json.map(Mutex::new);
        let tty = std::io::stderr().is_terminal() && !quiet;
        let bar = tty.then(|| {
            // Hidden until the first phase gives it a length: a bar of 0 points draws full.
            let b = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
            b.set_style(
                ProgressStyle::with_template(
                    "{prefix:>10} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} pts {msg}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        TermReporter {
            quiet,
            json,
            bar,
            done: AtomicU64::new(0),
            phase: Mutex::new(None),
            line_every: Duration::from_secs(10),
        }
    }

    fn json_line(&self, event: &str, p: &Phase, done: u64) {
        if self.json.is_none() {
            return;
        }
        let elapsed = p.started.elapsed();
        let r = rate(done.saturating_sub(p.resumed), elapsed);
        let eta = |v: Option<f64>| {
            v.map(|s| format!("{s:.1}"))
                .unwrap_or_else(|| "null".into())
        };
        let phase_eta = (r > 0.0 && done > 0).then(|| p.total.saturating_sub(done) as f64 / r);
        self.json_raw(&format!(
            "{{\"event\":\"{event}\",\"phase\":\"{}\",\"done\":{done},\"total\":{},\"elapsed_s\":{:.3},\"points_per_s\":{r:.0},\"eta_s\":{},\"run_eta_s\":{}}}",
            p.name,
            p.total,
            elapsed.as_secs_f64(),
            eta(phase_eta),
            eta(run_eta(p, done)),
        ));
    }

    /// Writes one JSON line (an object) to the JSON stream, if any; a write that fails is
    /// dropped (progress never stops a run).
    fn json_raw(&self, line: &str) {
        let Some(j) = &self.json else { return };
        if let Ok(mut f) = j.lock() {
            let _ = writeln!(f, "{line}");
            let _ = f.flush();
        }
    }

    /// The final event of a run: `{"event":"summary", ...}` with `fields` (JSON members,
    /// already encoded) and the run's wall time.
    pub fn summary(&self, fields: &[(&str, String)], seconds: f64) {
        let body: Vec<String> = fields.iter().map(|(k, v)| format!("\"{k}\":{v}")).collect();
        self.json_raw(&format!(
            "{{\"event\":\"summary\",{},\"wall_s\":{seconds:.3}}}",
            body.join(",")
        ));
    }

    fn line(&self, msg: &str) {
        match &self.bar {
            Some(b) => b.println(msg),
            None => say!("{msg}"),
        }
    }
}

/// The line that ends phase `p`: its points, time and rate, the rate of the points it did
/// itself when some were resumed.
fn end_line(p: &Phase) -> String {
    let t = p.started.elapsed();
    let worked = p.total.saturating_sub(p.resumed);
    match p.resumed {
        0 => format!(
            "{}: {} points in {:.1} s ({})",
            p.name,
            p.total,
            t.as_secs_f64(),
            human_rate(rate(p.total, t))
        ),
        r if worked == 0 => format!("{}: {} points, all {r} resumed", p.name, p.total),
        r => format!(
            "{}: {} points, {r} of them resumed, the other {worked} in {:.1} s ({})",
            p.name,
            p.total,
            t.as_secs_f64(),
            human_rate(rate(worked, t))
        ),
    }
}

fn rate(n: u64, d: Duration) -> f64 {
    n as f64 / d.as_secs_f64().max(1e-9)
}

impl Reporter for TermReporter {
    fn resumed(&self, n: u64) {
        if let Ok(mut guard) = self.phase.lock() {
            if let Some(p) = guard.as_mut() {
                p.resumed += n;
            }
        }
        self.advance(n);
    }

    fn phase(&self, name: &str, total: u64) {
        self.done.store(0, Ordering::Relaxed);
        if let Some(b) = &self.bar {
            b.reset();
            b.set_length(total);
            b.set_prefix(name.to_string());
            b.set_message("run ETA ...");
            if b.is_hidden() {
                b.set_draw_target(ProgressDrawTarget::stderr());
            }
        }
        if let Ok(mut guard) = self.phase.lock() {
            let p = Phase {
                name: name.into(),
                total,
                resumed: 0,
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
        let r = rate(done.saturating_sub(p.resumed), p.started.elapsed());
        let eta = run_eta(p, done)
            .map(|s| format!("run ETA {}", human_secs(s)))
            .unwrap_or_else(|| "run ETA ...".into());
        if let Some(b) = &self.bar {
            b.set_message(format!("{} {eta}", human_rate(r)));
        }
        if self.bar.is_some() || self.quiet || p.last_line.elapsed() < self.line_every {
            return;
        }
        p.last_line = Instant::now();
        say!(
            "{}: {done}/{} points ({:.1}%), {}, {eta}",
            p.name,
            p.total,
            100.0 * done as f64 / p.total.max(1) as f64,
            human_rate(r)
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
            self.line(&end_line(&p));
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

#[cfg(test)]
mod tests {
    use super::*;

    fn phase(name: &str, total: u64, ago_s: u64) -> Phase {
        let started = Instant::now()
            .checked_sub(Duration::from_secs(ago_s))
            .unwrap_or_else(Instant::now);
        Phase {
            name: name.into(),
            total,
            resumed: 0,
            started,
            last_line: started,
        }
    }

    /// Half the scan in 10 s: 10 s more of scan, then the curvature and write phases at the
    /// measured weights (33.8 + 5.9 s per 8 s of scan). Nothing before 1% and 2 s.
    #[test]
    fn one_eta_for_the_whole_run() {
        let eta = run_eta(&phase("scan", 1000, 10), 500).expect("an ETA");
        let want = 10.0 + 20.0 * (33.8 + 5.9) / 8.0;
        assert!((eta - want).abs() < 0.5, "{eta} vs {want}");
        let last = run_eta(&phase("write", 1000, 10), 500).expect("an ETA");
        assert!((last - 10.0).abs() < 0.5, "{last}");
        assert_eq!(run_eta(&phase("scan", 1000, 10), 5), None);
        assert_eq!(run_eta(&phase("scan", 1000, 0), 500), None);
        // 900 of 1000 resumed and 50 done in 10 s: 5 points/s, so 50 more take 10 s.
        let mut resumed = phase("curvature", 1000, 10);
        resumed.resumed = 900;
        let eta = run_eta(&resumed, 950).expect("an ETA");
        let want = 10.0 + 200.0 * 5.9 / 33.8;
        assert!((eta - want).abs() < 0.5, "{eta} vs {want}");
        assert!(end_line(&resumed)
            .starts_with("curvature: 1000 points, 900 of them resumed, the other 100 in 10.0 s ("));
        resumed.resumed = 1000;
        assert_eq!(
            end_line(&resumed),
            "curvature: 1000 points, all 1000 resumed"
        );
        assert_eq!(run_eta(&resumed, 1000), None);
        assert_eq!(human_rate(591_234.567), "591k points/s");
        assert_eq!(human_rate(1_213_000.0), "1.21M points/s");
        assert_eq!(human_secs(725.0), "12 min 5 s");
        assert_eq!(json_str("a\"b\\c\n"), "\"a\\\"b\\\\c\\n\"");
    }
}
