//! The columns tilecurv adds to every point: their names, types, descriptions (with the file's
//! unit) and their byte encoding. One definition used by the result files, the LAS/LAZ writer's
//! extra-bytes VLR, and the tests.

use crate::config::ColumnType;
use crate::core::compute::PointResult;
use crate::core::estimate::Extra;
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
    /// Whether the estimator's extra values ([`Extra`]: `SharpFeature`, `VcmNormalX/Y/Z`) are
    /// written (`--features`); NaN for points without them.
    pub features: bool,
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
        if self.features {
            v.extend(["SharpFeature", "VcmNormalX", "VcmNormalY", "VcmNormalZ"]);
        }
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
            "SharpFeature" => "VCM edge score l2/(l1+l2+l3)".into(),
            "VcmNormalX" | "VcmNormalY" | "VcmNormalZ" => {
                format!("VCM unit normal {}", &name[9..].to_lowercase())
            }
            d => format!("direction of k{} ({})", &d[1..2], &d[2..3]),
        };
        let mut cols: Vec<NewColumn> = self
            .float_names()
            .into_iter()
            .map(|n| NewColumn {
                name: n.to_string(),
                ty,
                description: describe(n),
            })
            .collect();
        cols.push(NewColumn {
            name: FLAGS_NAME.into(),
            ty: ScalarType::U8,
            description: "1few 2nrm 4dgn 8bnd 16umb 32file".into(),
        });
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

    /// Rewrites encoded columns as they read with the opposite normal (a propagation patch
    /// whose sign the cross-tile step reversed): normal and H negated, `k1' = -k2`,
    /// `k2' = -k1`, directions swapped, K and the flags unchanged (orient::flip_curvature).
    /// Negation and swaps are exact in f32 and f64, so this equals encoding the flipped values.
    pub fn flip_encoded(&self, rec: &mut [u8]) {
        let w = match self.ty {
            ColumnType::F32 => 4,
            ColumnType::F64 => 8,
        };
        let get = |rec: &[u8], i: usize| match self.ty {
            ColumnType::F32 => {
                f32::from_le_bytes(rec[i * w..i * w + 4].try_into().unwrap_or([0; 4])) as f64
            }
            ColumnType::F64 => {
                f64::from_le_bytes(rec[i * w..i * w + 8].try_into().unwrap_or([0; 8]))
            }
        };
        let names = self.float_names();
        let mut v: Vec<f64> = (0..names.len()).map(|i| get(rec, i)).collect();
        let at = |n: &str| names.iter().position(|x| *x == n);
        for n in [
            "NormalX",
            "NormalY",
            "NormalZ",
            "H",
            "VcmNormalX",
            "VcmNormalY",
            "VcmNormalZ",
        ] {
            if let Some(i) = at(n).filter(|&i| !v[i].is_nan()) {
                v[i] = -v[i];
            }
        }
        if let (Some(a), Some(b)) = (at("k1"), at("k2")) {
            // NaN (undefined) stays the NaN it was.
            let neg = |x: f64| if x.is_nan() { x } else { -x };
            let (k1, k2) = (v[a], v[b]);
            v[a] = neg(k2);
            v[b] = neg(k1);
        }
        for c in ["x", "y", "z"] {
            if let (Some(a), Some(b)) = (at(&format!("d1{c}")), at(&format!("d2{c}"))) {
                v.swap(a, b);
            }
        }
        for (i, x) in v.into_iter().enumerate() {
            match self.ty {
                ColumnType::F32 => rec[i * w..i * w + 4].copy_from_slice(&(x as f32).to_le_bytes()),
                ColumnType::F64 => rec[i * w..i * w + 8].copy_from_slice(&x.to_le_bytes()),
            }
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
        if self.features {
            let e = c.extra.unwrap_or(Extra {
                feature: f64::NAN,
                normal: [f64::NAN; 3],
            });
            put(e.feature);
            for v in e.normal {
                put(v);
            }
        }
        out.push(c.flags);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimate::Curvature;

    /// `--features` appends SharpFeature and VcmNormalX/Y/Z after the curvature columns, with
    /// the estimator's extra values, or NaN for a result without them.
    #[test]
    fn feature_columns_follow_the_curvature() {
        let cols = ColumnSet {
            ty: ColumnType::F64,
            normals: false,
            directions: false,
            features: true,
            unit: "m".into(),
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
        let read = |bytes: &[u8]| -> Vec<f64> {
            bytes[..64]
                .chunks(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect()
        };
        let mut r = PointResult {
            id: 0,
            normal: [0.0, 0.0, 1.0],
            curvature: Curvature {
                extra: Some(Extra {
                    feature: 0.25,
                    normal: [0.0, 0.6, 0.8],
                }),
                ..Curvature::undefined(0)
            },
            patch: crate::core::compute::NO_PATCH,
        };
        let mut out = Vec::new();
        cols.encode(&r, &mut out);
        assert_eq!(out.len(), cols.record_size());
        assert_eq!(read(&out)[4..], [0.25, 0.0, 0.6, 0.8]);
        r.curvature.extra = None;
        out.clear();
        cols.encode(&r, &mut out);
        assert!(read(&out)[4..].iter().all(|v| v.is_nan()));
    }
}
