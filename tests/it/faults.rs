//! Faults of the machine, made real: writes that fail (the file-size limit, a full
//! file system), temporary files of killed runs, the summary after a resume. Each failing run
//! must exit with its class, name the file, leave no temporary file beside the output and keep
//! the work directory, so that the same command resumes to the bytes of a clean run.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{
    finished_tiles, generate_terrain, process, resume, root, s, tilecurv, under_ci,
};

/// The shipped sample.
fn sample() -> PathBuf {
    root().join("data/Haystack_Rock.las")
}

/// Runs `tilecurv args` under `sh -c 'ulimit LIMIT; exec tilecurv ...'` (`-f 400`, `-n 12`).
fn tilecurv_limited(limit: &str, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit {limit} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_tilecurv"))
        .args(crate::common::with_test_columns(args))
        .output()
        .expect("sh runs")
}

/// Runs `tilecurv args` and asserts success.
fn run_ok(args: &[&str]) {
    let o = tilecurv(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Runs every tile task of the bucketed work directory `work` (their number from `status`).
fn run_every_tile(work: &Path) {
    let tasks = String::from_utf8_lossy(&tilecurv(&["status", "--work", s(work)]).stdout)
        .split(" of ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse::<u64>().ok())
        .expect("status names the tasks");
    for t in 0..tasks {
        run_ok(&[
            "run-tile",
            "--work",
            s(work),
            "--task",
            &t.to_string(),
            "-q",
        ]);
    }
}

/// Temporary outputs (`.<name>.tilecurv-<host>-<pid>.tmp`) left in `dir`.
fn temp_outputs(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("lists the output directory")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n.contains(".tilecurv-") && n.ends_with(".tmp"))
        .collect()
}

/// Checks a run that failed writing `out`: exit 4, the output named with `hint`, no output and
/// no temporary file beside it, the work directory `work` kept; then the same command without
/// the fault resumes to `reference`'s bytes.
fn failed_then_resumed(
    o: &Output,
    args: &[&str],
    out: &Path,
    work: &Path,
    hint: &str,
    ref_: &Path,
) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(4),
        "{}: exit 4 expected: {err}",
        out.display()
    );
    assert!(
        err.contains(&format!("{}: cannot write", out.display())) && err.contains(hint),
        "the message names the output and says what to do ({hint}): {err}"
    );
    assert!(
        !out.exists(),
        "{}: a failed write left an output",
        out.display()
    );
    let dir = out.parent().expect("output directory");
    assert_eq!(
        temp_outputs(dir),
        Vec::<String>::new(),
        "temporary file left: {err}"
    );
    assert!(
        work.join("manifest.txt").exists(),
        "the work directory was not kept: {err}"
    );
    assert!(
        err.contains("the finished work is kept in"),
        "the message says the work is kept: {err}"
    );
    resume(args);
    assert!(
        std::fs::read(out).expect("output") == std::fs::read(ref_).expect("reference"),
        "{}: the resumed output differs from a clean run's",
        out.display()
    );
    assert!(
        !work.exists(),
        "the work directory is removed after success"
    );
}

