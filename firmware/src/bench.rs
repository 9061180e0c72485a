//! Markers for the instruction-count benchmark (`scripts/bench-firmware.sh`).
//!
//! With the `bench` feature, [`step_begin`] and [`step_end`] are real, never-inlined functions
//! with fixed symbol names called right before and after each identifier step; a QEMU TCG
//! plugin counts the instructions executed between their entries. Without the feature they
//! are empty and inlined away, so the flight build carries no trace of them.

/// Called right before `Identifier::step`.
#[cfg(feature = "bench")]
#[inline(never)]
#[unsafe(no_mangle)]
pub extern "C" fn bench_step_begin() {
    barrier();
}

/// Called right after `Identifier::step`.
#[cfg(feature = "bench")]
#[inline(never)]
#[unsafe(no_mangle)]
pub extern "C" fn bench_step_end() {
    barrier();
}

/// Called once with nothing between begin and end, to measure the markers' own cost.
#[cfg(feature = "bench")]
pub fn calibrate() {
    bench_step_begin();
    bench_step_end();
}

#[cfg(feature = "bench")]
#[inline(always)]
fn barrier() {
    // An observable side effect, so the optimiser keeps the calls.
    core::hint::black_box(());
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
}

/// Marks the start of one identifier step.
#[inline(always)]
pub fn step_begin() {
    #[cfg(feature = "bench")]
    bench_step_begin();
}

/// Marks the end of one identifier step.
#[inline(always)]
pub fn step_end() {
    #[cfg(feature = "bench")]
    bench_step_end();
}
