//! Shared helpers of the integration tests: locating shared data, running the binary, reading
//! outputs back with the library's own LAS reader or with an independent PLY parser, and writing
//! synthetic LAS inputs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tilecurv::io::source::{LasSource, PointSource};

/// The project root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path as the `&str` a command line takes.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Whether this is a CI run (CI=true), where a missing prerequisite fails instead of skipping.
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// A file from `../shared/data`, or None with a loud message. Under CI=true a missing file
/// fails the test instead: CI may not skip the tests that matter.
pub fn shared(rel: &str) -> Option<PathBuf> {
    let p = root().join("../shared/data").join(rel);
    if p.exists() {
        return Some(p);
    }
    if under_ci() {
        panic!(
            "{} is missing and CI=true: the shared test data must be present",
            p.display()
        );
    }
    eprintln!(
        "SKIPPED: {} not found (shared test data absent); this test did not run",
        p.display()
    );
    None
}

/// laspy with lazrs is available; a failure under CI=true, else a loud skip.
pub fn laspy_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import laspy, lazrs"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        if under_ci() {
            panic!("python3 with laspy and lazrs is required under CI=true");
        }
        eprintln!("SKIPPED: laspy check (python3 -c 'import laspy, lazrs' failed)");
    }
    ok
}

/// The columns the tests' `process` and `plan` runs write unless they name `--columns`: every
/// curvature column, so that the invariance and closed-form tests check normals, k1 and k2
/// too. The default (H, K, flags) is checked by `compact::the_default_columns_are_h_k_and_flags`
/// through [`tilecurv_as_given`].
pub const ALL_CURVATURE: &str = "normals,H,K,k1,k2,flags";

/// Runs `tilecurv` with `args`; a `process` or `plan` without `--columns` gets
/// `--columns` [`ALL_CURVATURE`].
pub fn tilecurv(args: &[&str]) -> Output {
    tilecurv_as_given(&with_test_columns(args))
}

/// `args` with `--columns` [`ALL_CURVATURE`] added to a `process` or `plan` that names none
/// (for the tests that spawn the binary themselves).
pub fn with_test_columns<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut args = args.to_vec();
    let computes = matches!(args.first(), Some(&"process") | Some(&"plan"));
    if computes && !args.iter().any(|a| a.starts_with("--columns")) {
        args.extend(["--columns", ALL_CURVATURE]);
    }
    args
}

/// Runs `tilecurv` with exactly `args`.
pub fn tilecurv_as_given(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tilecurv"))
        .args(args)
        .output()
        .expect("the tilecurv binary runs")
}

