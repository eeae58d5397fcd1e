//! A hint to the processor to bring memory into its caches before a loop reaches it: for a
//! loop whose items are scattered over more memory than the second-level cache holds and whose
//! next addresses are known some iterations ahead (a tile's result records taken in id order).
//! A load that misses stalls the loop until it returns; a prefetch retires at once, so the
//! misses of several items ahead overlap.

/// The 64-byte lines of one x86-64 or AArch64 cache.
const LINE: usize = 64;

/// Prefetches every cache line of the `len` bytes from `start` into all cache levels. Any
/// address will do: a prefetch reads nothing into the program and never faults. Does nothing
/// on targets without a prefetch this crate uses.
#[inline(always)]
pub(crate) fn prefetch(start: *const u8, len: usize) {
    let end = (start as usize).saturating_add(len);
    let mut line = start as usize & !(LINE - 1);
    while line < end {
        prefetch_line(line as *const i8);
        line = line.saturating_add(LINE);
    }
}

#[inline(always)]
fn prefetch_line(at: *const i8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: SSE is in every x86-64 target's baseline, and a prefetch only hints: it
        // reads nothing into the program and never faults, whatever the address.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(at) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = at;
}

#[cfg(test)]
mod tests {
    use super::prefetch;

    /// A prefetch of any address returns, whatever it points at: none, the end of memory, a
    /// freed buffer, a span longer than a line.
    #[test]
    fn any_address_is_taken_without_a_fault() {
        prefetch(std::ptr::null(), 1);
        prefetch(usize::MAX as *const u8, 4096);
        let buffer = vec![7u8; 1000];
        let freed = buffer.as_ptr();
        drop(buffer);
        prefetch(freed, 1000);
        let kept = [1u8; 300];
        prefetch(kept.as_ptr().wrapping_add(250), 200);
        assert_eq!(kept.iter().map(|&b| u32::from(b)).sum::<u32>(), 300);
    }
}
