//! How the new columns are stored in an output (float noise does not compress; scaled integers on a
//! step a little below the estimator's error do). By default a LAS/LAZ output stores scaled
//! integers through the scale and offset fields of the extra-bytes descriptors, which laspy and
//! PDAL apply when reading:
//!
//! - unit vectors (normals, principal directions, the VCM normal) as i16 at 1/32767, and
//!   other bounded values (the VCM's sharp-feature score, at most 1/2) as i16 at
//!   bound/32767: an error of at most bound/65534 (1.5e-5 for a unit vector's component);
//! - H, K, and k1 with k2 (one step for both) as i32 at a power-of-two step chosen from the
//!   values of every point of the run (core::quantize): at most 1/4096 of the 99th percentile
//!   of |value|, so an error of at most 1.2e-4 of that percentile, and coarser only when the
//!   largest |value| would otherwise exceed 2^30 steps;
//! - the flags as u8.
//!
//! An undefined value (NaN) is the type's minimum (-32768, -2^31), declared as the column's
//! no-data value; a finite value never is (values are clamped to the type's range less its
//! minimum). `--f32` and `--f64` store floats (NaN where undefined, nothing declared), as a PLY
//! output, which has no scale field, always does.

use crate::core::compute::PointResult;
use crate::core::quantize::CurvatureStats;
use crate::io::columns::{Column, ColumnSet, ColumnType, TerrainValue, Value};
use crate::io::las::extra_bytes::{NewColumn, ScalarType};

/// The steps of the scaled curvature columns of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steps {
    /// Of H.
    pub h: f64,
    /// Of K.
    pub k: f64,
    /// Of k1 and k2.
    pub principal: f64,
}

impl Steps {
    /// The steps for the values counted in `stats` (core::quantize).
    pub fn from_stats(stats: &CurvatureStats) -> Self {
        Steps {
            h: stats.h.step(),
            k: stats.k.step(),
            principal: stats.principal.step(),
        }
    }
}

/// How an output stores the new columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Encoding {
    /// Scaled integers, the curvatures at these steps.
    Scaled(Steps),
    /// 32-bit floats.
    F32,
    /// 64-bit floats.
    F64,
}

impl Encoding {
    /// The encoding of `ty` with the run's curvature `steps`.
    pub fn new(ty: ColumnType, steps: Steps) -> Self {
        match ty {
            ColumnType::Scaled => Encoding::Scaled(steps),
            ColumnType::F32 => Encoding::F32,
            ColumnType::F64 => Encoding::F64,
        }
    }

    /// This encoding for a format without scaled columns (PLY): floats, f32 for scaled.
    pub fn floats(self) -> Self {
        match self {
            Encoding::Scaled(_) => Encoding::F32,
            other => other,
        }
    }
}

/// How one column is stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Storage {
    /// A float of this type (F32 or F64), NaN where undefined.
    Float(ScalarType),
    /// An unsigned integer of this type (U8 or U16): the flags, the chosen scale.
    Unsigned(ScalarType),
    /// An integer of this type (I16 or I32) times `scale`; its minimum where undefined.
    Scaled(ScalarType, f64),
}

impl Storage {
    /// Writes `v` as this storage says at the start of `out` (little-endian; at least
    /// [`Storage::size`] bytes); returns the bytes written. Inlined, so that a caller's loop
    /// over one storage compiles to its arm alone ([`super::Transcoder::encode_all`]).
    #[inline(always)]
    pub(super) fn put(self, v: f64, out: &mut [u8]) -> usize {
        fn write<const N: usize>(out: &mut [u8], b: [u8; N]) -> usize {
            out[..N].copy_from_slice(&b);
            N
        }
        match self {
            Storage::Float(ScalarType::F64) => write(out, v.to_le_bytes()),
            Storage::Float(_) => write(out, (v as f32).to_le_bytes()),
            Storage::Unsigned(ScalarType::U8) => write(out, [v as u8]),
            Storage::Unsigned(_) => write(out, (v as u16).to_le_bytes()),
            Storage::Scaled(ty, scale) => {
                let raw = scaled_raw(v, scale, ty);
                match ty {
                    ScalarType::I16 => write(out, (raw as i16).to_le_bytes()),
                    _ => write(out, raw.to_le_bytes()),
                }
            }
        }
    }

    /// Bytes of one value.
    pub(super) fn size(self) -> usize {
        match self {
            Storage::Float(ty) | Storage::Unsigned(ty) | Storage::Scaled(ty, _) => ty.size(),
        }
    }
}

