//! The CRS of a raster as GeoTIFF keys, from the CRS of the LAS input. GeoTIFF keys in the
//! input are copied as they are (with the raster type set to PixelIsArea, which the raster's
//! tie point assumes); a WKT becomes the EPSG codes it names (the horizontal CRS's, and the
//! vertical CRS's of a compound one). What cannot be expressed is said in
//! [`RasterCrs::warning`]: a WKT without EPSG codes, or no CRS at all.

use crate::io::crs::GeoKeys;
use crate::io::crs_summary::{crs_record, geotiff_name, CrsRecord};
use crate::io::las::vlr::Vlr;
use crate::io::source::{PointSource, SourceLayout};

/// GTModelTypeGeoKey, GTRasterTypeGeoKey, GeographicTypeGeoKey, ProjectedCSTypeGeoKey,
/// VerticalCSTypeGeoKey.
const MODEL_TYPE: u16 = 1024;
const RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC: u16 = 2048;
const PROJECTED: u16 = 3072;
const VERTICAL: u16 = 4096;

/// RasterPixelIsArea: a cell's value covers the cell, and the tie point is its corner.
const PIXEL_IS_AREA: u16 = 1;

/// A raster's CRS, as the three GeoTIFF key tags hold it.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct RasterCrs {
    /// GeoKeyDirectoryTag (34735): the header, then 4 shorts per key, sorted by key id; empty
    /// for no CRS (the tag is then not written).
    pub(crate) directory: Vec<u16>,
    /// GeoDoubleParamsTag (34736), if any key refers to it.
    pub(crate) doubles: Vec<f64>,
    /// GeoAsciiParamsTag (34737), if any key refers to it.
    pub(crate) ascii: String,
    /// What the keys say, for the log: "EPSG:26910 + EPSG:5703 (from the input's WKT)".
    pub(crate) described: String,
    /// What the keys cannot say, if anything, and what to do about it.
    pub(crate) warning: Option<String>,
    /// The input's WKT when the keys cannot hold its CRS (it names no EPSG code): written beside
    /// each raster for GDAL ([`crate::io::raster::sidecar`]).
    pub(crate) wkt: Option<String>,
}

impl RasterCrs {
    /// What the rasters carry, for the log: the keys' CRS, the WKT of the sidecar, or none.
    pub(crate) fn carried(&self) -> String {
        match (&self.wkt, self.directory.is_empty()) {
            (Some(_), _) => format!("{}, in GDAL's sidecar of each raster", self.described),
            (None, true) => "none".into(),
            (None, false) => self.described.clone(),
        }
    }

    /// The value of the key `id` stored in the directory itself, if any.
    fn key(&self, id: u16) -> Option<u16> {
        (self.directory.get(4..)?.chunks_exact(4))
            .find(|e| e[0] == id && e[1] == 0)
            .map(|e| e[3])
    }

    /// Whether the points of a file in `other` are placed on the same map as this CRS's (the
    /// horizontal CRS: a vertical CRS does not move a point on the map). Compared by EPSG code,
    /// so that the keys of one file and the WKT of another naming the same code agree. None
    /// when it cannot be told: either declares no CRS or a WKT without an EPSG code (unless both
    /// have the same WKT), or one is user-defined (its parameters in the keys) and the keys
    /// differ, which two writers may do for one projection.
    pub(crate) fn same_map(&self, other: &RasterCrs) -> Option<bool> {
        if self.wkt.is_some() && self.wkt == other.wkt {
            return Some(true);
        }
        if self.directory.is_empty() || other.directory.is_empty() {
            return None;
        }
        let code = |c: &RasterCrs| match c.key(PROJECTED) {
            Some(p) => Some((PROJECTED, p)),
            None => c.key(GEOGRAPHIC).map(|g| (GEOGRAPHIC, g)),
        };
        match (code(self), code(other)) {
            (Some(a), Some(b)) if a.1 != USER_DEFINED && b.1 != USER_DEFINED => Some(a == b),
            _ => ((&self.directory, &self.doubles) == (&other.directory, &other.doubles))
                .then_some(true),
        }
    }
}

