//! Coordinates from the integers a LAS record stores, in a form that does not depend on the
//! file's offset.
//!
//! A LAS file stores each coordinate as an integer `q` with a scale `s` and an offset `o`: the
//! position is `q * s + o`. Two files can hold the same points on the same grid with offsets
//! that differ by whole steps (a reprojection tool, a merge, a COPC rewrite all pick their own
//! offsets): their integers then differ by a constant, and `q * s + o` rounds differently in
//! each file. Those last-bit differences flip nearest-neighbour ties and change results.
//!
//! [`AxisGrid`] writes the offset as whole steps plus a phase, `o = (n + phase) * s` with `n`
//! an integer and `phase` in [-1/2, 1/2] rounded to 2^-20 of a step, and gives the coordinate
//! of `q` as `((q + n) + phase) * s`. The integer `q + n` is the point's index on the grid
//! counted from the origin, the same in every file that holds the point on that grid, and
//! `phase` is the same in every such file too: the coordinate is a function of the point and
//! the grid alone, bit for bit. It differs from `q * s + o` by at most 2^-21 of a step (the
//! phase's rounding) plus the last bit.
//!
//! A phase within the f64 noise of the step count (`representation_noise`) is 0: an offset
//! that is a whole number of steps in decimal is one in every file, whatever its magnitude.
//! The phase rounding moves a grid by at most 2^-21 of a step, far below any LAS scale's
//! meaning. The one split that two files could make differently is a phase within float noise
//! of an odd multiple of 2^-21 of a step; an offset that is a whole or half number of steps
//! (every writer's choice) is far from that. Grids whose offset is more than 2^52 steps from 0,
//! or whose scale is not a positive finite number, keep `q * s + o`.

/// The phase is rounded to this fraction of a step (2^-20).
const PHASE_STEPS: f64 = (1u64 << 20) as f64;

/// Offsets beyond this many steps keep the file's formula (their step count is not an exact
/// integer in f64).
const MAX_STEPS: f64 = (1u64 << 52) as f64;

/// A bound, in steps, on how far `offset / scale` computed in f64 lies from the ratio of the
/// decimal numbers a writer meant (16 times the sum of the offset's half ulp over the scale and
/// the scale's and the division's relative rounding): an offset that is a whole number of steps
/// in decimal (5270000 - 567 * 0.00025) comes out that far from an integer, which at UTM
/// northings and a 0.00025 scale exceeds the phase's 2^-20 of a step.
fn representation_noise(scale: f64, offset: f64) -> f64 {
    let o = offset.abs();
    let ulp = f64::from_bits(o.to_bits() + 1) - o;
    16.0 * (ulp / 2.0 / scale + (o / scale) * 2.0 * f64::EPSILON)
}

/// How one axis's stored integers map to coordinates: the file's scale and offset, and a factor
/// applied last (a vertical unit's, 1 for x and y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisGrid {
    scale: f64,
    offset: f64,
    post: f64,
    /// The offset's whole steps and phase, or None where the file's formula is kept.
    split: Option<(i64, f64)>,
    /// `1 / (scale * post)`: [`AxisGrid::integer`]'s first guess multiplies by it.
    inverse: f64,
}

impl AxisGrid {
    /// The grid of a file's `scale` and `offset`, its values multiplied by `post` last.
    pub fn new(scale: f64, offset: f64, post: f64) -> Self {
        let ratio = offset / scale;
        let split =
            (scale.is_finite() && scale > 0.0 && ratio.is_finite() && ratio.abs() < MAX_STEPS)
                .then(|| {
                    let n = ratio.round();
                    let phase = match (ratio - n).abs() <= representation_noise(scale, offset) {
                        true => 0.0,
                        false => ((ratio - n) * PHASE_STEPS).round() / PHASE_STEPS,
                    };
                    (n as i64, phase)
                });
        Self {
            scale,
            offset,
            post,
            split,
            inverse: 1.0 / (scale * post),
        }
    }

    /// The file's scale.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The file's offset.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// The factor applied last.
    pub fn post(&self) -> f64 {
        self.post
    }

    /// The coordinate of stored integer `q`.
    #[inline]
    pub fn value(&self, q: i64) -> f64 {
        match self.split {
            Some((n, phase)) => ((q.wrapping_add(n)) as f64 + phase) * self.scale * self.post,
            None => (q as f64 * self.scale + self.offset) * self.post,
        }
    }

