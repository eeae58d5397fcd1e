//! The legend panel beside a quick look's map: the quantity and its unit, a colour bar with
//! its limits labelled (and a triangle at an end where values go beyond it and saturate), the
//! data's full range, how it was clipped, and what transparency and shading mean. Opaque
//! white, text in near-black. Its size follows the map's: laid out in font pixels, drawn at a
//! whole `scale`, so that a picture shrunk to fit a screen keeps a legible legend.

use super::canvas::Rgba;
use super::colour::{self, Rgb, Stretch};
use super::font::{text_width, CAP_H, GLYPH_H};
use super::{Legend, Picture, Ramp, SUN_ALTITUDE_DEG, SUN_AZIMUTH_DEG};

// Lengths in font pixels, multiplied by the panel's scale.
const PAD: u32 = 8;
const LINE: u32 = GLYPH_H + 3;
const BAR_W: u32 = 14;
const BAR_H: u32 = 128;
/// Height of the triangles that mark saturated ends.
const TRIANGLE: u32 = 7;
const TICK: u32 = 4;
/// From the tick's end to its label.
const GAP: u32 = 3;
const INK: Rgba = [34, 34, 34, 255];
const RULE: Rgba = [110, 110, 110, 255];
const PAPER: Rgba = [255, 255, 255, 255];

/// What the legend reports beyond its title.
pub(super) struct Notes<'a> {
    /// The mapping of values to colours.
    pub(super) stretch: &'a Stretch,
    /// Whether the map is hillshaded.
    pub(super) shaded: bool,
    /// Whether some pixels of the map are no data.
    pub(super) any_missing: bool,
}

/// A laid-out legend panel.
pub(super) struct Panel {
    title: String,
    /// Tick positions on the bar (0 = low end, 1 = high end) and their labels; empty when
    /// there is no data (and then no bar).
    ticks: Vec<(f64, String)>,
    /// Whether values lie beyond the low and the high end.
    saturated: (bool, bool),
    lines: Vec<String>,
    width: u32,
    /// Image pixels per font pixel.
    scale: u32,
}

impl Panel {
    /// The panel of `legend` reporting `notes`, drawn at `scale` image pixels per font pixel.
    pub(super) fn new(legend: &Legend<'_>, notes: &Notes<'_>, scale: u32) -> Panel {
        let s = notes.stretch;
        let title = if legend.unit.is_empty() {
            legend.title.to_string()
        } else {
            format!("{} ({})", legend.title, legend.unit)
        };
        let mut lines = Vec::new();
        if !legend.statistic.is_empty() {
            lines.push(legend.statistic.to_string());
        }
        let (mut ticks, mut saturated) = (Vec::new(), (false, false));
        match s.range {
            None => lines.push("no data in any cell".to_string()),
            Some((min, max)) => {
                ticks = ticks_of(s);
                saturated = (min < s.low, max > s.high);
                if min == max {
                    lines.push(format!("all values {}", compact(min)));
                } else {
                    lines.push(format!("data {} to {}", compact(min), compact(max)));
                    lines.push(clip_note(s));
                }
                if notes.any_missing {
                    lines.push("no data: transparent, grey edge".to_string());
                }
            }
        }
        if notes.shaded {
            lines.push(format!(
                "hillshade: sun az {SUN_AZIMUTH_DEG}, alt {SUN_ALTITUDE_DEG}"
            ));
        }
        let labels = ticks.iter().map(|(_, l)| text_width(l, 1)).max();
        let bar_block = labels.map_or(0, |w| BAR_W + TICK + GAP + w);
        let text = lines.iter().chain([&title]).map(|l| text_width(l, 1));
        let width = (text.chain([bar_block]).max().unwrap_or(0) + 2 * PAD) * scale;
        Panel {
            title,
            ticks,
            saturated,
            lines,
            width,
            scale,
        }
    }

    /// Pixels across.
    pub(super) fn width(&self) -> u32 {
        self.width
    }

    /// The top of the colour bar, below the title and the upper triangle.
    fn bar_top(&self) -> u32 {
        (PAD + LINE + 5 + TRIANGLE) * self.scale
    }

    /// The top of the text lines, below the bar if there is one.
    fn lines_top(&self) -> u32 {
        if self.ticks.is_empty() {
            (PAD + LINE + 2) * self.scale
        } else {
            self.bar_top() + (BAR_H + TRIANGLE + 7) * self.scale
        }
    }

    /// Pixels down.
    pub(super) fn height(&self) -> u32 {
        self.lines_top() + (self.lines.len() as u32 * LINE + PAD) * self.scale
    }

