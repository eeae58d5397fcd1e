//! Tests of the column definitions (mod.rs).

use super::*;
use crate::core::compute::NO_PATCH;
use crate::core::estimate::{Curvature, EstimatorKind, EstimatorParams};

pub(super) fn vcm_columns() -> ColumnSet {
    let vcm = EstimatorKind::Vcm.build(&EstimatorParams::default());
    ColumnSet {
        choice: ColumnChoice::parse("normals,H,K,k1,k2,flags")
            .expect("valid")
            .with(Group::Directions)
            .with(Group::Features),
        extra: vcm.extra_columns().to_vec(),
        unit: "m".into(),
        wide: true,
    }
}

/// `--columns` takes names in any order and case and writes them in record order; an
/// unknown name lists the valid ones.
#[test]
fn column_lists_parse_in_record_order() {
    let c = ColumnChoice::parse("flags, h,K2").expect("valid");
    assert_eq!(c.to_string(), "H,k2,flags");
    assert_eq!(ColumnChoice::default().to_string(), "H,K,flags");
    assert_eq!(
        ColumnChoice::parse(&ColumnChoice::default().to_string()),
        Ok(ColumnChoice::default())
    );
    let e = ColumnChoice::parse("H,torsion").expect_err("unknown");
    assert!(
        e.contains("\"torsion\"")
            && e.contains("normals, H, K, k1, k2, directions, features, scale, flags, profile, tangential, plan, shape_index, curvedness, slope, aspect, terrain"),
        "{e}"
    );
    // `terrain` is every terrain group; it reads back as their names.
    let t = ColumnChoice::parse("Terrain,H").expect("valid");
    assert_eq!(
        t.to_string(),
        "H,profile,tangential,plan,shape_index,curvedness,slope,aspect"
    );
    assert!(t.has_terrain() && !ColumnChoice::default().has_terrain());
    assert_eq!(ColumnChoice::parse(&t.to_string()), Ok(t));
    assert!(ColumnChoice::parse("").is_err() && ColumnChoice::parse("H,").is_err());
}

/// Features follow the curvature and directions, the flags come last; a result file keeps
/// k1 and k2 together.
#[test]
fn columns_in_record_order() {
    let mut cols = vcm_columns();
    cols.choice = cols
        .choice
        .without(Group::Directions)
        .without(Group::Normals);
    let names: Vec<&str> = cols.columns().iter().map(|c| c.name).collect();
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
            "VcmNormalZ",
            FLAGS_NAME
        ]
    );
    assert!(cols.columns().iter().all(|c| c.description.len() <= 32));
    assert_eq!(cols.columns()[5].description, "VCM unit normal x");
    cols.choice = ColumnChoice::parse("k2").expect("valid");
    let stored: Vec<Value> = cols.stored().take(3).collect();
    assert_eq!(stored, [Value::K1, Value::K2, Value::Extra(0)]);
    assert_eq!(cols.result_size(), 8 * 6 + 1);
}

/// The layout (a fixed array) holds the fullest column set, every group with the most extra
/// values: exactly [`ColumnSet::stored`]'s list, which fills it. A group added later fails
/// here until the bound grows.
#[test]
fn the_layout_holds_the_fullest_column_set() {
    let mut cols = vcm_columns();
    assert_eq!(cols.extra.len(), MAX_EXTRA);
    let all: Vec<&str> = Group::ALL.iter().map(|g| g.name()).collect();
    cols.choice = ColumnChoice::parse(&all.join(",")).expect("valid");
    let layout = cols.layout();
    let stored: Vec<Value> = cols.stored().collect();
    assert_eq!(stored.len(), MAX_STORED);
    // The numbers in their order, then the flag bytes in theirs.
    let (bytes, numbers): (Vec<Value>, Vec<Value>) = stored.iter().partition(|v| v.is_flag_byte());
    assert_eq!(layout.values[..layout.numbers], numbers[..]);
    assert_eq!(layout.values[layout.numbers..layout.len], bytes[..]);
    assert_eq!(
        bytes,
        [Value::ScaleFlags, Value::Terrain(TerrainValue::Flags)]
    );
    // Every value comes back from a record whose bytes are all distinct from the next.
    let mut r = crate::core::compute::PointResult::not_computed(0);
    r.scale_flags = 3;
    r.terrain.flags = 9;
    r.curvature.flags = 16;
    r.curvature.h = 0.25;
    let mut rec = Vec::new();
    layout.encode(&r, &mut rec);
    assert_eq!(rec.len(), cols.result_size());
    // The flag bytes after the numbers but the terrain numbers, which end the record.
    let flags = layout.flags_at();
    assert_eq!(rec[flags..flags + 3], [16, 3, 9]);
    assert_eq!(
        layout.offset(Value::Terrain(TerrainValue::Aspect)),
        Some(rec.len() - 8)
    );
    let back = layout.decode(&rec);
    assert_eq!(
        (back.scale_flags, back.terrain.flags, back.curvature.flags),
        (3, 9, 16)
    );
    assert_eq!(back.curvature.h, 0.25);
    // The terrain numbers, written in one block when all seven are stored, come back each in
    // its place, narrow and wide, and so does each alone.
    let t = &mut r.terrain;
    (t.profile, t.tangential, t.plan, t.shape_index) = (0.1, -0.2, 0.3, -0.4);
    (t.curvedness, t.slope_deg, t.aspect_deg) = (0.5, 6.0, 270.0);
    for wide in [false, true] {
        for list in ["H,terrain", "slope", "H,plan,aspect"] {
            let mut cols = cols.clone();
            (cols.choice, cols.wide) = (ColumnChoice::parse(list).expect("valid"), wide);
            let layout = cols.layout();
            let mut rec = Vec::new();
            layout.encode(&r, &mut rec);
            let back = layout.decode(&rec).terrain;
            for v in TerrainValue::ALL.iter().filter(|v| v.group().is_some()) {
                let want = v.get(&r.terrain);
                let want = if wide { want } else { want as f32 as f64 };
                let stored = cols.choice.has(Group::Terrain(*v));
                let got = v.get(&back);
                assert!(got == want || !stored && got.is_nan(), "{list} {v:?}");
            }
        }
    }
}

