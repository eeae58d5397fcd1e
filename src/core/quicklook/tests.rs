use super::colour::{self, oklab_lightness, Stretch};
use super::*;

const NAN: f32 = f32::NAN;

fn grid(width: u32, height: u32, values: Vec<f32>) -> Grid {
    assert_eq!(values.len(), (width * height) as usize);
    Grid {
        width,
        height,
        values,
    }
}

fn legend() -> Legend<'static> {
    Legend {
        title: "MeanCurvature",
        unit: "1/m",
        clip_percentile: DEFAULT_CLIP_PERCENTILE,
        fixed: None,
        statistic: "",
    }
}

fn pixel(p: &Picture, x: u32, y: u32) -> [u8; 4] {
    let i = ((y * p.width + x) * 4) as usize;
    [p.rgba[i], p.rgba[i + 1], p.rgba[i + 2], p.rgba[i + 3]]
}

/// Equal within the rounding of two means of a few f32.
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-6 * b.abs().max(1.0)
}

#[test]
fn a_thumbnail_holds_the_mean_of_the_defined_cells_of_each_block() {
    // 7 x 5 cells into at most 3 pixels across: factor 3, a 3 x 2 thumbnail whose last
    // column's blocks are 1 cell wide and whose last row's are 2 cells tall.
    #[rustfmt::skip]
    let raster = [
        1.0, 2.0, 3.0,   4.0, 5.0, 6.0,   7.0,
        NAN, NAN, NAN,   1.0, NAN, 3.0,   NAN,
        4.0, 5.0, 6.0,   2.0, 2.0, 2.0,   NAN,
        //
        NAN, NAN, NAN,   -1.0, 1.0, 0.5,  10.0,
        NAN, NAN, NAN,   0.0, 0.0, 0.0,   20.0,
    ];
    let want = [[21.0 / 6.0, 25.0 / 8.0, 7.0], [NAN, 0.5 / 6.0, 15.0]];
    // Rows in strips of any size give the same thumbnail.
    for strips in [vec![5], vec![1, 1, 1, 1, 1], vec![2, 3], vec![4, 1]] {
        let mut t = Thumbnail::new(7, 5, 3);
        assert_eq!(t.factor(), 3);
        let mut row = 0;
        for n in strips {
            let cells = &raster[row as usize * 7..(row + n) as usize * 7];
            t.push_rows(row, cells);
            row += n;
        }
        let g = t.finish();
        assert_eq!((g.width, g.height), (3, 2));
        for (r, want_row) in want.iter().enumerate() {
            for (c, &w) in want_row.iter().enumerate() {
                let got = g.get(c as i64, r as i64);
                assert!(
                    close(got, w) || (got.is_nan() && w.is_nan()),
                    "{c},{r}: {got}"
                );
            }
        }
    }
}

#[test]
fn a_small_raster_is_its_own_thumbnail_and_missing_rows_are_no_data() {
    let mut t = Thumbnail::new(3, 4, DEFAULT_MAX_SIDE);
    assert_eq!(t.factor(), 1);
    t.push_rows(0, &[1.0, 2.0, 3.0]);
    // Row 1 never arrives; row 3 neither (the raster stopped early).
    t.push_rows(2, &[4.0, f32::INFINITY, 6.0]);
    let g = t.finish();
    let want = [1.0, 2.0, 3.0, NAN, NAN, NAN, 4.0, NAN, 6.0, NAN, NAN, NAN];
    assert_eq!(g.values.len(), want.len());
    for (got, w) in g.values.iter().zip(want) {
        assert!(*got == w || (got.is_nan() && w.is_nan()), "{:?}", g.values);
    }
    // A long raster: the long side sets the factor, and the short one rounds up.
    let t = Thumbnail::new(100, 3_201, 1_600);
    assert_eq!(t.factor(), 3);
    let g = t.finish();
    assert_eq!((g.width, g.height), (34, 1_067));
    let g = Thumbnail::new(0, 0, 1_600).finish();
    assert_eq!((g.width, g.height, g.values.len()), (0, 0, 0));
}