/// The names in directory `dir`, sorted.
fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("lists the directory")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A run whose buckets spilled deletes its bucket files once every tile is done, while it
/// writes the outputs. When that write fails (`ulimit -f`), the same command writes the output
/// from the results alone, without a scan; with a tile's result deleted as well, it scans
/// again. Both give a clean run's bytes.
#[test]
fn released_buckets_resume_without_a_scan_or_scan_again_for_a_missing_tile() {
    let dir = tempfile::tempdir().expect("temp dir");
    let terrain = dir.path().join("terrain.las");
    // 1M points: 32 MB of buckets, past the 26 MB that --memory 64M keeps in memory.
    generate_terrain(&terrain, "1M", 4, 10.0);
    let opts = ["--memory", "64M", "--tile", "50m"];
    let reference = dir.path().join("reference.las");
    process(&terrain, &reference, &opts);
    let out = dir.path().join("out/terrain.las");
    std::fs::create_dir_all(out.parent().expect("parent")).expect("output dir");
    let mut args = vec!["process", s(&terrain), "-o", s(&out)];
    args.extend(opts);
    let work = tilecurv::run::default_path(&out);
    for tile_missing in [false, true] {
        let failed = tilecurv_limited("-f 8000", &args);
        let err = String::from_utf8_lossy(&failed.stderr);
        assert_eq!(failed.status.code(), Some(4), "{err}");
        let buckets = work.join("buckets");
        assert_eq!(
            (names_in(&buckets), names_in(&buckets.join("t0"))),
            (
                vec!["frames.released".to_string(), "t0".to_string()],
                vec!["buckets.done".to_string()]
            ),
            "the bucket files are gone, the statistics kept: {err}"
        );
        let tiles = finished_tiles(&work);
        assert!(tiles >= 40, "{tiles} tiles: {err}");
        if tile_missing {
            let first = names_in(&work.join("results"))
                .into_iter()
                .find(|n| n.starts_with("tile_") && n.ends_with(".res"))
                .expect("a result file");
            std::fs::remove_file(work.join("results").join(first)).expect("delete a result");
        }
        let err = resume(&args);
        let said = match tile_missing {
            false => "every tile of the interrupted run is done",
            true => "tiles are missing and the interrupted run's buckets were released",
        };
        assert!(err.contains(said), "{err}");
        let resumed: Option<usize> = err
            .split(" resumed)")
            .next()
            .and_then(|head| head.rsplit('(').next())
            .and_then(|n| n.trim().parse().ok());
        assert_eq!(resumed, Some(tiles - tile_missing as usize), "{err}");
        // The curvature line's rate is of the points computed, not of those resumed.
        let curvature = err.lines().find(|l| l.starts_with("curvature:"));
        let expect = match tile_missing {
            false => ", all ",
            true => " of them resumed, the other ",
        };
        assert!(curvature.is_some_and(|l| l.contains(expect)), "{err}");
        assert!(
            std::fs::read(&out).expect("output") == std::fs::read(&reference).expect("reference"),
            "tile missing {tile_missing}: the resumed output differs from a clean run's"
        );
        std::fs::remove_file(&out).expect("remove the output");
    }
}

/// A write past the file-size limit (`ulimit -f`; SIGXFSZ is ignored, so
/// the write fails with EFBIG) is an output failure, exit 4, for every writer, both in the final
/// flush (the sample's outputs fit the writers' 4 MiB buffer) and in the middle of the records
/// (200k points); no temporary file is left, the work directory is kept, and the same command
/// then resumes to the bytes of a clean run. The work directory's files stay under the limit
/// (`--tile 50m`: tile results of at most 1.2 MB), so it is the output that fails.
#[test]
fn write_failures_are_output_failures_that_resume() {
    let dir = tempfile::tempdir().expect("temp dir");
    let terrain = dir.path().join("terrain.las");
    generate_terrain(&terrain, "200k", 2, 10.0);
    // `ulimit -f` counts 512-byte blocks in dash, 1024-byte ones in bash: either way the
    // limit lies between the largest work-directory file and the smallest output.
    let cases = [(sample(), "400"), (terrain, "8000")];
    for (input, blocks) in &cases {
        for ext in ["las", "laz", "ply"] {
            let stem = input
                .file_stem()
                .expect("stem")
                .to_string_lossy()
                .into_owned();
            let reference = dir.path().join(format!("{stem}_ref.{ext}"));
            let out = dir.path().join(format!("out/{stem}.{ext}"));
            std::fs::create_dir_all(out.parent().expect("parent")).expect("output dir");
            let args = ["process", s(input), "-o", s(&out), "--tile", "50m"];
            process(input, &reference, &["--tile", "50m"]);
            let failed = tilecurv_limited(&format!("-f {blocks}"), &args);
            let work = tilecurv::run::default_path(&out);
            failed_then_resumed(&failed, &args, &out, &work, "ulimit -f", &reference);
        }
    }
    // The cluster's assemble is the same writer: exit 4, nothing left, the work kept (the
    // cluster stages never remove it), and assembling again gives the same bytes.
    let work = dir.path().join("work");
    let out = dir.path().join("cluster/sample.laz");
    run_ok(&[
        "plan",
        s(&sample()),
        "--work",
        s(&work),
        "--tile",
        "50m",
        "-q",
    ]);
    run_ok(&["bucket", "--work", s(&work), "-q"]);
    run_every_tile(&work);
    std::fs::create_dir_all(out.parent().expect("parent")).expect("output dir");
    let failed = tilecurv_limited("-f 400", &["assemble", "--work", s(&work), "-o", s(&out)]);
    let err = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(4), "{err}");
    assert!(err.contains("ulimit -f"), "{err}");
    assert_eq!(
        temp_outputs(out.parent().expect("parent")),
        Vec::<String>::new()
    );
    assert!(
        work.join("manifest.txt").exists(),
        "assemble removed the work directory"
    );
    run_ok(&["assemble", "--work", s(&work), "-o", s(&out), "-q"]);
    assert!(
        std::fs::read(&out).expect("output")
            == std::fs::read(dir.path().join("Haystack_Rock_ref.laz")).expect("reference"),
        "the cluster's assembled output differs from process's"
    );
}

