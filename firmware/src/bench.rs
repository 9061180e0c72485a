//! Markers for the instruction-count benchmark (`scripts/bench-firmware.sh`).
//!
//! With the `bench` feature on Arm, [`step_begin`] and [`step_end`] each emit one otherwise
//! useless instruction right before and after the identifier step: `mov r9, r9` (0x46C9) and
//! `mov r10, r10` (0x46D2). The compiler never emits these itself, so a QEMU TCG plugin
//! (`firmware/bench/insn-count.c`) finds them by their encoding and counts the instructions
//! executed between them. An `asm!` block is volatile and may touch memory, so the optimiser
//! neither removes it nor moves the step's loads and stores across it. (Marker functions
//! with symbol names were tried first: with fat LTO they disappeared from the image.)
//!
//! Without the feature both are empty and the flight build carries no trace of them.

/// Marks the start of one identifier step.
#[inline(always)]
pub fn step_begin() {
    #[cfg(all(feature = "bench", target_arch = "arm"))]
    // SAFETY: a register move of r9 onto itself: no effect on any state.
    unsafe {
        core::arch::asm!("mov r9, r9", options(nostack, preserves_flags))
    };
}

/// Marks the end of one identifier step.
#[inline(always)]
pub fn step_end() {
    #[cfg(all(feature = "bench", target_arch = "arm"))]
    // SAFETY: a register move of r10 onto itself: no effect on any state.
    unsafe {
        core::arch::asm!("mov r10, r10", options(nostack, preserves_flags))
    };
}

/// Begin immediately followed by end, once before the loop: the plugin takes this first
/// interval as the markers' own cost.
pub fn calibrate() {
    step_begin();
    step_end();
}
