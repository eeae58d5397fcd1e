//! Hostile and degenerate inputs: axis-aligned and tiny geometry, counts and offsets
//! that would allocate or overflow, coordinates that are not finite or too far apart for the
//! tile grid. Each run must end with a documented exit code, never a panic or an abort, and
//! leave nothing beside the input but a complete output.

use std::path::Path;

use crate::common::{root, tilecurv, write_las};

/// Runs `process` on `input` with `extra` options; returns (exit code, stderr), after checking
/// that it did not panic or abort, that a failed run left no output, and that a refused run
/// (exit 2 or 3) left the folder as it was: no work directory, no temporary file.
fn run(input: &Path, extra: &[&str]) -> (Option<i32>, String) {
    let output = input.with_extension("out.las");
    let mut args = vec![
        "process",
        input.to_str().expect("utf-8"),
        "-o",
        output.to_str().expect("utf-8"),
        "-q",
    ];
    args.extend_from_slice(extra);
    let out = tilecurv(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    let code = out.status.code();
    assert!(code.is_some(), "{args:?} was killed by a signal: {err}");
    if code != Some(0) {
        assert!(!output.exists(), "{args:?} failed but left an output");
    }
    if matches!(code, Some(2 | 3)) {
        let work = tilecurv::run::default_path(&output);
        assert!(
            !work.exists(),
            "{args:?} was refused but left {}",
            work.display()
        );
        let dir = input.parent().expect("a folder");
        let temps: Vec<String> = std::fs::read_dir(dir)
            .expect("list")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(".tilecurv-") && n.ends_with(".tmp"))
            .collect();
        assert!(temps.is_empty(), "{args:?} was refused but left {temps:?}");
    }
    (code, err)
}

/// Writes `bytes` as `name` in `dir` and runs `process` on it.
fn run_bytes(dir: &Path, name: &str, bytes: &[u8], extra: &[&str]) -> (Option<i32>, String) {
    let input = dir.join(name);
    std::fs::write(&input, bytes).expect("write input");
    run(&input, extra)
}

fn sample() -> Vec<u8> {
    std::fs::read(root().join("data/Haystack_Rock.las")).expect("shipped sample")
}

/// A small LAS 1.2 file of `xyz` (the tests' own writer), as bytes.
fn las_bytes(dir: &Path, xyz: &[[f64; 3]], scale: f64) -> Vec<u8> {
    let p = dir.join("gen.las");
    write_las(&p, xyz, None, scale);
    std::fs::read(&p).expect("read back")
}

/// The LAS 1.2 file `b` made a LAS 1.`minor` file (3 or 4): its header grown to the size that
/// version requires, the new fields zero.
fn upgrade(b: &[u8], minor: u8) -> Vec<u8> {
    let size: u16 = if minor == 3 { 235 } else { 375 };
    let grow = size as usize - 227;
    let mut out = b[..227].to_vec();
    out.resize(size as usize, 0);
    out.extend_from_slice(&b[227..]);
    out[25] = minor;
    out[94..96].copy_from_slice(&size.to_le_bytes());
    let offset = u32::from_le_bytes(out[96..100].try_into().expect("4 bytes")) + grow as u32;
    out[96..100].copy_from_slice(&offset.to_le_bytes());
    if minor == 4 {
        let n = u32::from_le_bytes(out[107..111].try_into().expect("4 bytes")) as u64;
        out[247..255].copy_from_slice(&n.to_le_bytes());
    }
    out
}

/// A grid of `n` x `n` points spanning `span` in two axes, `fixed` in the third (`axis`).
fn plane(n: usize, span: f64, axis: usize, fixed: f64) -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b) = (i as f64 * span / n as f64, j as f64 * span / n as f64);
            v.push(match axis {
                0 => [fixed, a, b],
                1 => [a, fixed, b],
                _ => [a, b, fixed],
            });
        }
    }
    v
}