    /// The integer whose coordinate is exactly `v` (bit for bit), if there is one: the nearest
    /// to `v`'s step count or one of its two neighbours, whichever [`AxisGrid::value`] gives
    /// back `v` from.
    #[inline]
    pub fn integer(&self, v: f64) -> Option<i64> {
        // A multiplication rather than two divisions: the guess only has to be within a step.
        let q = match self.split {
            Some((n, phase)) => (v * self.inverse - phase).round() - n as f64,
            None => ((v / self.post - self.offset) / self.scale).round(),
        };
        if !q.is_finite() || q.abs() >= MAX_STEPS {
            return None;
        }
        let q = q as i64;
        [q, q - 1, q + 1]
            .into_iter()
            .find(|&c| self.value(c).to_bits() == v.to_bits())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same points on the same grid, offsets apart by whole steps: the same coordinates,
    /// bit for bit, for every point; and within a step's 2^-21 of `q * s + o`.
    #[test]
    fn offsets_whole_steps_apart_give_the_same_bits() {
        let s = 0.00025;
        let offsets = [0.0, 0.1, 0.35, 500_000.0, 4_100_123.25, -12.5];
        let mut rng = crate::core::rng::Rng::new(7);
        for _ in 0..2000 {
            let g = (rng.next_u64() % 40_000_000_000) as i64 - 20_000_000_000;
            let mut first: Option<u64> = None;
            for &o in &offsets {
                let a = AxisGrid::new(s, o, 1.0);
                let steps = (o / s).round() as i64;
                let q = g - steps;
                let v = a.value(q);
                let bits = v.to_bits();
                assert_eq!(
                    *first.get_or_insert(bits),
                    bits,
                    "offset {o}, grid index {g}"
                );
                let file = q as f64 * s + o;
                // The file's formula rounds twice, at the magnitude of its larger term.
                let ulps = (q as f64 * s).abs().max(o.abs()) * 4.5e-16;
                assert!((v - file).abs() <= s * 1e-6 + ulps, "{v} vs {file}");
                assert_eq!(a.integer(v), Some(q));
            }
        }
    }

    /// Offsets that are whole steps apart in decimal but not in binary (a UTM northing moved
    /// by whole steps of 0.00025, as a writer computes it in f64 or parses it from text) give
    /// the same bits: the f64 noise of the step count is not taken for a phase.
    #[test]
    fn whole_steps_apart_in_decimal_give_the_same_bits() {
        let s = 0.00025;
        let base = AxisGrid::new(s, 5_270_000.0, 1.0);
        for k in [-567i64, 1, 1234, -98_765, 4_000_001] {
            let computed = 5_270_000.0 - k as f64 * s;
            let parsed: f64 = format!("{computed:.5}").parse().expect("decimal");
            for o in [computed, parsed] {
                let g = AxisGrid::new(s, o, 1.0);
                for q in [0i64, 17, 1_000_000, -3_000_000] {
                    assert_eq!(
                        g.value(q + k).to_bits(),
                        base.value(q).to_bits(),
                        "offset {o} moved {k} steps"
                    );
                }
            }
        }
        // A true sub-step phase is kept.
        let tenth = AxisGrid::new(s, 5_270_000.0 + 0.1 * s, 1.0);
        assert!((tenth.value(0) - 5_270_000.000025).abs() < 1e-9);
    }

    /// An offset half a step off the grid of another file keeps its half: the coordinates are
    /// the true positions of both grids, not snapped together.
    #[test]
    fn a_half_step_phase_is_kept() {
        let a = AxisGrid::new(0.01, 0.0, 1.0);
        let b = AxisGrid::new(0.01, 0.005, 1.0);
        assert_eq!(a.value(100), 1.0);
        assert!((b.value(100) - 1.005).abs() < 1e-12);
        assert_eq!(b.value(100), AxisGrid::new(0.01, 1.005, 1.0).value(0));
    }

    /// A scale of zero or an absurd offset keeps the file's formula.
    #[test]
    fn degenerate_grids_keep_the_file_formula() {
        for (s, o) in [(0.0, 3.0), (1e-3, 1e300), (f64::NAN, 0.0)] {
            let g = AxisGrid::new(s, o, 2.0);
            assert_eq!(g.value(5).to_bits(), ((5.0 * s + o) * 2.0).to_bits());
        }
    }
}
