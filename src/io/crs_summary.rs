//! A file's CRS in words, for `tilecurv info`: its name, where it is stored, its horizontal
//! unit (the one `process` uses, from `crs`) and its vertical unit (a compound WKT's vertical
//! CRS, or GeoTIFF's VerticalUnitsGeoKey). Pure: works on VLR payloads; reads, never converts.

use crate::io::crs::{crs_unit, horizontal_unit, without_spaces, GeoKeys, LengthUnit, UnitSource};
use crate::io::las::vlr::Vlr;

/// What a file says about its CRS.
#[derive(Debug, Clone, PartialEq)]
pub struct CrsSummary {
    /// Where the CRS is stored: "WKT", "GeoTIFF" or "none".
    pub stored_as: &'static str,
    /// The CRS's name (WKT) or EPSG codes (GeoTIFF), if any.
    pub name: Option<String>,
    /// The horizontal unit, or why there is none.
    pub horizontal: UnitSource,
    /// The vertical unit, or why there is none.
    pub vertical: Result<LengthUnit, String>,
}

/// The CRS summary of a file whose VLRs and EVLRs are `records`. With both a WKT record and
/// GeoTIFF keys, the WKT is the CRS when `wkt_bit` (LAS 1.4's global encoding bit 4) is set,
/// the GeoTIFF keys otherwise (as LAS 1.0-1.3 readers take them).
pub fn crs_summary<'a>(records: impl IntoIterator<Item = &'a Vlr>, wkt_bit: bool) -> CrsSummary {
    let records: Vec<&Vlr> = records.into_iter().collect();
    let horizontal = horizontal_unit(records.iter().copied());
    match crs_record(&records, wkt_bit) {
        CrsRecord::Keys(v) => {
            let k = geo_keys(&v.data);
            CrsSummary {
                stored_as: "GeoTIFF",
                name: geotiff_name(&k),
                horizontal,
                vertical: geotiff_vertical_unit(&k),
            }
        }
        CrsRecord::Wkt(w) => CrsSummary {
            stored_as: "WKT",
            name: wkt_name(&w),
            horizontal,
            vertical: wkt_vertical_unit(&w),
        },
        CrsRecord::None => CrsSummary {
            stored_as: "none",
            name: None,
            horizontal,
            vertical: Err("the file has no CRS".into()),
        },
    }
}

/// The record that holds a LAS file's CRS.
pub(crate) enum CrsRecord<'a> {
    /// The GeoTIFF key directory's VLR (34735).
    Keys(&'a Vlr),
    /// The OGC WKT (VLR 2112), without its trailing NULs.
    Wkt(String),
    /// Neither.
    None,
}

/// Which record is the CRS of a file whose VLRs and EVLRs are `records`: with both a WKT and
/// GeoTIFF keys, the WKT when `wkt_bit` (LAS 1.4's global encoding bit 4) is set, the keys
/// otherwise (as LAS 1.0-1.3 readers take them).
pub(crate) fn crs_record<'a>(records: &[&'a Vlr], wkt_bit: bool) -> CrsRecord<'a> {
    let find = |id| {
        records
            .iter()
            .copied()
            .find(|v| v.is("LASF_Projection", id))
    };
    let wkt = find(2112).map(|v| {
        String::from_utf8_lossy(&v.data)
            .trim_end_matches('\0')
            .to_string()
    });
    match (find(34735), wkt) {
        (Some(keys), w) if !(wkt_bit && w.is_some()) => CrsRecord::Keys(keys),
        (_, Some(w)) => CrsRecord::Wkt(w),
        _ => CrsRecord::None,
    }
}

/// The keys of the directory `data`, none when it is cut short (`info` reports what it can).
fn geo_keys(data: &[u8]) -> GeoKeys {
    GeoKeys::parse(data).unwrap_or_default()
}

/// The name of the outermost CRS of a WKT: its first quoted string.
fn wkt_name(wkt: &str) -> Option<String> {
    let a = wkt.find('"')?;
    let b = a + 1 + wkt[a + 1..].find('"')?;
    Some(wkt[a + 1..b].to_string())
}

/// What a file says about its vertical unit, read from the record the horizontal unit came
/// from ([`horizontal_unit`]'s choice: the WKT, else the GeoTIFF keys).
#[derive(Debug, Clone, PartialEq)]
pub enum VerticalUnit {
    /// A vertical CRS with a unit tilecurv reads.
    Declared(LengthUnit),
    /// No vertical CRS at all (the common case): z is taken in the horizontal unit.
    Undeclared(String),
    /// A vertical CRS is declared but its unit cannot be read: z is taken in the horizontal
    /// unit, with a warning.
    Unreadable(String),
}

/// The vertical unit of a file whose VLRs and EVLRs are `records`, so that heights in another
/// unit than x and y are converted before any geometry.
pub fn vertical_unit<'a>(records: impl IntoIterator<Item = &'a Vlr>) -> VerticalUnit {
    let records: Vec<&Vlr> = records.into_iter().collect();
    let wkt = records
        .iter()
        .find(|v| v.is("LASF_Projection", 2112))
        .map(|v| String::from_utf8_lossy(&v.data).into_owned());
    let from_wkt = matches!(horizontal_unit(records.iter().copied()), UnitSource::Wkt(_));
    if let Some(w) = wkt.filter(|_| from_wkt) {
        return match wkt_vertical_unit(&w) {
            Ok(u) => VerticalUnit::Declared(u),
            Err(why) if why.contains("no vertical CRS") => VerticalUnit::Undeclared(why),
            Err(why) => VerticalUnit::Unreadable(why),
        };
    }
    let Some(v) = records.iter().find(|v| v.is("LASF_Projection", 34735)) else {
        return VerticalUnit::Undeclared("the file has no CRS".into());
    };
    let keys = geo_keys(&v.data);
    match geotiff_vertical_unit(&keys) {
        Ok(u) => VerticalUnit::Declared(u),
        Err(why) if keys.value(4099).is_some() => VerticalUnit::Unreadable(why),
        Err(_) => match keys.value(4096) {
            Some(code) => VerticalUnit::Unreadable(format!(
                "the GeoTIFF keys name the vertical CRS EPSG:{code} but no VerticalUnitsGeoKey"
            )),
            None => VerticalUnit::Undeclared("the GeoTIFF keys declare no vertical CRS".into()),
        },
    }
}

