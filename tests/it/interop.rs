//! Outputs that the tools LIDAR people use read as intended, checked with laspy (an
//! independent reader) and, where PDAL is concerned, against what the LAS 1.4 specification
//! (R15) requires of the bytes, since PDAL is not installable in the test environment.

use std::path::Path;
use std::process::Command;

use crate::common::{laspy_available, process, records, shared};

/// Runs a Python snippet with laspy on `args`, asserting it exits 0; returns its stdout.
pub fn laspy(code: &str, args: &[&Path]) -> String {
    let out = Command::new("python3")
        .arg("-c")
        .arg(code)
        .args(args)
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "laspy check failed: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// One extra-bytes descriptor of a test input: name, data type, options, scale, offset.
struct Dim {
    name: &'static str,
    ty: u8,
    scale: Option<f64>,
    offset: Option<f64>,
}

impl Dim {
    fn size(&self) -> usize {
        match self.ty {
            1 | 2 => 1,
            3 | 4 => 2,
            5 | 6 | 9 => 4,
            _ => 8,
        }
    }

    /// The 192-byte descriptor, from LAS 1.4 R15 table 24.
    fn descriptor(&self) -> [u8; 192] {
        let mut d = [0u8; 192];
        d[2] = self.ty;
        let mut options = 0u8;
        if let Some(s) = self.scale {
            options |= 0x08;
            d[112..120].copy_from_slice(&s.to_le_bytes());
        }
        if let Some(o) = self.offset {
            options |= 0x10;
            d[136..144].copy_from_slice(&o.to_le_bytes());
        }
        d[3] = options;
        d[4..4 + self.name.len()].copy_from_slice(self.name.as_bytes());
        d
    }
}

/// The dimensions of the two-VLR input, split as (first VLR, second VLR).
const FIRST: [Dim; 2] = [
    Dim {
        name: "Amplitude",
        ty: 9,
        scale: None,
        offset: None,
    },
    Dim {
        name: "Deviation",
        ty: 3,
        scale: Some(0.1),
        offset: None,
    },
];
const SECOND: [Dim; 2] = [
    Dim {
        name: "Reflectance",
        ty: 4,
        scale: Some(0.01),
        offset: Some(-5.0),
    },
    Dim {
        name: "Echo",
        ty: 1,
        scale: None,
        offset: None,
    },
];

/// The raw extra bytes of point `i`: Amplitude i/2 (f32), Deviation raw i (0.1 i), Reflectance
/// raw i - 200 (0.01 (i - 200) - 5), Echo i mod 7.
fn extra_bytes_of(i: usize) -> Vec<u8> {
    let mut e = Vec::new();
    e.extend_from_slice(&(i as f32 * 0.5).to_le_bytes());
    e.extend_from_slice(&(i as u16).to_le_bytes());
    e.extend_from_slice(&(i as i16 - 200).to_le_bytes());
    e.push((i % 7) as u8);
    e
}

/// A VLR (LAS 1.4 R15 table 15) with its 54-byte header.
fn vlr(user: &str, record: u16, data: &[u8]) -> Vec<u8> {
    let mut v = vec![0u8; 54];
    v[2..2 + user.len()].copy_from_slice(user.as_bytes());
    v[18..20].copy_from_slice(&record.to_le_bytes());
    v[20..22].copy_from_slice(&(data.len() as u16).to_le_bytes());
    v.extend_from_slice(data);
    v
}

/// Writes a LAS 1.4 point format 8 file of a 20 x 20 grid on the paraboloid z = (x^2 + y^2)/100
/// (metre scale 0.001), whose extra bytes are described by two extra-bytes VLRs ([`FIRST`] and
/// [`SECOND`]) and, when given, a WKT CRS record, byte by byte from the LAS 1.4 R15
/// specification (header table 4, point format 8 table 13), independently of the library's
/// writer.
fn write_two_eb_vlr_las14(path: &Path, wkt: Option<&str>) -> usize {
    let eb = |dims: &[Dim]| -> Vec<u8> { dims.iter().flat_map(|d| d.descriptor()).collect() };
    let mut vlrs = vlr("LASF_Spec", 4, &eb(&FIRST));
    vlrs.extend(vlr("LASF_Spec", 4, &eb(&SECOND)));
    if let Some(w) = wkt {
        vlrs.extend(vlr("LASF_Projection", 2112, w.as_bytes()));
    }
    let num_vlrs = 2 + wkt.is_some() as u32;
    let extra: usize = FIRST.iter().chain(&SECOND).map(Dim::size).sum();
    let record_length = 38 + extra;
    let n = 400usize;
    let mut h = vec![0u8; 375];
    h[0..4].copy_from_slice(b"LASF");
    h[6..8].copy_from_slice(&0x10u16.to_le_bytes()); // WKT bit: required for formats 6-10
    h[24] = 1;
    h[25] = 4;
    h[26..30].copy_from_slice(b"TEST");
    h[94..96].copy_from_slice(&375u16.to_le_bytes());
    h[96..100].copy_from_slice(&(375 + vlrs.len() as u32).to_le_bytes());
    h[100..104].copy_from_slice(&num_vlrs.to_le_bytes());
    h[104] = 8;
    h[105..107].copy_from_slice(&(record_length as u16).to_le_bytes());
    // Legacy counts (107..131) stay 0, as format 8 requires; the 64-bit counts follow.
    let (lo, hi) = ([-10.0, -10.0, 0.0], [9.0, 9.0, 1.81]);
    for a in 0..3 {
        h[131 + 8 * a..139 + 8 * a].copy_from_slice(&0.001f64.to_le_bytes());
        h[179 + 16 * a..187 + 16 * a].copy_from_slice(&f64::to_le_bytes(hi[a]));
        h[187 + 16 * a..195 + 16 * a].copy_from_slice(&f64::to_le_bytes(lo[a]));
    }
    h[247..255].copy_from_slice(&(n as u64).to_le_bytes());
    h[255..263].copy_from_slice(&(n as u64).to_le_bytes());
    let mut data = h;
    data.extend_from_slice(&vlrs);
    for i in 0..n {
        let (x, y) = ((i % 20) as f64 - 10.0, (i / 20) as f64 - 10.0);
        let z = (x * x + y * y) / 100.0;
        let mut r = vec![0u8; 38];
        for (a, v) in [x, y, z].into_iter().enumerate() {
            let q = (v / 0.001).round() as i32;
            r[4 * a..4 * a + 4].copy_from_slice(&q.to_le_bytes());
        }
        r[12..14].copy_from_slice(&(i as u16).to_le_bytes()); // intensity
        r[14] = 0x11; // return 1 of 1
        r[16] = 2; // ground
        r[22..30].copy_from_slice(&(i as f64).to_le_bytes()); // GPS time
        r[36..38].copy_from_slice(&7u16.to_le_bytes()); // NIR
        data.extend_from_slice(&r);
        data.extend_from_slice(&extra_bytes_of(i));
    }
    std::fs::write(path, data).expect("writes the test input");
    n
}

/// An input whose extra bytes are described by two extra-bytes VLRs gives an
/// output with exactly one, holding every input dimension under its own name (then tilecurv's),
/// so that PDAL (which refuses an extra-bytes specification longer than the records) and laspy
/// (which reads only the first record) see every dimension.
#[test]
fn two_extra_bytes_vlrs_are_merged_into_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let input = dir.path().join("two_eb.las");
    let n = write_two_eb_vlr_las14(&input, None);
    let (src, _) = records(&input);
    let names: Vec<&str> = src.extra.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["Amplitude", "Deviation", "Reflectance", "Echo"]);
    for ext in ["las", "laz"] {
        let output = dir.path().join(format!("out.{ext}"));
        process(&input, &output, &[]);
        let (out, _) = records(&output);
        let eb = out
            .vlrs
            .iter()
            .chain(out.evlrs.iter().map(|(_, v)| v))
            .filter(|v| v.is("LASF_Spec", 4))
            .count();
        assert_eq!(eb, 1, "{ext}: one extra-bytes record");
        let described: usize = out.extra.iter().map(|d| d.size).sum();
        assert_eq!(described, out.header.extra_bytes_len() as usize);
        if !laspy_available() {
            continue;
        }
        let check = r#"
import sys, laspy, numpy as np
a, b = laspy.read(sys.argv[1]), laspy.read(sys.argv[2])
n = len(b.points)
i = np.arange(n)
eb = [v for v in list(b.header.vlrs) + list(b.header.evlrs or []) if v.user_id == "LASF_Spec" and v.record_id == 4]
assert len(eb) == 1, f"{len(eb)} extra-bytes records"
names = list(b.point_format.extra_dimension_names)
want = ["Amplitude", "Deviation", "Reflectance", "Echo", "NormalX", "NormalY", "NormalZ", "H", "K", "k1", "k2", "CurvatureFlags"]
assert names == want, names
assert np.array_equal(np.asarray(b["Amplitude"]), (i * 0.5).astype(np.float32))
assert np.allclose(np.asarray(b["Deviation"]), i * 0.1, rtol=0, atol=1e-9)
assert np.allclose(np.asarray(b["Reflectance"]), (i - 200) * 0.01 - 5, rtol=0, atol=1e-9)
assert np.array_equal(np.asarray(b["Echo"]), i % 7)
for d in a.point_format.dimension_names:
    if d != "ExtraBytes":
        assert np.asarray(a[d]).tobytes() == np.asarray(b[d]).tobytes(), d
assert np.isfinite(np.asarray(b["H"])).sum() > n // 2
print("ok", n)
"#;
        let said = laspy(check, &[&input, &output]);
        assert_eq!(said.trim(), format!("ok {n}"), "{ext}");
    }
}

