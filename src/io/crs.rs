//! The horizontal length unit of a file's CRS (projected or geocentric), from its OGC WKT VLR or
//! its GeoTIFF keys, so that `--tile 50m` means 50 metres in a file stored in feet, or why there
//! is none (no CRS, a geographic CRS). Pure: works on VLR payloads.

use crate::io::las::vlr::Vlr;

/// A horizontal length unit: its name and its size in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct LengthUnit {
    /// Name as the CRS spells it (or a canonical name for GeoTIFF codes).
    pub name: String,
    /// Metres per unit.
    pub metres: f64,
}

impl LengthUnit {
    /// The metre.
    pub fn metre() -> Self {
        LengthUnit {
            name: "metre".into(),
            metres: 1.0,
        }
    }

    /// A short symbol for messages and column descriptions ("m", "ft", "ftUS" or the name).
    pub fn symbol(&self) -> String {
        if (self.metres - 1.0).abs() < 1e-12 {
            "m".into()
        } else if (self.metres - 0.3048).abs() < 1e-12 {
            "ft".into()
        } else if (self.metres - 1200.0 / 3937.0).abs() < 1e-12 {
            "ftUS".into()
        } else {
            self.name.clone()
        }
    }
}

/// Where the unit came from, for the log.
#[derive(Debug, Clone, PartialEq)]
pub enum UnitSource {
    /// From the OGC WKT VLR.
    Wkt(LengthUnit),
    /// From the GeoTIFF key directory.
    GeoTiff(LengthUnit),
    /// The file has no usable CRS: lengths are in file units.
    Unknown(String),
}

impl UnitSource {
    /// The unit, if known.
    pub fn unit(&self) -> Option<&LengthUnit> {
        match self {
            UnitSource::Wkt(u) | UnitSource::GeoTiff(u) => Some(u),
            UnitSource::Unknown(_) => None,
        }
    }
}

/// Determines the horizontal unit from a file's VLRs (and EVLRs, where LAS 1.4 may keep the WKT).
/// A WKT without a linear unit gives way to GeoTIFF keys; without them its reason is kept.
pub fn horizontal_unit<'a>(records: impl IntoIterator<Item = &'a Vlr>) -> UnitSource {
    let records: Vec<&Vlr> = records.into_iter().collect();
    let mut wkt_reason = None;
    if let Some(v) = records.iter().find(|v| v.is("LASF_Projection", 2112)) {
        let text = String::from_utf8_lossy(&v.data);
        match wkt_crs_unit(&text) {
            Ok(u) => return UnitSource::Wkt(u),
            Err(why) => wkt_reason = Some(why),
        }
    }
    if let Some(v) = records.iter().find(|v| v.is("LASF_Projection", 34735)) {
        let doubles = records
            .iter()
            .find(|v| v.is("LASF_Projection", 34736))
            .map(|v| v.data.as_slice());
        match geotiff_unit(&v.data, doubles) {
            Ok(u) => return UnitSource::GeoTiff(u),
            Err(why) => return UnitSource::Unknown(why),
        }
    }
    UnitSource::Unknown(
        wkt_reason.unwrap_or_else(|| "the file has no CRS, no WKT or GeoTIFF VLR".into()),
    )
}

