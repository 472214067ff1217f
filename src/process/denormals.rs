//! Flush-to-zero and denormals-are-zero on every thread that traces rays (x86-64's MXCSR; nothing
//! elsewhere).

/// MXCSR bits: flush-to-zero (bit 15) and denormals-are-zero (bit 6).
#[cfg(target_arch = "x86_64")]
const MXCSR_FTZ_DAZ: u32 = (1 << 15) | (1 << 6);

/// Turns on flush-to-zero and denormals-are-zero for SSE arithmetic on the calling thread, as
/// Embree recommends for speed. The flags are per thread: call this in every worker thread's start
/// handler (e.g. rayon's `ThreadPoolBuilder::start_handler`) and on any other thread that traces
/// rays. No-op on architectures other than x86_64.
pub fn set_flush_denormals() {
    #[cfg(target_arch = "x86_64")]
    {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr/ldmxcsr only read and write the calling thread's MXCSR and the local
        // `csr`; setting FTZ and DAZ changes only how denormals are rounded.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr as *mut u32, options(nostack, preserves_flags));
            csr |= MXCSR_FTZ_DAZ;
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr as *const u32, options(nostack, preserves_flags, readonly));
        }
    }
}

/// Whether flush-to-zero and denormals-are-zero are both on for the calling thread (always false
/// on architectures other than x86_64).
pub fn flush_denormals_enabled() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr only stores the calling thread's MXCSR into `csr`.
        unsafe { std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr as *mut u32, options(nostack, preserves_flags)) };
        csr & MXCSR_FTZ_DAZ == MXCSR_FTZ_DAZ
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