/// Runs `tilecurv args` (as [`tilecurv`]), asserts it exits with `code`, returns its stdout.
pub fn stdout_of(args: &[&str], code: i32) -> String {
    let out = tilecurv(args);
    assert_eq!(
        out.status.code(),
        Some(code),
        "tilecurv {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs the cluster stages by hand over the work directory `work` that `plan` made: bucket
/// tasks `0..buckets` in reverse order (as a cluster may finish them), tile tasks `0..tiles`,
/// then `assemble -o output`; asserts each succeeds.
pub fn run_stages(work: &Path, buckets: u64, tiles: u64, output: &str) {
    let work = work.to_str().expect("utf-8 path");
    for t in (0..buckets).rev() {
        stdout_of(
            &["bucket", "--work", work, "--task", &t.to_string(), "-q"],
            0,
        );
    }
    for t in 0..tiles {
        stdout_of(
            &["run-tile", "--work", work, "--task", &t.to_string(), "-q"],
            0,
        );
    }
    stdout_of(&["assemble", "--work", work, "-o", output, "-q"], 0);
}

/// The texts of a LAS file's tilecurv provenance records, in file order.
pub fn provenance_texts(path: &Path) -> Vec<String> {
    let (s, _) = records(path);
    tilecurv::io::las::provenance::texts(s.vlrs.iter())
}

/// The tiles whose result files the work directory `work` holds (finished, journalled).
pub fn finished_tiles(work: &Path) -> usize {
    std::fs::read_dir(work.join("results"))
        .map(|d| {
            d.flatten()
                .filter(|e| {
                    let name = e.file_name().to_string_lossy().into_owned();
                    name.starts_with("tile_") && name.ends_with(".res")
                })
                .count()
        })
        .unwrap_or(0)
}

/// Writes a noise-free generated terrain (`tilecurv generate terrain`) of `points` points
/// (`200k`, `1M` or a plain count) at `density` points per square metre; .las or .laz by the
/// extension, the same points in both.
pub fn generate_terrain(path: &Path, points: &str, seed: u64, density: f64) {
    generate_terrain_with(path, points, seed, density, &[]);
}

/// [`generate_terrain`] with more `generate terrain` options (`--noise 0:0.05`).
pub fn generate_terrain_with(path: &Path, points: &str, seed: u64, density: f64, more: &[&str]) {
    let (seed, density) = (seed.to_string(), density.to_string());
    let mut args = vec![
        "generate",
        "terrain",
        "-q",
        "-o",
        path.to_str().expect("utf-8 path"),
        "--points",
        points,
        "--density",
        &density,
        "--seed",
        &seed,
    ];
    args.extend_from_slice(more);
    let out = tilecurv(&args);
    assert!(
        out.status.success(),
        "generate {} failed: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs `tilecurv args` again after an interrupted or failed run: asserts it succeeds and
/// says it resumes; returns its stderr.
pub fn resume(args: &[&str]) -> String {
    let o = tilecurv(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "the rerun failed: {err}");
    assert!(
        err.contains("resuming the interrupted run"),
        "the rerun resumes: {err}"
    );
    err
}

/// Runs `tilecurv process` and asserts success.
pub fn process(input: &Path, output: &Path, extra: &[&str]) {
    let mut quiet = vec!["-q"];
    quiet.extend_from_slice(extra);
    let out = run_process(input, output, &quiet);
    assert!(
        out.status.success(),
        "tilecurv process {} {quiet:?} failed: {}",
        input.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs `tilecurv process INPUT -o OUTPUT EXTRA...` and returns what it did, whatever its exit.
pub fn run_process(input: &Path, output: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "process",
        input.to_str().expect("utf-8 path"),
        "-o",
        output.to_str().expect("utf-8 path"),
    ];
    args.extend_from_slice(extra);
    tilecurv(&args)
}

/// All raw point records of a LAS/LAZ file, in file order.
pub fn records(path: &Path) -> (LasSource, Vec<u8>) {
    let s = LasSource::open(path).expect("readable LAS");
    let mut all = Vec::new();
    s.for_each_chunk(100_000, &mut |_, r| {
        all.extend_from_slice(r);
        Ok(())
    })
    .expect("decodes");
    (s, all)
}

/// One named extra-bytes column of every point of a tilecurv output, as f64.
pub fn column(path: &Path, name: &str) -> Vec<f64> {
    let (s, all) = records(path);
    let d = s
        .extra
        .iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("{} has no column {name}", path.display()))
        .clone();
    let base =
        tilecurv::io::las::header::POINT_FORMAT_SIZES[s.header.point_format as usize] as usize;
    all.chunks_exact(s.header.record_length as usize)
        .map(|r| d.read(&r[base..]).expect("in range"))
        .collect()
}

/// The x coordinate of every point of a LAS/LAZ file, in file order.
pub fn xs(path: &Path) -> Vec<f64> {
    let (s, all) = records(path);
    all.chunks_exact(s.header.record_length as usize)
        .map(|r| {
            let raw = i32::from_le_bytes([r[0], r[1], r[2], r[3]]);
            raw as f64 * s.header.scale[0] + s.header.offset[0]
        })
        .collect()
}

/// The raw bytes of one column (for bit-identity checks).
pub fn column_bytes(path: &Path, name: &str) -> Vec<u8> {
    let (s, all) = records(path);
    let d = s
        .extra
        .iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("no column {name}"))
        .clone();
    let base =
        tilecurv::io::las::header::POINT_FORMAT_SIZES[s.header.point_format as usize] as usize;
    all.chunks_exact(s.header.record_length as usize)
        .flat_map(|r| r[base + d.offset..base + d.offset + d.size].to_vec())
        .collect()
}

/// Names of the columns of [`ALL_CURVATURE`], the tests' runs' columns (the default of
/// `tilecurv process` is H, K and CurvatureFlags).
pub const COLUMNS: [&str; 8] = [
    "NormalX",
    "NormalY",
    "NormalZ",
    "H",
    "K",
    "k1",
    "k2",
    "CurvatureFlags",
];

/// Writes a minimal LAS 1.2 file, point format 0, with the given coordinate scale, and, when
/// `normals` is given, NormalX/Y/Z as f64 extra bytes described by an extra-bytes VLR. Written
/// here byte by byte from the LAS 1.2 specification, independently of the library's writer.
pub fn write_las(path: &Path, xyz: &[[f64; 3]], normals: Option<&[[f64; 3]]>, scale: f64) {
    let n_extra = if normals.is_some() { 24 } else { 0 };
    let mut vlr = Vec::new();
    if normals.is_some() {
        vlr.extend_from_slice(&0u16.to_le_bytes());
        let mut uid = [0u8; 16];
        uid[..9].copy_from_slice(b"LASF_Spec");
        vlr.extend_from_slice(&uid);
        vlr.extend_from_slice(&4u16.to_le_bytes());
        vlr.extend_from_slice(&(3 * 192u16).to_le_bytes());
        vlr.extend_from_slice(&[0u8; 32]);
        for name in ["NormalX", "NormalY", "NormalZ"] {
            let mut d = [0u8; 192];
            d[2] = 10; // f64
            d[4..4 + name.len()].copy_from_slice(name.as_bytes());
            vlr.extend_from_slice(&d);
        }
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in xyz {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let offset: [f64; 3] = [0, 1, 2].map(|a| ((lo[a] + hi[a]) / 2.0).round());
    let mut h = vec![0u8; 227];
    h[0..4].copy_from_slice(b"LASF");
    h[24] = 1;
    h[25] = 2;
    h[94..96].copy_from_slice(&227u16.to_le_bytes());
    h[96..100].copy_from_slice(&(227 + vlr.len() as u32).to_le_bytes());
    h[100..104].copy_from_slice(&(if normals.is_some() { 1u32 } else { 0 }).to_le_bytes());
    h[104] = 0;
    h[105..107].copy_from_slice(&(20 + n_extra as u16).to_le_bytes());
    h[107..111].copy_from_slice(&(xyz.len() as u32).to_le_bytes());
    for a in 0..3 {
        h[131 + 8 * a..139 + 8 * a].copy_from_slice(&scale.to_le_bytes());
        h[155 + 8 * a..163 + 8 * a].copy_from_slice(&offset[a].to_le_bytes());
        h[179 + 16 * a..187 + 16 * a].copy_from_slice(&hi[a].to_le_bytes());
        h[187 + 16 * a..195 + 16 * a].copy_from_slice(&lo[a].to_le_bytes());
    }
    let mut data = h;
    data.extend_from_slice(&vlr);
    for (i, p) in xyz.iter().enumerate() {
        for a in 0..3 {
            let v = ((p[a] - offset[a]) / scale).round();
            assert!(
                v.abs() < i32::MAX as f64,
                "coordinate does not fit the scale"
            );
            data.extend_from_slice(&(v as i32).to_le_bytes());
        }
        data.extend_from_slice(&[0u8; 8]);
        if let Some(n) = normals {
            for c in n[i] {
                data.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    std::fs::write(path, data).expect("write synthetic LAS");
}

/// A table of points: property names, their PLY types (`double` for untyped text), and rows.
pub struct Table {
    pub format: String,
    pub names: Vec<String>,
    pub types: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// The column `name`, or a new column under its default PLY name (`NormalX` as `nx`, `H`
    /// as `scalar_H`).
    pub fn col(&self, name: &str) -> Vec<f64> {
        let ply = tilecurv::io::ply::PlyNames::CloudCompare.name(name);
        let j = self
            .names
            .iter()
            .position(|n| n == name)
            .or_else(|| self.names.iter().position(|n| *n == ply))
            .unwrap_or_else(|| panic!("no property {name} in {:?}", self.names));
        self.rows.iter().map(|r| r[j]).collect()
    }
}

pub fn type_size(ty: &str) -> usize {
    match ty {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        other => panic!("unknown PLY type {other}"),
    }
}

pub fn decode(ty: &str, b: &[u8], big: bool) -> f64 {
    let mut a = [0u8; 8];
    let n = type_size(ty);
    a[..n].copy_from_slice(&b[..n]);
    if big {
        a[..n].reverse();
    }
    match ty {
        "char" | "int8" => a[0] as i8 as f64,
        "uchar" | "uint8" => a[0] as f64,
        "short" | "int16" => i16::from_le_bytes([a[0], a[1]]) as f64,
        "ushort" | "uint16" => u16::from_le_bytes([a[0], a[1]]) as f64,
        "int" | "int32" => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "uint" | "uint32" => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "float" | "float32" => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        _ => f64::from_le_bytes(a),
    }
}

/// Reads the vertex element of a PLY file (any encoding; elements before it must be fixed-size).
pub fn read_ply(path: &Path) -> Table {
    let data = std::fs::read(path).expect("read PLY");
    let end = data
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("end_header")
        + 11;
    let header = String::from_utf8_lossy(&data[..end]).into_owned();
    let (mut format, mut names, mut types) = (String::new(), Vec::new(), Vec::new());
    let mut elements: Vec<(String, usize, usize)> = Vec::new(); // name, count, record size
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", f, _] => format = f.to_string(),
            ["element", name, n] => elements.push((name.to_string(), n.parse().expect("count"), 0)),
            ["property", ty, name] => {
                let e = elements.last_mut().expect("element");
                e.2 += type_size(ty);
                if e.0 == "vertex" {
                    names.push(name.to_string());
                    types.push(ty.to_string());
                }
            }
            _ => {}
        }
    }
    let vi = elements
        .iter()
        .position(|e| e.0 == "vertex")
        .expect("vertex element");
    let n = elements[vi].1;
    let mut rows = Vec::with_capacity(n);
    if format == "ascii" {
        let skip: usize = elements[..vi].iter().map(|e| e.1).sum();
        let body = String::from_utf8_lossy(&data[end..]).into_owned();
        for line in body.lines().skip(skip).take(n) {
            rows.push(
                line.split_whitespace()
                    .map(|t| t.parse::<f64>().expect("number"))
                    .collect(),
            );
        }
    } else {
        let big = format == "binary_big_endian";
        let mut at = end + elements[..vi].iter().map(|e| e.1 * e.2).sum::<usize>();
        for _ in 0..n {
            let mut row = Vec::new();
            for ty in &types {
                row.push(decode(ty, &data[at..], big));
                at += type_size(ty);
            }
            rows.push(row);
        }
    }
    assert_eq!(rows.len(), n, "{}: vertex count", path.display());
    Table {
        format,
        names,
        types,
        rows,
    }
}

/// The median of the finite values of `v`.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    assert!(!v.is_empty(), "median of no values");
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The names in `dir`, sorted.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