/// The code of a user-defined CRS, datum or unit in GeoTIFF keys.
const USER_DEFINED: u16 = 32767;

/// The raster CRS of a source: its LAS CRS ([`raster_crs`]); none for other formats. Its
/// warning names the file.
pub(crate) fn source_crs(s: &dyn PointSource) -> RasterCrs {
    let mut crs = match s.layout() {
        SourceLayout::Las(p) => {
            let h = p.header;
            let records = p.vlrs.iter().chain(p.evlrs.iter().map(|(_, v)| v));
            raster_crs(records, h.version.1 >= 4 && h.global_encoding & 0x10 != 0)
        }
        SourceLayout::Converted => raster_crs(std::iter::empty(), false),
    };
    if let Some(w) = &mut crs.warning {
        *w = format!("{}: {w}", s.path().display());
    }
    crs
}

/// The raster CRS of a LAS file whose VLRs and EVLRs are `records`. As `crs_summary` chooses:
/// the WKT when LAS 1.4's WKT bit is set, the GeoTIFF keys otherwise, either when there is only
/// one.
pub(crate) fn raster_crs<'a>(
    records: impl IntoIterator<Item = &'a Vlr>,
    wkt_bit: bool,
) -> RasterCrs {
    let records: Vec<&Vlr> = records.into_iter().collect();
    let find = |id| records.iter().find(|v| v.is("LASF_Projection", id));
    match crs_record(&records, wkt_bit) {
        CrsRecord::Keys(keys) => {
            let doubles = find(34736).map(|v| doubles_of(&v.data)).unwrap_or_default();
            let ascii = find(34737)
                .map(|v| ascii_params(&v.data))
                .unwrap_or_default();
            from_keys(GeoKeys::parse(&keys.data), doubles, ascii)
        }
        CrsRecord::Wkt(w) => from_wkt(&w),
        CrsRecord::None => RasterCrs {
            described: "none".into(),
            warning: Some("it has no CRS, so the rasters have none: assign one in the GIS (QGIS: Layer > Set CRS; GDAL: gdal_edit.py -a_srs EPSG:<code>)".into()),
            ..no_keys()
        },
    }
}

/// A LAS file's GeoAsciiParams record as a TIFF ASCII value, which holds ASCII without NULs.
/// The keys address its strings by byte offset and length, so each byte stays in its place:
/// the NULs that pad the record (the LAS specification allows them) are dropped from its end,
/// a NUL inside it, which ends a string as `|` does, becomes `|`, and a byte outside ASCII
/// (a citation's "å" in Latin-1) becomes `?`. The value ends with `|`, as GeoTIFF's strings do.
fn ascii_params(data: &[u8]) -> String {
    let end = data.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let mut s: String = data[..end]
        .iter()
        .map(|&b| match b {
            0 => '|',
            b if b.is_ascii() => char::from(b),
            _ => '?',
        })
        .collect();
    if !s.is_empty() && !s.ends_with('|') {
        s.push('|');
    }
    s
}

/// No key directory at all: GDAL reads such a raster as having no CRS, so that a GIS asks for
/// one. (A directory of a user-defined model type alone GDAL reads as `LOCAL_CS["unnamed"]`,
/// which a GIS takes as set; and without a model type, as the same. The raster type left out
/// is PixelIsArea, GeoTIFF's default.)
fn no_keys() -> RasterCrs {
    RasterCrs {
        directory: Vec::new(),
        ..RasterCrs::default()
    }
}

/// A key directory holding `keys` (id, value), each stored in the directory itself.
fn directory(keys: &[(u16, u16)]) -> Vec<u16> {
    let mut d = vec![1, 1, 0, keys.len() as u16];
    for &(id, v) in keys {
        d.extend_from_slice(&[id, 0, 1, v]);
    }
    d
}