/// The one flip, on decoded results: normal, H and the VCM normal negated, k1' = -k2,
/// k2' = -k1, directions swapped, K, the feature score and the flags kept; NaN stays the
/// same NaN; twice is the identity, byte for byte.
#[test]
fn flipping_decoded_results_is_exact() {
    let cols = vcm_columns();
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
        patch: NO_PATCH,
        scale: 0,
        scale_flags: 0,
        terrain: crate::core::terrain::TerrainValues::NONE,
    };
    let mut rec = Vec::new();
    cols.layout().encode(&r, &mut rec);
    assert_eq!(rec.len(), cols.result_size());
    assert_eq!(cols.layout().decode(&rec).curvature, r.curvature);
    let f = cols.layout().decode(&rec).flipped(&cols.extra);
    assert_eq!(f.normal, [-0.0, -0.6, -0.8]);
    let c = f.curvature;
    assert_eq!((c.h, c.k, c.k1, c.k2), (-0.5, 0.06, -0.3, -0.2));
    assert_eq!((c.d1, c.d2, c.flags), (r.curvature.d2, r.curvature.d1, 16));
    assert_eq!(f.extra[0], 0.125);
    assert!(f.extra[1].is_nan());
    assert_eq!(f.extra[2..], [0.6, -0.8]);
    let mut flipped = Vec::new();
    cols.layout().encode(&f, &mut flipped);
    let mut back = Vec::new();
    cols.layout().encode(
        &cols.layout().decode(&flipped).flipped(&cols.extra),
        &mut back,
    );
    assert_eq!(back, rec);
    // Narrow result files (every encoding but --f64): f32 values, half the bytes, the
    // same values as an f32 rounding of the f64 ones.
    let narrow = ColumnSet {
        wide: false,
        ..cols.clone()
    };
    let mut small = Vec::new();
    narrow.layout().encode(&r, &mut small);
    assert_eq!(small.len(), narrow.result_size());
    assert_eq!(narrow.result_size() - 1, (cols.result_size() - 1) / 2);
    let d = narrow.layout().decode(&small);
    assert_eq!(d.curvature.h, 0.5f32 as f64);
    assert_eq!(d.curvature.k, 0.06f32 as f64);
    assert_eq!(d.normal, r.normal.map(|v| v as f32 as f64));
    assert!(d.extra[1].is_nan() && d.curvature.flags == 16);
}

/// `encode_all` writes every byte of a record, whatever the column set: a tile's records are
/// encoded over the previous tile's without being zeroed first (results::write_tile_tmp).
#[test]
fn encoding_writes_every_byte_of_a_record() {
    let mut cols = vcm_columns();
    let all: Vec<&str> = Group::ALL.iter().map(|g| g.name()).collect();
    for (list, wide) in [
        (all.join(","), true),
        (all.join(","), false),
        ("H".into(), false),
    ] {
        cols.choice = ColumnChoice::parse(&list).expect("valid");
        cols.wide = wide;
        let layout = cols.layout();
        let mut r = crate::core::compute::PointResult::not_computed(0);
        r.curvature.h = 0.25;
        r.terrain.slope_deg = 3.0;
        let results = [r, crate::core::compute::PointResult::not_computed(1)];
        let size = layout.size();
        let [mut zeros, mut ones] = [0u8, 0xff].map(|b| vec![b; 2 * size]);
        layout.encode_all(&results, &mut zeros, size, 0);
        layout.encode_all(&results, &mut ones, size, 0);
        assert_eq!(zeros, ones, "{list}, wide {wide}");
    }
}