/// Where the points are sparser than the cells, a thumbnail's blocks hold enough cells that
/// nearly every block has a point: with `l` points a cell spread at random (Poisson), a block
/// of `b` x `b` cells is empty with probability `exp(-l b^2)`, at most 0.5%; where there is a
/// point a cell or more, the factor is the one that fits the side.
#[test]
fn sparse_rasters_get_blocks_that_hold_a_point() {
    for (w, h, points, want) in [
        (866u32, 866u32, 300_000u64, 4u32), // 0.2 m cells at 10 points/m^2: l = 0.4
        (866, 866, 7_500_000, 1),           // l = 10
        (1_000, 1_000, 2_000_000, 2),       // l = 2
        (4_000, 100, 400_000, 3),           // l = 1, and the side fits at 3 too
        (4_000, 100, 4_000_000, 3),         // l = 10: the side's factor
        (10, 10, 0, 10),                    // no point: one block for the whole raster
    ] {
        let t = Thumbnail::for_points(w, h, 1_600, points);
        let fit = Thumbnail::new(w, h, 1_600).factor();
        assert_eq!(t.factor(), want.max(fit), "{w}x{h} {points}");
        let l = points as f64 / (w as f64 * h as f64);
        let b = t.factor() as f64;
        if points > 0 && b < w.max(h) as f64 {
            assert!((-l * b * b).exp() <= 0.005, "{w}x{h} {points}: factor {b}");
        }
        if t.factor() > fit {
            assert!(
                (-l * (b - 1.0) * (b - 1.0)).exp() > 0.005,
                "{w}x{h}: not the least"
            );
        }
    }
}

#[test]
#[should_panic(expected = "out of order")]
fn rows_out_of_order_are_refused() {
    let mut t = Thumbnail::new(2, 4, 1);
    t.push_rows(2, &[1.0, 2.0]);
    t.push_rows(0, &[1.0, 2.0]);
}

#[test]
fn the_diverging_ramp_is_white_at_zero_and_mirrors_lightness() {
    let v = [-1.0, -0.5, -0.1, 0.0, 0.1, 0.5, 1.0];
    let p = render(&grid(7, 1, v.to_vec()), Ramp::Diverging, &legend(), None);
    // A 7 x 1 map is magnified to 480 / 7 = 68 pixels a value.
    let m = 68;
    let at = |i: u32| pixel(&p, i * m + m / 2, m / 2);
    assert_eq!(at(3), [255, 255, 255, 255]);
    let (blue, red) = (at(0), at(6));
    assert!(
        blue[2] > blue[0] + 60 && red[0] > red[2] + 60,
        "{blue:?} {red:?}"
    );
    for k in 0..3 {
        let (neg, pos) = (at(k), at(6 - k));
        let (ln, lp) = (
            oklab_lightness([neg[0], neg[1], neg[2]]),
            oklab_lightness([pos[0], pos[1], pos[2]]),
        );
        assert!(
            (ln - lp).abs() < 0.01,
            "{} and {}: {ln} {lp}",
            v[k as usize],
            v[6 - k as usize]
        );
        assert!(neg[2] > neg[0] && pos[0] > pos[2]);
    }
    // Darker as |v| grows, and the ends dark enough to read against white.
    let l: Vec<f64> = (3..7)
        .map(|i| oklab_lightness(at(i)[..3].try_into().unwrap()))
        .collect();
    assert!(l.windows(2).all(|w| w[1] < w[0] - 0.02), "{l:?}");
    assert!(l[3] < 0.45, "{l:?}");
}

#[test]
fn the_sequential_ramp_rises_evenly_in_lightness() {
    let lut = colour::lut(Ramp::Sequential);
    let l: Vec<f64> = lut.iter().map(|&c| oklab_lightness(c)).collect();
    // Steps of 1/32 of the ramp rise by 0.64 / 32 = 0.02 each, give or take 8-bit rounding.
    let steps: Vec<f64> = l.iter().step_by(32).copied().collect();
    let even = steps.windows(2).all(|w| (w[1] - w[0] - 0.02).abs() < 0.004);
    assert!(even, "{steps:?}");
    assert!((l[0] - 0.30).abs() < 0.01 && (l[l.len() - 1] - 0.94).abs() < 0.01);
    // Even: the middle entry halfway in lightness.
    assert!((l[l.len() / 2] - 0.62).abs() < 0.01, "{}", l[l.len() / 2]);
    let (low, high) = (lut[0], lut[lut.len() - 1]);
    assert!(low[2] > low[1], "violet-blue at the low end: {low:?}");
    assert!(
        high[0] > high[2] + 80 && high[1] > high[2] + 80,
        "yellow at the high end: {high:?}"
    );
}

