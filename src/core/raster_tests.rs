use super::*;

/// Cells are multiples of the cell size: the edges belong to the cell east and north.
#[test]
fn cells_are_aligned_to_multiples_of_the_cell_size() {
    assert_eq!(Cell::of(0.0, 0.0, 0.5), Some(Cell { ix: 0, iy: 0 }));
    assert_eq!(Cell::of(-0.1, 0.49, 0.5), Some(Cell { ix: -1, iy: 0 }));
    assert_eq!(
        Cell::of(500_000.5, 4_100_000.25, 0.5),
        Some(Cell {
            ix: 1_000_001,
            iy: 8_200_000
        })
    );
    assert_eq!(Cell::of(f64::NAN, 0.0, 1.0), None);
    assert_eq!(Cell::of(1e300, 0.0, 1.0), None);
}

/// Keys order cells north to south, then west to east, and give the cell back.
#[test]
fn keys_order_cells_as_a_north_up_raster_and_round_trip() {
    let cells = [(-3, 5), (7, 5), (-3, 4), (0, 4), (9, -2)];
    let keys: Vec<u64> = cells
        .iter()
        .map(|&(ix, iy)| Cell { ix, iy }.key())
        .collect();
    assert!(keys.windows(2).all(|w| w[0] < w[1]));
    for (&(ix, iy), &k) in cells.iter().zip(&keys) {
        assert_eq!(Cell::from_key(k), Cell { ix, iy });
    }
    let far = Cell {
        ix: -(1 << 31) + 1,
        iy: (1 << 31) - 1,
    };
    assert_eq!(Cell::from_key(far.key()), far);
}

/// The grid's corner and positions follow from its cells.
#[test]
fn the_grid_places_cells_north_up() {
    let g = CellGrid::covering(2.0, Cell { ix: 10, iy: -5 }, Cell { ix: 12, iy: -3 });
    let g = g.expect("small grid");
    assert_eq!((g.width, g.height), (3, 3));
    assert_eq!(g.corner(), (20.0, -4.0));
    assert_eq!(g.position(Cell { ix: 10, iy: -3 }), Some((0, 0)));
    assert_eq!(g.position(Cell { ix: 12, iy: -5 }), Some((2, 2)));
    assert_eq!(g.position(Cell { ix: 13, iy: -5 }), None);
}

/// Tallies of scaled integers give the statistics of the values `r s + o` they stand for,
/// with a negative scale too (its least value is its greatest integer), undefined ones
/// left out, and merged partial tallies the tally of all.
#[test]
fn tallies_of_integers_are_the_statistics_of_their_values() {
    let raws = [3i64, -5, UNDEFINED, 10, 7];
    for (scale, offset) in [(-0.5, 2.0), (0.25, -1.0), (1e-7, 0.0)] {
        let ints = Integers { scale, offset };
        let values: Vec<f64> = (raws.iter())
            .filter(|&&r| r != UNDEFINED)
            .map(|&r| r as f64 * scale + offset)
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let least = values.iter().copied().fold(f64::INFINITY, f64::min);
        let most = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        for (stat, want) in [
            (Stat::Mean, mean),
            (Stat::Min, least),
            (Stat::Max, most),
            (Stat::Count, 4.0),
        ] {
            let oriented: Vec<i64> = (raws.iter())
                .map(|&r| if r == UNDEFINED { r } else { ints.oriented(r) })
                .collect();
            let mut all = stat.empty();
            for r in &oriented {
                stat.add_all(std::slice::from_mut(&mut all), std::slice::from_ref(r));
            }
            let (mut a, mut b) = (stat.empty(), stat.empty());
            for (i, r) in oriented.iter().enumerate() {
                let t = if i % 2 == 0 { &mut a } else { &mut b };
                stat.add_all(std::slice::from_mut(t), std::slice::from_ref(r));
            }
            stat.merge(&mut a, b);
            assert_eq!(a, all, "{stat} merged");
            let got = stat.tally_value(all, ints) as f64;
            assert!(
                (got - want).abs() <= 1e-6 * want.abs(),
                "{stat} {scale}: {got} {want}"
            );
        }
        assert!(Stat::Mean.tally_value(Stat::Mean.empty(), ints).is_nan());
    }
}

/// Each statistic on a known set, undefined values left out, whatever the order.
#[test]
fn statistics_leave_out_undefined_values_and_ignore_order() {
    let base = [3.0f32, f32::NAN, 1.0, 2.0, 10.0];
    let expect = [
        (Stat::Mean, 4.0),
        (Stat::Median, 2.5),
        (Stat::Min, 1.0),
        (Stat::Max, 10.0),
        (Stat::Count, 4.0),
    ];
    for (stat, want) in expect {
        for rot in 0..base.len() {
            let mut v = base;
            v.rotate_left(rot);
            assert_eq!(stat.reduce(&mut v, false), want, "{stat} rotation {rot}");
        }
    }
    let mut odd = [5.0f32, 1.0, 3.0];
    assert_eq!(Stat::Median.reduce(&mut odd, false), 3.0);
    let mut none = [f32::NAN; 3];
    assert!(Stat::Mean.reduce(&mut none, false).is_nan());
    assert_eq!(Stat::Count.reduce(&mut none, false), 0.0);
}

