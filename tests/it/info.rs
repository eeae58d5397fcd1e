//! `tilecurv info` (issue 13 item 8) on a shared file and on a tilecurv output, text and JSON,
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
    let (i, o) = (
        input.to_str().expect("utf-8"),
        output.to_str().expect("utf-8"),
    );
    let out = tilecurv(&["info", i, o]);
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
        "    columns=f64\n",
    ] {
        assert!(text.contains(want), "{want:?} not in:\n{text}");
    }
    let json = tilecurv(&["info", "--json", i, o]);
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
assert len(info) == 2
for item, f in zip(info, sys.argv[2:]):
    h = laspy.open(f).header
    assert item["points"] == h.point_count
    assert item["las_version"] == str(h.version)
    assert item["point_format"] == h.point_format.id
    assert item["bounds"]["min"] == list(h.mins) and item["bounds"]["max"] == list(h.maxs)
    names = [d["name"] for d in item["extra_dimensions"]]
    assert names == list(h.point_format.extra_dimension_names), names
    assert item["crs"]["horizontal_unit"]["symbol"] == "m"
assert info[0]["provenance"] is None
assert "estimator=cnc-avg-hexagram" in info[1]["provenance"]
print("ok")
"#;
    let said = laspy(check, &[&path, &input, &output]);
    assert_eq!(said.trim(), "ok");
}

#[test]
fn info_of_a_missing_file_is_a_bad_input() {
    let out = tilecurv(&["info", "/nonexistent/file.las"]);
    assert_eq!(out.status.code(), Some(3));
}
