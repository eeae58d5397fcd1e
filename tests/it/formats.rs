//! Non-LAS formats end to end: every object file of ../shared/data (XYZ, PTS, PLY, OBJ, PCD) runs
//! through the CLI to PLY and to LAS/LAZ and reads back complete, with its properties intact and
//! its own normals used; the curvature is right where the geometry is known (noisy sphere,
//! planar building); malformed files of each format fail with exit code 3 and a position; a big
//! endian PLY with every type round-trips to little endian unchanged. Outputs and inputs are
//! read back with the tests' own small PLY parser (`common::read_ply`), independent of the
//! library's readers.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tilecurv::io::source::PointSource;

use crate::common::{column, median, process, read_ply, records, root, shared, tilecurv, Table};

/// Reads an input file independently of the library: PLY with `read_ply`, the text formats by
/// splitting lines.
fn read_input(path: &Path) -> Table {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default();
    if ext == "ply" {
        return read_ply(path);
    }
    let text = std::fs::read_to_string(path).expect("read text input");
    let numbers = |l: &str| -> Vec<f64> {
        l.split_whitespace()
            .map(|t| t.parse().expect("number"))
            .collect()
    };
    let line = |key: &str| -> Vec<&str> {
        let l = text
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .expect("PCD header line");
        l.split_whitespace().collect()
    };
    let doubles = |n: usize| vec!["double".to_string(); n];
    let (format, names, types, rows) = match ext {
        "obj" => {
            let rows = text
                .lines()
                .filter_map(|l| l.strip_prefix("v "))
                .map(numbers);
            ("text", vec!["x", "y", "z"], doubles(3), rows.collect())
        }
        "pcd" => {
            let types = line("TYPE ").into_iter().zip(line("SIZE ")).map(|t| {
                match t {
                    ("F", "4") => "float",
                    ("F", "8") => "double",
                    ("U", "1") => "uchar",
                    ("I", "4") => "int",
                    other => panic!("PCD type {other:?} not handled by this test"),
                }
                .to_string()
            });
            let body = text.lines().skip_while(|l| !l.starts_with("DATA")).skip(1);
            (
                "pcd",
                line("FIELDS "),
                types.collect(),
                body.map(numbers).collect(),
            )
        }
        _ => {
            let body = text
                .lines()
                .filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
            let names = vec!["x", "y", "z", "nx", "ny", "nz"];
            ("text", names, doubles(6), body.map(numbers).collect())
        }
    };
    Table {
        format: format.into(),
        names: names.into_iter().map(String::from).collect(),
        types,
        rows,
    }
}

/// Whether two values of PLY type `ty` are the same (text parsed to f64 then stored as `ty`).
fn same(ty: &str, a: f64, b: f64) -> bool {
    match ty {
        "float" | "float32" => (a as f32).to_bits() == (b as f32).to_bits(),
        _ => a == b,
    }
}

const OBJECTS: [&str; 7] = [
    "objects/kitten.xyz",
    "objects/sphere_20k_normal.xyz",
    "objects/building.ply",
    "objects/bun_zipper.ply",
    "objects/fandisk.obj",
    "objects/bun0.pcd",
    "reference/torus/torus_010000.pts",
];

/// Bit 32 of CurvatureFlags: the normal came from the file.
const FILE_NORMAL: u8 = 32;

fn flags(t: &Table) -> Vec<u8> {
    t.col("CurvatureFlags")
        .into_iter()
        .map(|f| f as u8)
        .collect()
}

/// laspy (the independent LAS reader the LAS tests use) reads `path` with `n` points. Skipped
/// loudly without laspy, except under CI=true, where it fails.
fn laspy_reads(path: &Path, n: usize) {
    let code = "import sys, laspy; print(len(laspy.read(sys.argv[1]).points))";
    let out = std::process::Command::new("python3")
        .args(["-c", code])
        .arg(path)
        .output();
    let missing = match &out {
        Ok(o) => String::from_utf8_lossy(&o.stderr).contains("No module named"),
        Err(_) => true,
    };
    if missing {
        assert!(
            !crate::common::under_ci(),
            "python3 with laspy is required under CI=true"
        );
        eprintln!(
            "SKIPPED: laspy cross-read of {} (no python3 laspy)",
            path.display()
        );
        return;
    }
    let o = out.expect("python3 ran");
    let got = String::from_utf8_lossy(&o.stdout).trim().to_string();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(got, n.to_string(), "laspy reads {}: {err}", path.display());
}

