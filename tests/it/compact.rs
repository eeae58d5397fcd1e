//! Compact columns: a default LAS/LAZ output stores scaled integers through
//! the extra-bytes descriptors' scale, offset and no-data fields; read back with laspy, they
//! equal the `--f64` run's values within the stated error; undefined values are the declared
//! no-data value; `--columns` picks the columns, `--f32` keeps the float layout, and an unknown
//! column name is a usage error.

use std::path::Path;

use tilecurv::io::source::PointSource;

use crate::common::{
    column, laspy_available, process, provenance_texts, records, s, tilecurv, tilecurv_as_given,
    write_las,
};
use crate::interop::laspy;

/// A saddle z = 0.02 (x^2 - 0.5 y^2) sampled on a jittered 60 x 60 grid (1 m), and 40 copies
/// of one point far from it, whose PCA normal is undefined (flag 2: NaN curvature).
fn saddle_with_duplicates(path: &Path) -> usize {
    let pts = saddle_points();
    write_las(path, &pts, None, 0.0001);
    pts.len()
}

fn saddle_points() -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    for i in 0..60 {
        for j in 0..60 {
            let jitter = |s: u64| ((s * 2654435761 % 1000) as f64 / 1000.0 - 0.5) * 0.3;
            let (x, y) = (
                i as f64 - 30.0 + jitter(i * 60 + j),
                j as f64 - 30.0 + jitter(i * 61 + j + 7),
            );
            pts.push([x, y, 0.02 * (x * x - 0.5 * y * y)]);
        }
    }
    pts.extend(std::iter::repeat_n([200.0, 200.0, 5.0], 40));
    pts
}

/// The default LAZ output, read by laspy, holds i16 normals at 1/32767 and i32 curvatures at a
/// power-of-two step between P99/8192 and P99/4096 of |value| (k1 and k2 one step), each with
/// scale, offset 0 and the type's minimum as no-data in its descriptor (options bits 0, 3, 4);
/// the scaled values equal the `--f64` run's within half a step (plus the f32 rounding of the
/// result files, 2^-24 of the value); the undefined points (flags
/// 1, 2 or 4) hold the no-data value, which laspy does not mask: it returns
/// no_data * scale, and the flags or the raw value tell them apart. Our own reader gives NaN.
#[test]
fn default_laz_holds_scaled_integers_within_half_a_step() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("saddle.las");
    let n = saddle_with_duplicates(&input);
    let (scaled, reference) = (dir.path().join("s.laz"), dir.path().join("r.las"));
    process(&input, &scaled, &[]);
    process(&input, &reference, &["--f64"]);
    let h = column(&scaled, "H");
    let flags = column(&scaled, "CurvatureFlags");
    assert_eq!(h.len(), n);
    assert_eq!(flags.iter().filter(|&&f| f as u8 & 7 != 0).count(), 40);
    for (v, f) in h.iter().zip(&flags) {
        assert_eq!(v.is_nan(), *f as u8 & 7 != 0, "NaN exactly where undefined");
    }
    if !laspy_available() {
        return;
    }
    let check = r#"
