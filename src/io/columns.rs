//! The columns tilecurv adds to every point: their names, types, descriptions (with the file's
//! unit) and their byte encoding. One definition used by the result files, the LAS/LAZ writer's
//! extra-bytes VLR, and the tests.

use crate::config::ColumnType;
use crate::core::compute::PointResult;
use crate::core::estimate::{Curvature, ExtraColumn, MAX_EXTRA};
use crate::io::las::extra_bytes::{NewColumn, ScalarType};

/// Name of the quality-flag column.
pub const FLAGS_NAME: &str = "CurvatureFlags";

/// The set of new columns of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSet {
    /// Storage type of the float columns.
    pub ty: ColumnType,
    /// Whether the normal columns are written (not when the input already has NormalX/Y/Z:
    /// those are the normals used, and they are kept as they are).
    pub normals: bool,
    /// Whether the principal directions are written.
    pub directions: bool,
    /// The estimator's extra values written (`--features`: its declared
    /// [`Estimator::extra_columns`](crate::core::estimate::Estimator::extra_columns), e.g. the
    /// VCM's `SharpFeature`, `VcmNormalX/Y/Z`); empty otherwise.
    pub extra: Vec<ExtraColumn>,
    /// Unit symbol of the coordinates, for the descriptions ("m", "ft", or "unit").
    pub unit: String,
}