    /// Draws the panel on `picture` from column `x0` to its right edge, the bar from `lut`.
    pub(super) fn draw(&self, picture: &mut Picture, x0: u32, lut: &[Rgb]) {
        picture.fill(
            x0,
            0,
            picture.width - x0.min(picture.width),
            picture.height,
            PAPER,
        );
        let k = self.scale;
        let x = x0 + PAD * k;
        // The title drawn twice, a pixel apart: bolder than the notes below it.
        picture.text(x, PAD * k, &self.title, k, INK);
        picture.text(x + 1, PAD * k, &self.title, k, INK);
        if !self.ticks.is_empty() {
            self.draw_bar(picture, x, lut);
        }
        for (i, line) in self.lines.iter().enumerate() {
            picture.text(x, self.lines_top() + i as u32 * LINE * k, line, k, INK);
        }
    }

    /// The colour bar (high end up) at column `x`, its saturation triangles, ticks and labels.
    fn draw_bar(&self, picture: &mut Picture, x: u32, lut: &[Rgb]) {
        let k = self.scale;
        let (top, bar_w, bar_h, tri) = (self.bar_top(), BAR_W * k, BAR_H * k, TRIANGLE * k);
        let opaque = |c: Rgb| [c[0], c[1], c[2], 255];
        for y in 0..bar_h {
            let u = 1.0 - f64::from(y) / f64::from(bar_h - 1);
            picture.fill(x, top + y, bar_w, 1, opaque(colour::at(lut, u)));
        }
        // The frame keeps the white middle of a diverging bar visible on the white panel.
        picture.frame(x - 1, top - 1, bar_w + 2, bar_h + 2, RULE);
        for i in 0..tri {
            let w = bar_w * (i + 1) / tri;
            let left = x + (bar_w - w) / 2;
            if self.saturated.1 {
                let c = opaque(colour::at(lut, 1.0));
                picture.fill(left, top - 2 - tri + i, w, 1, c);
            }
            if self.saturated.0 {
                let c = opaque(colour::at(lut, 0.0));
                picture.fill(left, top + bar_h + 1 + tri - i, w, 1, c);
            }
        }
        for (u, label) in &self.ticks {
            let y = top + ((1.0 - u) * f64::from(bar_h - 1)).round() as u32;
            picture.fill(x + bar_w, y.saturating_sub(k / 2), TICK * k, k, INK);
            let ty = y.saturating_sub(CAP_H * k / 2);
            picture.text(x + bar_w + (TICK + GAP) * k, ty, label, k, INK);
        }
    }
}

/// The ticks of the bar: the clip limits and 0 (diverging) or the low and high limits
/// (sequential); one tick when the ramp has no extent.
fn ticks_of(s: &Stretch) -> Vec<(f64, String)> {
    match s.ramp {
        Ramp::Diverging if s.high > 0.0 => vec![
            (1.0, compact(s.high)),
            (0.5, "0".to_string()),
            (0.0, compact(s.low)),
        ],
        Ramp::Diverging => vec![(0.5, "0".to_string())],
        Ramp::Sequential if s.high > s.low => {
            vec![(1.0, compact(s.high)), (0.0, compact(s.low))]
        }
        Ramp::Sequential => vec![(0.5, compact(s.low))],
        Ramp::Cyclic => [
            (1.0, " N"),
            (0.75, " W"),
            (0.5, " S"),
            (0.25, " E"),
            (0.0, " N"),
        ]
        .map(|(u, dir)| (u, format!("{}{dir}", compact(s.low + u * (s.high - s.low)))))
        .to_vec(),
    }
}

/// How the ramp was clipped, in words.
fn clip_note(s: &Stretch) -> String {
    let p = s.percentile;
    match s.ramp {
        Ramp::Cyclic if p.is_nan() => "cyclic: 0 and 360 are north".into(),
        _ if p.is_nan() => format!("fixed scale {} to {}", compact(s.low), compact(s.high)),
        Ramp::Diverging => format!("clipped at {} pct |value|", ordinal(p)),
        Ramp::Sequential | Ramp::Cyclic => {
            format!("clipped at {}-{} pct", ordinal(100.0 - p), ordinal(p))
        }
    }
}

/// `98` as "98th", `2` as "2nd", `99.5` as "99.5th".
pub(super) fn ordinal(p: f64) -> String {
    let text = compact(p);
    if p.fract() != 0.0 {
        return format!("{text}th");
    }
    let n = p.abs() as u64;
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{text}{suffix}")
}