import sys, laspy, numpy as np
s, r = laspy.read(sys.argv[1]), laspy.read(sys.argv[2])
eb = [v for v in s.header.vlrs if v.user_id == "LASF_Spec" and v.record_id == 4][0]
desc = {d.name.rstrip(b"\0").decode(): d for d in eb.extra_bytes_structs}
flags = np.asarray(s["CurvatureFlags"])
undefined = (flags & 7) != 0
assert undefined.sum() == 40
steps = {}
for name in ["NormalX", "NormalY", "NormalZ", "H", "K", "k1", "k2", "CurvatureFlags"]:
    d = desc[name]
    if name == "CurvatureFlags":
        assert (d.data_type, d.options) == (1, 0), (name, d.data_type, d.options)
        assert np.array_equal(flags, np.asarray(r[name]))
        continue
    normal = name.startswith("Normal")
    ty, lo = (4, -32768) if normal else (6, -2**31)
    assert d.data_type == ty, (name, d.data_type)
    assert d.options & 0x19 == 0x19, (name, d.options)
    assert d.offset[0] == 0.0 and d.no_data[0] == lo, (name, d.offset, d.no_data)
    q = d.scale[0]
    raw = s.points.array[name]
    assert raw.dtype == (np.int16 if normal else np.int32)
    ref = np.asarray(r[name], dtype=np.float64)
    val = np.asarray(s[name], dtype=np.float64)
    # laspy applies the scale and offset, and leaves no-data to the caller.
    assert np.array_equal(val, raw * q)
    if normal:
        assert q == 1 / 32767
        bad = np.isnan(ref)
    else:
        assert np.log2(q) == np.round(np.log2(q)), (name, q)
        steps[name] = q
        bad = undefined
        pool = ["k1", "k2"] if name in ("k1", "k2") else [name]
        a = np.sort(np.abs(np.concatenate([np.asarray(r[c])[~bad] for c in pool])))
        p99 = a[int(np.ceil(0.99 * len(a))) - 1]
        assert p99 / 8192 < q <= p99 / 4096 or a[-1] / q > 2**29, (name, q, p99)
    assert np.array_equal(raw == lo, bad), name
    assert np.all(np.isnan(ref[bad])) and np.all(val[bad] == lo * q), name
    # Half a step, plus the f32 rounding of the value in the result files (2^-24 relative).
    err = np.abs(val[~bad] - ref[~bad])
    bound = q / 2 * (1 + 1e-12) + np.abs(ref[~bad]) * 2.0**-24
    assert np.all(err <= bound), (name, err.max(), q)
    print(name, q, err.max())
assert steps["k1"] == steps["k2"]
print("ok")
"#;
    let said = laspy(check, &[&scaled, &reference]);
    assert!(said.trim_end().ends_with("ok"), "{said}");
}

/// The text of a LAS output's (only) tilecurv provenance record.
fn provenance(path: &Path) -> String {
    let texts = provenance_texts(path);
    assert_eq!(texts.len(), 1, "{texts:?}");
    texts[0].clone()
}

/// Without `--columns` a run writes H, K and CurvatureFlags only (the set whose LAZ output
/// stays within 2x its LAZ input on forest TLS, README "Compact columns"): 9 bytes a point after
/// the 20-byte format-0 record, and the provenance says so.
#[test]
fn the_default_columns_are_h_k_and_flags() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("saddle.las");
    saddle_with_duplicates(&input);
    let out = dir.path().join("o.laz");
    let o = tilecurv_as_given(&["process", s(&input), "-o", s(&out), "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (src, _) = records(&out);
    let names: Vec<&str> = src.extra.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["H", "K", "CurvatureFlags"]);
    assert_eq!(src.header.record_length, 20 + 4 + 4 + 1);
    let prov = provenance(&out);
    assert!(prov.contains("columns=H,K,flags\n"), "{prov}");
}

/// `--columns H,flags` writes those two only; the order given does not matter and --directions
/// adds its group; the provenance records the list and each column's encoding.
#[test]
fn columns_pick_what_is_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("saddle.las");
    saddle_with_duplicates(&input);
    let names = |p: &Path| {
        let (s, _) = records(p);
        let names: Vec<String> = s.extra.iter().map(|d| d.name.clone()).collect();
        (names, s.header.record_length)
    };
    let out = dir.path().join("h.laz");
    process(&input, &out, &["--columns", "flags,H"]);
    assert_eq!(
        names(&out),
        (vec!["H".into(), "CurvatureFlags".into()], 20 + 4 + 1)
    );
    let prov = provenance(&out);
    assert!(prov.contains("columns=H,flags\n"), "{prov}");
    assert!(prov.contains("column.H=i32 scale "), "{prov}");
    assert!(prov.contains("column.CurvatureFlags=u8\n"), "{prov}");
    let out = dir.path().join("d.las");
    process(&input, &out, &["--columns", "k2,normals", "--directions"]);
    let want = [
        "NormalX", "NormalY", "NormalZ", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z",
    ];
    assert_eq!(
        names(&out),
        (want.map(String::from).to_vec(), 20 + 9 * 2 + 4)
    );
}