#[test]
fn axis_aligned_geometry_is_computed_not_a_panic() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases: Vec<(&str, Vec<[f64; 3]>)> = vec![
        ("facade_x.las", plane(40, 10.0, 0, 5.0)),
        ("facade_y.las", plane(40, 10.0, 1, 5.0)),
        (
            "vertical_line.las",
            (0..500).map(|i| [3.0, 4.0, i as f64 * 0.01]).collect(),
        ),
        (
            "horizontal_line.las",
            (0..500).map(|i| [i as f64 * 0.01, 4.0, 1.0]).collect(),
        ),
        ("one_spot.las", vec![[1.0, 2.0, 3.0]; 50]),
    ];
    for (name, xyz) in cases {
        let input = dir.path().join(name);
        write_las(&input, &xyz, None, 0.001);
        let (code, err) = run(&input, &[]);
        assert_eq!(code, Some(0), "{name}: {err}");
        let (code, err) = run(&input, &["--tile", "0.01"]);
        assert_eq!(code, Some(0), "{name} with --tile 0.01: {err}");
    }
}

#[test]
fn tiny_tiles_on_the_sample() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (code, err) = run_bytes(dir.path(), "h.las", &sample(), &["--tile", "0.1"]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn tiny_scale_gives_points_closer_than_any_cell() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut b = las_bytes(dir.path(), &plane(20, 19.0, 2, 0.0), 1.0);
    for a in 0..3 {
        let at = 131 + 8 * a;
        b[at..at + 8].copy_from_slice(&1e-300f64.to_le_bytes());
        b[155 + 8 * a..163 + 8 * a].copy_from_slice(&0f64.to_le_bytes());
    }
    let (code, err) = run_bytes(dir.path(), "tiny.las", &b, &[]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn huge_vlr_count_is_bad_input_not_an_abort() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut b = sample();
    b[100..104].copy_from_slice(&u32::MAX.to_le_bytes());
    let (code, err) = run_bytes(dir.path(), "vlrs.las", &b, &[]);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("vlrs.las") && err.contains("VLR"), "{err}");
}

#[test]
fn huge_evlr_count_and_start_are_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let base = upgrade(&las_bytes(dir.path(), &plane(10, 9.0, 2, 0.0), 0.01), 4);
    let len = base.len() as u64;
    for (name, start, count) in [
        ("count.las", len - 60, u32::MAX),
        ("start.las", u64::MAX - 10, 1),
        ("start2.las", len - 1, 3),
    ] {
        let mut b = base.clone();
        b[235..243].copy_from_slice(&start.to_le_bytes());
        b[243..247].copy_from_slice(&count.to_le_bytes());
        let (code, err) = run_bytes(dir.path(), name, &b, &[]);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(err.contains(name) && err.contains("EVLR"), "{name}: {err}");
    }
}

#[test]
fn waveform_offset_near_2_pow_64_is_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let base = upgrade(&las_bytes(dir.path(), &plane(10, 9.0, 2, 0.0), 0.01), 3);
    for (name, start) in [("wf.las", u64::MAX - 20), ("wf2.las", u64::MAX)] {
        let mut b = base.clone();
        b[227..235].copy_from_slice(&start.to_le_bytes());
        let (code, err) = run_bytes(dir.path(), name, &b, &[]);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(err.contains(name), "{name}: {err}");
    }
}

#[test]
fn infinite_coordinates_name_the_point() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut b = las_bytes(dir.path(), &plane(10, 9.0, 2, 0.0), 0.01);
    // Scale 1e306 times raw x values up to 810: finite for the first points, infinite past them.
    b[131..139].copy_from_slice(&1e306f64.to_le_bytes());
    b[155..163].copy_from_slice(&0f64.to_le_bytes());
    let (code, err) = run_bytes(dir.path(), "inf.las", &b, &[]);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("inf.las") && err.contains("point"), "{err}");
    assert!(err.contains("not finite"), "{err}");
}