/// The integer of scaled type `ty` that holds `v` at `scale`: the nearest step, clamped to
/// +-[`max_raw`]; [`no_data`] where `v` is NaN. Without branches on `v`, so that a loop over
/// values compiles to vector instructions.
#[inline(always)]
pub(super) fn scaled_raw(v: f64, scale: f64, ty: ScalarType) -> i32 {
    let m = max_raw(ty);
    let raw = (v / scale).round().clamp(-m, m);
    let raw = if v.is_nan() { no_data(ty) } else { raw };
    // An integer of at most 2^31 in magnitude plus 1.5 * 2^52 is exact, and its low 32 bits
    // are the integer's two's complement: the conversion without the checks of `as i32`
    // (which saturates and maps NaN to 0: neither can happen here), which do not vectorise.
    (raw + 6_755_399_441_055_744.0).to_bits() as u32 as i32
}

/// The largest |raw| of a scaled type: its maximum (its minimum is the no-data value).
fn max_raw(ty: ScalarType) -> f64 {
    match ty {
        ScalarType::I16 => i16::MAX as f64,
        _ => i32::MAX as f64,
    }
}

/// The no-data raw value of a scaled type: its minimum.
fn no_data(ty: ScalarType) -> f64 {
    -max_raw(ty) - 1.0
}

/// The new columns of an output with their storage.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputColumns {
    pub(super) columns: Vec<(Column, Storage)>,
    /// Bytes per point.
    size: usize,
}

impl OutputColumns {
    /// The columns of `set` stored as `encoding` says.
    pub fn new(set: &ColumnSet, encoding: Encoding) -> Self {
        let storage = |c: &Column| match (c.value, encoding) {
            (Value::Flags | Value::ScaleFlags, _) => Storage::Unsigned(ScalarType::U8),
            (Value::Terrain(TerrainValue::Flags), _) => Storage::Unsigned(ScalarType::U8),
            (Value::ScaleK, _) => Storage::Unsigned(ScalarType::U16),
            (_, Encoding::F32) => Storage::Float(ScalarType::F32),
            (_, Encoding::F64) => Storage::Float(ScalarType::F64),
            (v, Encoding::Scaled(s)) => match v {
                Value::H => Storage::Scaled(ScalarType::I32, s.h),
                Value::K => Storage::Scaled(ScalarType::I32, s.k),
                Value::K1 | Value::K2 => Storage::Scaled(ScalarType::I32, s.principal),
                // Normal curvatures and curvedness lie within max(|k1|, |k2|): k1's step suits
                // them. Plan curvature is tangential / sin(slope), up to 573 times larger at the
                // flat threshold, the one value that may reach the i32's clamp.
                Value::Terrain(
                    TerrainValue::Profile
                    | TerrainValue::Tangential
                    | TerrainValue::Plan
                    | TerrainValue::Curvedness,
                ) => Storage::Scaled(ScalarType::I32, s.principal),
                Value::Terrain(TerrainValue::Slope) => {
                    Storage::Scaled(ScalarType::I16, 90.0 / i16::MAX as f64)
                }
                Value::Terrain(TerrainValue::Aspect) => {
                    Storage::Scaled(ScalarType::I16, 360.0 / i16::MAX as f64)
                }
                Value::Extra(i) => {
                    let bound = set.extra.get(i).map(|e| e.bound).unwrap_or(1.0);
                    Storage::Scaled(ScalarType::I16, bound / i16::MAX as f64)
                }
                _ => Storage::Scaled(ScalarType::I16, 1.0 / i16::MAX as f64),
            },
        };
        let columns: Vec<(Column, Storage)> = (set.columns().into_iter())
            .map(|c| {
                let s = storage(&c);
                (c, s)
            })
            .collect();
        let size = columns.iter().map(|(_, s)| s.size()).sum();
        OutputColumns { columns, size }
    }

    /// The extra-bytes descriptors of the columns, in record order (a scaled column with its
    /// scale, offset 0 and no-data value).
    pub fn descriptors(&self) -> Vec<NewColumn> {
        self.columns
            .iter()
            .map(|(c, s)| {
                let plain = |ty| NewColumn::plain(c.name, ty, c.description.clone());
                match *s {
                    Storage::Float(ty) => plain(ty),
                    Storage::Unsigned(ty) => plain(ty),
                    Storage::Scaled(ty, scale) => NewColumn {
                        scaling: Some((scale, 0.0)),
                        no_data: Some(no_data(ty)),
                        ..plain(ty)
                    },
                }
            })
            .collect()
    }