/// `--f32` keeps the float layout of earlier versions: f32 columns without scale or no-data,
/// NaN where undefined, 4 bytes a value (the tests' seven values and the flags: 29 bytes a point
/// after the record); a PLY output is f32 by default too (no scale field).
#[test]
fn f32_keeps_the_float_layout() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("saddle.las");
    saddle_with_duplicates(&input);
    let out = dir.path().join("f.laz");
    process(&input, &out, &["--f32"]);
    let (s, _) = records(&out);
    assert_eq!(s.header.record_length, 20 + 7 * 4 + 1);
    for d in s.extra.iter().filter(|d| d.name != "CurvatureFlags") {
        assert_eq!(
            (d.data_type, d.scale, d.no_data),
            (9, 1.0, None),
            "{}",
            d.name
        );
    }
    let h = column(&out, "H");
    assert_eq!(h.iter().filter(|v| v.is_nan()).count(), 40);
    let reference = dir.path().join("r.las");
    process(&input, &reference, &["--f64"]);
    for (a, b) in h.iter().zip(column(&reference, "H")) {
        assert!(a.to_bits() == (b as f32 as f64).to_bits() || (a.is_nan() && b.is_nan()));
    }
    let ply = dir.path().join("p.ply");
    process(&input, &ply, &[]);
    let t = crate::common::read_ply(&ply);
    let at = t.names.iter().position(|n| n == "scalar_H").expect("H");
    assert_eq!(t.types[at], "float");
}

/// An unknown column name is a usage error (exit 2) that lists the valid names; `--f32` with
/// `--f64` too.
#[test]
fn an_unknown_column_is_a_usage_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("saddle.las");
    saddle_with_duplicates(&input);
    let output = dir.path().join("o.laz");
    let run = |extra: &[&str]| crate::common::run_process(&input, &output, extra);
    let out = run(&["--columns", "H,torsion"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("torsion")
            && err.contains("normals, H, K, k1, k2, directions, features, scale, flags"),
        "{err}"
    );
    let out = run(&["--f32", "--f64"]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["--columns", "features"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--estimator vcm"), "{err}");
    assert!(!output.exists());
}

/// The steps come from every point of the run: a scene of two files whose curvatures differ
/// (z grows a cubic term where x > 0, so K there is larger) gives both outputs the encoding of
/// one file holding both, and every point its bytes in that file's output. Each file holds the
/// same two far corner points (flagged undefined), so that all three have the same bounds,
/// hence the same coordinate offsets and the same decoded coordinates.
#[test]
fn a_scene_of_several_files_shares_the_whole_clouds_encoding() {
    let dir = tempfile::tempdir().expect("temp dir");
    let corners = [[-200.0, -200.0, -100.0], [200.0, 200.0, 100.0]];
    let cubic = |p: &[f64; 3]| [p[0], p[1], p[2] + 0.001 * p[0].max(0.0).powi(3)];
    let grid: Vec<[f64; 3]> = saddle_points()[..3600].iter().map(cubic).collect();
    let (left, right): (Vec<[f64; 3]>, Vec<[f64; 3]>) = grid.iter().partition(|p| p[0] < 0.0);
    let halves = [dir.path().join("a.las"), dir.path().join("b.las")];
    let mut all = Vec::new();
    for (path, mut part) in halves.iter().zip([left, right]) {
        part.extend(corners);
        write_las(path, &part, None, 0.0001);
        all.extend(part);
    }
    let whole = dir.path().join("whole.las");
    write_las(&whole, &all, None, 0.0001);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    let whole_out = dir.path().join("whole_out.las");
    process(&whole, &whole_out, &[]);
    let status = tilecurv(&[
        "process",
        halves[0].to_str().expect("utf-8"),
        halves[1].to_str().expect("utf-8"),
        "-o",
        &format!("{}/", out.display()),
        "-q",
    ]);
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let (w, wrec) = records(&whole_out);
    let descriptors = |s: &tilecurv::io::source::LasSource| {
        s.extra
            .iter()
            .map(|d| (d.name.clone(), d.data_type, d.scale, d.no_data))
            .collect::<Vec<_>>()
    };
    let rl = w.header.record_length as usize;
    let mut first = 0;
    for name in ["a.las", "b.las"] {
        let (s, rec) = records(&out.join(name));
        assert_eq!(descriptors(&s), descriptors(&w), "{name}");
        assert_eq!(
            rec[..],
            wrec[first * rl..(first + s.len() as usize) * rl],
            "{name}"
        );
        first += s.len() as usize;
    }
    // The halves alone would have taken other steps for K.
    let alone = dir.path().join("alone.las");
    process(&halves[0], &alone, &[]);
    let step = |p: &Path| {
        let (s, _) = records(p);
        s.extra.iter().find(|d| d.name == "K").expect("K").scale
    };
    assert_ne!(step(&alone), step(&whole_out));
}