/// The input's own key directory (as [`GeoKeys::parse`] read it) with its raster type set to
/// PixelIsArea.
fn from_keys(keys: Result<GeoKeys, String>, doubles: Vec<f64>, ascii: String) -> RasterCrs {
    let Ok(mut keys) = keys else {
        return RasterCrs {
            described: "none".into(),
            warning: Some("its GeoTIFF key directory is cut short, so the rasters have no CRS: assign one in the GIS (QGIS: Layer > Set CRS; GDAL: gdal_edit.py -a_srs EPSG:<code>)".into()),
            ..no_keys()
        };
    };
    keys.entries.retain(|e| e[0] != RASTER_TYPE);
    keys.entries.push([RASTER_TYPE, 0, 1, PIXEL_IS_AREA]);
    keys.entries.sort_by_key(|e| e[0]);
    let mut directory = keys.header.to_vec();
    directory.push(keys.entries.len() as u16);
    keys.entries
        .iter()
        .for_each(|e| directory.extend_from_slice(e));
    let name = geotiff_name(&keys).unwrap_or_else(|| "user-defined".into());
    RasterCrs {
        directory,
        doubles,
        ascii,
        described: format!("{name}, from the input's GeoTIFF keys"),
        ..RasterCrs::default()
    }
}

/// Keys naming the EPSG codes of a WKT's horizontal (and vertical) CRS; the WKT itself, for
/// the sidecar, when it names no horizontal code.
fn from_wkt(wkt: &str) -> RasterCrs {
    let (tree, whole) = match parse(wkt) {
        Some((tree, whole)) => (Some(tree), whole),
        None => (None, Err("is not well-formed".into())),
    };
    let (horizontal, vertical) = match &tree {
        Some(n) if is(n, &["COMPD_CS", "COMPOUNDCRS"]) => (
            n.children.iter().find(|c| horizontal_kind(c).is_some()),
            n.children
                .iter()
                .find(|c| is(c, &["VERT_CS", "VERTCRS", "VERTICALCRS"])),
        ),
        Some(n) => (Some(n), None),
        None => (None, None),
    };
    let h = horizontal.and_then(|n| Some((horizontal_kind(n)?, epsg(n)?)));
    let v = vertical.and_then(epsg);
    let Some((kind, code)) = h else {
        return without_code(wkt, whole, name_of(horizontal.or(tree.as_ref())));
    };
    let mut keys = vec![
        (MODEL_TYPE, kind.0),
        (RASTER_TYPE, PIXEL_IS_AREA),
        (kind.1, code),
    ];
    keys.extend(v.map(|v| (VERTICAL, v)));
    let described = match v {
        Some(v) => format!("EPSG:{code} + EPSG:{v} (from the input's WKT)"),
        None => format!("EPSG:{code} (from the input's WKT)"),
    };
    RasterCrs {
        directory: directory(&keys),
        described,
        ..RasterCrs::default()
    }
}

/// The model type and the key of a horizontal CRS node: projected or geographic.
fn horizontal_kind(n: &Node) -> Option<(u16, u16)> {
    if is(n, &["PROJCS", "PROJCRS", "PROJECTEDCRS"]) {
        Some((1, PROJECTED))
    } else if is(n, &["GEOGCS", "GEOGCRS", "GEOGRAPHICCRS"]) {
        Some((2, GEOGRAPHIC))
    } else {
        None
    }
}

/// A node of a WKT: its keyword, quoted and bare values, and child nodes.
#[derive(Debug)]
struct Node {
    keyword: String,
    values: Vec<String>,
    children: Vec<Node>,
}

fn is(n: &Node, keywords: &[&str]) -> bool {
    keywords.iter().any(|k| n.keyword.eq_ignore_ascii_case(k))
}

/// The EPSG code of a node's own AUTHORITY (WKT 1) or ID (WKT 2), if it fits a GeoTIFF key.
fn epsg(n: &Node) -> Option<u16> {
    n.children
        .iter()
        .filter(|c| is(c, &["AUTHORITY", "ID"]))
        .find(|c| {
            c.values
                .first()
                .is_some_and(|a| a.eq_ignore_ascii_case("EPSG"))
        })
        .and_then(|c| c.values.get(1)?.trim().parse().ok())
}

