//! GDAL's sidecar of a raster, `NAME.tif.aux.xml` (its persistent auxiliary metadata, "PAM"):
//! the one place where a CRS that GeoTIFF keys cannot hold (a WKT naming no EPSG code) reaches
//! GDAL-based programs (QGIS, rasterio, R's terra, GRASS's r.in.gdal) and ArcGIS, which take
//! the WKT of its `SRS` element as the raster's CRS. No axis mapping is written: GDAL then
//! reads x as easting (or longitude), as the raster's cells are laid out.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::durable::write_durably;

/// The sidecar's path: the raster's with `.aux.xml` appended, as GDAL looks for it.
pub(crate) fn path_of(raster: &Path) -> PathBuf {
    let mut p = raster.as_os_str().to_owned();
    p.push(".aux.xml");
    PathBuf::from(p)
}

/// The sidecar holding `wkt` as the raster's CRS.
fn text(wkt: &str) -> String {
    format!(
        "<PAMDataset>\n  <SRS>{}</SRS>\n</PAMDataset>\n",
        xml_text(wkt)
    )
}

/// `s` as XML character data: the five special characters escaped, and the control characters
/// XML 1.0 forbids (a WKT record's padding, say) left out.
pub(super) fn xml_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c < ' ' && !matches!(c, '\t' | '\n' | '\r') => {}
            c => out.push(c),
        }
    }
    out
}

/// Writes the sidecar of each of `rasters` holding `wkt` and returns their paths. Without a
/// `wkt`, removes the sidecar an earlier raster of the same name left: GDAL would read its CRS
/// or statistics as the new raster's.
pub(crate) fn write_all(rasters: &[PathBuf], wkt: Option<&str>) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for raster in rasters {
        let path = path_of(raster);
        match wkt {
            Some(wkt) => {
                write_durably(&path, text(wkt).as_bytes())?;
                written.push(path);
            }
            None => match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(Error::write(&path, e));
                }
                _ => {}
            },
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A WKT's quotes, brackets and an ampersand survive as XML text and read back as they
    /// were; the control characters XML cannot hold are dropped.
    #[test]
    fn a_wkt_is_written_as_xml_text() {
        let wkt = "PROJCS[\"A & B <x>\",UNIT[\"foot\",0.3048]]\0";
        let xml = text(wkt);
        assert_eq!(
            xml,
            "<PAMDataset>\n  <SRS>PROJCS[&quot;A &amp; B &lt;x&gt;&quot;,UNIT[&quot;foot&quot;,0.3048]]</SRS>\n</PAMDataset>\n"
        );
        let inner = &xml[xml.find("<SRS>").map_or(0, |i| i + 5)..xml.find("</SRS>").unwrap_or(0)];
        let back = inner
            .replace("&quot;", "\"")
            .replace("&lt;", "<")
            .replace("&gt;", ">")
            .replace("&apos;", "'")
            .replace("&amp;", "&");
        assert_eq!(back, wkt.trim_end_matches('\0'));
    }

    /// Sidecars are written beside each raster, and removed again when the next rasters of the
    /// same names have a CRS the keys hold.
    #[test]
    fn sidecars_are_written_and_stale_ones_removed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let rasters = [dir.path().join("H.tif"), dir.path().join("K.tif")];
        let written = write_all(&rasters, Some("LOCAL_CS[\"x\"]")).expect("written");
        assert_eq!(
            written,
            [
                dir.path().join("H.tif.aux.xml"),
                dir.path().join("K.tif.aux.xml")
            ]
        );
        let got = std::fs::read_to_string(&written[0]).expect("read");
        assert!(got.contains("<SRS>LOCAL_CS[&quot;x&quot;]</SRS>"), "{got}");
        assert!(write_all(&rasters, None).expect("removed").is_empty());
        assert!(written.iter().all(|p| !p.exists()));
    }
}