/// The mean without a sort equals the mean of the sorted values, and values too far apart
/// in magnitude for an exact sum still give the same mean in every order.
#[test]
fn the_mean_is_the_sorted_sum_and_ignores_order_when_magnitudes_differ() {
    let mut rng = crate::core::rng::Rng::new(7);
    for case in 0..2000_i32 {
        let n = 1 + (rng.next_u64() % 12) as usize;
        // Exponent spreads from none to far beyond what an f64 sum holds exactly.
        let reach = case % 40;
        let mut v: Vec<f32> = (0..n)
            .map(|_| {
                let m = rng.uniform() * 2.0 - 1.0;
                let e = (rng.next_u64() % (reach as u64 + 1)) as i32 - reach / 2;
                (m * 2f64.powi(e)) as f32
            })
            .collect();
        let mut sorted = v.clone();
        sorted.sort_unstable_by(f32::total_cmp);
        let want = (sorted.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64) as f32;
        let exact = exact_mean(&v);
        if let Some(m) = exact {
            assert_eq!(m.to_bits(), want.to_bits(), "{v:?}");
        }
        // Values within a factor of 2^24 of each other (12 of them need at most 4 bits
        // more) always sum exactly: the sort-free path must answer for them.
        let big = v.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let small = v
            .iter()
            .filter(|x| **x != 0.0)
            .fold(f32::MAX, |m, x| m.min(x.abs()));
        if big <= small * 2f32.powi(24) {
            assert!(exact.is_some(), "an exact sum left to the sort: {v:?}");
        }
        for rot in 0..n {
            v.rotate_left(1);
            let got = Stat::Mean.reduce(&mut v.clone(), false);
            assert_eq!(
                got.to_bits(),
                want.to_bits(),
                "case {case} rotation {rot}: {v:?}"
            );
        }
    }
    // A spread of 2^40 between values is past an exact sum: the sorted path answers.
    let far = [1.0f32, 1e-12, -1.0];
    assert_eq!(exact_mean(&far), None);
    let first = Stat::Mean.reduce(&mut far.clone(), false);
    for order in [[1e-12f32, -1.0, 1.0], [-1.0, 1.0, 1e-12]] {
        assert_eq!(Stat::Mean.reduce(&mut order.clone(), false), first);
    }
}

/// The circular mean of aspects across north is north, not south.
#[test]
fn the_mean_of_aspects_is_circular() {
    let mut v = [350.0f32, 10.0];
    let m = Stat::Mean.reduce(&mut v, true);
    assert!(!(1e-3..=359.999).contains(&m), "{m}");
    let mut v = [80.0f32, 100.0, 90.0];
    assert!((Stat::Mean.reduce(&mut v, true) - 90.0).abs() < 1e-4);
    let mut v = [0.0f32, 180.0];
    assert!(Stat::Mean.reduce(&mut v, true).is_nan());
    assert_eq!(Stat::Mean.reduce(&mut [350.0f32, 10.0], false), 180.0);
}

/// The median, min and max of aspects are those of the angles about their circular mean:
/// the trial's cell of 6.5 and 358.8 degrees has the median 2.65 (it had 182.65), its min
/// 358.8 and max 6.5 (the arc from one to the other clockwise through north); away from
/// north they are the plain ones; where directions cancel they are undefined.
#[test]
fn the_median_min_and_max_of_aspects_are_circular() {
    let cell = [6.5f32, 358.8];
    let r = |s: Stat, v: &[f32]| s.reduce(&mut v.to_vec(), true);
    assert!(
        (r(Stat::Median, &cell) - 2.65).abs() < 1e-4,
        "{}",
        r(Stat::Median, &cell)
    );
    assert_eq!(r(Stat::Min, &cell), 358.8);
    assert_eq!(r(Stat::Max, &cell), 6.5);
    let across = [355.0f32, 359.0, 3.0, 20.0, 350.0];
    assert!((r(Stat::Median, &across) - 359.0).abs() < 1e-4);
    assert_eq!(r(Stat::Min, &across), 350.0);
    assert_eq!(r(Stat::Max, &across), 20.0);
    let east = [80.0f32, 95.0, 91.0, 120.0];
    assert_eq!(
        r(Stat::Median, &east),
        Stat::Median.reduce(&mut east.to_vec(), false)
    );
    assert_eq!(r(Stat::Min, &east), 80.0);
    assert_eq!(r(Stat::Max, &east), 120.0);
    for s in [Stat::Median, Stat::Min, Stat::Max] {
        assert!(r(s, &[0.0, 180.0]).is_nan(), "{s:?}");
        assert!(r(s, &[f32::NAN]).is_nan(), "{s:?}");
        assert_eq!(r(s, &[f32::NAN, 42.0]), 42.0, "{s:?}");
    }
    // Across north the values stay in [0, 360).
    for k in 0..200 {
        let a = 359.999f32 + k as f32 * 1e-5;
        for s in [Stat::Mean, Stat::Median, Stat::Min, Stat::Max] {
            let v = r(s, &[a, 360.0 - a, 1e-6]);
            assert!((0.0..360.0).contains(&v), "{s:?} of {a}: {v}");
        }
    }
}
