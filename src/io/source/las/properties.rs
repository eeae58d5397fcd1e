//! The properties of a LAS record as the writers of other formats (PLY) keep them: every
//! standard field of its point format and its scalar extra dimensions, named as laspy names
//! them.

use crate::io::las::extra_bytes::{Descriptor, ScalarType};
use crate::io::las::header::{LasHeader, POINT_FORMAT_SIZES};
use crate::io::source::{Property, Stored};

/// The one-bit flags of a LAS record and its scan angle (degrees) and, in formats 6 to 10, its
/// scanner channel ([`las_properties`]).
fn flag_properties(legacy: bool) -> Vec<Property> {
    use ScalarType::*;
    let bit = |at, shift| Stored::Bits {
        at,
        shift,
        width: 1,
    };
    // Legacy formats: direction and edge in byte 14, synthetic, key-point, withheld in the
    // top bits of the classification byte, the angle rank (whole degrees) in byte 16. Formats
    // 6 to 10: the four classification flags, the channel, direction and edge in byte 15, the
    // angle in steps of 0.006 degree at byte 18.
    let (flags, direction, angle) = if legacy {
        (
            vec![
                ("synthetic", bit(15, 5)),
                ("key_point", bit(15, 6)),
                ("withheld", bit(15, 7)),
            ],
            bit(14, 6),
            Property::new("scan_angle_rank", I8, Stored::Le(16)),
        )
    } else {
        let scaled = Stored::Scaled {
            raw: I16,
            at: 18,
            scale: 0.006,
            offset: 0.0,
        };
        (
            vec![
                ("synthetic", bit(15, 0)),
                ("key_point", bit(15, 1)),
                ("withheld", bit(15, 2)),
                ("overlap", bit(15, 3)),
            ],
            bit(15, 6),
            Property::new("scan_angle", F64, scaled),
        )
    };
    let mut v: Vec<Property> = flags
        .into_iter()
        .map(|(name, stored)| Property::new(name, U8, stored))
        .collect();
    if !legacy {
        let channel = Stored::Bits {
            at: 15,
            shift: 4,
            width: 2,
        };
        v.push(Property::new("scanner_channel", U8, channel));
    }
    v.push(Property::new("scan_direction_flag", U8, direction));
    let edge = if legacy { bit(14, 7) } else { bit(15, 7) };
    v.push(Property::new("edge_of_flight_line", U8, edge));
    v.push(angle);
    v
}