/// The horizontal unit of the CRS in an OGC WKT (1 or 2) string: the linear unit of a projected
/// CRS ([`wkt_unit`]) or of a geocentric one (WKT1 `GEOCCS`, WKT2 `GEODCRS` with a Cartesian
/// coordinate system: x, y, z in that unit, usually metres). Otherwise the reason, for the
/// message: a geographic CRS has angles, not lengths.
pub fn wkt_crs_unit(wkt: &str) -> Result<LengthUnit, String> {
    if let Some(u) = wkt_unit(wkt) {
        return Ok(u);
    }
    let wkt = without_spaces(wkt);
    let upper = wkt.to_ascii_uppercase();
    let geocentric = ["GEOCCS[", "GEOCENTRICCRS["]
        .iter()
        .chain(
            ["GEODCRS[", "GEODETICCRS["]
                .iter()
                .filter(|_| upper.contains("CS[CARTESIAN")),
        )
        .find_map(|k| upper.find(k).map(|p| (p, k.len())));
    if let Some((p, _)) = geocentric {
        return crs_unit(&wkt, p).ok_or_else(|| {
            "the WKT CRS is geocentric but names no linear unit tilecurv can read".into()
        });
    }
    let geographic = [
        "GEOGCS[",
        "GEOGCRS[",
        "GEOGRAPHICCRS[",
        "GEODCRS[",
        "GEODETICCRS[",
    ];
    if geographic.iter().any(|k| upper.contains(k)) {
        return Err(
            "the CRS is geographic (longitude and latitude in angles), which has no length unit"
                .into(),
        );
    }
    Err("the WKT CRS is neither projected, geocentric nor geographic, or names no linear unit tilecurv can read".into())
}

