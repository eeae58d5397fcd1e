//! The out-of-core engine on generated terrain (`tilecurv generate terrain`) and on the two
//! adjacent bcts tiles: peak memory stays flat as the cloud grows past the budget, a run killed
//! at any moment resumes to a byte-identical output, stale work is detected and discarded, two
//! files processed as one scene equal their merge, and the curvature matches the terrain's
//! closed form (algorithms.md 13.2, 13.7).
//!
//! Sizes are kept to a few million points so that each test takes seconds; `scripts/scale.sh`
//! runs the same checks' measurements at 1M, 10M and 100M points.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

use tilecurv::io::las::header::OutputLayout;
use tilecurv::io::source::PointSource;

use crate::common::{
    column, finished_tiles, process, records, resume, s, shared, tilecurv, under_ci,
    with_test_columns, COLUMNS,
};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_tilecurv")
}

/// Writes a noise-free generated terrain of `points` points (10 per square metre).
fn generate(path: &Path, points: &str, seed: &str) {
    let seed = seed.parse().expect("a numeric seed");
    crate::common::generate_terrain(path, points, seed, 10.0);
}

/// Runs `tilecurv args` and returns its output with its peak resident memory in KiB, measured
/// by `/usr/bin/time -f %M` or, without it, by polling VmHWM in /proc. None (with a loud message)
/// when neither works; under CI=true that is a failure.
fn run_with_peak_rss(args: &[&str], scratch: &Path) -> Option<(Output, u64)> {
    let time = Path::new("/usr/bin/time");
    if time.exists() {
        let report = scratch.join("time.txt");
        let out = Command::new(time)
            .args(["-f", "%M", "-o", s(&report), bin()])
            .args(with_test_columns(args))
            .output()
            .expect("/usr/bin/time runs");
        let kib = std::fs::read_to_string(&report)
            .ok()
            .and_then(|t| t.lines().last().and_then(|l| l.trim().parse::<u64>().ok()));
        if let Some(kib) = kib {
            return Some((out, kib));
        }
    }
    // Fallback: poll the child's high-water mark until it exits.
    let mut child = Command::new(bin())
        .args(with_test_columns(args))
        .stdout(Stdio::piped())
        .stderr(Stdio::from(
            File::create(scratch.join("stderr.txt")).expect("scratch file"),
        ))
        .spawn()
        .expect("tilecurv runs");
    let status_file = format!("/proc/{}/status", child.id());
    let mut peak = None;
    let status = loop {
        if let Ok(t) = std::fs::read_to_string(&status_file) {
            if let Some(kib) = t
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            {
                peak = Some(peak.unwrap_or(0).max(kib));
            }
        }
        if let Some(st) = child.try_wait().expect("wait") {
            break st;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stderr = std::fs::read(scratch.join("stderr.txt")).unwrap_or_default();
    let output = Output {
        status,
        stdout: Vec::new(),
        stderr,
    };
    match peak {
        Some(kib) => Some((output, kib)),
        None => {
            assert!(
                !under_ci(),
                "CI=true: cannot measure peak memory (no /usr/bin/time, no /proc VmHWM)"
            );
            eprintln!(
                "SKIPPED: peak-memory check (no /usr/bin/time and no /proc/<pid>/status VmHWM)"
            );
            None
        }
    }
}

/// The budget given to `--memory` in the flat-memory test.
const BUDGET_MIB: u64 = 64;
/// What the program needs beyond the budget: code, thread stacks, the rayon pool, read and write
/// buffers (4 MiB each), the LAZ chunk buffers and allocator slack. The CLI documents "about
/// 60M"; allowed here: 64 MiB.
const PROGRAM_MIB: u64 = 64;
/// Ten times the points may cost at most this factor in peak memory. Unbounded, the bucket
/// entries alone (72 bytes a point) would add 130 MB going from 200k to 2M points, over three
/// times the 200k run's whole peak (about 40 MiB); bounded, the 2M run only fills the budget
/// (measured 1.3 to 1.75 on a loaded 2-core machine).
const GROWTH_FACTOR: f64 = 2.5;

#[test]
fn peak_memory_is_flat_past_the_budget() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut peaks = Vec::new();
    for (points, seed) in [("200k", "1"), ("2M", "2")] {
        let input = dir.path().join(format!("terrain_{points}.las"));
        generate(&input, points, seed);
        let out = dir.path().join(format!("out_{points}.las"));
        let budget = format!("{BUDGET_MIB}M");
        let args = [
            "process",
            s(&input),
            "-o",
            s(&out),
            "--memory",
            &budget,
            "--threads",
            "2",
        ];
        let Some((o, kib)) = run_with_peak_rss(&args, dir.path()) else {
            return;
        };
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "tilecurv {args:?} failed: {err}");
        eprintln!(
            "flat memory: {points} points, --memory {budget}: peak RSS {:.1} MiB ({})",
            kib as f64 / 1024.0,
            err.lines()
                .find(|l| l.contains("plan:"))
                .unwrap_or("no plan line")
        );
        if points == "2M" {
            assert!(
                err.contains("spilled to the work directory"),
                "2M points (about 150 MB of bucket entries) must spill with a 64M budget: {err}"
            );
        }
        peaks.push(kib);
        std::fs::remove_file(&input).expect("cleanup");
        std::fs::remove_file(&out).expect("cleanup");
    }
    let (small, large) = (peaks[0] as f64 / 1024.0, peaks[1] as f64 / 1024.0);
    assert!(
        large < (BUDGET_MIB + PROGRAM_MIB) as f64,
        "2M points: peak {large:.1} MiB exceeds the {BUDGET_MIB} MiB budget plus {PROGRAM_MIB} MiB for the program"
    );
    assert!(
        large < GROWTH_FACTOR * small,
        "10x the points raised the peak from {small:.1} to {large:.1} MiB, more than {GROWTH_FACTOR}x"
    );
}

