//! The AVX2 kernels of the k-NN (x86-64-v3 builds; other builds keep the scalar code):
//!
//! - [`sort32`], a branch-free sorting network for 32 keys in registers: the exact ranking of
//!   a query sorts its 30-33 candidates at k = 30 (`sort_ranked`), where the standard
//!   library's sort spends much of its time on mispredicted branches (docs/performance.md,
//!   "Neighbours"). Bitonic:
//!   15 stages of compare-exchanges, each a vector min and max; pairs 4 or more apart are whole
//!   registers, closer pairs lanes of one register (a permute and a blend more);
//! - [`select_within`], the indices of the block's points within a squared radius, eight at a
//!   time (a compare, a mask and a permute from a table), in far fewer instructions than the
//!   scalar loop.
//!
//! Pure: no files, no channels.

use std::arch::x86_64::{
    __m256d, __m256i, _mm256_add_epi32, _mm256_blend_pd, _mm256_cmp_ps, _mm256_loadu_ps,
    _mm256_loadu_si256, _mm256_max_pd, _mm256_min_pd, _mm256_movemask_ps, _mm256_permute4x64_pd,
    _mm256_permute_pd, _mm256_permutevar8x32_epi32, _mm256_set1_epi32, _mm256_set1_ps,
    _mm256_setr_epi32, _mm256_setr_pd, _mm256_storeu_pd, _mm256_storeu_si256, _CMP_LE_OQ,
};

/// Sorts `a` ascending. Its values must not be NaN (squared distances and +inf padding).
/// Unsafe only to call from code compiled without AVX2: this module exists only in builds that
/// enable it (and the binary refuses a CPU without it, main.rs).
#[target_feature(enable = "avx2")]
pub(super) fn sort32(a: &mut [f64; 32]) {
    // Element i is lane i % 4 of register i / 4.
    let mut r: [__m256d; 8] =
        std::array::from_fn(|x| _mm256_setr_pd(a[4 * x], a[4 * x + 1], a[4 * x + 2], a[4 * x + 3]));
    // The stages (k, j) of the bitonic sort, spelt out so that every mask is a constant.
    stage::<2, 1>(&mut r);
    stage::<4, 2>(&mut r);
    stage::<4, 1>(&mut r);
    stage::<8, 4>(&mut r);
    stage::<8, 2>(&mut r);
    stage::<8, 1>(&mut r);
    stage::<16, 8>(&mut r);
    stage::<16, 4>(&mut r);
    stage::<16, 2>(&mut r);
    stage::<16, 1>(&mut r);
    stage::<32, 16>(&mut r);
    stage::<32, 8>(&mut r);
    stage::<32, 4>(&mut r);
    stage::<32, 2>(&mut r);
    stage::<32, 1>(&mut r);
    for (x, v) in r.iter().enumerate() {
        // SAFETY: lanes 4x..4x + 4 of a 32-element array, x < 8; unaligned store.
        unsafe { _mm256_storeu_pd(a.as_mut_ptr().add(4 * x), *v) };
    }
}

/// Stage (K, J): element i meets i ^ J, the smaller first where i & K == 0 (an ascending run),
/// the larger first otherwise. Pairs 4 or more apart are whole registers, closer ones lanes.
#[inline]
#[target_feature(enable = "avx2")]
fn stage<const K: usize, const J: usize>(r: &mut [__m256d; 8]) {
    if J >= 4 {
        let jr = J / 4;
        for x in (0..8).filter(|x| x & jr == 0) {
            let (lo, hi) = (r[x], r[x | jr]);
            let (mn, mx) = (_mm256_min_pd(lo, hi), _mm256_max_pd(lo, hi));
            // K >= 8 here: the run's direction is the same in every lane.
            (r[x], r[x | jr]) = if (4 * x) & K != 0 { (mx, mn) } else { (mn, mx) };
        }
    } else {
        for (x, v) in r.iter_mut().enumerate() {
            *v = lanes::<K, J>(*v, (4 * x) & K != 0);
        }
    }
}

