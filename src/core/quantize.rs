//! The scale of a curvature column stored as scaled integers, chosen from the data
//! (algorithms.md 12.4). A LAS extra-bytes column can hold `raw * scale` in an integer `raw`;
//! float noise does not compress, integers on a step a little below the estimator's error do.
//!
//! The rule, for the values v of one quantity over every point of a run: the step is the power
//! of two `q = 2^(e - 12)`, where `2^e <= P99 < 2^(e+1)` and P99 is the 99th percentile of |v|
//! over the defined values; unless the largest |v| would then exceed 2^30 steps, when the step
//! is the smallest power of two that keeps it within 2^30 steps (so an i32 never wraps or
//! saturates). A stored value is `round(v / q) * q`: both operations are exact in f64 (q is a
//! power of two), so the error is at most q/2 <= P99 / 8192 = 1.2e-4 P99, and its RMS over
//! many points q/sqrt(12) <= 7.0e-5 P99.
//!
//! Only the binary exponent of P99 matters, so [`Magnitudes`] counts the values per binary
//! exponent of |v| (exact integers) and keeps the largest |v|: sums of such counts over tiles
//! are the counts of the whole cloud, whatever the tiling, thread count or resume, and they fit
//! a few hundred bytes per tile.

use crate::core::estimate::Curvature;

/// Bits of the step below P99: the step is at most P99 / 2^12.
pub const PRECISION_BITS: i32 = 12;

/// Largest |raw value| the step allows is 2^30 (an i32 holds 2^31 - 1).
pub const HEADROOM_BITS: i32 = 30;

/// Bins: the biased exponent field of a finite f64 (0 for zero and subnormals, 1 to 2046).
const BINS: usize = 2047;

/// The bin of |v|: its biased binary exponent.
fn bin(v: f64) -> usize {
    ((v.abs().to_bits() >> 52) & 0x7ff) as usize
}

/// 2^e as an f64, exact for e in -1074..=1023 (clamped to that range).
pub fn pow2(e: i32) -> f64 {
    let e = e.clamp(-1074, 1023);
    if e >= -1022 {
        f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        f64::from_bits(1u64 << (e + 1074))
    }
}

/// A non-empty bin of [`Magnitudes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bin {
    /// The biased binary exponent of the values it counts.
    pub exponent: u16,
    /// How many values it counts.
    pub count: u64,
}

/// Counts of |v| per binary exponent and the largest |v|, over the finite values added.
#[derive(Debug, Clone, PartialEq)]
pub struct Magnitudes {
    counts: Vec<u64>,
    max: f64,
}

impl Default for Magnitudes {
    fn default() -> Self {
        Magnitudes {
            counts: vec![0; BINS],
            max: 0.0,
        }
    }
}

impl Magnitudes {
    /// Counts `v` if it is finite (undefined values, NaN, are not data).
    pub fn add(&mut self, v: f64) {
        if v.is_finite() {
            self.counts[bin(v)] += 1;
            self.max = self.max.max(v.abs());
        }
    }

    /// Adds the counts of `other`.
    pub fn merge(&mut self, other: &Magnitudes) {
        // Saturating: counts come from result-file headers, which a damaged file may inflate.
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a = a.saturating_add(*b);
        }
        self.max = self.max.max(other.max);
    }

    /// Values counted.
    pub fn count(&self) -> u64 {
        self.counts.iter().fold(0, |n, &c| n.saturating_add(c))
    }

    /// The largest |v| counted (0 when none).
    pub fn max(&self) -> f64 {
        self.max
    }

    /// The non-empty bins, in order.
    pub fn bins(&self) -> impl Iterator<Item = Bin> + '_ {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, &c)| c > 0)
            .map(|(b, &c)| Bin {
                exponent: b as u16,
                count: c,
            })
    }

    /// Rebuilds counts from [`Magnitudes::bins`] and [`Magnitudes::max`]; None when a bin is
    /// out of range, a bin's counts overflow, or the maximum is not a finite non-negative
    /// number.
    pub fn from_bins(bins: impl IntoIterator<Item = Bin>, max: f64) -> Option<Self> {
        let mut m = Magnitudes::default();
        if !(max.is_finite() && max >= 0.0) {
            return None;
        }
        m.max = max;
        for Bin { exponent, count } in bins {
            let slot = m.counts.get_mut(exponent as usize)?;
            *slot = slot.checked_add(count)?;
        }
        Some(m)
    }

    /// The biased exponent of the 99th percentile of |v| (the value of rank ceil(0.99 n) in
    /// increasing order); None when nothing was counted.
    fn p99_bin(&self) -> Option<usize> {
        let n = self.count() as u128;
        if n == 0 {
            return None;
        }
        let rank = (n * 99).div_ceil(100);
        let mut seen = 0u128;
        self.counts.iter().position(|&c| {
            seen += c as u128;
            seen >= rank
        })
    }

    /// The step of the values counted, as a power of two (see the module doc); 1 when there is
    /// no nonzero value.
    pub fn step(&self) -> f64 {
        // P99 in [2^(b - 1023), 2^(b - 1022)) for a bin b >= 1; bin 0 is zero or subnormal.
        let from_quantile = self
            .p99_bin()
            .filter(|&b| b > 0)
            .map(|b| b as i32 - 1023 - PRECISION_BITS);
        // max = m 2^E with m in [1, 2): max / 2^(E - 29) < 2^30.
        let from_max =
            (self.max > 0.0).then(|| bin(self.max).max(1) as i32 - 1023 - (HEADROOM_BITS - 1));
        match (from_quantile, from_max) {
            (Some(a), Some(b)) => pow2(a.max(b)),
            (None, Some(b)) => pow2(b),
            (Some(a), None) => pow2(a),
            (None, None) => 1.0,
        }
    }
}