#[test]
fn every_object_file_runs_to_ply_and_las_with_its_properties() {
    let dir = tempfile::tempdir().expect("temp dir");
    for rel in OBJECTS {
        let Some(input) = shared(rel) else { continue };
        let name = input
            .file_name()
            .expect("name")
            .to_string_lossy()
            .into_owned();
        let inp = read_input(&input);
        let ply = dir.path().join(format!("{name}.ply"));
        process(&input, &ply, &[]);
        let out = read_ply(&ply);
        assert_eq!(out.format, "binary_little_endian");
        assert_eq!(out.rows.len(), inp.rows.len(), "{name}: point count");
        for (j, prop) in inp.names.iter().enumerate() {
            let k = out
                .names
                .iter()
                .position(|n| n == prop)
                .unwrap_or_else(|| panic!("{name}: property {prop} lost"));
            if inp.format != "text" {
                assert_eq!(out.types[k], inp.types[j], "{name}: type of {prop}");
            }
            for (i, (a, b)) in inp.rows.iter().zip(&out.rows).enumerate() {
                assert!(
                    same(&out.types[k], a[j], b[k]),
                    "{name}: point {i} {prop}: {} became {}",
                    a[j],
                    b[k]
                );
            }
        }
        // CloudCompare's names (io/ply.rs): scalar_<name>, normals nx ny nz.
        for c in ["H", "K", "k1", "k2", "CurvatureFlags"] {
            assert!(
                out.names.iter().any(|n| *n == format!("scalar_{c}")),
                "{name}: column {c} missing"
            );
        }
        let file_normals = inp.names.iter().any(|n| n == "nx" || n == "normal_x");
        let with_flag = flags(&out)
            .iter()
            .filter(|&&f| f & FILE_NORMAL != 0)
            .count();
        if file_normals {
            assert_eq!(
                with_flag,
                out.rows.len(),
                "{name}: every point uses the file's normal"
            );
            assert!(
                !out.names.iter().any(|n| n == "NormalX"),
                "{name}: file normals are not duplicated"
            );
        } else {
            assert_eq!(with_flag, 0, "{name}: no file normals, all PCA");
            assert!(
                out.names.iter().any(|n| n == "nx"),
                "{name}: PCA normals written"
            );
        }

        // The same run to LAS: same points (within the quantisation), same properties as extra
        // bytes, the same curvature within half the LAS column's step (the PLY's is f32).
        let las = dir.path().join(format!("{name}.las"));
        process(&input, &las, &[]);
        let (src, all) = records(&las);
        assert_eq!(
            src.len() as usize,
            inp.rows.len(),
            "{name}: LAS point count"
        );
        let h = &src.header;
        assert_eq!((h.version, h.point_format), ((1, 4), 0));
        let extent = (0..3).map(|a| h.max[a] - h.min[a]).fold(0.0, f64::max);
        assert!(
            h.scale[0] <= 1e-8 * extent,
            "{name}: scale {} for extent {extent}",
            h.scale[0]
        );
        let xyz: Vec<usize> = ["x", "y", "z"]
            .iter()
            .map(|c| inp.names.iter().position(|n| n == c).expect("xyz"))
            .collect();
        // The batch read of the coordinates (the raster tap's) gives what decode gives.
        let mut batch = Vec::new();
        src.coordinates(0, &all, h.record_length as usize, &mut batch);
        assert_eq!(batch.len(), inp.rows.len(), "{name}: coordinates");
        for (i, rec) in all.chunks_exact(h.record_length as usize).enumerate() {
            let p = src.decode(i as u64, rec);
            assert_eq!(
                batch[i].map(f64::to_bits),
                p.xyz.map(f64::to_bits),
                "{name}: {i}"
            );
            for (a, &col) in xyz.iter().enumerate() {
                let want = inp.rows[i][col];
                assert!(
                    (p.xyz[a] - want).abs() <= 0.51 * h.scale[a] + 1e-12 * want.abs(),
                    "{name}: point {i} axis {a}: {} vs {want}",
                    p.xyz[a]
                );
            }
        }
        for (j, prop) in inp
            .names
            .iter()
            .enumerate()
            .filter(|(j, _)| !xyz.contains(j))
        {
            // A property named like a standard LAS field is renamed (bun_zipper's intensity).
            let v = match prop.as_str() {
                "intensity" => column(&las, "input_intensity"),
                _ => column(&las, prop),
            };
            let ty = inp.types[j].as_str();
            assert!(
                inp.rows.iter().zip(&v).all(|(a, b)| same(ty, a[j], *b)),
                "{name}: extra bytes {prop} differ"
            );
        }
        laspy_reads(&las, inp.rows.len());
        let (hl, hp) = (column(&las, "H"), out.col("H"));
        let step = src.extra.iter().find(|d| d.name == "H").expect("H").scale;
        assert!(
            hl.iter()
                .zip(&hp)
                .all(|(a, b)| (a - b).abs() <= step / 2.0 + 1e-7 * b.abs()
                    || (a.is_nan() && b.is_nan())),
            "{name}: H differs between LAS and PLY output"
        );
    }
}

