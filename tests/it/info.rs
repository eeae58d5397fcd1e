//! `tilecurv info` on a shared file and on a tilecurv output, text and JSON,
//! checked against laspy's view of the same files.

use crate::common::laspy_available;
use crate::common::{process, shared, tilecurv};
use crate::interop::laspy;

#[test]
fn info_describes_a_shared_file_and_a_tilecurv_output() {
    let Some(input) = shared("las/MixedConifer.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let output = dir.path().join("mc_curv.laz");
    process(&input, &output, &["--f64"]);
    let scaled = dir.path().join("mc_scaled.laz");
    process(&input, &scaled, &[]);
    let (i, o, sc) = (
        input.to_str().expect("utf-8"),
        output.to_str().expect("utf-8"),
        scaled.to_str().expect("utf-8"),
    );
    let out = tilecurv(&["info", i, o, sc]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for want in [
        "format: LAS 1.2 format 1\n",
        "points: 37657\n",
        "CRS: GeoTIFF, EPSG:26912\n",
        "horizontal unit: metre (1 m)\n",
        "    treeID f64 no_data 1.7976931348623157e308\n",
        "tilecurv provenance: none\n",
        "format: LAS 1.4 format 1 (LAZ)\n",
        "    H f64\n",
        "    CurvatureFlags u8\n",
        "    estimator=cnc-avg-hexagram\n",
        "    encoding=f64\n",
        "    NormalX i16 scale 0.00003051850947599719 offset 0 no_data -32768\n",
        " offset 0 no_data -2147483648\n    K i32 scale ",
        "    column.H=i32 scale ",
    ] {
        assert!(text.contains(want), "{want:?} not in:\n{text}");
    }
    let json = tilecurv(&["info", "--json", i, o, sc]);
    assert!(json.status.success());
    let path = dir.path().join("info.json");
    std::fs::write(&path, &json.stdout).expect("writes");
    if !laspy_available() {
        return;
    }
    // Python's json parser and laspy are the independent truth.
    let check = r#"
import json, sys, laspy
info = json.load(open(sys.argv[1]))
assert len(info) == 3
for item, f in zip(info, sys.argv[2:]):
    h = laspy.open(f).header
    assert item["points"] == h.point_count
    assert item["las_version"] == str(h.version)
    assert item["point_format"] == h.point_format.id
    assert item["bounds"]["min"] == list(h.mins) and item["bounds"]["max"] == list(h.maxs)
    names = [d["name"] for d in item["extra_dimensions"]]
    assert names == list(h.point_format.extra_dimension_names), names
    assert item["crs"]["horizontal_unit"]["symbol"] == "m"
    eb = [v for v in h.vlrs if v.user_id == "LASF_Spec" and v.record_id == 4][0]
    for d, s in zip(item["extra_dimensions"], eb.extra_bytes_structs):
        want = s.scale[0] if s.scale is not None else 1.0
        assert d["scale"] == want, (d, want)
        nd = s.no_data
        assert d["no_data"] == (None if nd is None else float(nd[0])), (d, nd)
assert info[0]["provenance"] is None
assert "estimator=cnc-avg-hexagram" in info[1]["provenance"]
print("ok")
"#;
    let said = laspy(check, &[&path, &input, &output, &scaled]);
    assert_eq!(said.trim(), "ok");
}

/// A missing file is a bad input (exit 3); the files around it are still described, each
/// with its own point count.
#[test]
fn info_of_a_missing_file_is_a_bad_input() {
    let out = tilecurv(&["info", "/nonexistent/file.las"]);
    assert_eq!(out.status.code(), Some(3));
    let (Some(a), Some(b)) = (shared("las/MixedConifer.las"), shared("las/Topography.las")) else {
        return;
    };
    let (a, b) = (a.to_str().expect("utf-8"), b.to_str().expect("utf-8"));
    let out = tilecurv(&["info", a, "/nonexistent/file.las", b]);
    assert_eq!(out.status.code(), Some(3));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("points: 37657\n") && text.contains("points: 73403\n"),
        "{text}"
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/file.las"));
}

/// A PLY output's provenance (its header comments) is shown as a LAS output's is, with the
/// run's options; a PLY that tilecurv did not write has none.
#[test]
fn info_shows_the_provenance_of_a_ply_output() {
    let dir = tempfile::tempdir().expect("temp dir");
    let output = dir.path().join("hay.ply");
    process(
        &crate::common::root().join("data/Haystack_Rock.las"),
        &output,
        &["-k", "24"],
    );
    let out = tilecurv(&["info", output.to_str().expect("utf-8")]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for want in [
        "  tilecurv provenance:\n    tilecurv ",
        "    k=24\n",
        "    inputs=Haystack_Rock.las\n",
    ] {
        assert!(text.contains(want), "{want:?} in:\n{text}");
    }
    let Some(plain) = shared("objects/building.ply") else {
        return;
    };
    let out = tilecurv(&["info", plain.to_str().expect("utf-8")]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("tilecurv provenance: none\n"), "{text}");
}
