//! The scan statistics of a bucket task as text (`buckets.done` in its directory): the point
//! count, the exact centroid sums, the bounds as f64 bits and the points per tile. Written last,
//! so a task directory with this file is complete; every task's file merges into the run's
//! statistics with the same bits in any grouping.

use crate::core::plan::{Centroid, ScanStats};

/// The statistics as text.
pub(crate) fn stats_text(s: &ScanStats) -> String {
    let c = &s.centroid;
    let bits = |v: [f64; 3]| format!("{} {} {}", v[0].to_bits(), v[1].to_bits(), v[2].to_bits());
    let mut t = format!(
        "count {}\ncentroid {} {} {} {}\nmin {}\nmax {}\n",
        s.count,
        c.sum[0],
        c.sum[1],
        c.sum[2],
        c.n,
        bits(s.min),
        bits(s.max)
    );
    for (k, n) in &s.per_tile {
        t.push_str(&format!("tile {} {} {n}\n", k.0, k.1));
    }
    t
}

/// Parses [`stats_text`]; None if anything is off (the task is then not done).
pub(crate) fn parse_stats(text: &str) -> Option<ScanStats> {
    let mut s = ScanStats::empty();
    let bits = |a: &str, b: &str, c: &str| -> Option<[f64; 3]> {
        Some([
            f64::from_bits(a.parse().ok()?),
            f64::from_bits(b.parse().ok()?),
            f64::from_bits(c.parse().ok()?),
        ])
    };
    let mut complete = false;
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["count", n] => {
                s.count = n.parse().ok()?;
                complete = true;
            }
            ["centroid", a, b, c, n] => {
                s.centroid = Centroid {
                    sum: [a.parse().ok()?, b.parse().ok()?, c.parse().ok()?],
                    n: n.parse().ok()?,
                };
            }
            ["min", a, b, c] => s.min = bits(a, b, c)?,
            ["max", a, b, c] => s.max = bits(a, b, c)?,
            ["tile", x, y, n] => {
                s.per_tile
                    .insert((x.parse().ok()?, y.parse().ok()?), n.parse().ok()?);
            }
            _ => return None,
        }
    }
    let counted: u64 = s.per_tile.values().sum();
    (complete && counted == s.count && s.centroid.n == s.count).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_text_round_trips_and_rejects_damage() {
        let mut s = ScanStats::empty();
        s.add([0.1, -0.3, 5.0]);
        s.add([9.0, 8.0, 7.0]);
        s.in_tile((-3, 4), 2);
        s.add([1e6 + 0.25, 4e6, -2.0]);
        s.in_tile((0, 0), 1);
        let text = stats_text(&s);
        let t = parse_stats(&text).expect("parse");
        assert_eq!(
            (t.count, t.min, t.max, t.centroid, &t.per_tile),
            (s.count, s.min, s.max, s.centroid, &s.per_tile)
        );
        // A truncated file (the tile lines cut) does not pass for a finished task.
        let cut = &text[..text.rfind("tile").expect("tile lines")];
        assert!(parse_stats(cut).is_none());
        assert!(parse_stats("count 3\nbogus\n").is_none());
    }
}