#[test]
fn ascii_ply_output_holds_the_same_values() {
    let Some(input) = shared("objects/kitten.xyz") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let (bin, txt) = (dir.path().join("k.ply"), dir.path().join("k.ascii.ply"));
    process(&input, &bin, &[]);
    process(&input, &txt, &[]);
    let (a, b) = (read_ply(&bin), read_ply(&txt));
    assert_eq!(b.format, "ascii");
    assert_eq!((&a.names, &a.types), (&b.names, &b.types));
    for (i, (x, y)) in a.rows.iter().zip(&b.rows).enumerate() {
        for (j, ty) in a.types.iter().enumerate() {
            assert!(
                same(ty, x[j], y[j]) || (x[j].is_nan() && y[j].is_nan()),
                "point {i} {}: {} vs {}",
                a.names[j],
                x[j],
                y[j]
            );
        }
    }
}

#[test]
fn noisy_unit_sphere_has_mean_curvature_near_one() {
    let Some(input) = shared("objects/sphere_20k_normal.xyz") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("s.ply");
    process(&input, &out, &[]);
    let t = read_ply(&out);
    // Radii lie in 0.84..1.19, so the true H = 1/r of any point lies in 1/1.19..1/0.84
    // = 0.840..1.190 (outward normals: positive). The median must fall inside.
    let h = median(t.col("H"));
    eprintln!("sphere_20k_normal: median H = {h}");
    assert!((1.0 / 1.19..=1.0 / 0.84).contains(&h), "median H {h}");
}

#[test]
fn building_faces_are_flat_and_edges_are_curved() {
    let Some(input) = shared("objects/building.ply") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("b.ply");
    process(&input, &out, &[]);
    let t = read_ply(&out);
    let (x, y, z, seg, h) = (
        t.col("x"),
        t.col("y"),
        t.col("z"),
        t.col("segment_index"),
        t.col("H"),
    );
    // A point is inside a face when every point in the 3x3x3 cells of 0.5 around it (the
    // building is ~55 units across) belongs to its segment; otherwise it is near an edge.
    let cell = |i: usize| [x[i], y[i], z[i]].map(|c| (c / 0.5).floor() as i64);
    let mut cells: HashMap<[i64; 3], Option<f64>> = HashMap::new();
    for (i, &s) in seg.iter().enumerate() {
        let e = cells.entry(cell(i)).or_insert(Some(s));
        if *e != Some(s) {
            *e = None;
        }
    }
    let (mut face, mut edge) = (Vec::new(), Vec::new());
    for i in 0..x.len() {
        let c = cell(i);
        let mut inside = true;
        for d in 0..27i64 {
            let n = [c[0] + d % 3 - 1, c[1] + d / 3 % 3 - 1, c[2] + d / 9 - 1];
            if let Some(s) = cells.get(&n) {
                inside &= *s == Some(seg[i]);
            }
        }
        if inside { &mut face } else { &mut edge }.push(h[i].abs());
    }
    let (hf, he) = (median(face.clone()), median(edge.clone()));
    eprintln!(
        "building: median |H| {hf} on {} face points, {he} on {} edge points",
        face.len(),
        edge.len()
    );
    assert!(face.len() > 10_000, "enough face points");
    assert!(hf < 0.05, "faces are flat: median |H| {hf}");
    assert!(
        he > 5.0 * hf,
        "edges are curved: median |H| {he} vs {hf} on faces"
    );
}