/// The magnitudes of the three curvature quantities that get a step of their own: H, K, and
/// the principal curvatures k1 and k2 together (one step for both, so that the flip of
/// `--orient propagate`, which turns k1 into -k2, changes none of the counts).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CurvatureStats {
    /// Mean curvature.
    pub h: Magnitudes,
    /// Gaussian curvature.
    pub k: Magnitudes,
    /// k1 and k2.
    pub principal: Magnitudes,
}

impl CurvatureStats {
    /// Counts one point's curvature (NaN values are skipped).
    pub fn add(&mut self, c: &Curvature) {
        self.h.add(c.h);
        self.k.add(c.k);
        self.principal.add(c.k1);
        self.principal.add(c.k2);
    }

    /// Adds the counts of `other`.
    pub fn merge(&mut self, other: &CurvatureStats) {
        self.h.merge(&other.h);
        self.k.merge(&other.k);
        self.principal.merge(&other.principal);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powers_of_two_are_exact() {
        assert_eq!(pow2(0), 1.0);
        assert_eq!(pow2(-12), 1.0 / 4096.0);
        assert_eq!(pow2(30), (1u64 << 30) as f64);
        assert_eq!(pow2(-1074), f64::from_bits(1));
        assert_eq!(pow2(-1030), 2f64.powi(-1030));
        assert_eq!(pow2(1023), 2f64.powi(1023));
    }

    /// The step follows the 99th percentile's exponent: 1000 values 1..=1000 have P99 = 990,
    /// in [512, 1024), so the step is 2^(9-12) = 1/8; the error is at most half of it.
    #[test]
    fn the_step_follows_the_99th_percentile() {
        let mut m = Magnitudes::default();
        for i in 1..=1000 {
            m.add(i as f64 * if i % 2 == 0 { 1.0 } else { -1.0 });
        }
        m.add(f64::NAN);
        assert_eq!(m.count(), 1000);
        assert_eq!(m.step(), 0.125);
        let q = m.step();
        for v in [0.3, -990.7, 1000.0, 123.456] {
            let stored = (v / q).round() * q;
            assert!((stored - v).abs() <= q / 2.0);
            assert!(q <= 990.0 / 4096.0 && q > 990.0 / 8192.0);
        }
    }

    /// An outlier far beyond P99 coarsens the step only when it would not fit 2^30 steps; all
    /// zeros or no values give step 1; a plane (P99 = 0) with a few edges takes the max's.
    #[test]
    fn the_largest_value_always_fits() {
        let mut m = Magnitudes::default();
        for _ in 0..1000 {
            m.add(1.0);
        }
        m.add(1e5);
        assert_eq!(m.step(), pow2(-12));
        m.add(-1e9);
        let q = m.step();
        assert!(q > pow2(-12) && 1e9 / q <= (1u64 << 30) as f64, "{q}");
        // 1e9 = m 2^29 with m in [1, 2): the step is 2^(29 - 29).
        assert_eq!(q, 1.0);
        let mut zeros = Magnitudes::default();
        assert_eq!(zeros.step(), 1.0);
        zeros.add(0.0);
        assert_eq!(zeros.step(), 1.0);
        let mut plane = Magnitudes::default();
        for i in 0..1000 {
            plane.add(if i < 995 { 0.0 } else { 0.5 });
        }
        assert_eq!(plane.step(), pow2(-1 - 29));
    }

    /// Counts merge exactly (order does not matter) and survive their sparse form.
    #[test]
    fn counts_merge_and_round_trip() {
        let values: Vec<f64> = (0..500)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) * 0.013)
            .collect();
        let mut whole = Magnitudes::default();
        values.iter().for_each(|&v| whole.add(v));
        let (mut a, mut b) = (Magnitudes::default(), Magnitudes::default());
        values[..123].iter().for_each(|&v| a.add(v));
        values[123..].iter().for_each(|&v| b.add(v));
        b.merge(&a);
        assert_eq!(b, whole);
        let back = Magnitudes::from_bins(whole.bins(), whole.max()).expect("valid");
        assert_eq!(back, whole);
        let outside = Bin {
            exponent: 2047,
            count: 1,
        };
        assert!(Magnitudes::from_bins([outside], 0.0).is_none());
        assert!(Magnitudes::from_bins([], f64::NAN).is_none());
    }
}
