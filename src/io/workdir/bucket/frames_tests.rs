use super::*;
use crate::core::point::SourcePoint;

fn point(id: u64, xyz: [f64; 3], normal: Option<[f64; 3]>) -> SourcePoint {
    SourcePoint { id, xyz, normal }
}

/// A LAS-like input: scale 0.001, a UTM offset, z in feet scaled to metres after decoding.
fn las_grid() -> [AxisGrid; 3] {
    let g = |offset, post| AxisGrid::new(0.001, offset, post);
    [g(500_000.0, 1.0), g(4_100_000.0, 1.0), g(0.0, 0.3048)]
}

fn decode(bytes: &[u8]) -> Result<Vec<SourcePoint>> {
    decode_frames(Path::new("b_0_0.zst"), bytes).map(|p| p.iter().collect())
}

fn encode(pts: &[SourcePoint], grids: &Grids) -> Vec<u8> {
    encode_frame(&pts.iter().copied().collect(), grids).expect("encode")
}

#[test]
fn frames_round_trip_every_encoding_bit_for_bit() {
    let g = las_grid();
    let mut grids = Grids::default();
    grids.push(0, Some(g));
    grids.push(1000, None);
    // Input 0: integers on its grid (one off the grid: raw f64 for that run's x).
    let on = |id: u64, q: [i64; 3]| point(id, [0, 1, 2].map(|a| g[a].value(q[a])), None);
    let mut pts: Vec<SourcePoint> = (0..300)
        .map(|i| on(i * 3, [i as i64 * 7, 99, -5 - i as i64]))
        .collect();
    // Input 1: f32 coordinates with f32 normals on some points, then one raw f64 value.
    pts.extend((0..50u64).map(|i| {
        let n = (i % 3 == 0).then_some([0.6f32 as f64, 0.0, 0.8f32 as f64]);
        point(1000 + i, [i as f32 as f64 * 0.5, -1.25, 3.0e5], n)
    }));
    pts.push(point(1100, [0.1, 0.2, 0.3], Some([0.0, 0.6, 0.8])));
    // Back to input 0, ids going down (another run), -0.0 and a value off the grid.
    pts.push(on(7, [0, 0, 0]));
    pts.push(point(5, [-0.0, g[1].value(3), g[2].value(4) + 1e-9], None));
    let mut bytes = encode(&pts, &grids);
    bytes.extend(encode(&pts[..3], &grids));
    let back = decode(&bytes).expect("decode");
    let bits = |v: &[SourcePoint]| -> Vec<(u64, [u64; 3], Option<[u64; 3]>)> {
        v.iter()
            .map(|p| {
                (
                    p.id,
                    p.xyz.map(f64::to_bits),
                    p.normal.map(|n| n.map(f64::to_bits)),
                )
            })
            .collect()
    };
    let mut expect = pts.clone();
    expect.extend_from_slice(&pts[..3]);
    assert_eq!(bits(&back), bits(&expect));
    // The integers take far less than the 57 bytes a point of raw f64 did.
    let ints: Vec<SourcePoint> = (0..20_000)
        .map(|i| {
            on(
                i,
                [
                    (i * 37 % 50_000) as i64,
                    (i / 100) as i64,
                    1000 + (i % 17) as i64,
                ],
            )
        })
        .collect();
    let small = encode(&ints, &grids);
    assert!(small.len() < ints.len() * 8, "{} bytes", small.len());
    assert_eq!(bits(&decode(&small).expect("decode")), bits(&ints));
}

#[test]
fn integers_of_a_grid_are_exact_or_refused() {
    let g = las_grid();
    for q in [0i64, 1, -1, 123_456_789, -(1 << 31)] {
        assert_eq!(g[2].integer(g[2].value(q)), Some(q));
    }
    assert_eq!(g[0].integer(0.1005), None);
    assert_eq!(g[0].integer(f64::NAN), None);
    assert_eq!(g[0].integer(1e300), None);
}

#[test]
fn damaged_truncated_and_old_frames_are_refused() {
    let mut grids = Grids::default();
    grids.push(0, Some(las_grid()));
    let pts: Vec<SourcePoint> = (0..5000u64)
        .map(|i| {
            point(
                i,
                [500_000.0 + i as f64 * 0.001, 4_100_000.0, 0.3048 * 2.0],
                None,
            )
        })
        .collect();
    let bytes = encode(&pts, &grids);
    assert_eq!(decode(&bytes).expect("decode").len(), pts.len());
    let refused = |b: &[u8]| {
        let e = decode(b).expect_err("refused").to_string();
        assert!(
            e.contains("b_0_0.zst") && e.contains("delete the work directory"),
            "{e}"
        );
        assert_eq!(
            decode(b).expect_err("refused").exit_class(),
            crate::error::ExitClass::Output
        );
    };
    refused(&bytes[..bytes.len() - 3]);
    refused(&bytes[..bytes.len() / 2]);
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 1;
    refused(&flipped);
    // A frame of the first format (raw records, no magic) is refused, not misread.
    let mut old = Vec::new();
    for p in &pts[..10] {
        old.extend_from_slice(&p.id.to_le_bytes());
        p.xyz
            .iter()
            .for_each(|c| old.extend_from_slice(&c.to_le_bytes()));
        old.push(0);
    }
    refused(&zstd::bulk::compress(&old, 1).expect("compress"));
}