/// Runs `process` on `path` and asserts exit code 3 with the file and every `expect` named.
fn assert_rejected(path: &Path, expect: &[&str]) {
    let out = path.with_extension("out.ply");
    let r = tilecurv(&[
        "process",
        path.to_str().expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
        "-q",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{}: {err}", path.display());
    assert!(
        err.contains(&path.display().to_string()),
        "the message names the file: {err}"
    );
    for e in expect {
        assert!(
            err.contains(e),
            "{}: expected {e:?} in: {err}",
            path.display()
        );
    }
    assert!(!out.exists(), "no output after a failure");
}

fn ply_header(format: &str, vertices: usize, props: &str) -> String {
    format!("ply\nformat {format} 1.0\nelement vertex {vertices}\n{props}end_header\n")
}

#[test]
fn malformed_files_fail_with_their_position() {
    let dir = tempfile::tempdir().expect("temp dir");
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).expect("write");
        p
    };
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let cases: Vec<(PathBuf, Vec<String>)> = vec![
        (
            write("columns.xyz", b"0 0 0\n1 0 0\n1 1\n"),
            vec!["line 3: expected 3 values (x y z) but found 2".into()],
        ),
        (
            write("number.xyz", b"0 0 0\n1 abc 0\n"),
            vec!["line 2: value 2 (y) is \"abc\", not a number".into()],
        ),
        (write("empty.pts", b"# x y z\n\n"), vec!["no points".into()]),
        (
            write(
                "count.ply",
                format!("{}0 0 0\n1 0 0\n", ply_header("ascii", 5, xyz)).as_bytes(),
            ),
            vec!["line 9: the header declares 5 vertices but the file ends after 2".into()],
        ),
        (
            write(
                "noxyz.ply",
                format!(
                    "{}0 0\n",
                    ply_header("ascii", 1, "property float a\nproperty float b\n")
                )
                .as_bytes(),
            ),
            vec!["no x, y and z".into()],
        ),
        (
            write(
                "type.ply",
                ply_header("ascii", 1, "property float128 x\n").as_bytes(),
            ),
            vec!["header line 4: unknown property type \"float128\"".into()],
        ),
        (
            write("zero.ply", ply_header("ascii", 0, xyz).as_bytes()),
            vec!["no points".into()],
        ),
    ];
    let mut cases = cases;
    for (format, name) in [
        ("binary_little_endian", "short_le.ply"),
        ("binary_big_endian", "short_be.ply"),
    ] {
        let head = ply_header(format, 10, xyz);
        let mut bytes = head.clone().into_bytes();
        bytes.extend_from_slice(&[0u8; 5 * 12 + 7]);
        cases.push((
            write(name, &bytes),
            vec![
                format!("at byte offset {}", head.len()),
                "only 5 whole points".into(),
            ],
        ));
    }
    let pcd = |data: &str, n: usize| {
        format!("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {data}\n")
    };
    cases.push((
        write(
            "number.pcd",
            format!("{}0 0 0\n0 0 zz\n", pcd("ascii", 2)).as_bytes(),
        ),
        vec!["line 12: value 3 (z) is \"zz\"".into()],
    ));
    let head = pcd("binary", 4);
    let mut bytes = head.clone().into_bytes();
    bytes.extend_from_slice(&[0u8; 3 * 12]);
    cases.push((
        write("short.pcd", &bytes),
        vec![
            format!("at byte offset {}", head.len()),
            "only 3 whole points".into(),
        ],
    ));
    cases.push((
        write("compressed.pcd", pcd("binary_compressed", 4).as_bytes()),
        vec!["binary_compressed is not supported".into()],
    ));
    cases.push((
        write("short.off", b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n"),
        vec!["line 5: the header declares 4 vertices but the file ends after 3".into()],
    ));
    cases.push((
        write("faces.off", b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
        vec!["line 6: expected 3 values (x y z) but found 4".into()],
    ));
    cases.push((
        write("number.obj", b"v 0 0 0\nvn 0 0 1\nv 1 0 0\nv 1 1 1e\n"),
        vec!["line 4: value 3 (z) is \"1e\"".into()],
    ));
    for (path, expect) in &cases {
        assert_rejected(path, &expect.iter().map(String::as_str).collect::<Vec<_>>());
    }
}

/// A big-endian PLY with every scalar type, a fixed-size element before the vertices and a face
/// list after them.
fn write_big_endian_ply(path: &Path, n: usize) -> Vec<Vec<f64>> {
    let types = [
        "double", "double", "double", "float", "float", "float", "char", "uchar", "short",
        "ushort", "int", "uint", "float", "double",
    ];
    let names = [
        "x", "y", "z", "nx", "ny", "nz", "c", "uc", "s", "us", "i", "ui", "f", "d",
    ];
    let mut head = String::from("ply\nformat binary_big_endian 1.0\ncomment every type\nelement camera 1\nproperty float view\nproperty uchar id\n");
    head += &format!("element vertex {n}\n");
    for (t, name) in types.iter().zip(names) {
        head += &format!("property {t} {name}\n");
    }
    head += "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut b = head.into_bytes();
    b.extend_from_slice(&1.5f32.to_be_bytes());
    b.push(7);
    let mut rows = Vec::new();
    // A Fibonacci sphere of radius 2 with its outward normals.
    for i in 0..n {
        let zz = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - zz * zz).sqrt();
        let phi = i as f64 * 2.399_963_229_728_653;
        let nrm = [r * phi.cos(), r * phi.sin(), zz];
        let k = i as i64;
        let row = vec![
            2.0 * nrm[0],
            2.0 * nrm[1],
            2.0 * nrm[2],
            nrm[0] as f32 as f64,
            nrm[1] as f32 as f64,
            nrm[2] as f32 as f64,
            (k % 256 - 128) as f64,
            (k % 256) as f64,
            (k * 37 % 65536 - 32768) as f64,
            (k * 91 % 65536) as f64,
            (k * 5_000_000 - 2_000_000_000) as f64,
            (k * 9_876_543 + 4_000_000_000) as f64 % 4_294_967_296.0,
            (k as f32 * 0.1f32) as f64,
            k as f64 * 1e-3 + 1e10,
        ];
        for (v, t) in row.iter().zip(types) {
            match t {
                "double" => b.extend_from_slice(&v.to_be_bytes()),
                "float" => b.extend_from_slice(&(*v as f32).to_be_bytes()),
                "char" => b.push(*v as i8 as u8),
                "uchar" => b.push(*v as u8),
                "short" => b.extend_from_slice(&(*v as i16).to_be_bytes()),
                "ushort" => b.extend_from_slice(&(*v as u16).to_be_bytes()),
                "int" => b.extend_from_slice(&(*v as i32).to_be_bytes()),
                _ => b.extend_from_slice(&(*v as u32).to_be_bytes()),
            }
        }
        rows.push(row);
    }
    b.push(3);
    for v in [0i32, 1, 2] {
        b.extend_from_slice(&v.to_be_bytes());
    }
    std::fs::write(path, b).expect("write PLY");
    rows
}

#[test]
fn big_endian_ply_round_trips_to_little_endian() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("be.ply");
    let rows = write_big_endian_ply(&input, 800);
    let inp = read_ply(&input);
    assert_eq!(inp.rows, rows, "the test's own parser reads what it wrote");
    let out = dir.path().join("le.ply");
    process(&input, &out, &[]);
    let t = read_ply(&out);
    assert_eq!(t.format, "binary_little_endian");
    assert_eq!(&t.names[..inp.names.len()], &inp.names[..]);
    assert_eq!(&t.types[..inp.types.len()], &inp.types[..]);
    for (i, (a, b)) in rows.iter().zip(&t.rows).enumerate() {
        assert_eq!(&b[..a.len()], &a[..], "point {i}");
    }
    assert!(
        flags(&t).iter().all(|f| f & FILE_NORMAL != 0),
        "the file's normals are used"
    );
    let h = median(t.col("H"));
    assert!((h - 0.5).abs() < 0.01, "sphere of radius 2: median H {h}");
    // A PLY output fed back in is refused before any work: not supported yet (run::rerun).
    assert_rejected(&out, &["a PLY output of tilecurv", "not supported yet"]);
}

