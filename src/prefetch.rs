//! Cache-prefetch hints: ask the CPU to start loading a line that will be read soon, so that the
//! miss overlaps other work. Hints only: a prefetch never faults and changes no value; off x86-64
//! they do nothing.

/// Asks the cache for the line holding `p`. A prefetch never faults, so `p` need not point into a
/// live allocation.
#[inline(always)]
pub(crate) fn prefetch_line<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86_64 baseline, and a prefetch never faults.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Asks the cache for the line holding `value`.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    prefetch_line(value as *const T);
}