impl ColumnSet {
    /// The float columns' names, in record order (the flag column follows them).
    pub fn float_names(&self) -> Vec<&'static str> {
        let mut v = if self.normals {
            vec!["NormalX", "NormalY", "NormalZ"]
        } else {
            Vec::new()
        };
        v.extend(["H", "K", "k1", "k2"]);
        if self.directions {
            v.extend(["d1x", "d1y", "d1z", "d2x", "d2y", "d2z"]);
        }
        v.extend(self.extra.iter().map(|c| c.name));
        v
    }

    /// Descriptors of all new columns, in record order.
    pub fn columns(&self) -> Vec<NewColumn> {
        let u = &self.unit;
        let ty = match self.ty {
            ColumnType::F32 => ScalarType::F32,
            ColumnType::F64 => ScalarType::F64,
        };
        let describe = |name: &str| match name {
            "NormalX" | "NormalY" | "NormalZ" => {
                format!("unit normal {}", &name[6..].to_lowercase())
            }
            "H" => format!("mean curvature (1/{u})"),
            "K" => format!("Gaussian curvature (1/{u}^2)"),
            "k1" => format!("min principal curvature (1/{u})"),
            "k2" => format!("max principal curvature (1/{u})"),
            d if d.starts_with('d') => format!("direction of k{} ({})", &d[1..2], &d[2..3]),
            other => self
                .extra
                .iter()
                .find(|c| c.name == other)
                .map(|c| c.description.to_string())
                .unwrap_or_default(),
        };
        let mut cols: Vec<NewColumn> = self
            .float_names()
            .into_iter()
            .map(|n| NewColumn::plain(n, ty, describe(n)))
            .collect();
        cols.push(NewColumn::plain(
            FLAGS_NAME,
            ScalarType::U8,
            "1few 2nrm 4dgn 8bnd 16umb 32file",
        ));
        cols
    }

    /// Bytes per point of the new columns.
    pub fn record_size(&self) -> usize {
        let w = match self.ty {
            ColumnType::F32 => 4,
            ColumnType::F64 => 8,
        };
        self.float_names().len() * w + 1
    }

    /// Decodes one point's columns (as [`ColumnSet::encode`] wrote them) back into a result
    /// with id 0 and no patch; columns this set does not hold are NaN. f32 values widen
    /// exactly, so `encode(decode(rec))` gives `rec` back.
    pub fn decode(&self, rec: &[u8]) -> PointResult {
        let w = match self.ty {
            ColumnType::F32 => 4,
            ColumnType::F64 => 8,
        };
        let mut at = 0;
        let mut next = || {
            let v = match self.ty {
                ColumnType::F32 => rec
                    .get(at..at + 4)
                    .and_then(|b| b.try_into().ok())
                    .map(|b| f32::from_le_bytes(b) as f64),
                ColumnType::F64 => rec
                    .get(at..at + 8)
                    .and_then(|b| b.try_into().ok())
                    .map(f64::from_le_bytes),
            };
            at += w;
            v.unwrap_or(f64::NAN)
        };
        let mut three = |on: bool| {
            if on {
                [next(), next(), next()]
            } else {
                [f64::NAN; 3]
            }
        };
        let normal = three(self.normals);
        let (h, k, k1, k2) = (next(), next(), next(), next());
        let (d1, d2) = if self.directions {
            ([next(), next(), next()], [next(), next(), next()])
        } else {
            ([0.0; 3], [0.0; 3])
        };
        let mut extra = [f64::NAN; MAX_EXTRA];
        for v in extra.iter_mut().take(self.extra.len()) {
            *v = next();
        }
        let flags = rec.get(self.record_size() - 1).copied().unwrap_or(0);
        PointResult {
            id: 0,
            normal,
            curvature: Curvature {
                h,
                k,
                k1,
                k2,
                d1,
                d2,
                flags,
            },
            extra,
            patch: crate::core::compute::NO_PATCH,
        }
    }

    /// Appends the encoded columns of one point to `out` (little-endian, record order).
    pub fn encode(&self, r: &PointResult, out: &mut Vec<u8>) {
        let c = &r.curvature;
        let mut put = |v: f64| match self.ty {
            ColumnType::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
            ColumnType::F64 => out.extend_from_slice(&v.to_le_bytes()),
        };
        if self.normals {
            for v in r.normal {
                put(v);
            }
        }
        for v in [c.h, c.k, c.k1, c.k2] {
            put(v);
        }
        if self.directions {
            for v in c.d1.into_iter().chain(c.d2) {
                put(v);
            }
        }
        for &v in r.extra.iter().take(self.extra.len()) {
            put(v);
        }
        out.push(c.flags);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimate::{EstimatorKind, EstimatorParams};

    fn vcm_columns(ty: ColumnType) -> ColumnSet {
        let vcm = EstimatorKind::Vcm.build(&EstimatorParams::default());
        ColumnSet {
            ty,
            normals: true,
            directions: true,
            extra: vcm.extra_columns().to_vec(),
            unit: "m".into(),
        }
    }

    /// `--features` appends the estimator's declared columns (the VCM's SharpFeature and
    /// VcmNormalX/Y/Z) after the curvature columns, with its values or NaN.
    #[test]
    fn feature_columns_follow_the_curvature() {
        let cols = ColumnSet {
            directions: false,
            normals: false,
            ..vcm_columns(ColumnType::F64)
        };
        let names: Vec<String> = cols.columns().into_iter().map(|c| c.name).collect();
        assert_eq!(
            names,
            [
                "H",
                "K",
                "k1",
                "k2",
                "SharpFeature",
                "VcmNormalX",
                "VcmNormalY",
                "VcmNormalZ"
            ]
            .into_iter()
            .chain([FLAGS_NAME])
            .collect::<Vec<_>>()
        );
        // LAS extra-bytes descriptions hold 32 bytes.
        assert!(cols.columns().iter().all(|c| c.description.len() <= 32));
        assert_eq!(cols.columns()[5].description, "VCM unit normal x");
        let read = |bytes: &[u8]| -> Vec<f64> {
            bytes[..64]
                .chunks(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect()
        };
        let mut r = PointResult {
            id: 0,
            normal: [0.0, 0.0, 1.0],
            curvature: Curvature::undefined(0),
            extra: [0.25, 0.0, 0.6, 0.8],
            patch: crate::core::compute::NO_PATCH,
        };
        let mut out = Vec::new();
        cols.encode(&r, &mut out);
        assert_eq!(out.len(), cols.record_size());
        assert_eq!(read(&out)[4..], [0.25, 0.0, 0.6, 0.8]);
        r.extra = [f64::NAN; MAX_EXTRA];
        out.clear();
        cols.encode(&r, &mut out);
        assert!(read(&out)[4..].iter().all(|v| v.is_nan()));
    }

    /// The one flip, on decoded columns: normal, H and the VCM normal negated, k1' = -k2,
    /// k2' = -k1, directions swapped, K, the feature score and the flags kept; NaN stays the
    /// same NaN; twice is the identity, byte for byte, in f32 and f64.
    #[test]
    fn flipping_decoded_columns_is_exact() {
        for ty in [ColumnType::F32, ColumnType::F64] {
            let cols = vcm_columns(ty);
            let r = PointResult {
                id: 0,
                normal: [0.0, 0.6, 0.8],
                curvature: Curvature {
                    h: 0.5,
                    k: 0.06,
                    k1: 0.2,
                    k2: 0.3,
                    d1: [1.0, 0.0, 0.0],
                    d2: [0.0, 0.8, -0.6],
                    flags: 16,
                },
                extra: [0.125, f64::NAN, -0.6, 0.8],
                patch: crate::core::compute::NO_PATCH,
            };
            let mut rec = Vec::new();
            cols.encode(&r, &mut rec);
            let f = cols.decode(&rec).flipped(&cols.extra);
            let widen = |v: f64| {
                if ty == ColumnType::F32 {
                    v as f32 as f64
                } else {
                    v
                }
            };
            assert_eq!(f.normal, [-0.0, -0.6, -0.8].map(widen));
            let c = f.curvature;
            assert_eq!(
                (c.h, c.k, c.k1, c.k2),
                (widen(-0.5), widen(0.06), widen(-0.3), widen(-0.2))
            );
            assert_eq!(
                (c.d1, c.d2, c.flags),
                (r.curvature.d2.map(widen), r.curvature.d1.map(widen), 16)
            );
            assert_eq!(f.extra[0], widen(0.125));
            assert!(f.extra[1].is_nan());
            assert_eq!(f.extra[2..], [widen(0.6), widen(-0.8)]);
            let mut flipped = Vec::new();
            cols.encode(&f, &mut flipped);
            let mut back = Vec::new();
            cols.encode(&cols.decode(&flipped).flipped(&cols.extra), &mut back);
            assert_eq!(back, rec);
        }
    }
}
