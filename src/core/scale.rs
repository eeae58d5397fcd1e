//! `-k auto`: the scale chosen per point among a ladder of neighbourhood sizes, by the
//! stability of H across scales (algorithms.md 9, after the ASO paper's Prop. 2 and Growing
//! Least Squares). This file holds the ladder and the choice of a rung from the criterion;
//! `core::compute::auto` runs the rungs over a tile.

use std::fmt;

/// How many nearest points (the point itself included) the criterion averages over: C_s(p) is
/// the mean of (H_{s+1}(q) - H_s(q))^2 over the 64 nearest q of p (algorithms.md 9.3;
/// without this smoothing the rule was 1.7x worse).
pub const SMOOTH: usize = 64;

/// The smallest first rung: rungs of K <= 10 have heavy tails that break the rule
/// (algorithms.md 9.1), and the criterion's 64 neighbours must fit in the top rung's list.
pub const MIN_FIRST_RUNG: usize = 16;

/// The ladder of `-k auto`: rungs K_s = `min` * 2^s up to `max` (`--k-range min..max`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ladder {
    /// K of the first rung.
    pub min: usize,
    /// K of the top rung: `min` times a power of two, at least 4 `min`.
    pub max: usize,
}

impl Default for Ladder {
    /// 20..320: the rungs 20, 40, 80, 160, 320 of algorithms.md 9.1.
    fn default() -> Self {
        Ladder { min: 20, max: 320 }
    }
}

impl fmt::Display for Ladder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.min, self.max)
    }
}

impl Ladder {
    /// Parses `MIN..MAX` (e.g. `20..320`): MIN at least [`MIN_FIRST_RUNG`], MAX = MIN * 2^m
    /// with m from 2 to 6 (3 to 7 rungs: the rule compares neighbouring pairs and needs two
    /// pairs to tell a falling error from a rising one).
    pub fn parse(text: &str) -> Result<Ladder, String> {
        let usage = "give --k-range as MIN..MAX, e.g. 20..320 (rungs 20, 40, 80, 160, 320)";
        let (a, b) = text
            .split_once("..")
            .ok_or_else(|| format!("--k-range {text:?}: {usage}"))?;
        let num = |s: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| format!("--k-range {text:?}: {s:?} is not a count; {usage}"))
        };
        let ladder = Ladder {
            min: num(a)?,
            max: num(b)?,
        };
        if ladder.min < MIN_FIRST_RUNG {
            return Err(format!(
                "--k-range {text}: the first rung must be at least {MIN_FIRST_RUNG} neighbours (smaller ones give outliers that mislead the choice); {usage}"
            ));
        }
        let ratio = ladder.max / ladder.min;
        let doublings = ratio.trailing_zeros() as usize;
        if !ladder.max.is_multiple_of(ladder.min)
            || !ratio.is_power_of_two()
            || !(2..=6).contains(&doublings)
        {
            return Err(format!(
                "--k-range {text}: MAX must be MIN times 4, 8, 16, 32 or 64 (the rungs double); {usage}"
            ));
        }
        if ladder.max > 10_000 {
            return Err(format!(
                "--k-range {text}: the top rung may have at most 10000 neighbours"
            ));
        }
        Ok(ladder)
    }

    /// How many rungs.
    pub fn rungs(&self) -> usize {
        (self.max / self.min).trailing_zeros() as usize + 1
    }

    /// Neighbours of rung `s` (the estimator's neighbourhood).
    pub fn k(&self, s: usize) -> usize {
        self.min << s
    }

    /// Neighbours of rung `s`'s PCA normals: half its K (algorithms.md 9.2).
    pub fn normal_k(&self, s: usize) -> usize {
        self.k(s) / 2
    }
}

/// Bits of the `ScaleFlags` column.
pub mod scale_flags {
    /// The top rung was chosen while the criterion was still falling (C of the top pair below
    /// the one before it): a larger K would likely have been better (strong noise).
    pub const SATURATED: u8 = 1;
    /// H was undefined at the rung the criterion chose: the next larger rung with H defined
    /// was taken.
    pub const LARGER_DEFINED: u8 = 2;
    /// No rung pair had a defined criterion (too few defined neighbours): the smallest rung
    /// with H defined was taken.
    pub const NO_CRITERION: u8 = 4;
}

/// The rung a point takes and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Choice {
    /// The chosen rung.
    pub rung: usize,
    /// [`scale_flags`] bits.
    pub flags: u8,
}