#[test]
fn las_input_to_ply_keeps_coordinates_and_standard_fields() {
    let input = root().join("data/Haystack_Rock.las");
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("hay.ply");
    process(&input, &out, &[]);
    let t = read_ply(&out);
    let (src, all) = records(&input);
    assert_eq!(t.rows.len() as u64, src.len());
    assert_eq!(
        &t.names[..7],
        [
            "x",
            "y",
            "z",
            "intensity",
            "return_number",
            "number_of_returns",
            "classification",
        ]
    );
    assert_eq!(&t.types[..4], ["double", "double", "double", "ushort"]);
    for (i, rec) in all
        .chunks_exact(src.header.record_length as usize)
        .enumerate()
    {
        // The PLY holds what every LAS reader gives: integer * scale + offset.
        let h = &src.header;
        let q = |a: usize| i32::from_le_bytes(rec[4 * a..4 * a + 4].try_into().expect("4 bytes"));
        let xyz: Vec<f64> = (0..3)
            .map(|a| q(a) as f64 * h.scale[a] + h.offset[a])
            .collect();
        let r = &t.rows[i];
        assert_eq!(&r[..3], &xyz[..], "point {i} coordinates");
        assert_eq!(
            r[3],
            u16::from_le_bytes([rec[12], rec[13]]) as f64,
            "point {i} intensity"
        );
        assert_eq!(r[4], (rec[14] & 7) as f64, "point {i} return number");
        assert_eq!(r[6], (rec[15] & 31) as f64, "point {i} classification");
    }
}