    /// Bytes per point.
    pub fn record_size(&self) -> usize {
        self.size
    }

    /// Appends one point's columns to `out` (little-endian, record order).
    pub fn encode(&self, r: &PointResult, out: &mut Vec<u8>) {
        let start = out.len();
        out.resize(start + self.size, 0);
        let mut at = start;
        for (c, s) in &self.columns {
            at += s.put(c.value.get(r), &mut out[at..]);
        }
    }

    /// The provenance lines of the encoding: one `column.<name>=<type>` line per column, with
    /// `scale S offset 0 no_data N` for a scaled one.
    pub fn provenance(&self) -> String {
        let mut t = String::new();
        for d in self.descriptors() {
            let ty = match d.ty {
                ScalarType::U8 => "u8",
                ScalarType::U16 => "u16",
                ScalarType::I16 => "i16",
                ScalarType::I32 => "i32",
                ScalarType::F32 => "f32",
                _ => "f64",
            };
            t.push_str(&format!("column.{}={ty}", d.name));
            if let (Some((scale, offset)), Some(n)) = (d.scaling, d.no_data) {
                t.push_str(&format!(" scale {scale:e} offset {offset} no_data {n}"));
            }
            t.push('\n');
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimate::Curvature;
    use crate::core::quantize::pow2;
    use crate::core::terrain::TerrainValues;
    use crate::io::columns::tests::vcm_columns;
    use crate::io::columns::{ColumnChoice, Group};

    /// The integer of a scaled value is the one `as` gives of the rounded, clamped value, for
    /// both types, their bounds, halves, signed zeros, NaN and values far out of range.
    #[test]
    fn scaled_integers_are_the_rounded_clamped_values() {
        for ty in [ScalarType::I16, ScalarType::I32] {
            let m = max_raw(ty);
            for scale in [1.0, 0.5, 1.0 / 4096.0, 90.0 / 32767.0] {
                let mut values = vec![f64::NAN, 0.0, -0.0, f64::INFINITY, f64::NEG_INFINITY];
                for x in [0.5, 1.5, 2.5, 0.49999999999999994, 1e-300, 1e300, 123.456] {
                    values.extend([x, -x, x * scale, -x * scale]);
                }
                for b in [m, m + 1.0, m - 0.5, m + 0.5, 2.0 * m] {
                    values.extend([b * scale, -b * scale]);
                }
                for v in values {
                    let want = match (v.is_nan(), ty) {
                        (true, ScalarType::I16) => i16::MIN as i64,
                        (true, _) => i32::MIN as i64,
                        (false, _) => (v / scale).round().clamp(-m, m) as i64,
                    };
                    assert_eq!(scaled_raw(v, scale, ty) as i64, want, "{v:e} at {scale:e}");
                }
            }
        }
    }

    const STEPS: Steps = Steps {
        h: 1.0 / 1024.0,
        k: 1.0 / 65536.0,
        principal: 1.0 / 2048.0,
    };

    fn result(h: f64) -> PointResult {
        PointResult {
            id: 0,
            normal: [0.6, 0.0, -0.8],
            curvature: Curvature {
                h,
                k: 0.06,
                k1: -0.2,
                k2: 1e12,
                d1: [1.0, 0.0, 0.0],
                d2: [0.0, 0.8, -0.6],
                flags: 8,
            },
            extra: [0.5, 0.0, 0.6, -0.8],
            patch: crate::core::compute::NO_PATCH,
            scale: 160,
            scale_flags: 1,
            terrain: TerrainValues {
                profile: 0.25,
                tangential: -0.1,
                plan: f64::NAN,
                shape_index: 0.5,
                curvedness: 0.3,
                slope_deg: 36.87,
                aspect_deg: 359.99,
                flags: 2,
            },
        }
    }

    /// The terrain columns: after the flags, curvatures i32 at k1's step, the shape index,
    /// slope and aspect i16 at 1/32767, 90/32767 and 360/32767, TerrainFlags u8; they go
    /// through a result file's record unchanged.
    #[test]
    fn terrain_columns_are_stored_as_documented() {
        let set = ColumnSet {
            choice: ColumnChoice::parse("H,flags,terrain").expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide: false,
        };
        let out = OutputColumns::new(&set, Encoding::Scaled(STEPS));
        let d = out.descriptors();
        let names: Vec<&str> = d.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "H",
                "CurvatureFlags",
                "ProfileCurvature",
                "TangentialCurvature",
                "PlanCurvature",
                "ShapeIndex",
                "Curvedness",
                "Slope",
                "Aspect",
                "TerrainFlags"
            ]
        );
        assert!(d.iter().all(|c| c.description.len() <= 32));
        let scale = |i: usize| (d[i].ty, d[i].scaling.map(|s| s.0));
        for i in [2, 3, 4, 6] {
            assert_eq!(scale(i), (ScalarType::I32, Some(STEPS.principal)));
        }
        assert_eq!(scale(5), (ScalarType::I16, Some(1.0 / 32767.0)));
        assert_eq!(scale(7), (ScalarType::I16, Some(90.0 / 32767.0)));
        assert_eq!(scale(8), (ScalarType::I16, Some(360.0 / 32767.0)));
        assert_eq!(scale(9), (ScalarType::U8, None));
        // Through a result file's record (f32) and back.
        let mut stored = Vec::new();
        set.layout().encode(&result(0.3), &mut stored);
        let back = set.layout().decode(&stored);
        assert_eq!(back.terrain.flags, 2);
        assert_eq!(back.terrain.slope_deg, 36.87f32 as f64);
        assert!(back.terrain.plan.is_nan());
        let mut rec = Vec::new();
        out.encode(&back, &mut rec);
        let parsed = crate::io::las::extra_bytes::parse(
            &d.iter()
                .flat_map(crate::io::las::extra_bytes::encode)
                .collect::<Vec<u8>>(),
        )
        .expect("descriptors");
        let read = |i: usize| parsed[i].read(&rec).expect("value");
        let want = [0.25, -0.1, f64::NAN, 0.5, 0.3, 36.87, 359.99, 2.0];
        for (i, w) in (2..10).zip(want) {
            let step = d[i].scaling.map_or(0.0, |s| s.0);
            let v = read(i);
            assert!(
                (v.is_nan() && w.is_nan()) || (v - w).abs() <= step / 2.0 + 1e-6,
                "{}: {v} against {w}",
                d[i].name
            );
        }
    }

