//! A least-significant-digit radix sort of (key, index) pairs, for the orders a tile is put in
//! many thousand times a run: the grid's cells and the k-NN query order (core::neighbors),
//! the k-NN position ranks, the points' Morton order (core::tile) and the results' id order
//! (io::workdir::results). Comparison sorts of these keys cost more (docs/performance.md, "Sorting"):
//! their comparisons are data-dependent branches, and the radix passes have none.

use std::cmp::Ordering;

/// Below this many pairs the comparison sort is as fast.
const SMALL: usize = 256;

/// Sorts `pairs` by key, stably: pairs with equal keys keep their order. When the indices
/// increase in the input (as when they number the pairs), the result is the order by (key,
/// index). `spare` is scratch, reused from call to call. Passes sort 8 bits at a time (11 past
/// 2048 pairs, where the larger count table pays), and only where the keys differ: a pass
/// starts at the lowest bit that varies above the last one, so the unused bits between two
/// fields of a key (the grid's cell keys) cost nothing.
pub fn sort_by_key(pairs: &mut Vec<(u64, u32)>, spare: &mut Vec<(u64, u32)>) {
    if pairs.len() < SMALL {
        pairs.sort_by_key(|p| p.0);
        return;
    }
    let first = pairs[0].0;
    let varying = pairs.iter().fold(0, |v, p| v | (p.0 ^ first));
    let bits = if pairs.len() > 2048 { 11 } else { 8 };
    let mask = (1u64 << bits) - 1;
    spare.clear();
    spare.resize(pairs.len(), (0, 0));
    let mut count = vec![0u32; 1 << bits];
    let mut shift = 0u32;
    while shift < u64::BITS && varying >> shift != 0 {
        shift += (varying >> shift).trailing_zeros();
        let at = shift;
        let digit = |k: u64| (k >> at & mask) as usize;
        count.fill(0);
        for p in pairs.iter() {
            count[digit(p.0)] += 1;
        }
        let mut start = 0;
        for c in count.iter_mut() {
            (*c, start) = (start, start + *c);
        }
        for &p in pairs.iter() {
            let d = digit(p.0);
            spare[count[d] as usize] = p;
            count[d] += 1;
        }
        std::mem::swap(pairs, spare);
        shift += bits;
    }
}

/// [`sort_by_key`], then each run of pairs sharing a key ordered by `tie` (for keys that
/// quantize a finer order: Morton cells, one coordinate of a position).
pub fn sort_by_key_then(
    pairs: &mut Vec<(u64, u32)>,
    spare: &mut Vec<(u64, u32)>,
    mut tie: impl FnMut(u32, u32) -> Ordering,
) {
    sort_by_key(pairs, spare);
    for run in pairs.chunk_by_mut(|a, b| a.0 == b.0) {
        if run.len() > 1 {
            run.sort_unstable_by(|a, b| tie(a.1, b.1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::Rng;

    /// The order is the standard library's stable sort by key, for keys spread over every bit
    /// width, with many ties, with two fields and unused bits between them (as the grid's cell
    /// keys), and at both sides of the small-input cut.
    #[test]
    fn sorts_like_a_stable_sort() {
        let mut rng = Rng::new(7);
        let mut spare = Vec::new();
        for (n, bits) in [
            (10, 64),
            (300, 3),
            (5000, 20),
            (5000, 33),
            (20_000, 64),
            (257, 1),
        ] {
            let mut pairs: Vec<(u64, u32)> = (0..n as u32)
                .map(|i| {
                    let k = rng.next_u64() >> (64 - bits);
                    match bits {
                        1 => (k.wrapping_add(u64::MAX / 3), i),
                        // Two fields: 12 bits at 32..44, 4 bits at 0..4.
                        20 => ((k >> 4) << 32 | (k & 15), i),
                        _ => (k, i),
                    }
                })
                .collect();
            let mut expected = pairs.clone();
            expected.sort_by_key(|p| p.0);
            sort_by_key(&mut pairs, &mut spare);
            assert_eq!(pairs, expected, "{n} pairs, keys of {bits} bits");
        }
    }

    /// Runs sharing a key come out in the tie order: the standard sort by (key, finer value).
    #[test]
    fn ties_go_by_the_finer_order() {
        let mut rng = Rng::new(3);
        for n in [100, 5000] {
            let fine: Vec<u64> = (0..n).map(|_| rng.next_u64() >> 40).collect();
            // Keys quantize the fine values: many share one.
            let mut pairs: Vec<(u64, u32)> =
                (0..n as u32).map(|i| (fine[i as usize] >> 16, i)).collect();
            let mut expected = pairs.clone();
            expected.sort_by_key(|&(k, i)| (k, fine[i as usize], i));
            sort_by_key_then(&mut pairs, &mut Vec::new(), |a, b| {
                (fine[a as usize], a).cmp(&(fine[b as usize], b))
            });
            assert_eq!(pairs, expected, "{n} pairs");
        }
    }
}
