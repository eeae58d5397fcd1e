//! The shipped sample (data/Haystack_Rock.las, aerial LIDAR) gives a plausible result: normals
//! point up, curvature is finite on at least 99% of the points, and the undefined ones say so.

use crate::common::{column, process, root};

#[test]
fn haystack_rock_is_plausible() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("hay.laz");
    process(&root().join("data/Haystack_Rock.las"), &out, &[]);
    let nz = column(&out, "NormalZ");
    let h = column(&out, "H");
    let k = column(&out, "K");
    let flags = column(&out, "CurvatureFlags");
    let n = h.len() as f64;
    let defined = nz.iter().filter(|v| v.is_finite()).count();
    assert!(
        nz.iter().filter(|v| v.is_finite()).all(|&z| z >= 0.0),
        "--orient up gives upward normals"
    );
    let finite = h
        .iter()
        .zip(&k)
        .filter(|(h, k)| h.is_finite() && k.is_finite())
        .count() as f64;
    assert!(
        finite / n >= 0.99,
        "finite curvature on {:.2}% of the points",
        100.0 * finite / n
    );
    assert!(defined as f64 / n >= 0.99);
    for (i, (&hv, &f)) in h.iter().zip(&flags).enumerate() {
        assert_eq!(
            hv.is_nan(),
            (f as u8) & 7 != 0,
            "point {i}: NaN exactly when flagged undefined"
        );
    }
}

/// `--progress-json -` writes the JSON stream to stdout: every line an object that Python's
/// json module parses, the phases scan, curvature and write each started and ended in that
/// order, every progress line with the phase's and the run's ETA, and a last `summary` event
/// whose counts match the output (points, undefined = points with a NaN H) and name it.
#[test]
fn progress_json_on_stdout_ends_with_a_summary() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("hay.las");
    let r = crate::common::tilecurv(&[
        "process",
        root()
            .join("data/Haystack_Rock.las")
            .to_str()
            .expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
        "--progress-json",
        "-",
        "-q",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let check = r#"
import json, sys
lines = [json.loads(l) for l in sys.stdin.read().splitlines()]
ends = [(l["event"], l["phase"]) for l in lines if l["event"] in ("phase_start", "phase_end")]
want = [(e, p) for p in ("scan", "curvature", "write") for e in ("phase_start", "phase_end")]
assert ends == want, ends
assert all("eta_s" in l and "run_eta_s" in l for l in lines if l["event"] == "progress")
s = lines[-1]
assert s["event"] == "summary", s
print(s["points"], s["undefined"], s["tiles"], s["outputs"][0], s["wall_s"] > 0)
"#;
    let mut py = std::process::Command::new("python3")
        .args(["-c", check])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3");
    std::io::Write::write_all(&mut py.stdin.take().expect("stdin"), &r.stdout).expect("pipe");
    let res = py.wait_with_output().expect("python3");
    let said = String::from_utf8_lossy(&res.stdout);
    assert!(
        res.status.success(),
        "{said} {}",
        String::from_utf8_lossy(&res.stderr)
    );
    let f: Vec<&str> = said.split_whitespace().collect();
    let h = crate::common::column(&out, "H");
    let nan = h.iter().filter(|v| v.is_nan()).count();
    assert_eq!(f[0], h.len().to_string());
    assert_eq!(f[1], nan.to_string());
    assert!(f[2].parse::<u64>().expect("tiles") > 0);
    assert_eq!(f[3], out.to_str().expect("utf-8"));
    assert_eq!(f[4], "True");
}