/// The shared LAS 1.2 file with extra bytes keeps them through the same path (one record).
#[test]
fn one_extra_bytes_vlr_stays_one() {
    let Some(input) = shared("las/MixedConifer.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let output = dir.path().join("mc.las");
    process(&input, &output, &[]);
    let (out, _) = records(&output);
    let eb: Vec<_> = out.vlrs.iter().filter(|v| v.is("LASF_Spec", 4)).collect();
    assert_eq!(eb.len(), 1);
    assert_eq!(out.extra[0].name, "treeID");
}

/// A LAS 1.0-1.3 input gives a LAS 1.4 output by default, since PDAL reads
/// the extra-bytes VLR of LAS 1.4 files only. PDAL is not installable here, so this checks
/// what it relies on: what laspy reads back and what LAS 1.4 R15 requires of the header (375
/// bytes, the 64-bit point counts, the legacy counts kept for formats 0-5, the global encoding's
/// WKT bit set only when a WKT record is the CRS). The points, the header's other fields and
/// every VLR survive; `--keep-version` keeps the input's version.
#[test]
fn old_las_versions_become_las14_with_every_field_and_vlr() {
    let dir = tempfile::tempdir().expect("temp dir");
    let laspy_ok = laspy_available();
    let check = r#"
import struct, sys, laspy, numpy as np
src, out, want = sys.argv[1], sys.argv[2], sys.argv[3]
a, b = laspy.read(src), laspy.read(out)
raw_a, raw_b = open(src, "rb").read(400), open(out, "rb").read(400)
assert str(b.header.version) == want, b.header.version
assert b.header.point_format.id == a.header.point_format.id
assert len(a.points) == len(b.points)
for d in a.point_format.dimension_names:
    assert np.asarray(a[d]).tobytes() == np.asarray(b[d]).tobytes(), d
for f in ["scales", "offsets", "mins", "maxs", "system_identifier", "generating_software",
          "creation_date", "file_source_id", "uuid", "point_count"]:
    x, y = getattr(a.header, f), getattr(b.header, f)
    assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y, f
assert list(b.header.number_of_points_by_return[:5]) == list(a.header.number_of_points_by_return[:5])
assert not any(b.header.number_of_points_by_return[5:])
ga, gb = struct.unpack_from("<H", raw_a, 6)[0], struct.unpack_from("<H", raw_b, 6)[0]
assert gb & 0x0f == ga & 0x0f, (ga, gb)
def vlrs(path):
    data = open(path, "rb").read(1 << 20)
    pos, n, out = struct.unpack_from("<H", data, 94)[0], struct.unpack_from("<I", data, 100)[0], []
    for _ in range(n):
        user = data[pos + 2:pos + 18].rstrip(b"\0").decode()
        rid, length = struct.unpack_from("<HH", data, pos + 18)
        out.append((user, rid, data[pos + 54:pos + 54 + length]))
        pos += 54 + length
    return out
va = [v for v in vlrs(src) if v[0] != "laszip encoded"]
vb = vlrs(out)
for v in va:
    assert v in vb or (v[0], v[1]) == ("LASF_Spec", 4) and any(w[:2] == v[:2] and w[2].startswith(v[2]) for w in vb), v[:2]
geotiff = any(v[:2] == ("LASF_Projection", 34735) for v in va)
wkt = any(v[:2] == ("LASF_Projection", 2112) for v in va)
if want == "1.4":
    assert struct.unpack_from("<H", raw_b, 94)[0] == 375
    assert struct.unpack_from("<Q", raw_b, 247)[0] == len(a.points)
    assert struct.unpack_from("<I", raw_b, 107)[0] == len(a.points), "legacy count kept"
    assert bool(gb & 0x10) == (wkt and not geotiff), gb
    assert "H" in b.point_format.extra_dimension_names
print("ok")
"#;
    for (f, ext) in [
        ("Haystack_Rock.las", "las"),
        ("autzen_trim.laz", "laz"),
        ("32-1-472-150-76.laz", "laz"),
        ("MixedConifer.las", "las"),
    ] {
        let Some(input) = shared(&format!("las/{f}")) else {
            continue;
        };
        let (src, _) = records(&input);
        assert!(src.header.version.1 < 4, "{f} is an old version");
        for keep in [false, true] {
            let output = dir.path().join(format!("{f}.{keep}.{ext}"));
            process(
                &input,
                &output,
                if keep { &["--keep-version"] } else { &[] },
            );
            let (out, _) = records(&output);
            let want = if keep { src.header.version } else { (1, 4) };
            assert_eq!(out.header.version, want, "{f}");
            assert_eq!(out.header.point_format, src.header.point_format);
            if laspy_ok {
                let v = format!("{}.{}", want.0, want.1);
                let said = laspy(check, &[&input, &output, Path::new(&v)]);
                assert_eq!(said.trim(), "ok", "{f}");
            }
        }
    }
}

/// The log names the unit of a geocentric WKT CRS (metres: a COPC or LAS 1.4 file in
/// EPSG:4978 has a CRS with a length unit), and a file without a CRS, or a geographic one,
/// says why it has no length unit instead of "unit unit".
#[test]
fn crs_messages_name_the_unit_or_why_there_is_none() {
    let dir = tempfile::tempdir().expect("temp dir");
    let geoccs = r#"GEOCCS["WGS 84",DATUM["World Geodetic System 1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Geocentric X",OTHER],AXIS["Geocentric Y",OTHER],AXIS["Geocentric Z",NORTH],AUTHORITY["EPSG","4978"]]"#;
    let geog = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
    for (name, wkt, want) in [
        ("geoccs", Some(geoccs), "unit m; tile 50m = 50.000 m"),
        ("none", None, "no length unit (the file has no CRS"),
        ("geog", Some(geog), "no length unit (the CRS is geographic"),
    ] {
        let input = dir.path().join(format!("{name}.las"));
        write_two_eb_vlr_las14(&input, wkt);
        let output = dir.path().join(format!("{name}_out.las"));
        let out = crate::common::tilecurv(&[
            "process",
            input.to_str().expect("utf-8"),
            "-o",
            output.to_str().expect("utf-8"),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
        assert!(!err.contains("unit unit"), "{name}: {err}");
        if wkt == Some(geoccs) {
            assert!(!err.contains("no CRS"), "{name}: {err}");
        }
    }
}

/// A PLY output names its new columns as CloudCompare loads them without a
/// dialog (its PLY filter takes a vertex property as a scalar field only when its name contains
/// "scal", strips a `scalar_` prefix, and reads `nx ny nz` as normals): `nx ny nz`, then
/// `scalar_H` and so on; `--ply-las-names` keeps the LAS names. Values equal the LAS output's.
#[test]
fn ply_columns_are_named_for_cloudcompare() {
    let input = crate::common::root().join("data/Haystack_Rock.las");
    let dir = tempfile::tempdir().expect("temp dir");
    let (ply, plain, las) = (
        dir.path().join("h.ply"),
        dir.path().join("h_plain.ply"),
        dir.path().join("h.las"),
    );
    process(&input, &ply, &[]);
    process(&input, &plain, &["--ply-las-names"]);
    // PLY outputs are f32 (PLY has no scale field): the LAS one too, for bit equality.
    process(&input, &las, &["--f32"]);
    let t = crate::common::read_ply(&ply);
    let new: Vec<&str> = t
        .names
        .iter()
        .map(String::as_str)
        .skip_while(|n| *n != "nx")
        .collect();
    assert_eq!(
        new,
        [
            "nx",
            "ny",
            "nz",
            "scalar_H",
            "scalar_K",
            "scalar_k1",
            "scalar_k2",
            "scalar_CurvatureFlags"
        ]
    );
    for n in &new[3..] {
        assert!(n.to_ascii_uppercase().contains("SCAL"), "{n}");
    }
    let p = crate::common::read_ply(&plain);
    assert!(p.names.iter().any(|n| n == "H") && p.names.iter().any(|n| n == "NormalX"));
    let h_las = crate::common::column(&las, "H");
    let idx = t
        .names
        .iter()
        .position(|n| n == "scalar_H")
        .expect("scalar_H");
    let h_ply: Vec<f64> = t.rows.iter().map(|r| r[idx]).collect();
    assert_eq!(h_las.len(), h_ply.len());
    for (a, b) in h_las.iter().zip(&h_ply) {
        assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
    }
}

/// Extra-bytes descriptors that do not fit a VLR (more
/// than 65535 bytes: an input with 340 extra dimensions plus the 8 new columns) are written as
/// one extra-bytes EVLR in a LAS 1.4 output, with a warning; laspy parses that EVLR's
/// descriptors (it does not take a point format from an EVLR, so the test decodes H from the
/// raw extra bytes with them) and they match the records. A LAS 1.2 input with
/// `--keep-version` is refused before any work (exit 2), since LAS 1.2 has no EVLRs.
#[test]
fn descriptors_past_a_vlr_go_to_an_evlr_in_las14() {
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let write = r#"
import sys, laspy, numpy as np
h = laspy.LasHeader(point_format=int(sys.argv[3]), version=sys.argv[2])
h.scales, h.offsets = [0.001] * 3, [0.0] * 3
h.add_extra_dims([laspy.ExtraBytesParams(name=f"e{j}", type=np.uint8) for j in range(340)])
f = laspy.LasData(h)
i = np.arange(400)
x, y = i % 20 - 10.0, i // 20 - 10.0
f.x, f.y, f.z = x, y, (x * x + y * y) / 100
f["e339"] = i % 200
f.write(sys.argv[1])
print("ok")
"#;
    let read = r#"
import sys, laspy, numpy as np
f = laspy.read(sys.argv[1])
eb = [v for v in f.header.evlrs if v.user_id == "LASF_Spec" and v.record_id == 4]
assert len(eb) == 1 and not [v for v in f.header.vlrs if v.user_id == "LASF_Spec"]
dims = eb[0].type_of_extra_dims()
names = [d.name for d in dims]
assert names[:340] == [f"e{j}" for j in range(340)], names[:3]
raw = np.asarray(f.points["ExtraBytes"]).reshape(len(f.points), -1)
at = sum(np.dtype(d.type).itemsize for d in dims[:names.index("H")])
h = dims[names.index("H")]
q = raw[:, at:at + 4].copy().view("<i4")[:, 0]
v = np.where(q == -2 ** 31, np.nan, q * h.scales[0])
print(",".join(names[340:]))
print(" ".join(repr(float(x)) for x in v))
"#;
    let input = dir.path().join("many.las");
    let said = laspy(write, &[&input, Path::new("1.4"), Path::new("6")]);
    assert_eq!(said.trim(), "ok");
    for ext in ["las", "laz"] {
        let output = dir.path().join(format!("many_out.{ext}"));
        let out = crate::common::run_process(&input, &output, &["-q"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(err.contains("written as an extra-bytes EVLR"), "{err}");
        let (src, _) = records(&output);
        assert_eq!(src.extra.len(), 348, "{ext}");
        let said = laspy(read, &[&output]);
        let mut lines = said.lines();
        assert_eq!(
            lines.next(),
            Some(crate::common::COLUMNS.join(",").as_str())
        );
        let h: Vec<f64> = lines
            .next()
            .expect("H values")
            .split(' ')
            .map(|v| v.parse().expect("a number"))
            .collect();
        let ours = crate::common::column(&output, "H");
        let same = |(a, b): (&f64, &f64)| a == b || (a.is_nan() && b.is_nan());
        assert!(h.len() == 400 && h.iter().zip(&ours).all(same), "{ext}");
        assert_eq!(crate::common::column(&output, "e339")[399], 199.0);
    }
    let old = dir.path().join("many12.las");
    assert_eq!(
        laspy(write, &[&old, Path::new("1.2"), Path::new("0")]).trim(),
        "ok"
    );
    let output = dir.path().join("kept.las");
    let out = crate::common::run_process(&old, &output, &["--keep-version"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("many12.las") && err.contains("348 extra-bytes descriptors"),
        "{err}"
    );
    assert!(
        err.contains("without --keep-version") && !err.contains("scan:"),
        "{err}"
    );
    assert!(!output.exists() && !dir.path().join(".kept.las.tilecurv").exists());
}

/// A header whose point counts contradict each other or the data is warned about, and the
/// output's header counts the records it holds, as laspy reads them: Topography.las (LAS 1.2)
/// counting 100 of its 73,403 records; test1_4.las (LAS 1.4 format 6, 1,000 points) with its
/// 64-bit count zeroed (the 32-bit one is read) or set to 100 (the 64-bit one is read). The
/// first records of the output are the input's, byte for byte.
#[test]
fn output_headers_count_the_records_they_hold() {
    let (Some(topo), Some(las14)) = (shared("las/Topography.las"), shared("las/test1_4.las"))
    else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let patched = |from: &Path, name: &str, at: usize, bytes: &[u8]| {
        let mut b = std::fs::read(from).expect("input");
        b[at..at + bytes.len()].copy_from_slice(bytes);
        let p = dir.path().join(name);
        std::fs::write(&p, b).expect("write");
        p
    };
    let cases = [
        (
            patched(&topo, "topo100.las", 107, &100u32.to_le_bytes()),
            100,
            "holds 73403 whole records but the header counts 100",
        ),
        (
            patched(&las14, "c64_zero.las", 247, &0u64.to_le_bytes()),
            1000,
            "1000 in the 32-bit field (byte 107), 0 in the 64-bit one",
        ),
        (
            patched(&las14, "c64_100.las", 247, &100u64.to_le_bytes()),
            100,
            "1000 in the 32-bit field (byte 107), 100 in the 64-bit one",
        ),
    ];
    for (input, n, said) in &cases {
        let output = input.with_extension("out.las");
        let run = crate::common::run_process(input, &output, &["-q"]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{}: {err}", input.display());
        assert!(err.contains(said), "{}: {err}", input.display());
        let (out, recs) = records(&output);
        assert_eq!(out.header.point_count, *n);
        // The 32-bit count: the count for format 1 (LAS 1.2), 0 for format 6 (LAS 1.4 2.4).
        let legacy = u32::from_le_bytes(out.header.raw[107..111].try_into().expect("4 bytes"));
        let want = if out.header.point_format <= 5 {
            *n as u32
        } else {
            0
        };
        assert_eq!(legacy, want, "{}", input.display());
        let (src, inrecs) = records(input);
        let (a, b) = (
            src.header.record_length as usize,
            out.header.record_length as usize,
        );
        for i in [0, *n as usize - 1] {
            assert_eq!(
                &inrecs[i * a..i * a + a],
                &recs[i * b..i * b + a],
                "record {i}"
            );
        }
        if laspy_available() {
            let said = laspy(
                "import sys, laspy; print(len(laspy.read(sys.argv[1]).points))",
                &[&output],
            );
            assert_eq!(said.trim(), n.to_string(), "{}", input.display());
        }
    }
    // An output read again: its own columns are trimmed from its records, which the count of
    // whole records does not take for the stored ones (it said 157,292 of Topography's 60-byte
    // records, counted at 28 bytes).
    let output = dir.path().join("topo.las");
    let again = dir.path().join("again.las");
    for (input, out) in [(&topo, &output), (&output, &again)] {
        let run = crate::common::run_process(input, out, &["-q"]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{err}");
        assert!(!err.contains("whole records"), "{}: {err}", input.display());
    }
}
