//! Instructions per step on the Cortex-M4F under QEMU (`netduinoplus2`, an STM32F405, with
//! `-icount shift=0`: one instruction per virtual nanosecond). SysTick runs on the core clock
//! of the model; the tick-to-instruction factor is calibrated on a block of a known number of
//! `nop`s, and the cost of reading SysTick is subtracted. Each method runs `N` steps on the
//! same test signal (samples generated before timing each step).
#![no_std]
#![no_main]

use bench_mcu::{Ekf32, Ekf32Sparse, Signal};
use cortex_m::peripheral::{syst::SystClkSource, Peripherals, SYST};
use cortex_m_rt::entry;
use identifier_core::{Identifier, Refined, RefinedSettings, Settings};
use semihosting::println;

const N: u32 = 4000;

#[inline(always)]
fn now() -> u32 {
    SYST::get_current()
}

#[inline(always)]
fn elapsed(t0: u32, t1: u32) -> u32 {
    // SysTick counts down, 24 bits.
    t0.wrapping_sub(t1) & 0x00FF_FFFF
}

#[inline(never)]
fn nops_1000() {
    // SAFETY: a block of plain `nop` instructions with no operands or side effects.
    unsafe {
        core::arch::asm!(
            ".rept 1000",
            "nop",
            ".endr",
            options(nomem, nostack, preserves_flags)
        );
    }
}

/// Runs `f` on `N` samples and returns the average SysTick ticks per call.
fn measure<F: FnMut([f32; 3], f32)>(mut f: F) -> f32 {
    let mut sig = Signal::paper();
    let dt = sig.dt();
    let mut ticks: u64 = 0;
    for _ in 0..N {
        let w = sig.next_sample();
        let t0 = now();
        f(w, dt);
        let t1 = now();
        ticks += u64::from(elapsed(t0, t1));
    }
    ticks as f32 / N as f32
}

#[entry]
fn main() -> ! {
    let Some(mut p) = Peripherals::take() else {
        semihosting::process::exit(2)
    };
    p.SYST.set_clock_source(SystClkSource::Core);
    p.SYST.set_reload(0x00FF_FFFF);
    p.SYST.clear_current();
    p.SYST.enable_counter();

    // Calibration: ticks for 100 x 1000 nops, and the cost of an empty measurement.
    let t0 = now();
    for _ in 0..100 {
        nops_1000();
    }
    let t1 = now();
    let per_tick = 100_000.0 / elapsed(t0, t1) as f32;
    let empty = measure(|w, _| {
        core::hint::black_box(w);
    });

    let report = |name: &str, ticks: f32, how: &str| {
        let instr = (ticks - empty) * per_tick;
        println!("{},{:.0},{}", name, instr, how);
    };
    println!(
        "# instructions per SysTick tick {:.2}; empty measurement {:.2} ticks",
        per_tick, empty
    );
    println!("method,instructions,how");

    let mut paper = match Identifier::new(Settings::with_lambda(3.0)) {
        Ok(id) => id,
        Err(_) => semihosting::process::exit(3),
    };
    let t = measure(|w, dt| {
        core::hint::black_box(paper.step(core::hint::black_box(w), dt));
    });
    report(
        "paper",
        t,
        "Cortex-M4F QEMU -icount; Settings::with_lambda(3)",
    );

    // The refined identifier as configured for 1 kHz (defaults: 32-sample blocks, no end
    // correction), and as configured for 100 Hz (8-sample blocks, end correction).
    let Some(mut refined) = Refined::new(RefinedSettings::new()) else {
        semihosting::process::exit(4)
    };
    let t = measure(|w, dt| {
        core::hint::black_box(refined.step(core::hint::black_box(w), dt));
    });
    report("refined", t, "Cortex-M4F QEMU -icount; 1 kHz settings");
    let mut s = RefinedSettings::new();
    s.end_correction = true;
    s.block = 8;
    let Some(mut r100) = Refined::new(s) else {
        semihosting::process::exit(5)
    };
    let t = measure(|w, dt| {
        core::hint::black_box(r100.step(core::hint::black_box(w), dt));
    });
    report(
        "refined-100hz",
        t,
        "Cortex-M4F QEMU -icount; 100 Hz settings: 8-sample blocks and end correction",
    );

    let mut ekf = Ekf32::new([1.0, 1.0, 1.0], 2e-3);
    let t = measure(|w, dt| {
        ekf.step(core::hint::black_box(w), dt);
        core::hint::black_box(&ekf);
    });
    report(
        "ekf",
        t,
        "Cortex-M4F QEMU -icount; dense f32 EKF (bench-mcu)",
    );

    let mut sparse = Ekf32Sparse::new([1.0, 1.0, 1.0], 2e-3);
    let t = measure(|w, dt| {
        sparse.step(core::hint::black_box(w), dt);
        core::hint::black_box(&sparse);
    });
    report(
        "ekf-sparse",
        t,
        "Cortex-M4F QEMU -icount; f32 EKF exploiting sparsity and symmetry (bench-mcu)",
    );
    let a = refined.estimate();
    let e = ekf.a();
    println!(
        "# check: refined a = ({:.4}, {:.4}, {:.4}), ekf a = ({:.4}, {:.4}, {:.4})",
        a[0], a[1], a[2], e[0], e[1], e[2]
    );
    let sp = sparse.a();
    println!(
        "# check: sparse ekf a = ({:.4}, {:.4}, {:.4})",
        sp[0], sp[1], sp[2]
    );
    semihosting::process::exit(0)
}