/// Finds the end of the bracketed group that opens at `open` (the index of '[' or '(').
fn group_end(s: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0usize;
    let mut in_str = false;
    for (i, &c) in s.iter().enumerate().skip(open) {
        match c {
            b'"' => in_str = !in_str,
            b'[' | b'(' if !in_str => depth += 1,
            b']' | b')' if !in_str => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The linear unit of the projected CRS in an OGC WKT (1 or 2) string.
pub fn wkt_unit(wkt: &str) -> Option<LengthUnit> {
    let wkt = without_spaces(wkt);
    let upper = wkt.to_ascii_uppercase();
    let start = ["PROJCRS[", "PROJCS[", "PROJECTEDCRS["]
        .iter()
        .filter_map(|k| upper.find(k))
        .min()?;
    crs_unit(&wkt, start)
}

/// `wkt` without the whitespace outside quoted names: writers put spaces anywhere ("UNIT [").
pub(crate) fn without_spaces(wkt: &str) -> String {
    let mut in_str = false;
    wkt.chars()
        .filter(|&c| {
            if c == '"' {
                in_str = !in_str;
            }
            in_str || !c.is_whitespace()
        })
        .collect()
}

/// The first linear unit inside the CRS group of `wkt` (passed through [`without_spaces`])
/// that opens at byte `start`, outside the subtrees whose units are not the CRS axes' (base
/// CRS, conversion parameters, prime meridian, vertical CRS).
pub(crate) fn crs_unit(wkt: &str, start: usize) -> Option<LengthUnit> {
    let upper = wkt.to_ascii_uppercase();
    let bytes = upper.as_bytes();
    let open = start + upper[start..].find('[')?;
    let end = group_end(bytes, open)?;
    // Blank out the subtrees whose units are not the projected axes' (geographic base CRS, the
    // WKT2 conversion parameters).
    let mut body: Vec<u8> = bytes[open + 1..end].to_vec();
    let mut orig: Vec<u8> = wkt.as_bytes()[open + 1..end].to_vec();
    for key in [
        "GEOGCS[",
        "BASEGEOGCRS[",
        "BASEGEODCRS[",
        "GEOGCRS[",
        "CONVERSION[",
        "VERT_CS[",
        "VERTCRS[",
        "PRIMEM[",
    ] {
        while let Some(p) = find(&body, key.as_bytes()) {
            let o = p + key.len() - 1;
            let e = group_end(&body, o)?;
            for i in p..=e {
                body[i] = b' ';
                orig[i] = b' ';
            }
        }
    }
    let p = ["LENGTHUNIT[", "UNIT["]
        .iter()
        .filter_map(|k| find(&body, k.as_bytes()).map(|p| (p, k.len())))
        .min()?;
    let inner_start = p.0 + p.1;
    let inner_end = group_end(&body, inner_start - 1)?;
    let inner = String::from_utf8_lossy(&orig[inner_start..inner_end]).into_owned();
    let mut parts = inner.splitn(3, ',');
    let name = parts.next()?.trim().trim_matches('"').to_string();
    let metres: f64 = parts.next()?.trim().trim_end_matches(']').parse().ok()?;
    (metres.is_finite() && metres > 0.0).then_some(LengthUnit { name, metres })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// A GeoTIFF key directory (GeoKeyDirectoryTag; LAS VLR 34735): the header's version,
/// revision and minor revision, and the keys as (id, location, count, value) entries.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct GeoKeys {
    pub(crate) header: [u16; 3],
    pub(crate) entries: Vec<[u16; 4]>,
}

impl GeoKeys {
    /// The directory stored as little-endian shorts in `data` (a VLR's payload).
    pub(crate) fn parse(data: &[u8]) -> Result<GeoKeys, String> {
        let w: Vec<u16> = data
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        GeoKeys::of_shorts(&w)
    }

    /// The directory whose shorts are `w`: an error when they are fewer than the header or
    /// its key count says.
    pub(crate) fn of_shorts(w: &[u16]) -> Result<GeoKeys, String> {
        let [a, b, c, n, ..] = *w else {
            return Err("the GeoTIFF key directory is shorter than its 8-byte header".into());
        };
        let entries = w
            .get(4..4 + 4 * n as usize)
            .ok_or("the GeoTIFF key directory is shorter than its key count says")?;
        Ok(GeoKeys {
            header: [a, b, c],
            entries: (entries.chunks_exact(4))
                .map(|e| [e[0], e[1], e[2], e[3]])
                .collect(),
        })
    }

    /// The value of key `id` when it is stored in the directory itself (location 0).
    pub(crate) fn value(&self, id: u16) -> Option<u16> {
        self.entries
            .iter()
            .find(|e| e[0] == id && e[1] == 0)
            .map(|e| e[3])
    }
}

/// The linear unit from a GeoTIFF key directory (ProjLinearUnitsGeoKey 3076, or
/// ProjLinearUnitSizeGeoKey 3077 for a user-defined unit).
pub fn geotiff_unit(keys: &[u8], doubles: Option<&[u8]>) -> Result<LengthUnit, String> {
    let keys = GeoKeys::parse(keys)?;
    let mut units = None;
    let mut size = None;
    let mut projected = None;
    for e in &keys.entries {
        match e[0] {
            3076 if e[1] == 0 => units = Some(e[3]),
            3077 if e[1] == 34736 => {
                let d = doubles
                    .ok_or("ProjLinearUnitSizeGeoKey points to a missing GeoDoubleParams VLR")?;
                let o = e[3] as usize * 8;
                let b = d
                    .get(o..o + 8)
                    .ok_or("ProjLinearUnitSizeGeoKey points past the GeoDoubleParams VLR")?;
                size = Some(f64::from_le_bytes(b.try_into().map_err(|_| "bad double")?));
            }
            3072 if e[1] == 0 => projected = Some(e[3]),
            _ => {}
        }
    }
    let named = |name: &str, metres: f64| {
        Ok(LengthUnit {
            name: name.into(),
            metres,
        })
    };
    match units {
        Some(9001) => named("metre", 1.0),
        Some(9002) => named("foot", 0.3048),
        Some(9003) => named("US survey foot", 1200.0 / 3937.0),
        Some(9005) => named("Clarke's foot", 0.3047972654),
        Some(9014) => named("fathom", 1.8288),
        Some(9036) => named("kilometre", 1000.0),
        Some(32767) | None if size.is_some_and(|s| s > 0.0) => named("user-defined", size.unwrap_or(1.0)),
        Some(code) => Err(format!("the GeoTIFF linear unit code {code} is not one tilecurv knows")),
        None => match projected {
            Some(code) => projected_unit(code).ok_or_else(|| format!("the GeoTIFF keys name EPSG:{code} but no linear unit, and tilecurv does not know that code's unit")),
            None => Err("the GeoTIFF keys define no projected CRS (geographic coordinates have no length unit)".into()),
        },
    }
}

/// The unit of common projected EPSG codes whose GeoTIFF keys often omit the unit key: the UTM
/// zones (WGS 84, NAD83, ETRS89) are in metres.
fn projected_unit(code: u16) -> Option<LengthUnit> {
    let metre =
        matches!(code, 32601..=32660 | 32701..=32760 | 26901..=26923 | 25828..=25838 | 3005 | 2949);
    metre.then(LengthUnit::metre)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wkt1_projected_foot_not_geographic_degree() {
        let wkt = r#"PROJCS["NAD83 / Oregon GIC Lambert (ft)",GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101]],UNIT["degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["foot",0.3048,AUTHORITY["EPSG","9002"]]]"#;
        let u = wkt_unit(wkt).expect("unit");
        assert_eq!(u.metres, 0.3048);
        assert_eq!(u.symbol(), "ft");
    }

    #[test]
    fn wkt1_with_spaces_inside_compound_crs() {
        // As written by a Leica pipeline (las14_pdrf6.laz).
        let wkt = r#"COMPD_CS["Projected", PROJCS["UTM_10N", GEOGCS [ "WGS84", DATUM [ "WGS84", SPHEROID ["WGS 84", 6378137.000, 298.257223563 ] ], UNIT [ "degree", 0.0174532925] ], PROJECTION["Transverse_Mercator"], UNIT [ "US survey foot", 0.30480060960]] ], VERT_CS["NAVD88", UNIT [ "metres", 1.00000000] ] ]"#;
        let u = wkt_unit(wkt).expect("unit");
        assert_eq!(
            (u.name.as_str(), u.metres),
            ("US survey foot", 0.3048006096)
        );
    }

    #[test]
    fn wkt2_unit_from_axes_not_conversion() {
        let wkt = r#"PROJCRS["x",BASEGEOGCRS["g",ANGLEUNIT["degree",0.01745]],CONVERSION["c",PARAMETER["False easting",0,LENGTHUNIT["metre",1]]],CS[Cartesian,2],AXIS["E",east,LENGTHUNIT["US survey foot",0.304800609601219]]]"#;
        let u = wkt_unit(wkt).expect("unit");
        assert!((u.metres - 0.304800609601219).abs() < 1e-15);
    }

    #[test]
    fn geocentric_wkt_has_metres_and_geographic_has_no_length_unit() {
        let geoccs = r#"GEOCCS["WGS 84",DATUM["World Geodetic System 1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Geocentric X",OTHER],AXIS["Geocentric Y",OTHER],AXIS["Geocentric Z",NORTH],AUTHORITY["EPSG","4978"]]"#;
        assert_eq!(wkt_crs_unit(geoccs).expect("metres").symbol(), "m");
        let wkt2 = r#"GEODCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563,LENGTHUNIT["metre",1]]],PRIMEM["Greenwich",0,ANGLEUNIT["degree",0.0174532925199433]],CS[Cartesian,3],AXIS["(X)",geocentricX],AXIS["(Y)",geocentricY],AXIS["(Z)",geocentricZ],LENGTHUNIT["metre",1]]"#;
        assert_eq!(wkt_crs_unit(wkt2).expect("metres").metres, 1.0);
        let geog = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
        let why = wkt_crs_unit(geog).expect_err("no length unit");
        assert!(why.contains("geographic"), "{why}");
        let vlr = Vlr::new("LASF_Projection", 2112, "", geog.as_bytes().to_vec());
        match horizontal_unit([&vlr]) {
            UnitSource::Unknown(why) => assert!(why.contains("geographic"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn geotiff_units_key() {
        let mut k = Vec::new();
        for w in [1u16, 1, 0, 2, 3072, 0, 1, 2994, 3076, 0, 1, 9002] {
            k.extend_from_slice(&w.to_le_bytes());
        }
        assert_eq!(geotiff_unit(&k, None).expect("unit").metres, 0.3048);
    }
}
