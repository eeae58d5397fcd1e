//! Colour ramps and the stretch that maps values onto them. Both ramps are defined in OKLab
//! (Ottosson 2020), where equal steps of lightness look equal: the diverging ramp runs from a
//! dark blue through white to a dark red with the same lightness and chroma at +v and -v, the
//! sequential one from a dark violet through teal and green to a light yellow with lightness
//! rising linearly, so both read in order in grey print and for the common colour blindnesses.
//! Colours outside sRGB lose chroma, never lightness.

use super::{Grid, Ramp};

/// Entries of a ramp's lookup table; odd, so that the middle entry (0 of a diverging ramp) is
/// exactly white.
pub(super) const LUT_LEN: usize = 1025;

/// An sRGB colour.
pub(super) type Rgb = [u8; 3];

/// A ramp sampled at [`LUT_LEN`] positions from 0 (low) to 1 (high).
pub(super) fn lut(ramp: Ramp) -> Vec<Rgb> {
    (0..LUT_LEN)
        .map(|i| {
            let u = i as f64 / (LUT_LEN - 1) as f64;
            let (l, c, h) = match ramp {
                Ramp::Diverging => diverging_lch(2.0 * u - 1.0),
                Ramp::Sequential => sequential_lch(u),
                Ramp::Cyclic => cyclic_lch(u),
            };
            oklch_to_srgb(l, c, h)
        })
        .collect()
}

/// The colour at position `u` in [0, 1] of a lookup table.
pub(super) fn at(lut: &[Rgb], u: f64) -> Rgb {
    let i = (u.clamp(0.0, 1.0) * (lut.len() - 1) as f64).round() as usize;
    lut[i.min(lut.len() - 1)]
}

/// OKLCh of the diverging ramp at `t` in [-1, 1]: lightness falls and chroma rises with |t|
/// alike on both sides, so only the hue tells the sign.
fn diverging_lch(t: f64) -> (f64, f64, f64) {
    let s = t.abs();
    let lightness = 1.0 - 0.62 * s;
    let chroma = 0.2 * s;
    let hue = if t >= 0.0 { 27.0 } else { 252.0 };
    (lightness, chroma, hue)
}

/// OKLCh of the sequential ramp at `u` in [0, 1]: lightness from 0.3 to 0.94, the hue turning
/// from violet through blue, teal and green to yellow.
fn sequential_lch(u: f64) -> (f64, f64, f64) {
    let lightness = 0.30 + 0.64 * u;
    let chroma = 0.11 + 0.07 * u;
    let hue = 300.0 - 195.0 * u;
    (lightness, chroma, hue)
}

/// OKLCh of the cyclic ramp at `u` in [0, 1]: every hue once at one lightness and chroma, 0
/// and 1 the same colour, so that only the hue tells the direction.
fn cyclic_lch(u: f64) -> (f64, f64, f64) {
    (0.72, 0.12, 40.0 + 360.0 * u)
}