#[test]
fn extent_too_large_for_the_tile_grid_is_a_usage_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("far.xyz");
    let mut text = String::new();
    for i in 0..40 {
        text.push_str(&format!("{} {} 0\n", i % 7, i / 7));
    }
    text.push_str("1e21 0 0\n");
    std::fs::write(&input, text).expect("write");
    let (code, err) = run(&input, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--tile"), "{err}");
    // The same with a LAS file whose scale makes the extent 9e15 units: found by the scan when
    // the header's bounds say 0..9, before any work when they are right.
    let mut b = las_bytes(dir.path(), &plane(10, 9.0, 2, 0.0), 1.0);
    b[131..139].copy_from_slice(&1e15f64.to_le_bytes());
    b[155..163].copy_from_slice(&0f64.to_le_bytes());
    let (code, err) = run_bytes(dir.path(), "wide.las", &b, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--tile"), "{err}");
    b[179..187].copy_from_slice(&9e15f64.to_le_bytes());
    let (code, err) = run_bytes(dir.path(), "wide2.las", &b, &["--dry-run"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--tile"), "{err}");
}

#[test]
fn coordinates_beyond_computable_magnitudes_are_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut b = las_bytes(dir.path(), &plane(10, 9.0, 2, 0.0), 1.0);
    b[131..139].copy_from_slice(&1e299f64.to_le_bytes());
    b[155..163].copy_from_slice(&0f64.to_le_bytes());
    let (code, err) = run_bytes(dir.path(), "huge.las", &b, &["--tile", "1e300"]);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("huge.las") && err.contains("point"), "{err}");
}

/// autzen_trim.laz (110,000 points in fixed chunks of 50,000) and the offset of its chunk
/// table, or None when the shared data is absent.
fn autzen_laz() -> Option<(Vec<u8>, usize)> {
    let b = std::fs::read(crate::common::shared("las/autzen_trim.laz")?).expect("read");
    let start = u32::from_le_bytes(b[96..100].try_into().expect("4 bytes")) as usize;
    let table = i64::from_le_bytes(b[start..start + 8].try_into().expect("8 bytes")) as usize;
    Some((b, table))
}

#[test]
fn corrupt_laz_chunk_tables_are_bad_input() {
    let Some((base, table)) = autzen_laz() else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let start = u32::from_le_bytes(base[96..100].try_into().expect("4 bytes")) as usize;
    let mut cases: Vec<(&str, Vec<u8>, &str)> = Vec::new();
    let mut b = base.clone();
    b[table + 4..table + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    cases.push(("count.laz", b, "declares 4294967295 chunks"));
    let mut b = base.clone();
    b[table + 4..table + 8].copy_from_slice(&1u32.to_le_bytes());
    cases.push(("few.laz", b, "declares 1 chunks"));
    // The table offset pointing into the compressed data: a garbage table body.
    let mut b = base.clone();
    b[start..start + 8].copy_from_slice(&((start + 108) as i64).to_le_bytes());
    cases.push(("body.laz", b, "chunk table"));
    let mut b = base.clone();
    b[start..start + 8].copy_from_slice(&((base.len() + 100) as i64).to_le_bytes());
    cases.push(("past.laz", b, "chunk table offset"));
    // A garbage table body at the right place: its chunk sizes run past the data.
    let mut b = base.clone();
    for (i, x) in b[table + 8..].iter_mut().enumerate() {
        *x = (i * 37 + 11) as u8;
    }
    cases.push(("sizes.laz", b, "chunk"));
    for (name, bytes, needle) in cases {
        let (code, err) = run_bytes(dir.path(), name, &bytes, &[]);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains(needle) && err.contains("byte offset"),
            "{name}: expected {needle:?} and a byte offset in: {err}"
        );
    }
}

#[test]
fn a_zeroed_laz_chunk_is_an_error_naming_the_chunk() {
    let Some((base, _)) = autzen_laz() else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let start = u32::from_le_bytes(base[96..100].try_into().expect("4 bytes")) as usize;
    // Zeroed bytes early in chunk 0, and in the middle of chunk 1: either the codec fails or
    // the points decode far outside the header's bounds; both name the chunk's byte offset.
    for (name, at, len) in [
        ("z0.laz", start + 108, 3000),
        ("z1.laz", start + 400_000, 100_000),
    ] {
        let mut b = base.clone();
        b[at..at + len].fill(0);
        let (code, err) = run_bytes(dir.path(), name, &b, &[]);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains("chunk") && err.contains("byte offset"),
            "{name}: {err}"
        );
    }
}

