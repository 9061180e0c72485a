//! Markers for the instruction-count benchmark (`scripts/bench-firmware.sh`).
//!
//! With the `bench` feature on Arm, each marker emits one otherwise useless instruction, a
//! register moved onto itself, with a register per marker:
//!
//! | interval                          | begin                 | end                     |
//! |-----------------------------------|-----------------------|-------------------------|
//! | paper's identifier step           | `mov r9, r9` (0x46C9) | `mov r10, r10` (0x46D2) |
//! | refined identifier step           | `mov r11, r11` (0x46DB) | `mov r12, r12` (0x46E4) |
//! | sample-loop iteration that stepped (`SampleLoop::poll`) | `mov r8, r8` (0x46C0) | `mov lr, lr` (0x46F6) |
//!
//! The compiler never emits these itself on this target (its no-op is `nop`, 0xBF00;
//! `scripts/bench-firmware.sh` checks that each appears once in the image), so a QEMU TCG
//! plugin (`firmware/bench/insn-count.c`) finds them by their encoding and counts the
//! instructions executed between each pair. An `asm!` block is volatile and may touch memory,
//! so the optimiser neither removes it nor moves the step's loads and stores across it.
//! (Not marker functions with symbol names: with fat LTO they disappear from the image.)
//!
//! Without the feature all are empty and the flight build carries no trace of them.

macro_rules! marker {
    ($(#[$doc:meta])* $name:ident, $insn:literal) => {
        $(#[$doc])*
        #[inline(always)]
        pub fn $name() {
            #[cfg(all(feature = "bench", target_arch = "arm"))]
            // SAFETY: a register moved onto itself: no effect on any state.
            unsafe {
                core::arch::asm!($insn, options(nostack, preserves_flags))
            };
        }
    };
}

marker!(
    /// Marks the start of one step of the paper's identifier.
    step_begin,
    "mov r9, r9"
);
marker!(
    /// Marks the end of one step of the paper's identifier.
    step_end,
    "mov r10, r10"
);
marker!(
    /// Marks the start of one step of the refined identifier.
    refined_begin,
    "mov r11, r11"
);
marker!(
    /// Marks the end of one step of the refined identifier.
    refined_end,
    "mov r12, r12"
);
marker!(
    /// Marks the start of one sample-loop iteration.
    loop_begin,
    "mov r8, r8"
);
marker!(
    /// Marks the end of one sample-loop iteration.
    loop_end,
    "mov lr, lr"
);

/// Each begin immediately followed by its end, once before the loop: the plugin takes this
/// first interval of each pair as the markers' own cost.
pub fn calibrate() {
    loop_begin();
    loop_end();
    step_begin();
    step_end();
    refined_begin();
    refined_end();
}
