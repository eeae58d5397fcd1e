//! Every LAS/LAZ file of ../shared/data/las runs to completion, as LAS and as LAZ output; the
//! original point records are byte-identical in the output, VLRs and existing extra bytes survive,
//! and an independent reader (laspy with lazrs) reads the result back.

use std::path::Path;
use std::process::Command;

use tilecurv::io::source::PointSource;

use crate::common::{laspy_available, process, records, shared, COLUMNS};

pub(crate) const FILES: [&str; 15] = [
    "32-1-472-150-76.laz",
    "Haystack_Rock.las",
    "Megaplot.las",
    "MixedConifer.las",
    "Topography.las",
    "autzen_trim.las",
    "autzen_trim.laz",
    "autzen_trim_7.las",
    "bcts_1.laz",
    "bcts_2.laz",
    "extra_byte.las",
    "extrabytes.las",
    "hexbin-crop.las",
    "las14_pdrf6.laz",
    "test1_4.las",
];

fn check_preserved(input: &Path, output: &Path) {
    let (a, ra) = records(input);
    let (b, rb) = records(output);
    assert_eq!(a.len(), b.len(), "{}: point count", output.display());
    let (la, lb) = (
        a.header.record_length as usize,
        b.header.record_length as usize,
    );
    assert_eq!(
        lb,
        la + 23,
        "3 i16 normals, 4 i32 curvatures and 1 flag byte are added"
    );
    for (i, (x, y)) in ra.chunks_exact(la).zip(rb.chunks_exact(lb)).enumerate() {
        assert_eq!(
            x,
            &y[..la],
            "{}: point {i} record differs",
            output.display()
        );
    }
    let (ha, hb) = (&a.header, &b.header);
    assert_eq!(
        (ha.scale, ha.offset, ha.min, ha.max, ha.point_format,),
        (hb.scale, hb.offset, hb.min, hb.max, hb.point_format,)
    );
    // LAS 1.0-1.3 become LAS 1.4 (interop.rs checks the header).
    assert_eq!(hb.version, (1, 4));
    // Every input VLR is kept in order (the LAZ and COPC ones are rebuilt or dropped; the
    // extra-bytes VLR keeps its descriptors as a prefix).
    let keep =
        |v: &&tilecurv::io::las::vlr::Vlr| !(v.is("laszip encoded", 22204) || v.user_id == "copc");
    let va: Vec<_> = a.vlrs.iter().filter(keep).collect();
    let vb: Vec<_> = b.vlrs.iter().filter(keep).collect();
    for v in &va {
        let w = vb
            .iter()
            .find(|w| w.user_id == v.user_id && w.record_id == v.record_id)
            .unwrap_or_else(|| panic!("VLR {} {} lost", v.user_id, v.record_id));
        assert!(
            w.data.starts_with(&v.data),
            "VLR {} {} changed",
            v.user_id,
            v.record_id
        );
    }
    let ea: Vec<_> = a.evlrs.iter().map(|(_, v)| v).filter(keep).collect();
    let eb: Vec<_> = b.evlrs.iter().map(|(_, v)| v).filter(keep).collect();
    assert_eq!(ea, eb, "EVLRs kept");
    for name in COLUMNS {
        assert!(
            b.extra.iter().any(|d| d.name == name),
            "column {name} missing"
        );
    }
    for d in &a.extra {
        let e = b
            .extra
            .iter()
            .find(|e| e.name == d.name)
            .unwrap_or_else(|| panic!("extra dimension {} lost", d.name));
        assert_eq!(
            (e.offset, e.size, e.data_type),
            (d.offset, d.size, d.data_type)
        );
    }
}

#[test]
fn every_shared_las_file_round_trips() {
    let dir = tempfile::tempdir().expect("temp dir");
    let laspy = laspy_available();
    let mut checked = 0;
    for f in FILES {
        let Some(input) = shared(&format!("las/{f}")) else {
            continue;
        };
        for ext in ["las", "laz"] {
            let output = dir.path().join(format!("{f}.out.{ext}"));
            process(&input, &output, &[]);
            check_preserved(&input, &output);
            if laspy {
                let out = Command::new("python3")
                    .arg(crate::common::root().join("scripts/laspy_check.py"))
                    .args([&input, &output])
                    .output()
                    .expect("python3 runs");
                assert!(
                    out.status.success(),
                    "laspy: {}{}",
                    String::from_utf8_lossy(&out.stdout),
                    String::from_utf8_lossy(&out.stderr)
                );
            }
            checked += 1;
        }
    }
    eprintln!("{checked} outputs checked");
}

#[test]
fn existing_extra_bytes_keep_their_values() {
    let Some(input) = shared("las/MixedConifer.las") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let output = dir.path().join("mc.laz");
    process(&input, &output, &["--f64", "--directions"]);
    // Byte for byte: treeID declares a no-data value (f64::MAX), which reads as NaN.
    assert_eq!(
        crate::common::column_bytes(&input, "treeID"),
        crate::common::column_bytes(&output, "treeID")
    );
    let tree = crate::common::column(&input, "treeID");
    assert!(tree.iter().any(|&t| t > 0.0), "treeID carries values");
    assert!(tree.iter().any(|t| t.is_nan()), "and no-data values");
    let (b, _) = records(&output);
    let h = b.extra.iter().find(|d| d.name == "H").expect("H");
    assert_eq!(h.data_type, 10, "--f64 stores f64 (type 10)");
    assert!(b.extra.iter().any(|d| d.name == "d2z"));
}

#[test]
fn copc_input_gives_a_plain_laz_without_the_stale_index() {
    let Some(las14) = shared("las/autzen_trim_7.las") else {
        return;
    };
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let copc = dir.path().join("autzen.copc.laz");
    let made = Command::new("python3")
        .arg(crate::common::root().join("scripts/make_copc.py"))
        .args([&las14, &copc])
        .output()
        .expect("python3 runs");
    if !made.status.success() {
        let why = String::from_utf8_lossy(&made.stderr);
        if crate::common::under_ci() {
            panic!(
                "making the COPC test file failed (copclib from PyPI is required under CI): {why}"
            );
        }
        eprintln!("SKIPPED: COPC test: scripts/make_copc.py failed (pip install copclib): {why}");
        return;
    }
    let (src, _) = records(&copc);
    assert!(
        src.vlrs.iter().any(|v| v.user_id == "copc")
            && src.evlrs.iter().any(|(_, v)| v.user_id == "copc"),
        "the test input is COPC"
    );
    for ext in ["laz", "las"] {
        let out = dir.path().join(format!("out.{ext}"));
        process(&copc, &out, &[]);
        check_preserved(&copc, &out);
        let (o, _) = records(&out);
        assert!(
            !o.vlrs.iter().any(|v| v.user_id == "copc")
                && !o.evlrs.iter().any(|(_, v)| v.user_id == "copc"),
            "COPC records dropped"
        );
        let check = Command::new("python3")
            .arg(crate::common::root().join("scripts/laspy_check.py"))
            .args([&copc, &out])
            .output()
            .expect("python3 runs");
        assert!(
            check.status.success(),
            "laspy: {}",
            String::from_utf8_lossy(&check.stdout)
        );
    }
}