/// The CRS of a WKT that names no EPSG code for its horizontal CRS (`name`): no keys, and the
/// WKT for GDAL's sidecar when it is `whole` (else what is wrong with it). A WKT whose brackets
/// close before its end (the root node ends early: las14_pdrf6's vertical CRS is outside it)
/// is one GDAL refuses too.
fn without_code(wkt: &str, whole: Result<(), String>, name: String) -> RasterCrs {
    let gis =
        "assign it in the GIS (QGIS: Layer > Set CRS; GDAL: gdal_edit.py -a_srs with the CRS)";
    let (warning, wkt) = match whole {
        Ok(()) => (format!("its WKT CRS ({name}) names no EPSG code, which GeoTIFF keys need: each raster's CRS is that WKT in GDAL's sidecar file beside it (NAME.tif.aux.xml beside NAME.tif), which GDAL (QGIS, rasterio, R terra) and ArcGIS read; a program that reads only GeoTIFF keys sees no CRS"), Some(wkt.to_string())),
        Err(why) => (format!("its WKT CRS ({name}) names no EPSG code, which GeoTIFF keys need, and {why}, so GDAL cannot read it either: the rasters have no CRS; {gis}"), None),
    };
    RasterCrs {
        described: format!("{name} (the input's WKT, which names no EPSG code)"),
        warning: Some(warning),
        wkt,
        ..no_keys()
    }
}

/// A node's name (its first quoted value), for messages.
fn name_of(n: Option<&Node>) -> String {
    n.and_then(|n| n.values.first().cloned())
        .unwrap_or_else(|| "unnamed".into())
}

/// Parses a WKT into its tree, with whether the tree is the whole text (else where it ends,
/// for a message); None when it is not a WKT.
fn parse(wkt: &str) -> Option<(Node, Result<(), String>)> {
    let chars: Vec<char> = wkt.chars().collect();
    let mut at = 0;
    let tree = node(&chars, &mut at)?;
    skip_spaces(&chars, &mut at);
    let whole = match at == chars.len() {
        true => Ok(()),
        false => Err(format!(
            "its brackets close at character {} of {}, before its end",
            at,
            chars.len()
        )),
    };
    Some((tree, whole))
}

fn skip_spaces(c: &[char], at: &mut usize) {
    while c.get(*at).is_some_and(|ch| ch.is_whitespace()) {
        *at += 1;
    }
}

/// One node starting at `at` (a keyword, then its bracketed contents).
fn node(c: &[char], at: &mut usize) -> Option<Node> {
    skip_spaces(c, at);
    let start = *at;
    while c
        .get(*at)
        .is_some_and(|ch| ch.is_ascii_alphanumeric() || *ch == '_')
    {
        *at += 1;
    }
    let keyword: String = c[start..*at].iter().collect();
    skip_spaces(c, at);
    if keyword.is_empty() || !matches!(c.get(*at), Some('[') | Some('(')) {
        return None;
    }
    *at += 1;
    let mut n = Node {
        keyword,
        values: Vec::new(),
        children: Vec::new(),
    };
    loop {
        skip_spaces(c, at);
        match c.get(*at)? {
            ']' | ')' => {
                *at += 1;
                return Some(n);
            }
            ',' => *at += 1,
            '"' => n.values.push(quoted(c, at)?),
            ch if ch.is_ascii_alphabetic() => {
                let save = *at;
                match node(c, at) {
                    Some(child) => n.children.push(child),
                    None => {
                        *at = save;
                        n.values.push(bare(c, at));
                    }
                }
            }
            _ => n.values.push(bare(c, at)),
        }
    }
}

/// A quoted string ("" inside is a quote).
fn quoted(c: &[char], at: &mut usize) -> Option<String> {
    *at += 1;
    let mut s = String::new();
    loop {
        match c.get(*at)? {
            '"' if c.get(*at + 1) == Some(&'"') => {
                s.push('"');
                *at += 2;
            }
            '"' => {
                *at += 1;
                return Some(s);
            }
            ch => {
                s.push(*ch);
                *at += 1;
            }
        }
    }
}

/// A bare value: up to the next comma or closing bracket.
fn bare(c: &[char], at: &mut usize) -> String {
    let start = *at;
    while c.get(*at).is_some_and(|ch| !matches!(ch, ',' | ']' | ')')) {
        *at += 1;
    }
    c[start..*at].iter().collect::<String>().trim().to_string()
}