/// A number in at most 3 significant digits ("0.31", "-0.0042", "152", "12346"), scientific
/// ("1.5e-4", "2.1e6") only below 0.001 and from 100000 on, without trailing zeros.
pub(super) fn compact(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    if !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if !(1e-3..1e5).contains(&a) {
        let text = format!("{x:.2e}");
        let Some((mantissa, exponent)) = text.split_once('e') else {
            return text;
        };
        return format!("{}e{exponent}", trim_zeros(mantissa));
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    trim_zeros(&format!("{x:.decimals$}")).to_string()
}

/// "0.310" as "0.31", "2.00" as "2"; an integer stays as it is.
fn trim_zeros(text: &str) -> &str {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::quicklook::Grid;

    #[test]
    fn numbers_are_compact_and_readable() {
        let cases = [
            (0.0, "0"),
            (-0.0, "0"),
            (0.31, "0.31"),
            (-0.3104, "-0.31"),
            (0.27, "0.27"),
            (0.004_21, "0.00421"),
            (0.000_123_4, "1.23e-4"),
            (1.0, "1"),
            (2.5, "2.5"),
            (152.4, "152"),
            (12_345.6, "12346"),
            (2_100_000.0, "2.1e6"),
            (-0.000_5, "-5e-4"),
            (0.999_6, "1"),
        ];
        for (x, want) in cases {
            assert_eq!(compact(x), want, "{x}");
        }
        let ords = [(98.0, "98th"), (2.0, "2nd"), (1.0, "1st"), (3.0, "3rd")];
        for (p, want) in ords.into_iter().chain([(11.0, "11th"), (99.5, "99.5th")]) {
            assert_eq!(ordinal(p), want);
        }
    }

    fn panel(values: Vec<f32>, ramp: Ramp, shaded: bool) -> Panel {
        let width = values.len() as u32;
        let grid = Grid {
            width,
            height: 1,
            values,
        };
        let stretch = Stretch::of(&grid, ramp, 98.0, None);
        let any_missing = grid.values.iter().any(|v| v.is_nan());
        let legend = Legend {
            title: "ProfileCurvature",
            unit: "1/m",
            clip_percentile: 98.0,
            fixed: None,
            statistic: "cell mean of the points",
        };
        let notes = Notes {
            stretch: &stretch,
            shaded,
            any_missing,
        };
        Panel::new(&legend, &notes, 2)
    }

    /// A direction spans 0 to 360 on a cyclic ramp whatever its values, labelled by compass
    /// point; a fixed scale replaces the percentiles and says so, symmetric when diverging.
    #[test]
    fn cyclic_and_fixed_scales_ignore_the_percentiles() {
        let grid = |values: Vec<f32>| Grid {
            width: values.len() as u32,
            height: 1,
            values,
        };
        let aspect = Stretch::of(&grid(vec![10.0, 20.0, 350.0]), Ramp::Cyclic, 98.0, None);
        assert_eq!((aspect.low, aspect.high), (0.0, 360.0));
        assert_eq!(clip_note(&aspect), "cyclic: 0 and 360 are north");
        let labels: Vec<String> = ticks_of(&aspect).into_iter().map(|(_, l)| l).collect();
        assert_eq!(labels, ["360 N", "270 W", "180 S", "90 E", "0 N"]);
        // 0 and 360 are one colour: the ramp's ends meet.
        let lut = super::super::colour::lut(Ramp::Cyclic);
        assert_eq!(lut[0], lut[lut.len() - 1]);
        let si = grid(vec![-0.2, 0.1, 0.3]);
        let s = Stretch::of(&si, Ramp::Diverging, 98.0, Some((-1.0, 1.0)));
        assert_eq!((s.low, s.high), (-1.0, 1.0));
        assert_eq!(clip_note(&s), "fixed scale -1 to 1");
        assert_eq!(s.position(0.5), Some(0.75));
        let s = Stretch::of(&si, Ramp::Diverging, 98.0, Some((-0.5, 2.0)));
        assert_eq!((s.low, s.high), (-2.0, 2.0));
    }

    #[test]
    fn the_legend_states_name_range_clipping_and_no_data() {
        let p = panel(vec![-0.31, 0.0, 0.27, f32::NAN], Ramp::Diverging, true);
        assert_eq!(p.title, "ProfileCurvature (1/m)");
        assert_eq!(p.lines[0], "cell mean of the points");
        assert_eq!(p.lines[1], "data -0.31 to 0.27");
        assert_eq!(p.lines[2], "clipped at 98th pct |value|");
        assert_eq!(p.lines[3], "no data: transparent, grey edge");
        assert_eq!(p.lines[4], "hillshade: sun az 315, alt 45");
        let labels: Vec<&str> = p.ticks.iter().map(|(_, l)| l.as_str()).collect();
        // 98th percentile of |v| over {0, 0.27, 0.31}: rank 1.96, 0.27 + 0.96 * 0.04.
        assert_eq!(labels, ["0.308", "0", "-0.308"]);
        assert_eq!(p.saturated, (true, false));

        let p = panel(vec![0.0, 10.0, 20.0, 30.0], Ramp::Sequential, false);
        let lines = [
            "cell mean of the points",
            "data 0 to 30",
            "clipped at 2nd-98th pct",
        ];
        assert_eq!(p.lines, lines);
        let labels: Vec<&str> = p.ticks.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["29.4", "0.6"]);

        let p = panel(vec![f32::NAN; 3], Ramp::Diverging, false);
        assert_eq!(p.lines, ["cell mean of the points", "no data in any cell"]);
        assert!(p.ticks.is_empty());
        let p = panel(vec![0.0; 3], Ramp::Diverging, false);
        assert_eq!(p.lines, ["cell mean of the points", "all values 0"]);
        assert_eq!(p.ticks.len(), 1);
    }
}