/// A stage whose pairs are lanes J (1 or 2) apart in one register, whose run is `descending`
/// (for K >= 4; with K = 2 the direction changes within the register). A lane keeps the
/// smaller of its pair when it is the pair's first in an ascending run or its second in a
/// descending one: the set bits of the blend, which takes `mn` there.
#[inline]
#[target_feature(enable = "avx2")]
fn lanes<const K: usize, const J: usize>(v: __m256d, descending: bool) -> __m256d {
    let partner = if J == 1 {
        _mm256_permute_pd::<0b0101>(v)
    } else {
        _mm256_permute4x64_pd::<0b0100_1110>(v)
    };
    let (mn, mx) = (_mm256_min_pd(v, partner), _mm256_max_pd(v, partner));
    match (K, J, descending) {
        (2, _, _) => _mm256_blend_pd::<0b1001>(mx, mn),
        (_, 1, false) => _mm256_blend_pd::<0b0101>(mx, mn),
        (_, 1, true) => _mm256_blend_pd::<0b1010>(mx, mn),
        (_, _, false) => _mm256_blend_pd::<0b0011>(mx, mn),
        (_, _, true) => _mm256_blend_pd::<0b1100>(mx, mn),
    }
}

/// Per 8-bit mask, the lanes whose bit is set, in order, then zeros: the permutation that
/// packs those lanes to the front.
const PACK: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut lane, mut n) = (0, 0);
        while lane < 8 {
            if m >> lane & 1 == 1 {
                t[m][n] = lane as u32;
                n += 1;
            }
            lane += 1;
        }
        m += 1;
    }
    t
};

/// Writes to the front of `out` the indices j of `d2` with `d2[j] <= lim` (false for NaN), in
/// increasing order, and returns how many; `out` is grown to at least `d2.len() + 8` (each
/// step stores eight lanes). The scalar loop in `grid` is the same selection.
#[target_feature(enable = "avx2")]
pub(super) fn select_within(d2: &[f32], lim: f32, out: &mut Vec<u32>) -> usize {
    if out.len() < d2.len() + 8 {
        out.resize(d2.len() + 8, 0);
    }
    let (limv, eight) = (_mm256_set1_ps(lim), _mm256_set1_epi32(8));
    let mut idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mut n = 0;
    let chunks = d2.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        // SAFETY: `c` holds 8 f32 (unaligned load); PACK rows hold 8 u32; `n` is at most the
        // number of indices before this chunk, so n + 8 <= d2.len() + 8 <= out.len().
        unsafe {
            let v = _mm256_loadu_ps(c.as_ptr());
            let m = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(v, limv)) as usize;
            let perm = _mm256_loadu_si256(PACK[m].as_ptr() as *const __m256i);
            let packed = _mm256_permutevar8x32_epi32(idx, perm);
            _mm256_storeu_si256(out.as_mut_ptr().add(n) as *mut __m256i, packed);
            n += m.count_ones() as usize;
        }
        idx = _mm256_add_epi32(idx, eight);
    }
    let first = d2.len() - rest.len();
    for (o, &d) in rest.iter().enumerate() {
        out[n] = (first + o) as u32;
        n += (d <= lim) as usize;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The selection is the scalar filter's: every length up to 40, limits inside and outside
    /// the values, NaN among them.
    #[test]
    fn selects_like_the_scalar_filter() {
        let mut rng = crate::core::rng::Rng::new(5);
        let mut out = Vec::new();
        for case in 0..5_000 {
            let len = case % 41;
            let d2: Vec<f32> = (0..len)
                .map(|j| match (case + j) % 17 {
                    0 => f32::NAN,
                    _ => rng.uniform() as f32,
                })
                .collect();
            let lim = [0.5f32, -1.0, 2.0, f32::NAN][case % 4];
            let want: Vec<u32> = (0..len as u32).filter(|&j| d2[j as usize] <= lim).collect();
            // SAFETY: this module is compiled only with AVX2 enabled.
            let n = unsafe { select_within(&d2, lim, &mut out) };
            assert_eq!(out[..n], want[..], "case {case}");
        }
    }

    /// The network sorts like the standard library's sort: random keys of every count up to 32
    /// padded with +inf, with repeated values and zeros among them.
    #[test]
    fn sorts_like_the_standard_sort() {
        let mut rng = crate::core::rng::Rng::new(11);
        for case in 0..20_000 {
            let n = case % 33;
            let mut a = [f64::INFINITY; 32];
            for v in a.iter_mut().take(n) {
                // Few distinct values in some cases, so that ties are common.
                *v = match case % 3 {
                    0 => rng.uniform() * 100.0,
                    1 => (rng.uniform() * 4.0).floor(),
                    _ => rng.uniform() * 1e-300,
                };
            }
            let mut want = a;
            want.sort_by(f64::total_cmp);
            // SAFETY: this module is compiled only with AVX2 enabled.
            unsafe { sort32(&mut a) };
            assert_eq!(a.map(f64::to_bits), want.map(f64::to_bits), "case {case}");
        }
    }
}