/// The unit of the vertical CRS of a (compound) WKT.
pub fn wkt_vertical_unit(wkt: &str) -> Result<LengthUnit, String> {
    let wkt = without_spaces(wkt);
    let upper = wkt.to_ascii_uppercase();
    let Some(p) = ["VERT_CS[", "VERTCRS[", "VERTICALCRS["]
        .iter()
        .filter_map(|k| upper.find(k))
        .min()
    else {
        return Err("the WKT has no vertical CRS (not a compound CRS)".into());
    };
    crs_unit(&wkt, p).ok_or_else(|| "the WKT's vertical CRS names no unit".into())
}

/// The EPSG codes a GeoTIFF directory names: projected (3072) or geographic (2048), and
/// vertical (4096); "user-defined" for GeoTIFF's code 32767.
pub(crate) fn geotiff_name(keys: &GeoKeys) -> Option<String> {
    // 32767 is GeoTIFF's "user-defined": the CRS is in other keys, not an EPSG code.
    let code = |c: u16, user: &str| match c {
        32767 => user.to_string(),
        c => format!("EPSG:{c}"),
    };
    let horizontal = (keys.value(3072))
        .map(|c| code(c, "user-defined"))
        .or_else(|| {
            (keys.value(2048)).map(|c| format!("{} (geographic)", code(c, "user-defined")))
        });
    let vertical = keys
        .value(4096)
        .map(|c| code(c, "user-defined vertical CRS"));
    match (horizontal, vertical) {
        (Some(h), Some(v)) => Some(format!("{h} + {v}")),
        (h, v) => h.or(v),
    }
}

/// The vertical unit of a GeoTIFF directory (VerticalUnitsGeoKey 4099, an EPSG unit code).
fn geotiff_vertical_unit(keys: &GeoKeys) -> Result<LengthUnit, String> {
    let Some(code) = keys.value(4099) else {
        return Err("the GeoTIFF keys have no VerticalUnitsGeoKey".into());
    };
    let (name, metres) = match code {
        9001 => ("metre", 1.0),
        9002 => ("foot", 0.3048),
        9003 => ("US survey foot", 1200.0 / 3937.0),
        9036 => ("kilometre", 1000.0),
        other => {
            return Err(format!(
                "the GeoTIFF vertical unit code {other} is not one tilecurv knows"
            ))
        }
    };
    Ok(LengthUnit {
        name: name.into(),
        metres,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compound_wkt_has_a_vertical_unit() {
        let wkt = r#"COMPD_CS["NAD83 + NAVD88 height (ftUS)",PROJCS["NAD83 / UTM 10N",GEOGCS["NAD83",DATUM["D",SPHEROID["GRS 1980",6378137,298.257222101]],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],UNIT["metre",1]],VERT_CS["NAVD88 height (ftUS)",VERT_DATUM["North American Vertical Datum 1988",2005],UNIT["US survey foot",0.304800609601219]]]"#;
        let v = Vlr::new("LASF_Projection", 2112, "", wkt.as_bytes().to_vec());
        let s = crs_summary([&v], false);
        assert_eq!(s.name.as_deref(), Some("NAD83 + NAVD88 height (ftUS)"));
        assert_eq!(s.horizontal.unit().map(|u| u.symbol()), Some("m".into()));
        assert_eq!(s.vertical.expect("vertical").symbol(), "ftUS");
    }

    #[test]
    fn geotiff_codes_and_vertical_units() {
        let mut k = Vec::new();
        for w in [
            1u16, 1, 0, 3, 3072, 0, 1, 26910, 4096, 0, 1, 5703, 4099, 0, 1, 9003,
        ] {
            k.extend_from_slice(&w.to_le_bytes());
        }
        let v = Vlr::new("LASF_Projection", 34735, "", k);
        let s = crs_summary([&v], false);
        assert_eq!(s.stored_as, "GeoTIFF");
        assert_eq!(s.name.as_deref(), Some("EPSG:26910 + EPSG:5703"));
        assert_eq!(s.vertical.expect("vertical").symbol(), "ftUS");
    }

    /// GeoTIFF's code 32767 is a user-defined CRS (its parameters in other keys), which no EPSG
    /// code names: autzen_trim.las's projection.
    #[test]
    fn a_user_defined_code_is_named_so() {
        let mut k = Vec::new();
        for w in [1u16, 1, 0, 2, 3072, 0, 1, 32767, 4096, 0, 1, 32767] {
            k.extend_from_slice(&w.to_le_bytes());
        }
        let v = Vlr::new("LASF_Projection", 34735, "", k);
        let s = crs_summary([&v], false);
        assert_eq!(
            s.name.as_deref(),
            Some("user-defined + user-defined vertical CRS")
        );
    }
}