    /// Scaled: unit vectors i16 at 1/32767, curvatures i32 at their steps (k1 and k2 one
    /// step), the feature score i16 at 0.5/32767, flags u8; values round to the nearest
    /// step, clamp instead of wrapping, and NaN is the type's minimum, the declared no-data.
    #[test]
    fn scaled_columns_round_clamp_and_mark_undefined() {
        let out = OutputColumns::new(&vcm_columns(), Encoding::Scaled(STEPS));
        let d = out.descriptors();
        let get = |name: &str| d.iter().position(|c| c.name == name).expect("column");
        let ty_scale = |name: &str| (d[get(name)].ty, d[get(name)].scaling);
        assert_eq!(
            ty_scale("NormalX"),
            (ScalarType::I16, Some((1.0 / 32767.0, 0.0)))
        );
        assert_eq!(
            ty_scale("d2z"),
            (ScalarType::I16, Some((1.0 / 32767.0, 0.0)))
        );
        assert_eq!(ty_scale("H"), (ScalarType::I32, Some((STEPS.h, 0.0))));
        assert_eq!(ty_scale("k1"), ty_scale("k2"));
        assert_eq!(
            ty_scale("SharpFeature"),
            (ScalarType::I16, Some((0.5 / 32767.0, 0.0)))
        );
        assert_eq!(ty_scale("CurvatureFlags"), (ScalarType::U8, None));
        assert_eq!(d[get("H")].no_data, Some(i32::MIN as f64));
        assert_eq!(d[get("NormalZ")].no_data, Some(i16::MIN as f64));
        assert_eq!(out.record_size(), 3 * 2 + 4 * 4 + 6 * 2 + 4 * 2 + 1);
        let mut rec = Vec::new();
        out.encode(&result(0.3), &mut rec);
        assert_eq!(rec.len(), out.record_size());
        let parsed = crate::io::las::extra_bytes::parse(
            &d.iter()
                .flat_map(crate::io::las::extra_bytes::encode)
                .collect::<Vec<u8>>(),
        )
        .expect("descriptors");
        let read = |rec: &[u8], name: &str| parsed[get(name)].read(rec).expect("value");
        assert_eq!(read(&rec, "H"), (0.3f64 * 1024.0).round() / 1024.0);
        assert!((read(&rec, "H") - 0.3).abs() <= STEPS.h / 2.0);
        for (name, v) in [("NormalX", 0.6), ("NormalZ", -0.8), ("d2y", 0.8)] {
            assert!(
                (read(&rec, name) - v).abs() <= 0.5 / 32767.0 + 1e-15,
                "{name}"
            );
        }
        assert_eq!(read(&rec, "SharpFeature"), 0.5);
        assert_eq!(
            read(&rec, "k2"),
            i32::MAX as f64 * STEPS.principal,
            "clamped, not wrapped"
        );
        assert_eq!(read(&rec, "CurvatureFlags"), 8.0);
        // `-k auto`'s columns: exact unsigned integers before the flags.
        let auto = ColumnSet {
            choice: ColumnChoice::parse("H,scale,flags").expect("valid"),
            ..vcm_columns()
        };
        let scale = OutputColumns::new(&auto, Encoding::Scaled(STEPS));
        let names: Vec<&str> = scale.columns.iter().map(|(c, _)| c.name).collect();
        assert_eq!(
            &names[names.len() - 3..],
            ["ScaleK", "ScaleFlags", "CurvatureFlags"]
        );
        let mut srec = Vec::new();
        scale.encode(&result(0.3), &mut srec);
        assert_eq!(srec[srec.len() - 4..], [160, 0, 1, 8][..]);
        let sd = scale.descriptors();
        assert_eq!(sd[sd.len() - 3].ty, ScalarType::U16);
        assert_eq!(sd[sd.len() - 3].scaling, None);
        rec.clear();
        let mut undefined = result(f64::NAN);
        undefined.normal = [f64::NAN; 3];
        out.encode(&undefined, &mut rec);
        assert!(read(&rec, "H").is_nan() && read(&rec, "NormalY").is_nan());
        let at = get_offset(&d, "H");
        assert_eq!(rec[at..at + 4], i32::MIN.to_le_bytes());
        assert_eq!(read(&rec, "K"), (0.06f64 / STEPS.k).round() * STEPS.k);
        assert_eq!(pow2(-10), STEPS.h);
    }

