//! The header of a LAS 1.0-1.3 input rewritten as LAS 1.4, for outputs that PDAL reads with
//! their extra-bytes columns (it reads the extra-bytes VLR of LAS 1.4 files only, unless told
//! `use_eb_vlr`). The point format and the records stay as they are (formats 0-5 are LAS 1.4
//! formats); only the header changes, as LAS 1.4 R15 section 2.4 requires: 375 bytes, the
//! 64-bit point counts (the legacy ones kept, since the file keeps legacy compatibility), the
//! EVLR fields (set by the writer), and a global encoding whose WKT bit says which CRS record
//! holds the CRS. It does not touch the VLRs, and it does not write the file.

use super::header::LasHeader;
use super::vlr::Vlr;

/// Size of a LAS 1.4 header.
pub const LAS14_HEADER_SIZE: u16 = 375;

/// Global encoding bit 4: the CRS is WKT (LAS 1.4).
const WKT_BIT: u16 = 0x10;

/// The global encoding bits LAS 1.4 defines (GPS time type, waveform internal and external,
/// synthetic return numbers, WKT); the others are reserved and must be zero.
const DEFINED_BITS: u16 = 0x1f;

/// The LAS 1.4 header of a LAS 1.0-1.3 input `h` whose VLRs are `vlrs` (a 1.4 header is
/// returned as it is). Every field up to byte 227 is kept but the version, the header size and
/// the global encoding; the start of the waveform data (LAS 1.3) is kept for the writer to
/// move; bytes the input's header had past its standard fields (an extension that LAS 1.0-1.3
/// allowed) follow the 375 bytes.
pub fn to_las14(h: &LasHeader, vlrs: &[Vlr]) -> LasHeader {
    if h.version.1 >= 4 {
        return h.clone();
    }
    let standard = if h.version.1 == 3 { 235 } else { 227 };
    let mut raw = vec![0u8; LAS14_HEADER_SIZE as usize];
    raw[..227].copy_from_slice(&h.raw[..227]);
    if h.version.1 == 3 {
        raw[227..235].copy_from_slice(&h.raw[227..235]);
    }
    raw.extend_from_slice(&h.raw[standard.min(h.raw.len())..]);
    let header_size = raw.len() as u16;
    raw[25] = 4;
    raw[94..96].copy_from_slice(&header_size.to_le_bytes());
    let global_encoding = global_encoding(h, vlrs);
    raw[6..8].copy_from_slice(&global_encoding.to_le_bytes());
    raw[247..255].copy_from_slice(&h.point_count.to_le_bytes());
    for r in 0..5 {
        let legacy = &h.raw[111 + 4 * r..115 + 4 * r];
        let n = u32::from_le_bytes([legacy[0], legacy[1], legacy[2], legacy[3]]) as u64;
        raw[255 + 8 * r..263 + 8 * r].copy_from_slice(&n.to_le_bytes());
    }
    LasHeader {
        version: (1, 4),
        global_encoding,
        header_size,
        evlr_start: 0,
        evlr_count: 0,
        raw,
        ..h.clone()
    }
}

/// The input's defined global encoding bits, with the WKT bit set exactly when the CRS is a WKT
/// record: LAS 1.4 formats 0-5 use GeoTIFF or WKT as that bit says, not both. A file with
/// GeoTIFF keys keeps them as its CRS (an OGC WKT record beside them, which some LAS 1.2
/// writers add, is kept but not declared); a file with only a WKT record declares it.
fn global_encoding(h: &LasHeader, vlrs: &[Vlr]) -> u16 {
    let geotiff = vlrs.iter().any(|v| v.is("LASF_Projection", 34735));
    let wkt = vlrs.iter().any(|v| v.is("LASF_Projection", 2112));
    let bits = h.global_encoding & DEFINED_BITS & !WKT_BIT;
    if wkt && !geotiff {
        bits | WKT_BIT
    } else {
        bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::las::header::NewHeader;
    use std::path::Path;

    fn las12(points: u64) -> LasHeader {
        let mut raw = NewHeader {
            minor: 2,
            system: "S",
            software: "W",
            point_format: 3,
            record_length: 34,
            points,
            scale: [0.01; 3],
            offset: [1.0, 2.0, 3.0],
            min: [0.0; 3],
            max: [1.0; 3],
        }
        .bytes();
        raw[6] = 0x01; // GPS time is adjusted standard time
        raw[115..119].copy_from_slice(&3u32.to_le_bytes()); // second returns
        LasHeader::parse(Path::new("t.las"), &raw, 1 << 20).expect("header")
    }

    #[test]
    fn las12_becomes_las14_with_both_counts_and_the_fields_kept() {
        let h = las12(10);
        let u = to_las14(&h, &[]);
        // The writer sets the offset to the points; the header is otherwise a valid 1.4 one.
        let mut raw = u.raw.clone();
        raw[96..100].copy_from_slice(&375u32.to_le_bytes());
        let back = LasHeader::parse(Path::new("u.las"), &raw, 1 << 20).expect("parses");
        assert_eq!((back.version, back.header_size), ((1, 4), 375));
        assert_eq!(back.point_count, 10);
        assert_eq!(&u.raw[107..111], &10u32.to_le_bytes(), "legacy count kept");
        assert_eq!(&u.raw[255..263], &10u64.to_le_bytes(), "first returns");
        assert_eq!(&u.raw[263..271], &3u64.to_le_bytes(), "second returns");
        assert_eq!(&u.raw[26..94], &h.raw[26..94], "ids, software, dates");
        assert_eq!(&u.raw[100..227], &h.raw[100..227], "layout, scales, bounds");
        assert_eq!(
            (back.scale, back.offset, back.min, back.max),
            (h.scale, h.offset, h.min, h.max)
        );
        assert_eq!(back.global_encoding, 0x01);
    }

    #[test]
    fn the_wkt_bit_says_which_crs_record_is_the_crs() {
        let h = las12(1);
        let geotiff = Vlr::new("LASF_Projection", 34735, "", vec![1, 0, 1, 0, 0, 0, 0, 0]);
        let wkt = Vlr::new("LASF_Projection", 2112, "", b"PROJCS[]".to_vec());
        let bit = |vlrs: &[Vlr]| to_las14(&h, vlrs).global_encoding & WKT_BIT != 0;
        assert!(!bit(&[]));
        assert!(!bit(std::slice::from_ref(&geotiff)));
        assert!(bit(std::slice::from_ref(&wkt)));
        assert!(!bit(&[geotiff, wkt]));
    }
}