/// The properties of a LAS record that a non-LAS writer keeps, named as laspy names them: x,
/// y, z as f64 (scale and offset applied), every standard field of the format (intensity,
/// return numbers, classification and its flags, scan direction and edge of flight line, the
/// scan angle in degrees, user data, point source id, GPS time, RGB, NIR, the wave packet
/// fields), and every scalar extra dimension (as f64 when it has a scale or offset).
pub(super) fn las_properties(h: &LasHeader, extra: &[Descriptor]) -> Vec<Property> {
    use ScalarType::*;
    let mut v: Vec<Property> = (0..3)
        .map(|a| {
            let stored = Stored::Scaled {
                raw: I32,
                at: 4 * a,
                scale: h.scale[a],
                offset: h.offset[a],
            };
            Property::new(["x", "y", "z"][a], F64, stored)
        })
        .collect();
    v.push(Property::new("intensity", U16, Stored::Le(12)));
    let legacy = h.point_format < 6;
    let bits = |at, shift, width| Stored::Bits { at, shift, width };
    let (rn, nr, class) = if legacy {
        (bits(14, 0, 3), bits(14, 3, 3), bits(15, 0, 5))
    } else {
        (bits(14, 0, 4), bits(14, 4, 4), Stored::Le(16))
    };
    v.push(Property::new("return_number", U8, rn));
    v.push(Property::new("number_of_returns", U8, nr));
    v.push(Property::new("classification", U8, class));
    v.extend(flag_properties(legacy));
    let (user, source_id) = if legacy { (17, 18) } else { (17, 20) };
    v.push(Property::new("user_data", U8, Stored::Le(user)));
    v.push(Property::new("point_source_id", U16, Stored::Le(source_id)));
    let gps = match h.point_format {
        1 | 3 | 4 | 5 => Some(20),
        6..=10 => Some(22),
        _ => None,
    };
    if let Some(at) = gps {
        v.push(Property::new("gps_time", F64, Stored::Le(at)));
    }
    let rgb = match h.point_format {
        2 => Some(20),
        3 | 5 => Some(28),
        7 | 8 | 10 => Some(30),
        _ => None,
    };
    if let Some(at) = rgb {
        for (i, c) in ["red", "green", "blue"].into_iter().enumerate() {
            v.push(Property::new(c, U16, Stored::Le(at + 2 * i)));
        }
    }
    if matches!(h.point_format, 8 | 10) {
        v.push(Property::new("nir", U16, Stored::Le(36)));
    }
    let wave = match h.point_format {
        4 => Some(28),
        5 => Some(34),
        9 => Some(30),
        10 => Some(38),
        _ => None,
    };
    if let Some(at) = wave {
        v.push(Property::new("wavepacket_index", U8, Stored::Le(at)));
        v.push(Property::new("wavepacket_offset", U64, Stored::Le(at + 1)));
        v.push(Property::new("wavepacket_size", U32, Stored::Le(at + 9)));
        let floats = ["return_point_wave_location", "x_t", "y_t", "z_t"];
        for (i, name) in floats.into_iter().enumerate() {
            v.push(Property::new(name, F32, Stored::Le(at + 13 + 4 * i)));
        }
    }
    let base = POINT_FORMAT_SIZES[h.point_format as usize] as usize;
    for d in extra {
        let Some(raw) = d.scalar() else { continue };
        let at = base + d.offset;
        if d.scale == 1.0 && d.value_offset == 0.0 {
            v.push(Property::new(d.name.clone(), raw, Stored::Le(at)));
        } else {
            let stored = Stored::Scaled {
                raw,
                at,
                scale: d.scale,
                offset: d.value_offset,
            };
            v.push(Property::new(d.name.clone(), F64, stored));
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::las::header::NewHeader;
    use std::path::Path;

    /// Each format's fields lie within its record and the last one ends it: the sizes of the
    /// LAS 1.4 specification's table 2.6 (20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67 bytes),
    /// which the wave packet fields (4, 5, 9, 10) and NIR (8) reach exactly; no two fields
    /// share a bit.
    #[test]
    fn every_format_s_fields_fill_its_record() {
        for format in 0..=10u8 {
            let size = POINT_FORMAT_SIZES[format as usize];
            let raw = NewHeader {
                minor: 4,
                system: "S",
                software: "W",
                point_format: format,
                record_length: size,
                points: 1,
                scale: [0.01; 3],
                offset: [0.0; 3],
                min: [0.0; 3],
                max: [1.0; 3],
            }
            .bytes();
            let h = LasHeader::parse(Path::new("t.las"), &raw, 1 << 20).expect("header");
            let mut bits = vec![false; 8 * size as usize];
            for p in las_properties(&h, &[]) {
                let (first, count) = match p.stored {
                    Stored::Bits { at, shift, width } => (8 * at + shift as usize, width as usize),
                    Stored::Le(at) => (8 * at, 8 * p.ty.size()),
                    Stored::Scaled { raw, at, .. } => (8 * at, 8 * raw.size()),
                    other => panic!("format {format}: {} stored as {other:?}", p.name),
                };
                let end = first + count;
                assert!(
                    end <= bits.len(),
                    "format {format}: {} ends past the record",
                    p.name
                );
                for b in &mut bits[first..end] {
                    assert!(!*b, "format {format}: {} overlaps another field", p.name);
                    *b = true;
                }
            }
            assert!(
                bits.last() == Some(&true),
                "format {format}: the record's last byte is not read"
            );
        }
    }
}