/// A LAS input written to PLY keeps every standard field of its format, each equal to what
/// laspy reads under the same name (the scan angle of formats 6 to 10 in degrees: laspy's
/// steps of 0.006 degree): point formats 1 (Topography), 3 (autzen), 6 (test1_4) and 7
/// (autzen's LAS 1.4 copy). Compared by two sums over the points (of the values and of the
/// values weighted by the point's index), so that a wrong field or a shifted order shows.
#[test]
fn las_to_ply_keeps_every_standard_field_as_laspy_reads_it() {
    let files = [
        "Topography.las",
        "autzen_trim.las",
        "test1_4.las",
        "autzen_trim_7.las",
    ];
    let Some(inputs) = files
        .iter()
        .map(|f| shared(&format!("las/{f}")))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    if !crate::common::laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let sums = r#"
import sys, laspy, numpy as np
f = laspy.read(sys.argv[1])
i = np.arange(len(f.points), dtype=np.float64)
for d in f.point_format.standard_dimension_names:
    v = np.asarray(f[d], dtype=np.float64)
    if d == "scan_angle":
        v = v * 0.006
    print(d, repr(float(v.sum())), repr(float((v * i).sum())))
"#;
    for input in &inputs {
        let out = dir.path().join("out.ply");
        process(input, &out, &[]);
        let t = read_ply(&out);
        let said = crate::interop::laspy(sums, &[input]);
        let mut fields = 0;
        for line in said.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            let (name, sum, wsum) = (
                w[0],
                w[1].parse::<f64>().expect("sum"),
                w[2].parse::<f64>().expect("sum"),
            );
            let name = name.to_lowercase();
            if ["x", "y", "z"].contains(&name.as_str()) {
                continue;
            }
            let Some(c) = t.names.iter().position(|n| *n == name) else {
                panic!(
                    "{}: {name} is not in the PLY ({:?})",
                    input.display(),
                    t.names
                );
            };
            let (mut a, mut b) = (0.0, 0.0);
            for (i, r) in t.rows.iter().enumerate() {
                a += r[c];
                b += r[c] * i as f64;
            }
            let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()).max(1.0);
            assert!(
                close(a, sum) && close(b, wsum),
                "{} {name}: {a} {b} against laspy's {sum} {wsum}",
                input.display()
            );
            fields += 1;
        }
        assert!(
            fields >= 12,
            "{}: {fields} fields compared",
            input.display()
        );
    }
}