fn doubles_of(b: &[u8]) -> Vec<f64> {
    b.chunks_exact(8)
        .map(|p| f64::from_le_bytes(p.try_into().unwrap_or([0; 8])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const UTM: &str = r#"PROJCS["NAD83 / UTM zone 10N",GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101,AUTHORITY["EPSG","7019"]],AUTHORITY["EPSG","6269"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4269"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AUTHORITY["EPSG","26910"]]"#;

    fn key(c: &RasterCrs, id: u16) -> Option<u16> {
        (c.directory.get(4..).unwrap_or_default())
            .chunks_exact(4)
            .find(|e| e[0] == id)
            .map(|e| e[3])
    }

    /// The real surveys' GeoAsciiParams become values the TIFF writer takes, each string at
    /// the offset and length its key gives (autzen: a padding NUL; a Norwegian survey: Latin-1).
    #[test]
    fn ascii_params_keep_their_offsets_without_nul_or_non_ascii() {
        let autzen = b"NAD_1983_HARN|GCS Name = GCS_NAD83||\x00";
        assert_eq!(ascii_params(autzen), "NAD_1983_HARN|GCS Name = GCS_NAD83||");
        let norway = b"UTM sone 32, basert p\xe5 EUREF89|NN2000|";
        let clean = ascii_params(norway);
        assert_eq!(clean.len(), norway.len());
        assert_eq!(&clean[31..38], "NN2000|");
        assert_eq!(&clean[20..23], "p? ");
        assert_eq!(ascii_params(b"A\x00B\x00\x00"), "A|B|");
        assert_eq!(ascii_params(b"\x00\x00"), "");
        let clean = ascii_params(b"WGS 84");
        assert_eq!(clean, "WGS 84|");
        assert!(clean.is_ascii() && !clean.contains('\0'));
    }

    /// Two CRSs place points on the same map when their horizontal EPSG codes agree, whether
    /// from a WKT or from keys and whatever their vertical CRS; user-defined ones when their
    /// keys and parameters do (else undecided: two writers may spell one projection apart); a
    /// file without a CRS is undecided.
    #[test]
    fn same_map_compares_horizontal_codes() {
        let wkt = from_wkt(UTM);
        let keys = |k: &[(u16, u16)]| RasterCrs {
            directory: directory(k),
            ..RasterCrs::default()
        };
        let same = keys(&[(MODEL_TYPE, 1), (PROJECTED, 26910), (VERTICAL, 5703)]);
        let other = keys(&[(MODEL_TYPE, 1), (PROJECTED, 26911)]);
        assert_eq!(wkt.same_map(&same), Some(true));
        assert_eq!(wkt.same_map(&other), Some(false));
        assert_eq!(wkt.same_map(&no_keys()), None);
        assert_eq!(no_keys().same_map(&no_keys()), None);
        let user = |d: f64| RasterCrs {
            doubles: vec![d],
            ..keys(&[(MODEL_TYPE, 1), (PROJECTED, USER_DEFINED)])
        };
        assert_eq!(user(43.0).same_map(&user(43.0)), Some(true));
        assert_eq!(user(43.0).same_map(&user(44.0)), None);
        assert_eq!(user(43.0).same_map(&wkt), None);
        // WKTs without an EPSG code: the same text is the same map, another one undecided.
        let lcc = |o: f64| {
            from_wkt(&format!(
                r#"PROJCS["lcc",GEOGCS["g",DATUM["d",SPHEROID["GRS 1980",6378137,298.257222101]]],PROJECTION["Lambert_Conformal_Conic_2SP"],PARAMETER["latitude_of_origin",{o}],UNIT["foot",0.3048]]"#
            ))
        };
        assert!(lcc(41.75).wkt.is_some());
        assert_eq!(lcc(41.75).same_map(&lcc(41.75)), Some(true));
        assert_eq!(lcc(41.75).same_map(&lcc(42.0)), None);
        assert_eq!(lcc(41.75).same_map(&no_keys()), None);
    }

    /// A WKT without an EPSG code goes to the sidecar when it is one whole node; one whose
    /// brackets close early (las14_pdrf6's, its vertical CRS outside the root) does not, and
    /// the warning says where it ends.
    #[test]
    fn only_a_whole_wkt_without_a_code_goes_to_the_sidecar() {
        let whole = r#"PROJCS["UTM_10N",GEOGCS["WGS84",DATUM["WGS84",SPHEROID["WGS 84",6378137,298.257223563]]],PROJECTION["Transverse_Mercator"],UNIT["metres",1]]"#;
        let c = from_wkt(whole);
        assert_eq!(c.wkt.as_deref(), Some(whole));
        assert!(c.warning.as_deref().is_some_and(|w| w.contains("aux.xml")));
        let cut = format!(r#"COMPD_CS["P",{whole}],VERT_CS["v",UNIT["metres",1]]]"#);
        let c = from_wkt(&cut);
        assert_eq!(c.wkt, None);
        // `COMPD_CS["P",` (13 characters), the projected CRS, then the `]` that ends the root.
        let at = format!(
            "close at character {} of {}",
            13 + whole.len() + 1,
            cut.len()
        );
        assert!(
            c.warning.as_deref().is_some_and(|w| w.contains(&at)),
            "{:?}",
            c.warning
        );
        assert!(c.described.contains("UTM_10N"), "{}", c.described);
    }

    /// A WKT 1 projected CRS gives its own code, not a nested one (the datum's, the unit's).
    #[test]
    fn a_projected_wkt_gives_its_epsg_code() {
        let c = from_wkt(UTM);
        assert_eq!(key(&c, PROJECTED), Some(26910));
        assert_eq!(key(&c, MODEL_TYPE), Some(1));
        assert_eq!(key(&c, RASTER_TYPE), Some(PIXEL_IS_AREA));
        assert_eq!(c.directory[3] as usize * 4 + 4, c.directory.len());
        assert!(c.warning.is_none());
    }

    /// A compound CRS gives the horizontal and the vertical code; WKT 2 IDs count too.
    #[test]
    fn compound_and_wkt2_crs_give_both_codes() {
        let compound = format!(
            r#"COMPD_CS["NAD83 / UTM 10N + NAVD88",{UTM},VERT_CS["NAVD88 height",VERT_DATUM["North American Vertical Datum 1988",2005],UNIT["metre",1],AUTHORITY["EPSG","5703"]]]"#
        );
        let c = from_wkt(&compound);
        assert_eq!(
            (key(&c, PROJECTED), key(&c, VERTICAL)),
            (Some(26910), Some(5703))
        );
        let wkt2 = r#"GEOGCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563]],CS[ellipsoidal,2],ID["EPSG",4326]]"#;
        let c = from_wkt(wkt2);
        assert_eq!(
            (key(&c, GEOGRAPHIC), key(&c, MODEL_TYPE)),
            (Some(4326), Some(2))
        );
    }

    /// A WKT without a code is said, not guessed; the keys then carry no CRS.
    #[test]
    fn a_wkt_without_a_code_is_a_warning() {
        let c = from_wkt(r#"PROJCS["local grid",UNIT["metre",1]]"#);
        assert!(c
            .warning
            .as_deref()
            .is_some_and(|w| w.contains("local grid")));
        assert_eq!(key(&c, PROJECTED), None);
    }

    /// The input's keys are kept, with the raster type replaced and the keys still sorted.
    #[test]
    fn the_inputs_keys_are_kept_with_pixel_is_area() {
        let keys = [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 2, 3072, 0, 1, 32633];
        let c = from_keys(GeoKeys::of_shorts(&keys), vec![], String::new());
        assert_eq!(
            c.directory,
            vec![1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633]
        );
        let without = [1, 1, 0, 1, 3072, 0, 1, 32633];
        let c = from_keys(GeoKeys::of_shorts(&without), vec![], String::new());
        assert_eq!(
            c.directory,
            vec![1, 1, 0, 2, 1025, 0, 1, 1, 3072, 0, 1, 32633]
        );
        assert!(from_keys(
            GeoKeys::of_shorts(&[1, 1, 0, 9, 3072]),
            vec![],
            String::new()
        )
        .warning
        .is_some());
    }
}