/// The rule of algorithms.md 9.3, 9.4: `c[s]` is C_s (NaN when undefined) for the pairs
/// (s, s + 1), `defined[s]` whether the point's H is defined at rung s. s* = argmin C (the
/// smaller s on ties); take s* + 1, or s* when the pair above s* exists and C rises by a
/// factor 1.5 or more to it (bias growing fast); then the next larger rung with H defined.
pub fn choose(c: &[f64], defined: &[bool]) -> Choice {
    let rungs = defined.len();
    let best = (0..c.len())
        .filter(|&s| !c[s].is_nan())
        .min_by(|&a, &b| c[a].total_cmp(&c[b]).then(a.cmp(&b)));
    let Some(star) = best else {
        let rung = (0..rungs).find(|&s| defined[s]).unwrap_or(rungs - 1);
        return Choice {
            rung,
            flags: scale_flags::NO_CRITERION,
        };
    };
    let guard = star + 2 < rungs && c[star + 1] >= 1.5 * c[star];
    let chosen = if guard { star } else { star + 1 };
    let mut flags = 0;
    if chosen == rungs - 1 && rungs >= 3 && c[rungs - 2] < c[rungs - 3] {
        flags |= scale_flags::SATURATED;
    }
    let rung = match (chosen..rungs).find(|&s| defined[s]) {
        Some(s) if s != chosen => {
            flags |= scale_flags::LARGER_DEFINED;
            s
        }
        Some(s) => s,
        None => chosen,
    };
    Choice { rung, flags }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ladders_parse_and_refuse_with_reasons() {
        let l = Ladder::parse("20..320").expect("valid");
        assert_eq!(l, Ladder::default());
        assert_eq!(l.rungs(), 5);
        assert_eq!(
            (0..5).map(|s| l.k(s)).collect::<Vec<_>>(),
            [20, 40, 80, 160, 320]
        );
        assert_eq!(l.normal_k(4), 160);
        assert_eq!(l.to_string(), "20..320");
        assert_eq!(Ladder::parse("16..64").map(|l| l.rungs()), Ok(3));
        for bad in [
            "20",
            "10..160",
            "20..300",
            "20..40",
            "20..2560",
            "a..b",
            "20..320..640",
        ] {
            assert!(Ladder::parse(bad).is_err(), "{bad}");
        }
        assert!(Ladder::parse("20..300")
            .expect_err("not a power of two")
            .contains("times 4, 8"));
    }

    /// The rule's cases, on the criterion values of algorithms.md 9.4.
    #[test]
    fn the_rung_follows_the_criterion() {
        let all = [true; 5];
        // Minimum at s* = 1, C_2 < 1.5 C_1: s* + 1.
        assert_eq!(
            choose(&[4.0, 1.0, 1.4, 3.0], &all),
            Choice { rung: 2, flags: 0 }
        );
        // C_2 >= 1.5 C_1: bias growing fast, s*.
        assert_eq!(
            choose(&[4.0, 1.0, 1.5, 3.0], &all),
            Choice { rung: 1, flags: 0 }
        );
        // Minimum at the top pair, still falling: the top rung, saturated.
        let sat = choose(&[4.0, 3.0, 2.0, 1.0], &all);
        assert_eq!(
            sat,
            Choice {
                rung: 4,
                flags: scale_flags::SATURATED
            }
        );
        // A tie at the minimum takes the smaller pair: rung 3, not the saturated top.
        assert_eq!(
            choose(&[2.0, 3.0, 1.0, 1.0], &all),
            Choice { rung: 3, flags: 0 }
        );
        // Ties take the smaller s; NaN pairs are skipped.
        assert_eq!(choose(&[2.0, 2.0, 9.0, 9.0], &all).rung, 1);
        assert_eq!(choose(&[f64::NAN, 2.0, 9.0, f64::NAN], &all).rung, 1);
        // H undefined at the chosen rung: the next larger defined one.
        let holes = [true, true, false, false, true];
        assert_eq!(
            choose(&[4.0, 1.0, 1.4, 3.0], &holes),
            Choice {
                rung: 4,
                flags: scale_flags::LARGER_DEFINED
            }
        );
        // No criterion at all: the smallest defined rung.
        let none = choose(&[f64::NAN; 4], &[false, true, true, true, true]);
        assert_eq!(
            none,
            Choice {
                rung: 1,
                flags: scale_flags::NO_CRITERION
            }
        );
    }
}