#[test]
fn clip_limits_are_exact_percentiles_and_values_beyond_saturate() {
    // |v| over -100..=100: 0 once, every k in 1..=100 twice; rank 0.98 * 200 = 196 is 98.
    let values: Vec<f32> = (-100..=100).map(|k| k as f32).collect();
    let g = grid(201, 1, values);
    let s = Stretch::of(&g, Ramp::Diverging, 98.0, None);
    assert_eq!(
        (s.low, s.high, s.range),
        (-98.0, 98.0, Some((-100.0, 100.0)))
    );
    assert_eq!(s.position(99.0), s.position(98.0));
    assert_eq!(s.position(-100.0), Some(0.0));
    assert_eq!(s.position(49.0), Some(0.75));
    let s = Stretch::of(&g, Ramp::Diverging, 90.0, None);
    assert_eq!(s.high, 90.0);
    // 0..=100 with NaN holes: the 2nd and 98th percentiles are 2 and 98.
    let mut values: Vec<f32> = (0..=100).map(|k| k as f32).collect();
    values.extend([NAN; 9]);
    let g = grid(110, 1, values);
    let s = Stretch::of(&g, Ramp::Sequential, 98.0, None);
    assert_eq!((s.low, s.high), (2.0, 98.0));
    assert_eq!(s.position(1.0), Some(0.0));
    assert_eq!(s.position(50.0), Some(0.5));
    assert_eq!(s.position(NAN), None);
    // In the picture: 99 and 100 get the colour of 98, 97 another.
    let p = render(&g, Ramp::Sequential, &legend(), None);
    let m = (MIN_MAP_SIDE / 110).max(1);
    let at = |k: u32| pixel(&p, k * m, 0);
    assert_eq!(at(99), at(98));
    assert_eq!(at(100), at(98));
    assert_ne!(at(97), at(98));
}

#[test]
fn percentiles_of_shuffled_integers_interpolate_between_ranks() {
    // 0..n in a scrambled order: the p-th percentile is p/100 * (n - 1), between two integers.
    let n = 1001u32;
    let mut values: Vec<f32> = (0..n).map(|i| ((i * 389) % n) as f32).collect();
    for p in [0.0, 2.0, 37.25, 50.0, 98.0, 99.95, 100.0] {
        let want = p / 100.0 * f64::from(n - 1);
        assert!(
            (colour::percentile(&mut values, p) - want).abs() < 1e-9,
            "{p}"
        );
    }
    assert_eq!(colour::percentile(&mut [], 50.0), 0.0);
    assert_eq!(colour::percentile(&mut [3.5], 98.0), 3.5);
}