    fn get_offset(d: &[NewColumn], name: &str) -> usize {
        d.iter()
            .take_while(|c| c.name != name)
            .map(|c| c.ty.size())
            .sum()
    }

    /// --f32 and --f64 (and PLY outputs) keep floats with NaN, nothing scaled or declared.
    #[test]
    fn floats_stay_floats() {
        let set = ColumnSet {
            choice: ColumnChoice::parse("H,flags").expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide: true,
        };
        for (enc, ty, size) in [
            (Encoding::F32, ScalarType::F32, 5),
            (Encoding::F64, ScalarType::F64, 9),
            (Encoding::Scaled(STEPS).floats(), ScalarType::F32, 5),
        ] {
            let out = OutputColumns::new(&set, enc);
            let d = out.descriptors();
            assert_eq!(
                d.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
                ["H", "CurvatureFlags"]
            );
            assert_eq!((d[0].ty, d[0].scaling, d[0].no_data), (ty, None, None));
            let mut rec = Vec::new();
            out.encode(&result(f64::NAN), &mut rec);
            assert_eq!(rec.len(), size);
            assert!(ty.decode(&rec).is_nan());
            assert_eq!(rec[size - 1], 8);
        }
        assert!(!set.choice.has(Group::Normals));
    }

    /// The provenance names each column's type, and a scaled one's scale and no-data value.
    #[test]
    fn provenance_lists_the_encoding() {
        let set = ColumnSet {
            choice: ColumnChoice::parse("normals,H").expect("valid"),
            extra: Vec::new(),
            unit: "m".into(),
            wide: true,
        };
        let t = OutputColumns::new(&set, Encoding::Scaled(STEPS)).provenance();
        assert!(
            t.contains("column.NormalX=i16 scale 3.051850947599719e-5 offset 0 no_data -32768\n"),
            "{t}"
        );
        assert!(
            t.contains("column.H=i32 scale 9.765625e-4 offset 0 no_data -2147483648\n"),
            "{t}"
        );
        let f = OutputColumns::new(&set, Encoding::F64).provenance();
        assert_eq!(
            f,
            "column.NormalX=f64\ncolumn.NormalY=f64\ncolumn.NormalZ=f64\ncolumn.H=f64\n"
        );
    }
}