/// A `process` run in the background, its stderr going to a file.
struct Background {
    child: Child,
    stderr: PathBuf,
    started: Instant,
}

fn start(args: &[&str], stderr: &Path) -> Background {
    let child = Command::new(bin())
        .args(with_test_columns(args))
        .stdout(Stdio::null())
        .stderr(Stdio::from(File::create(stderr).expect("stderr file")))
        .spawn()
        .expect("tilecurv starts");
    Background {
        child,
        stderr: stderr.to_path_buf(),
        started: Instant::now(),
    }
}

impl Background {
    /// Sends `signal` as soon as `ready(elapsed)` holds (unless the run has finished by then)
    /// and waits. Returns the exit status, its stderr, and whether the signal was sent.
    fn signal_when(
        mut self,
        mut ready: impl FnMut(Duration) -> bool,
        signal: i32,
    ) -> (ExitStatus, String, bool) {
        let mut sent = false;
        loop {
            if let Some(st) = self.child.try_wait().expect("wait") {
                let err = std::fs::read_to_string(&self.stderr).unwrap_or_default();
                return (st, err, sent);
            }
            if !sent && ready(self.started.elapsed()) {
                // SAFETY: kill(2) on our own child's pid, which has not been reaped yet.
                let r = unsafe { libc::kill(self.child.id() as libc::pid_t, signal) };
                assert_eq!(r, 0, "kill({signal}) failed");
                sent = true;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// The number in "(N resumed)" of the final summary line.
fn resumed_tiles(stderr: &str) -> usize {
    stderr
        .split(" resumed)")
        .next()
        .and_then(|head| head.rsplit('(').next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or(0)
}

/// When to interrupt a run.
#[derive(Debug, Clone, Copy)]
enum Moment {
    /// This long after the start.
    After(Duration),
    /// Once this many tiles are finished in the work directory.
    Tiles(usize),
}

#[test]
fn killed_runs_resume_to_a_byte_identical_output() {
    // 1M points over 316 m x 316 m, 20 m tiles: 256 tiles, so kills land between tiles.
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("terrain.las");
    generate(&input, "1M", "3");
    let reference = dir.path().join("reference.las");
    let o = tilecurv(&[
        "process",
        s(&input),
        "-o",
        s(&reference),
        "--tile",
        "20m",
        "--threads",
        "2",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let tiles: usize = err
        .split("plan: ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no plan line: {err}"));
    assert!(tiles >= 200, "{tiles} tiles");

    let out = dir.path().join("resumed.las");
    let work = tilecurv::run::default_path(&out);
    let args = [
        "process",
        s(&input),
        "-o",
        s(&out),
        "--tile",
        "20m",
        "--threads",
        "2",
    ];
    let log = dir.path().join("stderr.txt");
    // Kill moments: 0.5 s in (the scan or the first tiles, nothing committed yet), then once a
    // quarter and half of the tiles are finished (finished tiles are committed in batches every
    // 2 s, so these moments do not depend on the machine's speed). Each rerun resumes the
    // previous one's work. The SIGINT must stop the run cleanly with exit code 130.
    let kills = [
        (Moment::After(Duration::from_millis(500)), libc::SIGKILL),
        (Moment::Tiles(tiles / 4), libc::SIGINT),
        (Moment::Tiles(tiles / 2), libc::SIGKILL),
    ];
    let mut tiles_after = Vec::new();
    for (moment, signal) in kills {
        let b = start(&args, &log);
        let (status, err, sent) = b.signal_when(
            |elapsed| match moment {
                Moment::After(t) => elapsed >= t,
                Moment::Tiles(n) => finished_tiles(&work) >= n,
            },
            signal,
        );
        assert!(sent, "the run finished before {moment:?}: {err}");
        assert!(!out.exists(), "an interrupted run left an output");
        if signal == libc::SIGINT {
            assert_eq!(
                status.code(),
                Some(130),
                "SIGINT: exit code 130 expected: {err}"
            );
            assert!(
                err.contains("run the same command again to resume"),
                "SIGINT: the message says how to resume: {err}"
            );
        } else {
            use std::os::unix::process::ExitStatusExt;
            assert_eq!(status.signal(), Some(libc::SIGKILL));
        }
        tiles_after.push(finished_tiles(&work));
    }
    eprintln!(
        "resume: {tiles} tiles; finished tiles in the work directory after SIGKILL at 0.5 s, SIGINT at >= {}, SIGKILL at >= {}: {tiles_after:?}",
        tiles / 4,
        tiles / 2
    );
    let last = *tiles_after.last().expect("kills");
    assert!(last >= tiles / 2, "{last} tiles survived the last kill");
    let err = resume(&args);
    let resumed = resumed_tiles(&err);
    assert!(
        resumed >= last,
        "{resumed} tiles resumed, {last} were done: {err}"
    );
    // The resumed tiles' points were computed by the runs before: no rate over them.
    let done = err
        .lines()
        .find(|l| l.starts_with("done:"))
        .expect("a done line");
    assert!(!done.contains("points/s"), "a rate after a resume: {done}");
    assert!(
        std::fs::read(&out).expect("output") == std::fs::read(&reference).expect("reference"),
        "the resumed output differs from the uninterrupted run's"
    );
    assert!(
        !work.exists(),
        "the work directory is removed after success"
    );
}

/// SIGINT while `process --raster` writes its rasters, its point output written by then: exit
/// 130, the output's path holds what it held before, byte for byte, with nothing beside it,
/// and the raster directory the run made is gone. The same command then resumes and finishes.
#[test]
fn an_interrupted_raster_write_leaves_the_previous_output() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("terrain.las");
    generate(&input, "300k", "4");
    let out = dir.path().join("out.las");
    process(&input, &out, &["--columns", "H,K,flags"]);
    let before = std::fs::read(&out).expect("the first output");
    let rasters = dir.path().join("out.rasters");
    // 5 cm cells: 16 rasters of 3465 x 3465 cells take a second or more to write.
    let args = [
        "process",
        s(&input),
        "-o",
        s(&out),
        "--columns",
        "H,K,flags,terrain",
        "--raster",
        "5cm",
    ];
    let writing = |_| {
        std::fs::read_dir(&rasters).is_ok_and(|mut d| {
            d.any(|e| e.is_ok_and(|e| e.file_name().to_string_lossy().contains(".tif.")))
        })
    };
    let log = dir.path().join("stderr.txt");
    let (status, err, sent) = start(&args, &log).signal_when(writing, libc::SIGINT);
    assert!(
        sent,
        "the run finished before its rasters were written: {err}"
    );
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("no output was written"), "{err}");
    assert!(
        std::fs::read(&out).expect("the output") == before,
        "the interrupted run replaced the output"
    );
    assert!(!rasters.exists(), "the raster directory is left");
    let beside: Vec<String> = std::fs::read_dir(dir.path())
        .expect("list")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.starts_with(".out.las") && !n.ends_with(".tilecurv"))
        .collect();
    assert!(beside.is_empty(), "left beside the output: {beside:?}");
    resume(&args);
    assert!(std::fs::read(&out).expect("the output") != before);
    assert!(rasters.join("ProfileCurvature.tif").exists());
}

#[test]
fn stale_work_is_discarded() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("terrain.las");
    generate(&input, "300k", "4");
    let out = dir.path().join("out.las");
    let work = tilecurv::run::default_path(&out);
    let log = dir.path().join("stderr.txt");
    let run = |k: &str| {
        vec![
            "process".to_string(),
            s(&input).to_string(),
            "-o".into(),
            s(&out).into(),
            "--tile".into(),
            "20m".into(),
            "-k".into(),
            k.into(),
        ]
    };
    let interrupt = |args: &[String]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        // Kill once some tiles are finished.
        let (_, err, sent) =
            start(&args, &log).signal_when(|_| finished_tiles(&work) > 0, libc::SIGKILL);
        assert!(
            sent,
            "the run finished before it could be interrupted: {err}"
        );
        assert!(
            finished_tiles(&work) > 0,
            "no finished tile to be stale: {err}"
        );
    };
    let message = "the work left there came from other inputs or parameters: discarded";

    // A different -k.
    interrupt(&run("30"));
    let o = tilecurv(&run("20").iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains(message), "changed -k: {err}");
    let fresh = dir.path().join("fresh_k20.las");
    process(&input, &fresh, &["--tile", "20m", "-k", "20"]);
    assert!(
        std::fs::read(&out).expect("out") == std::fs::read(&fresh).expect("fresh"),
        "after discarding stale work the output equals a fresh run's"
    );

    // The same parameters, but the input changed (rewritten with other points, same size).
    interrupt(&run("30"));
    std::thread::sleep(Duration::from_millis(20)); // a visibly newer modification time
    generate(&input, "300k", "5");
    let o = tilecurv(&run("30").iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains(message), "changed input: {err}");
    let fresh = dir.path().join("fresh_new_input.las");
    process(&input, &fresh, &["--tile", "20m", "-k", "30"]);
    assert!(
        std::fs::read(&out).expect("out") == std::fs::read(&fresh).expect("fresh"),
        "after a changed input the output equals a fresh run's"
    );
}

/// Merges LAS/LAZ files with the same point format, scale and offset into one uncompressed
/// LAS 1.2 file: the first file's header and VLRs (minus LASzip), then every file's records in
/// order.
fn merge_las(inputs: &[PathBuf], output: &Path) {
    let parts: Vec<_> = inputs.iter().map(|p| records(p)).collect();
    let (first, _) = &parts[0];
    let h = &first.header;
    assert_eq!(h.version, (1, 2), "the merge writes a LAS 1.2 header");
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut count = 0u64;
    for (src, _) in &parts {
        let g = &src.header;
        assert_eq!(
            (g.point_format, g.record_length, g.scale, g.offset),
            (h.point_format, h.record_length, h.scale, h.offset),
            "merged files must share their record layout and quantisation"
        );
        for a in 0..3 {
            lo[a] = lo[a].min(g.min[a]);
            hi[a] = hi[a].max(g.max[a]);
        }
        count += src.len();
    }
    let mut vlr_bytes = Vec::new();
    let mut n_vlrs = 0u32;
    for v in first.vlrs.iter().filter(|v| !v.is("laszip encoded", 22204)) {
        v.write_vlr(&mut vlr_bytes).expect("VLR fits");
        n_vlrs += 1;
    }
    let mut data = h.patched(&OutputLayout {
        offset_to_point_data: u32::from(h.header_size) + vlr_bytes.len() as u32,
        num_vlrs: n_vlrs,
        compressed: false,
        record_length: h.record_length,
        evlr_start: 0,
        evlr_count: 0,
        waveform_start: 0,
    });
    data[107..111].copy_from_slice(&u32::try_from(count).expect("LAS 1.2 count").to_le_bytes());
    data[111..131].fill(0); // points by return: not needed by the test
    for a in 0..3 {
        data[179 + 16 * a..187 + 16 * a].copy_from_slice(&hi[a].to_le_bytes());
        data[187 + 16 * a..195 + 16 * a].copy_from_slice(&lo[a].to_le_bytes());
    }
    data.extend_from_slice(&vlr_bytes);
    for (_, recs) in &parts {
        data.extend_from_slice(recs);
    }
    std::fs::write(output, data).expect("write merged LAS");
}

/// Per point of a LAS/LAZ file (read once): the raw x, y, z integers and the bytes of the
/// named extra-bytes columns, plus the decoded y.
struct PointColumns {
    xyz: Vec<[u8; 12]>,
    y: Vec<f64>,
    /// One byte vector per requested column, `width` bytes per point.
    columns: Vec<(usize, Vec<u8>)>,
}

fn point_columns(path: &Path, names: &[&str]) -> PointColumns {
    let (src, recs) = records(path);
    let len = src.header.record_length as usize;
    let base =
        tilecurv::io::las::header::POINT_FORMAT_SIZES[src.header.point_format as usize] as usize;
    let descs: Vec<_> = names
        .iter()
        .map(|n| {
            src.extra
                .iter()
                .find(|d| d.name == *n)
                .unwrap_or_else(|| panic!("{} has no column {n}", path.display()))
                .clone()
        })
        .collect();
    let mut out = PointColumns {
        xyz: Vec::new(),
        y: Vec::new(),
        columns: descs.iter().map(|d| (d.size, Vec::new())).collect(),
    };
    for (i, r) in recs.chunks_exact(len).enumerate() {
        out.xyz.push(r[..12].try_into().expect("12 bytes"));
        out.y.push(src.decode(i as u64, r).xyz[1]);
        for (d, (_, col)) in descs.iter().zip(out.columns.iter_mut()) {
            col.extend_from_slice(&r[base + d.offset..base + d.offset + d.size]);
        }
    }
    out
}

#[test]
fn two_files_are_one_scene() {
    let (Some(a), Some(b)) = (shared("las/bcts_1.laz"), shared("las/bcts_2.laz")) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let outdir = dir.path().join("out/");
    let o = tilecurv(&[
        "process",
        s(&a),
        s(&b),
        "-o",
        outdir.to_str().expect("utf-8"),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let outs = [outdir.join("bcts_1.laz"), outdir.join("bcts_2.laz")];
    for p in &outs {
        assert!(p.exists(), "{} was written", p.display());
    }
    let merged = dir.path().join("merged.las");
    merge_las(&[a.clone(), b.clone()], &merged);
    let merged_out = dir.path().join("merged_out.las");
    process(&merged, &merged_out, &[]);

    // Point i of the merge is point i of bcts_1, then point j of bcts_2: check it by the raw
    // coordinates, then compare every column bit for bit.
    let m = point_columns(&merged_out, &COLUMNS);
    let (mut offset, mut border_points, mut differing_elsewhere) = (0usize, 0usize, 0usize);
    for out in &outs {
        let p = point_columns(out, &COLUMNS);
        let n = p.xyz.len();
        assert!(
            p.xyz[..] == m.xyz[offset..offset + n],
            "{}: its points are points {offset}.. of the merge",
            out.display()
        );
        for i in 0..n {
            let j = offset + i;
            let border = (p.y[i] - 629_400.0).abs() < 5.0;
            border_points += usize::from(border);
            for (name, ((w, mine), (_, theirs))) in
                COLUMNS.iter().zip(p.columns.iter().zip(&m.columns))
            {
                let same = mine[i * w..(i + 1) * w] == theirs[j * w..(j + 1) * w];
                assert!(
                    same || !border,
                    "{} point {i} (y {:.2}, {:+.2} m from the border): column {name} differs from the merged run",
                    out.display(),
                    p.y[i],
                    p.y[i] - 629_400.0
                );
                differing_elsewhere += usize::from(!same);
            }
        }
        offset += n;
    }
    eprintln!(
        "two files as one scene: {offset} points, {border_points} within 5 m of y = 629400 bit-identical in all {} columns; {differing_elsewhere} values elsewhere differ",
        COLUMNS.len()
    );
    assert_eq!(
        offset,
        m.xyz.len(),
        "the outputs hold every point of the merge"
    );
    assert!(border_points > 10_000, "{border_points} border points");
    assert_eq!(
        differing_elsewhere, 0,
        "tiling is invisible: away from the border the columns are bit-identical too"
    );
}

#[test]
fn terrain_curvature_matches_its_closed_form() {
    // 400k noise-free points at 10 per square metre (a 200 m square), K = 30, PCA normals.
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("terrain.las");
    generate(&input, "400k", "6");
    let out = dir.path().join("out.las");
    process(&input, &out, &["-k", "30"]);
    let got = ["H", "K", "k1", "k2"].map(|c| column(&out, c));
    let truth = tilecurv::tools::generate::TRUTH_COLUMNS.map(|c| column(&out, c));
    let flags = column(&out, "CurvatureFlags");
    let (src, recs) = records(&out);
    let len = src.header.record_length as usize;
    let xy: Vec<[f64; 2]> = recs
        .chunks_exact(len)
        .enumerate()
        .map(|(i, r)| {
            let p = src.decode(i as u64, r).xyz;
            [
                p[0] - tilecurv::tools::generate::ORIGIN_M[0],
                p[1] - tilecurv::tools::generate::ORIGIN_M[1],
            ]
        })
        .collect();
    let side = (400_000.0f64 / 10.0).sqrt();
    // Away from the square's edge (one-sided neighbourhoods there): a K = 30 neighbourhood at
    // 10 points/m^2 has radius sqrt(30 / (10 pi)) = 1 m, and curvature uses the neighbours'
    // normals, so 3 m is clear of it.
    let inside = |p: &[f64; 2]| p.iter().all(|&c| c > 3.0 && c < side - 3.0);
    let mut sum = [0.0; 4];
    let (mut kappa2, mut kappa4, mut n) = (0.0, 0.0, 0usize);
    for i in 0..flags.len() {
        if !inside(&xy[i]) {
            continue;
        }
        assert_eq!(
            flags[i] as u8 & 7,
            0,
            "point {i} undefined on smooth terrain"
        );
        for c in 0..4 {
            sum[c] += (got[c][i] - truth[c][i]).powi(2);
        }
        let k2 = 0.5 * (truth[2][i].powi(2) + truth[3][i].powi(2));
        kappa2 += k2;
        kappa4 += k2 * k2;
        n += 1;
    }
    let rms = sum.map(|x| (x / n as f64).sqrt());
    let kappa_rms = (kappa2 / n as f64).sqrt();
    let kappa4_root = (kappa4 / n as f64).sqrt(); // sqrt(E[kappa^4])
                                                  // The bound, from two terms that add (linearly: a conservative sum):
                                                  // - PCA normals on noise-free random sampling: H picks up 1.37 kappa / K (the module doc of
                                                  //   closed_form.rs), here with the terrain's RMS principal curvature kappa_rms;
                                                  // - the 1 mm quantisation of z (uniform, sigma_q = 1 mm / sqrt(12) = 0.29 mm): a
                                                  //   least-squares plane over K points in a disk of radius rho has a slope error of
                                                  //   2 sigma_q / (rho sqrt(K)) (var(u) = rho^2/4), and Avg-Hexagram differentiates sector
                                                  //   normals (sqrt(6) noisier) over a distance ~rho: sqrt(6) * 2 sigma_q / (rho^2 sqrt(K)),
                                                  //   with rho = sqrt(K / (pi * 10 points/m^2)) = 0.98 m: 2.6e-4 / m.
                                                  // k1 and k2 come from one direction each: twice the H bound (as in closed_form.rs). K = k1 k2
                                                  // moves by k2 dk1 + k1 dk2: at most 2 sqrt(E[kappa^2 dk^2]), with dk the k bound whose PCA
                                                  // part scales with kappa (so E[kappa^4] enters) and whose quantisation part does not.
    let k = 30.0;
    let rho = (k / (std::f64::consts::PI * 10.0)).sqrt();
    let quant = 6f64.sqrt() * 2.0 * (1e-3 / 12f64.sqrt()) / (rho * rho * k.sqrt());
    let bound_h = 1.37 * kappa_rms / k + quant;
    let bound_k12 = 2.0 * bound_h;
    let bound_gauss = 2.0 * (2.0 * 1.37 / k * kappa4_root + 2.0 * quant * kappa_rms);
    eprintln!(
        "terrain 400k K=30 PCA normals, {n} points, RMS kappa {kappa_rms:.2e}: RMS error H {:.2e} (bound {bound_h:.2e}) K {:.2e} (bound {bound_gauss:.2e}) k1 {:.2e} k2 {:.2e} (bound {bound_k12:.2e})",
        rms[0], rms[1], rms[2], rms[3]
    );
    assert!(n > 350_000, "{n} points inside");
    assert!(rms[0] < bound_h, "RMS H {} >= {bound_h}", rms[0]);
    assert!(rms[1] < bound_gauss, "RMS K {} >= {bound_gauss}", rms[1]);
    assert!(
        rms[2] < bound_k12 && rms[3] < bound_k12,
        "RMS k1 {} k2 {} >= {bound_k12}",
        rms[2],
        rms[3]
    );
}