/// Against the percentile of the sorted values, to the bit, on values of every sign and
/// magnitude (zeros of both signs, subnormals, repeats, huge and tiny), at ranks throughout.
#[test]
fn percentiles_are_those_of_the_sorted_values() {
    let mut rng = crate::core::rng::Rng::new(5);
    for n in [1usize, 2, 3, 17, 1000, 5000] {
        let values: Vec<f32> = (0..n)
            .map(|i| match rng.below(6) {
                0 => 0.0,
                1 => -0.0,
                2 => {
                    f32::from_bits(1 + rng.below(1000) as u32) * if i % 2 == 0 { 1.0 } else { -1.0 }
                }
                3 => (rng.below(7) as f32 - 3.0) * 0.25,
                4 => ((rng.uniform() - 0.5) * 1e30) as f32,
                _ => (rng.normal() * 1e-3) as f32,
            })
            .collect();
        let mut sorted = values.clone();
        sorted.sort_by(f32::total_cmp);
        for p in [0.0, 0.1, 2.0, 25.0, 50.0, 73.3, 98.0, 99.99, 100.0] {
            let rank = p / 100.0 * (n - 1) as f64;
            let i = (rank.floor() as usize).min(n - 1);
            let (a, b) = (f64::from(sorted[i]), f64::from(sorted[(i + 1).min(n - 1)]));
            let want = a + (rank - i as f64) * (b - a);
            let got = colour::percentile(&mut values.clone(), p);
            assert_eq!(
                got.to_bits(),
                want.to_bits(),
                "n {n}, p {p}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn no_data_is_transparent_and_degenerate_grids_render() {
    let g = grid(2, 2, vec![1.0, NAN, -1.0, 0.5]);
    let p = render(&g, Ramp::Diverging, &legend(), None);
    assert_eq!(pixel(&p, 240 + 10, 10)[3], 0, "no data is transparent");
    assert_eq!(pixel(&p, 10, 10)[3], 255);
    assert_eq!(
        pixel(&p, 239, 10),
        NO_DATA_EDGE,
        "the edge of no data is outlined"
    );
    assert_eq!(
        pixel(&p, 10, 239),
        pixel(&p, 10, 10),
        "the map's own edge is not"
    );
    // The legend panel is opaque white beside the map.
    assert_eq!(pixel(&p, p.width - 2, p.height - 2), [255, 255, 255, 255]);
    for ramp in [Ramp::Diverging, Ramp::Sequential] {
        for values in [vec![NAN; 4], vec![0.0; 4], vec![5.0; 4], vec![]] {
            let n = values.len() as u32 / 2;
            let p = render(&grid(n, 2.min(n), values.clone()), ramp, &legend(), None);
            assert_eq!(p.rgba.len(), (p.width * p.height * 4) as usize);
            assert!(
                p.width > 100 && p.height > 50,
                "{values:?}: a legend is drawn"
            );
            let map: Vec<[u8; 4]> = (0..n).map(|i| pixel(&p, i * 240, 0)).collect();
            match values.first() {
                Some(v) if v.is_nan() => assert!(map.iter().all(|c| c[3] == 0)),
                Some(&v) => assert!(map.iter().all(|c| c[3] == 255 && *c == map[0]), "{v}"),
                None => {}
            }
        }
    }
    let p = render(&grid(2, 1, vec![0.0; 2]), Ramp::Diverging, &legend(), None);
    assert_eq!(pixel(&p, 0, 0), [255, 255, 255, 255], "all zero is white");
}

/// A plane `z = gx * col + gy * row` (rows run south) with cell 1, 9 x 9.
fn plane(gx: f32, gy: f32) -> Grid {
    let values = (0..81)
        .map(|i| gx * (i % 9) as f32 + gy * (i / 9) as f32)
        .collect();
    grid(9, 9, values)
}

#[test]
fn a_plane_facing_the_sun_is_brighter_than_one_facing_away() {
    // Rising to the south-east at 45 degrees: faces the north-west sun, 45 up: cos 0 = 1.
    let g = std::f32::consts::FRAC_1_SQRT_2;
    let facing = plane(g, g);
    let away = plane(-g, -g);
    let flat = plane(0.0, 0.0);
    let shade = |e: &Grid| Shade::of(e, 1.0).levels[40];
    assert!((shade(&facing) - 1.0).abs() < 1e-5, "{}", shade(&facing));
    // Facing away at 45 degrees: the normal is 90 degrees from the sun.
    assert!(shade(&away).abs() < 1e-5, "{}", shade(&away));
    assert!((shade(&flat) - g).abs() < 1e-5, "flat: sin 45");
    // The cell size scales the slope: the same plane with 2 m cells is 26.6 degrees steep.
    let half = Shade::of(&facing, 2.0).levels[40];
    assert!(
        (half - (45f32 - 26.565).to_radians().cos()).abs() < 1e-4,
        "{half}"
    );
    // Edges and holes are shaded as their neighbourhood, not as cliffs.
    let edge = Shade::of(&facing, 1.0).levels[0];
    assert!(edge > 0.9, "{edge}");
    // In the picture the shaded colours darken in the same order.
    let values = grid(9, 9, vec![1.0; 81]);
    let look = |e: &Grid| {
        let p = render(
            &values,
            Ramp::Diverging,
            &legend(),
            Some(&Shade::of(e, 1.0)),
        );
        oklab_lightness(pixel(&p, 240, 240)[..3].try_into().unwrap())
    };
    assert!(look(&facing) > look(&flat) && look(&flat) > look(&away));
    // Level ground keeps the legend's colours: 0 stays white under the shade.
    let zero = grid(9, 9, vec![0.0; 81]);
    let shade = Shade::of(&flat, 1.0);
    let p = render(&zero, Ramp::Diverging, &legend(), Some(&shade));
    assert_eq!(pixel(&p, 240, 240), [255, 255, 255, 255]);
}