/// A tmpfs mounted for one test, unmounted when dropped.
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// Mounts a tmpfs of `size` at `at`; None when that is impossible (not root, no
    /// CAP_SYS_ADMIN), with the reason.
    fn mount(at: &Path, size: &str) -> Result<Self, String> {
        std::fs::create_dir_all(at).map_err(|e| e.to_string())?;
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs", s(at)])
            .output()
            .map_err(|e| format!("mount: {e}"))?;
        if !o.status.success() {
            return Err(String::from_utf8_lossy(&o.stderr).into_owned());
        }
        Ok(Tmpfs(at.to_path_buf()))
    }

    /// Gives the file system `size` (its files stay).
    fn resize(&self, size: &str) {
        let o = Command::new("mount")
            .args(["-o", &format!("remount,size={size}"), s(&self.0)])
            .output()
            .expect("mount runs");
        assert!(
            o.status.success(),
            "remount: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// The disk fills while the LAZ output is written (a 256 KiB tmpfs; the output needs 600 KB): exit
/// 4 naming the output and saying the disk is full (an output failure, not exit 1 "a bug"), nothing
/// is left on the full disk, the work directory (elsewhere, `--work-dir`) is kept, and once the
/// file system has room the same command resumes to the bytes of a clean run. Needs root to mount
/// the tmpfs: a loud skip otherwise, a failure under CI=true (CI runs as root).
#[test]
fn a_full_disk_while_writing_laz_keeps_the_work_and_resumes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mnt = match Tmpfs::mount(&dir.path().join("mnt"), "256k") {
        Ok(m) => m,
        Err(why) if under_ci() => {
            panic!("CI=true: cannot mount a tmpfs for the disk-full test: {why}")
        }
        Err(why) => {
            eprintln!("SKIPPED: the disk-full test needs a tmpfs mount (root): {why}");
            return;
        }
    };
    let reference = dir.path().join("reference.laz");
    process(&sample(), &reference, &["--tile", "50m"]);
    let out = mnt.0.join("out.laz");
    let work = dir.path().join("work");
    let input = sample();
    let args = [
        "process",
        s(&input),
        "-o",
        s(&out),
        "--tile",
        "50m",
        "--work-dir",
        s(&work),
    ];
    let failed = tilecurv(&args);
    let err = String::from_utf8_lossy(&failed.stderr);
    assert!(err.contains("No space left on device"), "{err}");
    assert_eq!(
        std::fs::read_dir(&mnt.0).expect("lists").count(),
        0,
        "the full disk holds files"
    );
    mnt.resize("16m");
    failed_then_resumed(
        &failed,
        &args,
        &out,
        &work,
        "no space left there",
        &reference,
    );
}

/// The pid of a process that has finished (and been reaped): dead, and not reused while pids
/// count up to pid_max.
fn dead_pid() -> u32 {
    let mut c = Command::new("true").spawn().expect("true runs");
    let pid = c.id();
    c.wait().expect("true ends");
    pid
}

/// A rerun removes the temporary files (`.<name>.tilecurv-<host>-<pid>.tmp`) of dead processes
/// of this host, beside the outputs and in the work directory (manifest, result files, bucket
/// task directories), and keeps those of live processes (this test's) and of other hosts.
#[test]
fn reruns_sweep_the_temporary_files_of_dead_processes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").expect("hostname");
    let host = host.trim();
    let (dead, live) = (dead_pid(), std::process::id());
    let work = dir.path().join("work");
    let input = sample();
    let plan = ["plan", s(&input), "--work", s(&work), "--tile", "50m", "-q"];
    run_ok(&plan);
    let plant = |dir: &Path, name: &str, is_dir: bool| {
        let p = dir.join(name);
        if is_dir {
            std::fs::create_dir_all(p.join("inner")).expect("plants a directory");
        } else {
            std::fs::create_dir_all(dir).expect("parent");
            std::fs::write(&p, b"half-written").expect("plants a file");
        }
        p
    };
    let mut gone = Vec::new();
    let mut kept = Vec::new();
    for (sub, base, is_dir) in [
        ("", "manifest.txt", false),
        ("results", "tile_0_0.res", false),
        ("results", "tile_0_0.ori", false),
        ("buckets", "t0", true),
    ] {
        let d = work.join(sub);
        gone.push(plant(
            &d,
            &format!(".{base}.tilecurv-{host}-{dead}.tmp"),
            is_dir,
        ));
        kept.push(plant(
            &d,
            &format!(".{base}.tilecurv-{host}-{live}.tmp"),
            is_dir,
        ));
        kept.push(plant(
            &d,
            &format!(".{base}.tilecurv-another-node-{dead}.tmp"),
            is_dir,
        ));
    }
    let outdir = dir.path().join("out");
    for name in ["a.laz", "b.ply"] {
        gone.push(plant(
            &outdir,
            &format!(".{name}.tilecurv-{host}-{dead}.tmp"),
            false,
        ));
        kept.push(plant(
            &outdir,
            &format!(".{name}.tilecurv-{host}-{live}.tmp"),
            false,
        ));
        kept.push(plant(
            &outdir,
            &format!(".{name}.tilecurv-another-node-{dead}.tmp"),
            false,
        ));
    }
    // The cluster stages: plan again (it reopens the work directory), bucket, every tile task,
    // assemble; then `process`, which writes beside its output too.
    run_ok(&plan);
    run_ok(&["bucket", "--work", s(&work), "-q"]);
    run_every_tile(&work);
    run_ok(&[
        "assemble",
        "--work",
        s(&work),
        "-o",
        s(&outdir.join("a.laz")),
        "-q",
    ]);
    run_ok(&[
        "process",
        s(&input),
        "-o",
        s(&outdir.join("b.ply")),
        "--tile",
        "50m",
        "-q",
    ]);
    for p in &gone {
        assert!(
            !p.exists(),
            "{}: a dead process's temporary file was kept",
            p.display()
        );
    }
    for p in &kept {
        assert!(
            p.exists(),
            "{}: a live or foreign temporary file was removed",
            p.display()
        );
    }
}

