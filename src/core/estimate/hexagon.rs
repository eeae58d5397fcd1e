//! The hexagon of the CNC Hexagram variants (algorithms.md 4.5): its plane normal, its
//! in-plane frame, the sector of a neighbour, and per sector the sums of the neighbours'
//! positions and normals that CNC-Avg-Hexagram averages. The sectors of four neighbours at a
//! time are found with AVX2 where the build has it (x86-64-v3), with the same bits as the
//! scalar [`hexagon_sector`]. Pure: no files, no threads.

use super::Neighbourhood;
use crate::core::geometry::{add, cross, dot, normalize, scale, TangentBasis, V3};

/// The in-plane frame of the reference code's hexagon (algorithms.md 4.5): `e` is the axis after the
/// normal's largest component, `e1 = n x e`, `e2 = n x e1` (unit to a few ulps).
pub(super) fn hexagon_frame(n: V3) -> TangentBasis {
    let a = n.map(f64::abs);
    let e = if a[0] >= a[1] && a[0] >= a[2] {
        [0.0, 1.0, 0.0]
    } else if a[1] >= a[2] {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let u = normalize(cross(n, e)).unwrap_or([1.0, 0.0, 0.0]);
    // n and u are unit and orthogonal (to rounding), so n x u is unit to a few ulps: its
    // length would only scale the sector tests, which compare signs (a normalisation here
    // would lengthen this estimator's chain of dependent operations).
    let v = cross(n, u);
    TangentBasis { e1: u, e2: v }
}

/// Directions of the six hexagon vertices, (cos k pi/3, sin k pi/3) for k = 0..5.
pub(super) const HEX: [[f64; 2]; 6] = [
    [1.0, 0.0],
    [0.5, SIN_60],
    [-0.5, SIN_60],
    [-1.0, 0.0],
    [-0.5, -SIN_60],
    [0.5, -SIN_60],
];

/// sin 60 degrees, the nearest double.
const SIN_60: f64 = 0.866_025_403_784_438_6;

/// Wedge by (above the 30 degree line, left of the 90 degree line, above the 150 degree line)
/// as the bits 4, 2, 1 of a code; codes 2 and 5 are impossible but for rounding next to the
/// centre.
const WEDGE: [u8; 8] = [0, 5, 3, 4, 1, 0, 2, 3];

/// The hexagon sector (0..6) of a neighbour at relative position `d`: the Voronoi region of the
/// nearest hexagon vertex. The vertices are equidistant from the centre, so the nearest one
/// maximises <d | w_k> and the radius drops out (algorithms.md 4.5): the sectors are the 60
/// degree wedges centred on the vertex directions, bounded by the three lines at 30, 90 and
/// 150 degrees. The side of each line (a sign test, no branch) names the wedge; a point on a
/// line goes to one of its two wedges. Returns None for a point whose tangential projection is
/// exactly zero (equidistant from all six vertices, like the query point itself).
#[inline]
pub fn hexagon_sector(d: V3, u: V3, v: V3) -> Option<usize> {
    let (a, b) = (dot(d, u), dot(d, v));
    if a == 0.0 && b == 0.0 {
        return None;
    }
    let s = SIN_60 * b;
    let code = (((s - 0.5 * a > 0.0) as usize) << 2)
        | (((a < 0.0) as usize) << 1)
        | ((-0.5 * a - s > 0.0) as usize);
    Some(WEDGE[code] as usize)
}

/// The hexagon plane normal of the reference code: the query normal blended half and half with
/// the normalised mean neighbour normal (algorithms.md 4.5, W = 0.5).
pub fn hexagon_normal(nb: &Neighbourhood<'_>) -> V3 {
    let n0 = nb.normals[0];
    // Four partial sums: one running sum was a chain of K dependent additions.
    let fours = nb.normals.chunks_exact(4);
    let rest = fours
        .remainder()
        .iter()
        .fold([0.0; 3], |acc, &u| add(acc, u));
    let part = fours.fold([[0.0; 3]; 4], |acc, q| {
        [0, 1, 2, 3].map(|l| add(acc[l], q[l]))
    });
    let mean = add(add(add(part[0], part[1]), add(part[2], part[3])), rest);
    match normalize(mean) {
        Some(m) => normalize(add(scale(n0, 0.5), scale(m, 0.5))).unwrap_or(n0),
        None => n0,
    }
}

/// The sector of a point in no sector ([`hexagon_sector`]'s None) in [`sector_sums`].
const NO_SECTOR: u8 = 6;

/// Per hexagon sector: the sums of its neighbours' positions (lanes 0-2), their count (lane 3)
/// and the sums of their normals (lanes 4-6); the query point (first) is left out, and so is
/// a point in no sector (row 6 takes it). The sectors of a run of neighbours are found first,
/// then the run is added in order: adding each neighbour as soon as its sector is known is
/// slower although it executes fewer instructions (its stores go to an address known late,
/// which holds up the loads after them; docs/performance.md).
pub(super) fn sector_sums(nb: &Neighbourhood<'_>, u: V3, v: V3) -> [[f64; 8]; 7] {
    const RUN: usize = 32;
    let mut sums = [[0.0f64; 8]; 7];
    let mut sectors = [0u8; RUN];
    let positions = nb.positions.get(1..).unwrap_or(&[]);
    let normals = nb.normals.get(1..).unwrap_or(&[]);
    for (ps, qs) in positions.chunks(RUN).zip(normals.chunks(RUN)) {
        sector_codes(ps, u, v, &mut sectors[..ps.len()]);
        for ((&c, p), q) in sectors.iter().zip(ps).zip(qs) {
            let sum = &mut sums[c as usize];
            let lanes = [p[0], p[1], p[2], 1.0, q[0], q[1], q[2], 0.0];
            for (acc, x) in sum.iter_mut().zip(lanes) {
                *acc += x;
            }
        }
    }
    sums
}

/// The sector of each of `ps` into `out` (same length): [`hexagon_sector`], [`NO_SECTOR`] for
/// None. Four at a time with AVX2.
fn sector_codes(ps: &[V3], u: V3, v: V3, out: &mut [u8]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    let done = {
        // SAFETY: compiled only where the build enables AVX2, whose absence main.rs refuses.
        unsafe { simd::sector_codes4(ps, u, v, out) }
    };
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    let done = 0;
    for (c, &p) in out[done..].iter_mut().zip(&ps[done..]) {
        *c = hexagon_sector(p, u, v).map_or(NO_SECTOR, |s| s as u8);
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod simd {
    use super::{NO_SECTOR, SIN_60, WEDGE};
    use crate::core::geometry::V3;
    use std::arch::x86_64::{
        __m256d, __m256i, _mm256_add_pd, _mm256_and_pd, _mm256_and_si256, _mm256_blend_pd,
        _mm256_blendv_epi8, _mm256_castpd_si256, _mm256_cmp_pd, _mm256_loadu_pd, _mm256_mul_pd,
        _mm256_or_si256, _mm256_permute2f128_pd, _mm256_permutevar8x32_epi32, _mm256_set1_epi64x,
        _mm256_set1_pd, _mm256_setr_epi32, _mm256_setzero_pd, _mm256_shuffle_pd,
        _mm256_storeu_si256, _mm256_sub_pd, _CMP_EQ_OQ, _CMP_GT_OQ, _CMP_LT_OQ,
    };

    /// `a . w` for the four points whose coordinates are `x`, `y`, `z`, with the scalar
    /// [`dot`](crate::core::geometry::dot)'s operations in its order (same bits).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn dot4(x: __m256d, y: __m256d, z: __m256d, w: V3) -> __m256d {
        let [wx, wy, wz] = w.map(|c| _mm256_set1_pd(c));
        _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(x, wx), _mm256_mul_pd(y, wy)),
            _mm256_mul_pd(z, wz),
        )
    }

    /// The sectors of the first multiple of four of `ps` into `out`, as
    /// [`hexagon_sector`](super::hexagon_sector) finds them (the same comparisons of the same
    /// values); returns how many were done.
    #[target_feature(enable = "avx2")]
    pub(super) fn sector_codes4(ps: &[V3], u: V3, v: V3, out: &mut [u8]) -> usize {
        let table = _mm256_setr_epi32(
            WEDGE[0] as i32,
            WEDGE[1] as i32,
            WEDGE[2] as i32,
            WEDGE[3] as i32,
            WEDGE[4] as i32,
            WEDGE[5] as i32,
            WEDGE[6] as i32,
            WEDGE[7] as i32,
        );
        let (zero, half, neg_half, sin60) = (
            _mm256_setzero_pd(),
            _mm256_set1_pd(0.5),
            _mm256_set1_pd(-0.5),
            _mm256_set1_pd(SIN_60),
        );
        let bit = |b: i64| _mm256_set1_epi64x(b);
        let chunks = ps.chunks_exact(4);
        let done = ps.len() - chunks.remainder().len();
        for (four, dst) in chunks.zip(out.chunks_exact_mut(4)) {
            // SAFETY: four points are 12 contiguous f64 (V3 = [f64; 3]); unaligned loads.
            let (p0, p1, p2) = unsafe {
                let f = four.as_ptr() as *const f64;
                (
                    _mm256_loadu_pd(f),
                    _mm256_loadu_pd(f.add(4)),
                    _mm256_loadu_pd(f.add(8)),
                )
            };
            // [x0 y0 z0 x1] [y1 z1 x2 y2] [z2 x3 y3 z3] -> x, y, z of the four points.
            let t0 = _mm256_blend_pd::<0b1100>(p0, p1); // x0 y0 x2 y2
            let t1 = _mm256_blend_pd::<0b1100>(p1, p2); // y1 z1 y3 z3
            let t2 = _mm256_permute2f128_pd::<0x21>(p0, p2); // z0 x1 z2 x3
            let x = _mm256_blend_pd::<0b1010>(t0, t2);
            let y = _mm256_shuffle_pd::<0b0101>(t0, t1);
            let z = _mm256_blend_pd::<0b1010>(t2, t1);
            let a = dot4(x, y, z, u);
            let b = dot4(x, y, z, v);
            // The scalar code's comparisons: s - 0.5 a > 0, a < 0, -0.5 a - s > 0.
            let s = _mm256_mul_pd(b, sin60);
            let above30 =
                _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_sub_pd(s, _mm256_mul_pd(half, a)), zero);
            let left = _mm256_cmp_pd::<_CMP_LT_OQ>(a, zero);
            let above150 =
                _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_sub_pd(_mm256_mul_pd(neg_half, a), s), zero);
            let centre = _mm256_castpd_si256(_mm256_and_pd(
                _mm256_cmp_pd::<_CMP_EQ_OQ>(a, zero),
                _mm256_cmp_pd::<_CMP_EQ_OQ>(b, zero),
            ));
            let code: __m256i = _mm256_or_si256(
                _mm256_or_si256(
                    _mm256_and_si256(_mm256_castpd_si256(above30), bit(4)),
                    _mm256_and_si256(_mm256_castpd_si256(left), bit(2)),
                ),
                _mm256_and_si256(_mm256_castpd_si256(above150), bit(1)),
            );
            // Each 64-bit lane's low half indexes the table; its high half (0) takes entry 0,
            // which is 0.
            let sector = _mm256_permutevar8x32_epi32(table, code);
            let sector = _mm256_blendv_epi8(sector, bit(NO_SECTOR as i64), centre);
            let mut lanes = [0i64; 4];
            // SAFETY: four i64 lanes into a four-i64 array; unaligned store.
            unsafe { _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, sector) };
            for (d, l) in dst.iter_mut().zip(lanes) {
                *d = l as u8;
            }
        }
        done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sign tests pick the hexagon vertex nearest to the projected point (the definition).
    #[test]
    fn hexagon_sector_is_the_nearest_vertex() {
        let (u, v) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        for step in 0..3600 {
            let t = (step as f64 + 0.37) * std::f64::consts::PI / 1800.0;
            let r = 0.1 + (step % 7) as f64;
            let d = [r * t.cos(), r * t.sin(), 0.3];
            let nearest = HEX
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    let da = (d[0] - r * a.1[0]).powi(2) + (d[1] - r * a.1[1]).powi(2);
                    let db = (d[0] - r * b.1[0]).powi(2) + (d[1] - r * b.1[1]).powi(2);
                    da.total_cmp(&db)
                })
                .map(|(k, _)| k);
            assert_eq!(hexagon_sector(d, u, v), nearest, "angle {t}");
        }
        assert_eq!(hexagon_sector([0.0, 0.0, 2.0], u, v), None);
    }

    /// The four-at-a-time sectors are the scalar ones, lane by lane: random points in random
    /// frames, points exactly on the wedge lines, at the centre, NaN, and every run length.
    #[test]
    fn sector_codes_match_the_scalar_sector() {
        let mut rng = crate::core::rng::Rng::new(3);
        let mut unit = || 2.0 * rng.uniform() - 1.0;
        let mut out = [0u8; 40];
        for case in 0..20_000 {
            let n = [unit(), unit(), unit()];
            let TangentBasis { e1: u, e2: v } =
                hexagon_frame(normalize(n).unwrap_or([0.0, 0.0, 1.0]));
            let len = case % 41;
            let ps: Vec<V3> = (0..len)
                .map(|j| match (case + j) % 9 {
                    // On a wedge line (30, 90, 150 degrees) or at the centre of the frame.
                    0 => add(scale(u, SIN_60), scale(v, 0.5)),
                    1 => scale(v, unit()),
                    2 => add(scale(u, -SIN_60), scale(v, 0.5)),
                    3 => scale(cross(u, v), unit()),
                    4 if case % 5 == 0 => [f64::NAN, 0.0, 1.0],
                    _ => [unit(), unit(), unit()],
                })
                .collect();
            sector_codes(&ps, u, v, &mut out[..len]);
            for (j, &p) in ps.iter().enumerate() {
                let want = hexagon_sector(p, u, v).map_or(NO_SECTOR, |s| s as u8);
                assert_eq!(out[j], want, "case {case}, point {j}: {p:?}");
            }
        }
    }
}
