//! Peak memory stays within `--memory` plus the program's own (about 60 MB, README "Options";
//! the bound here is 64 MiB) in every neighbourhood mode, for `run-tile` with every tile of the
//! plan in one task and for `process` (whose mapped input counts besides). The peak is the
//! child's own high-water mark of resident memory.

use std::path::Path;
use std::process::{Command, Stdio};

use crate::common::{generate_terrain, s};

const MIB: f64 = 1024.0 * 1024.0;
/// The budget: small enough that every mode's tiles are split into parts.
const BUDGET_MIB: f64 = 64.0;
/// What the program takes besides its budget.
const OVERHEAD_MIB: f64 = 64.0;

/// The high-water mark of resident memory of process `pid` in MiB (`VmHWM`), None once it has
/// exited.
fn high_water(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Runs tilecurv with `args`; returns its exit code and peak resident memory in MiB. The peak
/// is the child's own `VmHWM`, read every 5 ms while it runs (a rusage's maximum would count
/// this test process's memory at the fork); it only grows, so the last reading is the peak
/// but for the final milliseconds.
fn peak_rss(args: &[&str]) -> (i32, f64) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tilecurv"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("tilecurv starts");
    let mut peak: f64 = 0.0;
    loop {
        if let Some(status) = child.try_wait().expect("waits") {
            let code = status.code().expect("exited normally");
            return (code, peak);
        }
        if let Some(h) = high_water(child.id()) {
            peak = peak.max(h);
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

fn bounds(mode: &[&str], input: &Path, dir: &Path) -> (f64, f64) {
    let work = dir.join(format!("w{}", mode.join("").replace(['-', '.'], "")));
    let mut plan = vec![
        "plan",
        s(input),
        "--work",
        s(&work),
        "--tiles-per-task",
        "100000",
    ];
    plan.extend_from_slice(mode);
    plan.push("-q");
    assert_eq!(peak_rss(&plan).0, 0, "{plan:?}");
    let budget = format!("{BUDGET_MIB}M");
    let bucket = ["bucket", "--work", s(&work), "--memory", &budget, "-q"];
    assert_eq!(peak_rss(&bucket).0, 0);
    let task = [
        "run-tile",
        "--work",
        s(&work),
        "--task",
        "0",
        "--memory",
        &budget,
        "-q",
    ];
    let (code, tile_task) = peak_rss(&task);
    assert_eq!(code, 0, "{task:?}");
    let out = dir.join("out.las");
    let mut process = vec![
        "process",
        s(input),
        "-o",
        s(&out),
        "--memory",
        &budget,
        "-q",
    ];
    process.extend_from_slice(mode);
    let (code, whole) = peak_rss(&process);
    assert_eq!(code, 0, "{process:?}");
    (tile_task, whole)
}

/// `-k 30`, `-k auto`, `--radius` and `--orient propagate` on 500k points at `--memory 64M`.
#[test]
fn peak_memory_stays_within_the_budget_in_every_mode() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("t.las");
    generate_terrain(&input, "500k", 2, 8.0);
    let mapped = std::fs::metadata(&input).expect("input").len() as f64 / MIB;
    for mode in [
        &["-k", "30"][..],
        &["-k", "auto"],
        &["--radius", "2m"],
        &["--orient", "propagate"],
    ] {
        let (tile_task, whole) = bounds(mode, &input, dir.path());
        eprintln!("{mode:?}: run-tile {tile_task:.0} MiB, process {whole:.0} MiB");
        assert!(
            tile_task <= BUDGET_MIB + OVERHEAD_MIB,
            "{mode:?}: run-tile peaked at {tile_task:.0} MiB, over {BUDGET_MIB} + {OVERHEAD_MIB}"
        );
        assert!(
            whole <= BUDGET_MIB + OVERHEAD_MIB + mapped,
            "{mode:?}: process peaked at {whole:.0} MiB, over {BUDGET_MIB} + {OVERHEAD_MIB} + the {mapped:.0} MiB input"
        );
    }
}