/// A chunk of 0xFF bytes makes the laz crate's GPS-time decoder recurse once per symbol with
/// nothing to stop it: the depth guard of the LAZ reader turns it into an error naming the
/// chunk (before, the process died of a stack overflow, exit 134). Whole chunk, and the chunk
/// after its first point (stored raw), in the first and in the last chunk.
#[test]
fn a_laz_chunk_of_0xff_bytes_is_an_error_not_a_stack_overflow() {
    let Some((base, table)) = autzen_laz() else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let start = u32::from_le_bytes(base[96..100].try_into().expect("4 bytes")) as usize;
    // Format 3: 34 bytes of first point, stored raw, then the arithmetic-coded stream.
    let last = table - 20_000;
    for (name, at, len, chunk) in [
        ("ff_whole.laz", start + 8, 20_000, "chunk 0 of 3"),
        (
            "ff_after_first.laz",
            start + 8 + 34,
            200_000,
            "chunk 0 of 3",
        ),
        ("ff_last.laz", last, 20_000, "chunk 2 of 3"),
    ] {
        let mut b = base.clone();
        b[at..at + len].fill(0xff);
        let (code, err) = run_bytes(dir.path(), name, &b, &[]);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains(chunk) && err.contains("byte offset"),
            "{name}: expected {chunk:?} and a byte offset in: {err}"
        );
    }
}

/// Every input the fuzz targets found (tests/fuzz_findings, named `<target>-<hash>.<ext>`) is
/// a clean error or a success of the binary, never a panic or an abort.
#[test]
fn fuzz_findings_fail_cleanly() {
    let dir = tempfile::tempdir().expect("temp dir");
    let found = std::fs::read_dir(root().join("tests/fuzz_findings")).expect("findings dir");
    let mut n = 0;
    for e in found {
        let p = e.expect("entry").path();
        let name = p.file_name().expect("name").to_string_lossy().into_owned();
        let (code, err) = run_bytes(dir.path(), &name, &std::fs::read(&p).expect("read"), &[]);
        assert!(
            matches!(code, Some(0 | 2 | 3)),
            "{name}: exit {code:?}: {err}"
        );
        n += 1;
    }
    assert!(n > 0, "no findings read");
}

/// Two fuzz findings. The first: a LASzip VLR whose fixed chunk size is 2^32-2 made the laz codec reserve a
/// 4 GiB buffer (libFuzzer's out-of-memory, an abort wherever address space is limited). The
/// chunk size is now clamped to the point count, which decodes the same points: under
/// `ulimit -v` of 1.5 GiB the corrupt file is bad input (exit 3), the valid file it was cut
/// from (chunk size 50000, 5658 points) is computed.
#[test]
fn a_huge_laz_chunk_size_reserves_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let limited = |input: &Path, out: &Path| {
        let script = format!(
            "ulimit -v 1500000; exec {} process {} -o {} -q --memory 256M --threads 1",
            env!("CARGO_BIN_EXE_tilecurv"),
            input.display(),
            out.display()
        );
        let r = std::process::Command::new("sh")
            .args(["-c", &script])
            .output()
            .expect("sh");
        (
            r.status.code(),
            String::from_utf8_lossy(&r.stderr).into_owned(),
        )
    };
    let out = dir.path().join("o.las");
    // The second: a layered (point format 6) chunk whose layer sizes add up to 17 GB in a
    // 46 kB file made the codec allocate a 2.8 GB layer; the sizes are now checked against the
    // chunk's bytes, naming the chunk.
    for (name, says) in [
        ("las-oom-85453f38.laz", "LAZ"),
        (
            "las-oom-6c92c036.laz",
            "LAZ chunk 0 of 1: its layers declare",
        ),
    ] {
        let (code, err) = limited(&root().join("tests/fuzz_findings").join(name), &out);
        assert_eq!(code, Some(3), "{name}: {err}");
        assert!(
            err.contains(says) && !err.contains("memory allocation"),
            "{name}: {err}"
        );
        assert!(!out.exists());
    }
    if let Some(valid) = crate::common::shared("las/32-1-472-150-76.laz") {
        let (code, err) = limited(&valid, &out);
        assert_eq!(code, Some(0), "{err}");
        let h = crate::common::column(&out, "H");
        assert_eq!(h.len(), 5658);
        assert!(h.iter().filter(|v| v.is_finite()).count() > 5000);
    }
}
