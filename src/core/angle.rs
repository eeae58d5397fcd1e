//! The arctangent of the terrain columns (slope, aspect, shape index: three a point), within 2
//! units in the last place of the C library's and about twice as fast (1M random arguments:
//! 10.4 ms against glibc's 21.5 ms): glibc's `atan2` rounds correctly at the price of a slow
//! path, which made it a quarter of the terrain columns' cost.
//! The columns are written as f32 or as integers of a coarser step, so an ulp or two of f64
//! is far below what any output holds.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// atan(k/8) for k = 0..=8, the nearest f64 (checked against `f64::atan` in the tests).
const ATAN_EIGHTHS: [f64; 9] = [
    0.0,
    0.124_354_994_546_761_44,
    0.244_978_663_126_864_14,
    0.358_770_670_270_572_25,
    0.463_647_609_000_806_1,
    0.558_599_315_343_562_4,
    0.643_501_108_793_284_4,
    0.718_829_999_621_624_5,
    FRAC_PI_4,
];

/// The angle of the vector (x, y) from +x, in (-pi, pi], as `f64::atan2` (the same signs of
/// zero and quadrants; NaN, infinite and (0, 0) arguments are passed to it).
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    if !(ax.is_finite() && ay.is_finite()) || (ax == 0.0 && ay == 0.0) {
        return y.atan2(x);
    }
    atan2_finite(y, x)
}

/// [`atan2`] of finite arguments that are not both zero, as the caller knows them to be: the
/// same bits without the tests for the library's special cases (a fifth of the instructions
/// of a point's terrain values, with their three arctangents).
#[inline(always)]
pub fn atan2_finite(y: f64, x: f64) -> f64 {
    debug_assert!(y.is_finite() && x.is_finite() && (y != 0.0 || x != 0.0));
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay > ax;
    let (lo, hi) = if steep { (ax, ay) } else { (ay, ax) };
    let a = atan_ratio(lo, hi);
    let a = if steep { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    a.copysign(y)
}

/// atan(lo / hi) for 0 <= lo <= hi, hi > 0: atan(c) + atan(u) with c the multiple of 1/8
/// nearest lo/hi (found by comparisons, without dividing) and u = (lo - c hi) / (hi + c lo)
/// = (t - c) / (1 + t c), |u| <= 1/16, one division. The odd series of atan(u) up to u^13
/// leaves an error below u^15/15 < 2^-63.
#[inline(always)]
fn atan_ratio(lo: f64, hi: f64) -> f64 {
    // k = round(8 lo / hi): the count of the midpoints (2j + 1)/16 that lo / hi passes.
    let k = (0..8)
        .map(|j| usize::from(16.0 * lo > f64::from(2 * j + 1) * hi))
        .sum::<usize>();
    let c = k as f64 / 8.0;
    let u = (-c).mul_add(hi, lo) / c.mul_add(lo, hi);
    let u2 = u * u;
    let series: f64 = 1.0 / 13.0;
    let series = series.mul_add(-u2, 1.0 / 11.0);
    let series = series.mul_add(-u2, 1.0 / 9.0);
    let series = series.mul_add(-u2, 1.0 / 7.0);
    let series = series.mul_add(-u2, 1.0 / 5.0);
    let series = series.mul_add(-u2, 1.0 / 3.0);
    let odd = (u * u2) * series;
    ATAN_EIGHTHS[k] + (u - odd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::Rng;

    /// Units in the last place between `a` and `b` (same sign expected).
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn the_table_is_the_nearest_f64_of_each_arctangent() {
        for (k, &v) in ATAN_EIGHTHS.iter().enumerate() {
            assert_eq!(v, (k as f64 / 8.0).atan(), "atan({k}/8)");
        }
    }

    /// Against the C library over every quadrant and magnitudes from 1e-300 to 1e300: within 2
    /// ulps (or 1e-300 absolute near zero).
    #[test]
    fn agrees_with_the_library_within_two_ulps() {
        let mut rng = Rng::new(11);
        for i in 0..400_000 {
            let scale = |r: &mut Rng| 10f64.powf(r.uniform() * 40.0 - 20.0);
            let (mut y, mut x) = (rng.uniform() * 2.0 - 1.0, rng.uniform() * 2.0 - 1.0);
            if i % 3 == 0 {
                y *= scale(&mut rng);
                x *= scale(&mut rng);
            }
            if i % 1000 == 0 {
                (y, x) = (y * 1e280, x * 1e-280);
            }
            let (want, got) = (y.atan2(x), atan2(y, x));
            if want.abs() < 1e-300 {
                assert!((want - got).abs() < 1e-300, "atan2({y}, {x})");
                continue;
            }
            let u = ulps(want, got);
            assert!(
                u <= 2,
                "atan2({y:e}, {x:e}) = {got:e}, library {want:e}: {u} ulps"
            );
        }
    }

    #[test]
    fn signs_of_zero_axes_and_special_values_are_the_library_s() {
        let cases = [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (1.0, -0.0),
            (-1.0, 0.0),
            (-1.0, -0.0),
            (0.0, 0.0),
            (-0.0, -0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (f64::INFINITY, 1.0),
            (1.0, f64::NEG_INFINITY),
            (f64::INFINITY, f64::INFINITY),
            (1e-320, 1.0),
            (1.0, 1e-320),
        ];
        for (y, x) in cases {
            let (want, got) = (y.atan2(x), atan2(y, x));
            assert!(
                ulps(want, got) <= 1,
                "atan2({y}, {x}): {got} against {want}"
            );
            assert_eq!(
                got.is_sign_negative(),
                want.is_sign_negative(),
                "atan2({y}, {x})"
            );
        }
        assert!(atan2(f64::NAN, 1.0).is_nan() && atan2(1.0, f64::NAN).is_nan());
    }
}