/// sRGB of an OKLCh colour, its chroma reduced (by bisection) until it fits in sRGB.
fn oklch_to_srgb(l: f64, c: f64, hue_deg: f64) -> Rgb {
    let (sin, cos) = hue_deg.to_radians().sin_cos();
    let linear = |c: f64| oklab_to_linear_srgb(l, c * cos, c * sin);
    let fits = |rgb: [f64; 3]| rgb.iter().all(|&v| (-1e-9..=1.0 + 1e-9).contains(&v));
    let mut rgb = linear(c);
    if !fits(rgb) {
        let (mut lo, mut hi) = (0.0, c);
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if fits(linear(mid)) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        rgb = linear(lo);
    }
    rgb.map(|v| (encode_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8)
}

/// Linear sRGB of an OKLab colour (Ottosson's matrices).
fn oklab_to_linear_srgb(l: f64, a: f64, b: f64) -> [f64; 3] {
    let l_ = l + 0.396_337_777_4 * a + 0.215_803_757_3 * b;
    let m_ = l - 0.105_561_345_8 * a - 0.063_854_172_8 * b;
    let s_ = l - 0.089_484_177_5 * a - 1.291_485_548_0 * b;
    let (l3, m3, s3) = (l_ * l_ * l_, m_ * m_ * m_, s_ * s_ * s_);
    [
        4.076_741_662_1 * l3 - 3.307_711_591_3 * m3 + 0.230_969_929_2 * s3,
        -1.268_438_004_6 * l3 + 2.609_757_401_1 * m3 - 0.341_319_396_5 * s3,
        -0.004_196_086_3 * l3 - 0.703_418_614_7 * m3 + 1.707_614_701_0 * s3,
    ]
}

/// The OKLab lightness of an sRGB colour: what the tests compare to call two colours equally
/// light.
#[cfg(test)]
pub(super) fn oklab_lightness(rgb: Rgb) -> f64 {
    let [r, g, b] = rgb.map(|v| decode_srgb(f64::from(v) / 255.0));
    let l = 0.412_221_470_8 * r + 0.536_332_536_3 * g + 0.051_445_992_9 * b;
    let m = 0.211_903_498_2 * r + 0.680_699_545_1 * g + 0.107_396_956_6 * b;
    let s = 0.088_302_461_9 * r + 0.281_718_837_6 * g + 0.629_978_700_5 * b;
    0.210_454_255_3 * l.cbrt() + 0.793_617_785_0 * m.cbrt() - 0.004_072_046_8 * s.cbrt()
}

#[cfg(test)]
fn decode_srgb(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn encode_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// How values map onto a ramp: the data's range and the clip limits, from the grid's defined
/// values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Stretch {
    /// The smallest and largest defined value; `None` when no value is defined.
    pub(super) range: Option<(f64, f64)>,
    /// The value at the low end of the ramp (`-high` for a diverging ramp).
    pub(super) low: f64,
    /// The value at the high end of the ramp.
    pub(super) high: f64,
    /// The ramp.
    pub(super) ramp: Ramp,
    /// The clip percentile used (the legend's, bounded to 0..=100, or 50..=100 for a
    /// sequential ramp); NaN for a fixed scale.
    pub(super) percentile: f64,
}

impl Stretch {
    /// The stretch of `grid`'s defined (finite) values: a diverging ramp clipped at
    /// ±(percentile `pct` of |value|), a sequential one from percentile `100 - pct` to `pct`.
    /// Percentiles are exact (selected from a copy) and interpolate linearly between ranks.
    /// A `fixed` scale (made symmetric for a diverging ramp) replaces them, and a cyclic ramp
    /// spans 0 to 360 unless given one.
    pub(super) fn of(grid: &Grid, ramp: Ramp, pct: f64, fixed: Option<(f64, f64)>) -> Stretch {
        let pct = if pct.is_finite() {
            pct
        } else {
            super::DEFAULT_CLIP_PERCENTILE
        };
        let defined = || grid.values.iter().filter(|x| x.is_finite());
        let range = defined().fold(None, |r: Option<(f32, f32)>, &x| {
            Some(r.map_or((x, x), |(lo, hi)| (lo.min(x), hi.max(x))))
        });
        let range = range.map(|(lo, hi)| (f64::from(lo), f64::from(hi)));
        let fixed = fixed.or((ramp == Ramp::Cyclic).then_some((0.0, 360.0)));
        if let Some((low, high)) = fixed {
            let limit = low.abs().max(high.abs());
            let (low, high) = match ramp {
                Ramp::Diverging => (-limit, limit),
                _ => (low, high),
            };
            return Stretch {
                range,
                low,
                high,
                ramp,
                percentile: f64::NAN,
            };
        }
        let percentile_used = match ramp {
            Ramp::Diverging => pct.clamp(0.0, 100.0),
            Ramp::Sequential | Ramp::Cyclic => pct.clamp(50.0, 100.0),
        };
        // One copy in f32 (|value| for a diverging ramp): 4 bytes a defined pixel.
        let mut copy: Vec<f32> = match ramp {
            Ramp::Diverging => defined().map(|x| x.abs()).collect(),
            Ramp::Sequential | Ramp::Cyclic => defined().copied().collect(),
        };
        let p = percentile_used;
        let (low, high) = match ramp {
            Ramp::Diverging => {
                let limit = percentile(&mut copy, p);
                (-limit, limit)
            }
            Ramp::Sequential | Ramp::Cyclic => {
                (percentile(&mut copy, 100.0 - p), percentile(&mut copy, p))
            }
        };
        Stretch {
            range,
            low,
            high,
            ramp,
            percentile: percentile_used,
        }
    }

    /// The position in [0, 1] of `value` on the ramp, values beyond the clip limits saturating;
    /// `None` for no data. A ramp with no extent (a constant grid) puts 0 in the middle of a
    /// diverging ramp and its sign at the ends, and every value in the middle of a sequential one.
    pub(super) fn position(&self, value: f32) -> Option<f64> {
        if !value.is_finite() {
            return None;
        }
        let v = f64::from(value);
        let span = self.high - self.low;
        Some(match self.ramp {
            Ramp::Diverging if span > 0.0 => 0.5 + 0.5 * (v / self.high).clamp(-1.0, 1.0),
            Ramp::Diverging if v > 0.0 => 1.0,
            Ramp::Diverging if v < 0.0 => 0.0,
            Ramp::Diverging => 0.5,
            Ramp::Sequential | Ramp::Cyclic if span > 0.0 => {
                ((v - self.low) / span).clamp(0.0, 1.0)
            }
            Ramp::Sequential | Ramp::Cyclic => 0.5,
        })
    }
}

/// The `p`-th percentile (0..=100) of `values`, interpolating linearly between ranks (numpy's
/// default); 0 for no values. The two ranks are found by selection, not a full sort, which
/// reorders `values`.
pub(super) fn percentile(values: &mut [f32], p: f64) -> f64 {
    let Some(last) = values.len().checked_sub(1) else {
        return 0.0;
    };
    let rank = p / 100.0 * last as f64;
    let below = (rank.floor() as usize).min(last);
    let frac = rank - below as f64;
    let (_, &mut a, upper) = values.select_nth_unstable_by(below, f32::total_cmp);
    // The next rank is the least of the values above the selected one.
    let b = upper.iter().copied().min_by(f32::total_cmp).unwrap_or(a);
    let (a, b) = (f64::from(a), f64::from(b));
    a + frac * (b - a)
}