/// The `N` of "N undefined" in the final summary line.
fn summary_undefined(stderr: &str) -> u64 {
    stderr
        .rsplit("done: ")
        .next()
        .and_then(|line| line.split(" undefined").next())
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no undefined count in the summary: {stderr}"))
}

/// Points of `out` whose H is NaN, and those whose flags say undefined (the same points).
fn undefined_in(out: &Path) -> (usize, usize) {
    let h = crate::common::column(out, "H");
    let flags = crate::common::column(out, "CurvatureFlags");
    let nan = h.iter().filter(|v| v.is_nan()).count();
    let flagged = flags
        .iter()
        .filter(|&&f| (f as u8) & tilecurv::core::estimate::flags::UNDEFINED != 0)
        .count();
    (nan, flagged)
}

/// After a resume the summary counts the undefined points of every point written, whichever run
/// computed their tile, not only those of the tiles the last run computed. A 1 pt/m2 plane of 320 m
/// x 320 m in 1024 tiles of 10 m, with a stack of 40 coincident points (no normal: undefined) in
/// every 8th tile; the run is killed once the first batch of tiles is journalled, then resumed.
#[test]
fn the_summary_counts_undefined_points_of_resumed_tiles() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("stacks.las");
    let mut xyz = Vec::new();
    for i in 0..320 {
        for j in 0..320 {
            let (x, y) = (i as f64 + 0.5, j as f64 + 0.5);
            xyz.push([x, y, 0.01 * ((x * 0.37).sin() + (y * 0.23).cos())]);
        }
    }
    for t in (0..1024).step_by(8) {
        let (x, y) = ((t % 32) as f64 * 10.0 + 5.25, (t / 32) as f64 * 10.0 + 5.25);
        xyz.extend(std::iter::repeat_n([x, y, 3.0], 40));
    }
    crate::common::write_las(&input, &xyz, None, 0.001);
    let out = dir.path().join("out.las");
    let work = tilecurv::run::default_path(&out);
    let args = [
        "process",
        s(&input),
        "-o",
        s(&out),
        "--tile",
        "10m",
        "--threads",
        "2",
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_tilecurv"))
        .args(crate::common::with_test_columns(&args))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("tilecurv starts");
    let killed = loop {
        if child.try_wait().expect("wait").is_some() {
            break false;
        }
        if finished_tiles(&work) > 0 {
            child.kill().expect("SIGKILL");
            child.wait().expect("reaped");
            break true;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    assert!(
        killed,
        "the run finished before its first tiles were journalled"
    );
    let journalled = finished_tiles(&work);
    assert!(journalled < 1024, "every tile was done before the kill");
    let err = resume(&args);
    let (nan, flagged) = undefined_in(&out);
    assert_eq!(nan, flagged, "NaN H and the undefined flags disagree");
    assert!(
        nan >= 40 * 128,
        "{nan} undefined points: the stacks are undefined"
    );
    assert_eq!(
        summary_undefined(&err),
        nan as u64,
        "the summary's undefined count (after {journalled} tiles resumed) is not the output's: {err}"
    );
}

/// `ulimit -n` for `extra` descriptors beyond those the tool starts with (its standard streams
/// and whatever the test harness lets it inherit: `ls /proc/self/fd` counts those and its own
/// listing's one).
fn open_files(extra: i32) -> String {
    format!("-n $(( $(ls /proc/self/fd | wc -l) - 1 + {extra} ))")
}

/// Too many open files: running out of descriptors is not bad input (exit 3), and neither is a
/// work-directory file that cannot be read. A limit on open files too low to merge the results
/// gives exit 4 naming the file and saying to raise `ulimit -n`, and the work is kept (a
/// manifest that cannot be read is not taken for "no work"). The limit is raised one descriptor
/// at a time from below what the tool starts with (the dynamic loader fails there, before
/// tilecurv runs), then the lock, the manifest, the merge: every failure of tilecurv is that
/// exit 4, naming the manifest, then a result file; at a few descriptors the merge fits itself to the
/// limit (it merges in runs) and the same command resumes to a clean run's bytes.
#[test]
fn too_many_open_files_is_a_resource_error_not_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = sample();
    let reference = dir.path().join("reference.las");
    process(&input, &reference, &["--tile", "20m"]);
    let out = dir.path().join("out.las");
    let work = tilecurv::run::default_path(&out);
    let args = ["process", s(&input), "-o", s(&out), "--tile", "20m"];
    let mut named = Vec::new();
    let mut done = None;
    for extra in -2..=12 {
        let o = tilecurv_limited(&open_files(extra), &args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        if o.status.success() {
            done = Some((extra, err));
            break;
        }
        if err.contains("error while loading shared libraries") {
            continue; // too few for the dynamic loader, before tilecurv runs
        }
        assert_eq!(o.status.code(), Some(4), "ulimit -n start + {extra}: {err}");
        assert!(
            err.contains("Too many open files") && err.contains("ulimit -n"),
            "the message says to raise the limit: {err}"
        );
        let line = err
            .lines()
            .find(|l| l.contains("error:"))
            .unwrap_or_default();
        if line.contains(&format!("{}/", work.display())) {
            named.push(line.to_string());
        }
        assert!(!out.exists());
        assert_eq!(temp_outputs(dir.path()), Vec::<String>::new());
    }
    let (extra, err) = done.expect("no run succeeded with up to 12 descriptors more than at start");
    eprintln!("open files: start + {extra} suffice; the failures below: {named:?}");
    for file in ["manifest.txt: cannot read", ".res: cannot read"] {
        assert!(
            named.iter().any(|l| l.contains(file)),
            "no failure named the work directory's {file}: {named:?}"
        );
    }
    assert!(err.contains("resuming the interrupted run"), "{err}");
    assert!(
        std::fs::read(&out).expect("output") == std::fs::read(&reference).expect("reference"),
        "the output merged under a low open-file limit differs from a clean run's"
    );
}

/// Under `ulimit -v` the memory budget is fitted to the limit, against which the mapped inputs and
/// the threads' stacks count (a budget that ignores it aborts: on a 1M-point terrain with the
/// default 4 GiB budget, exit 134 in the write phase at 341 MiB, whose chunk buffer is sized from
/// the budget, a panic starting the tile threads at 292 MiB, exit 134 in the scan below): a limit
/// that cannot hold even the smallest budget is refused (exit 2, naming it and what to raise it
/// to), and 100 MiB above that the run lowers its budget with a message and completes, with a clean
/// run's bytes.
#[test]
fn an_address_space_limit_lowers_the_budget_or_refuses_cleanly() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("terrain.las");
    generate_terrain(&input, "500k", 4, 10.0);
    let reference = dir.path().join("reference.las");
    process(&input, &reference, &[]);
    let out = dir.path().join("out.las");
    let args = ["process", s(&input), "-o", s(&out), "--memory", "4G"];
    // Room for the program and the mapped input, not for a budget.
    let mapped_kib = std::fs::metadata(&input).expect("input").len() / 1024;
    let refused = tilecurv_limited(&format!("-v {}", mapped_kib + 40 * 1024), &args);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(
        err.contains("the address-space limit (ulimit -v) of") && err.contains("is too small"),
        "the refusal names the limit: {err}"
    );
    let need: u64 = err
        .split("raise it to `ulimit -v ")
        .nth(1)
        .and_then(|t| t.split('`').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the refusal says what to raise the limit to: {err}"));
    assert!(!out.exists());
    let fitted = tilecurv_limited(&format!("-v {}", need + 100 * 1024), &args);
    let err = String::from_utf8_lossy(&fitted.stderr);
    assert!(
        fitted.status.success(),
        "under ulimit -v {} KiB: {err}",
        need + 100 * 1024
    );
    assert!(
        err.contains("--memory 4096 MiB does not fit the address-space limit (ulimit -v)")
            && err.contains("using --memory"),
        "the lowered budget is said: {err}"
    );
    assert!(
        std::fs::read(&out).expect("output") == std::fs::read(&reference).expect("reference"),
        "the output under a lowered budget differs from a clean run's"
    );
}
