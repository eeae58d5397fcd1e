//! Vertical units: a terrain whose CRS is metres horizontally and US survey
//! feet vertically gives the curvature of the metre terrain (its z is converted before any
//! geometry), from a compound WKT and from GeoTIFF's VerticalUnitsGeoKey; a vertical CRS whose
//! unit cannot be read is warned about. The terrain is generated with its closed-form curvature
//! (TrueH, in 1/m), rewritten in feet by laspy.

use std::path::Path;

use crate::common::{column, laspy_available, median, process, s, tilecurv};

const FT_US: f64 = 1200.0 / 3937.0;

/// Rewrites the metre terrain `src` as `dst` with z in US survey feet and `crs` ("wkt",
/// "geotiff" or "wkt-no-unit") as its only CRS record.
fn in_feet(src: &Path, dst: &Path, crs: &str) {
    let script = format!(
        r#"
import laspy, struct, numpy as np
f = laspy.read({src:?})
f.header.vlrs = [v for v in f.header.vlrs if v.user_id != "LASF_Projection"]
z = np.asarray(f.z) / {FT_US:?}
f.header.offsets = [f.header.offsets[0], f.header.offsets[1], 0.0]
f.z = z
proj = 'PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],UNIT["metre",1]]'
if "{crs}" == "geotiff":
    keys = [1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32610, 4099, 0, 1, 9003]
    f.header.vlrs.append(laspy.VLR("LASF_Projection", 34735, "", struct.pack("<%dH" % len(keys), *keys)))
else:
    unit = ',UNIT["US survey foot",0.304800609601219]' if "{crs}" == "wkt" else ""
    wkt = 'COMPD_CS["UTM 10N + NAVD88 height (ftUS)",' + proj + ',VERT_CS["NAVD88 height (ftUS)",VERT_DATUM["North American Vertical Datum 1988",2005]' + unit + ']]'
    f.header.vlrs.append(laspy.VLR("LASF_Projection", 2112, "", wkt.encode() + b"\0"))
f.write({dst:?})
"#,
        src = src.to_str().expect("utf-8"),
        dst = dst.to_str().expect("utf-8"),
    );
    crate::interop::laspy(&script, &[]);
}

/// Median |H - TrueH| over median |TrueH| (both 1/m).
fn relative_error(out: &Path) -> f64 {
    let (h, t) = (column(out, "H"), column(out, "TrueH"));
    let err: Vec<f64> = h.iter().zip(&t).map(|(a, b)| (a - b).abs()).collect();
    median(err) / median(t.iter().map(|x| x.abs()).collect())
}

#[test]
fn heights_in_feet_under_a_metre_crs_are_converted() {
    if !laspy_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let metres = dir.path().join("terrain_m.las");
    crate::common::generate_terrain(&metres, "30000", 0, 10.0);
    let out_m = dir.path().join("out_m.las");
    process(&metres, &out_m, &[]);
    let base = relative_error(&out_m);
    assert!(base < 0.25, "metre terrain: relative error {base}");
    let h_m = median(column(&out_m, "H").iter().map(|x| x.abs()).collect());
    for crs in ["wkt", "geotiff"] {
        let feet = dir.path().join(format!("terrain_{crs}.las"));
        in_feet(&metres, &feet, crs);
        let out = dir.path().join(format!("out_{crs}.las"));
        process(&feet, &out, &[]);
        let e = relative_error(&out);
        let h = median(column(&out, "H").iter().map(|x| x.abs()).collect());
        // Unconverted, z is 3.28x steeper and H comes out 2-3x too large (relative error > 1).
        assert!(
            e < base * 1.2 + 0.01,
            "{crs}: relative error {e} against {base} in metres"
        );
        assert!(
            (h / h_m - 1.0).abs() < 0.02,
            "{crs}: median |H| {h} against {h_m}"
        );
        let info = tilecurv(&["info", out.to_str().expect("utf-8")]);
        let text = String::from_utf8_lossy(&info.stdout);
        assert!(
            text.contains("z_scale=0.3048006096"),
            "{crs}: provenance: {text}"
        );
        // Rasters name each band's unit as the file's CRS has it: z in US survey feet, H in
        // 1/m (the horizontal unit), as rasterio (GDAL) reads them.
        let r = dir.path().join(format!("r_{crs}"));
        let run = tilecurv(&[
            "raster",
            s(&out),
            "--cell",
            "5m",
            "--columns",
            "z,H",
            "-o",
            s(&r),
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let read = r#"
import sys, rasterio
for n in ("z", "H", "PointCount"):
    with rasterio.open(f"{sys.argv[1]}/{n}.tif") as t:
        print(t.descriptions[0], t.units[0])
"#;
        let said = crate::interop::laspy(read, &[&r]);
        assert_eq!(said, "z ftUS\nH 1/m\nPointCount points\n", "{crs}");
    }
    // A vertical CRS without a unit: taken in metres, with a warning naming the file.
    let vague = dir.path().join("terrain_vague.las");
    in_feet(&metres, &vague, "wkt-no-unit");
    let out = dir.path().join("out_vague.las");
    let r = tilecurv(&[
        "process",
        vague.to_str().expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("terrain_vague.las") && err.contains("vertical CRS names no unit"),
        "{err}"
    );
}
