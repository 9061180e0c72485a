//! Fault injection on the MCU, under QEMU (mps2-an386, Cortex-M4F).
//!
//! The real ICM-42688-P driver talks to the simulated part (`icm42688::sim`) through a
//! fault-injecting SPI layer; the flight firmware's own sample loop (`firmware::SampleLoop`,
//! the code that flies) feeds `identifier-core`, counts every fault and re-initialises the
//! sensor when it stops making sense; this program reports over defmt and feeds a watchdog once
//! per loop iteration (the CMSDK APB watchdog that QEMU models on this machine; the STM32F405
//! image feeds its IWDG the same way, which QEMU's netduinoplus2 does not model). The motion is
//! the paper's body tumbling from (1, 1, 1) rad/s, integrated on the target (RK4, f32) at the
//! gyro's 1 kHz ODR, with seeded white noise of 1e-3 rad/s.
//!
//! Scenarios, each a 20 s replay: clean; 1 % corrupted + 1 % dropped samples + 1 % bus errors
//! (the figure: RMS error of `a` over the last 10 s against the clean replay, within 2x); the
//! bus dead for a while; `WHO_AM_I` reading 0x00 for a while; no data-ready for a while; the
//! data stalled for a while; and a hang inside an SPI transfer, which only the watchdog can end:
//! the machine resets, the firmware finds its marker in RAM that survives the reset, reports
//! the recovery and carries on with the remaining scenarios.
//!
//! Exit code (semihosting): 0 when every check passed, 1 otherwise.
#![no_std]
#![no_main]

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};

use cortex_m_rt::entry;
use defmt_semihosting as _;
use firmware::{LoopCounters, NoDelay, SampleLoop};
use icm42688::sim::{FaultySpi, Faults, Injected, SampleSource, SimIcm42688, XorShift32};
use icm42688::{Config, Icm42688, SpiInterface};

// ---------------------------------------------------------------------------------------------
// Watchdog: CMSDK APB watchdog at 0x4000_8000 on mps2-an386, clocked at 25 MHz.

const WDOG: usize = 0x4000_8000;
const WDOG_LOAD: usize = WDOG;
const WDOG_CONTROL: usize = WDOG + 0x008;
const WDOG_INTCLR: usize = WDOG + 0x00C;
const WDOG_LOCK: usize = WDOG + 0xC00;
const WDOG_UNLOCK: u32 = 0x1ACC_E551;
/// 50 ms at 25 MHz; the reset comes at the second expiry without a feed, after 100 ms.
const WDOG_TICKS: u32 = 1_250_000;

fn wdog_write(addr: usize, v: u32) {
    // SAFETY: a memory-mapped register of the CMSDK watchdog on this machine.
    unsafe { write_volatile(addr as *mut u32, v) }
}

fn watchdog_start() {
    if cfg!(feature = "selftest-no-watchdog") {
        return;
    }
    wdog_write(WDOG_LOCK, WDOG_UNLOCK);
    wdog_write(WDOG_LOAD, WDOG_TICKS);
    wdog_write(WDOG_CONTROL, 0b11); // INTEN | RESEN
    wdog_write(WDOG_LOCK, 0);
}

fn watchdog_feed() {
    wdog_write(WDOG_LOCK, WDOG_UNLOCK);
    wdog_write(WDOG_INTCLR, 1);
    wdog_write(WDOG_LOCK, 0);
}

// ---------------------------------------------------------------------------------------------
// A marker in RAM that the reset leaves alone (cortex-m-rt does not initialise .uninit).

const MAGIC_HANG: u32 = 0x4841_4E47; // "HANG"

#[link_section = ".uninit.faults"]
static mut MARK: MaybeUninit<[u32; 2]> = MaybeUninit::uninit();

fn mark_read() -> [u32; 2] {
    // SAFETY: plain words in RAM; any bit pattern is a valid [u32; 2].
    unsafe { read_volatile(addr_of!(MARK).cast::<[u32; 2]>()) }
}

fn mark_write(v: [u32; 2]) {
    // SAFETY: as above; single-threaded.
    unsafe { write_volatile(addr_of_mut!(MARK).cast::<[u32; 2]>(), v) }
}

// ---------------------------------------------------------------------------------------------
// Stack high-water by painting.

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}
const PAINT: u32 = 0xC0DE_57AC;

fn stack_bounds() -> (usize, usize) {
    // Only the addresses of the linker symbols are taken.
    (
        addr_of!(_stack_end) as usize,
        addr_of!(_stack_start) as usize,
    )
}

#[inline(never)]
fn stack_paint() {
    let (bottom, _) = stack_bounds();
    let end = (cortex_m::register::msp::read() as usize).saturating_sub(256) & !3;
    let mut p = (bottom + 3) & !3;
    while p < end {
        // SAFETY: free stack below every live frame.
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

fn stack_high_water() -> usize {
    let (bottom, top) = stack_bounds();
    let mut p = (bottom + 3) & !3;
    // SAFETY: reading stack RAM between the linker's bounds.
    while p < top && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    top - p
}

// ---------------------------------------------------------------------------------------------
// Seeded randomness and maths without std.

#[derive(Clone, Copy)]
struct XorShift(u32);

impl XorShift {
    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
    /// Approximately normal, unit variance (sum of four uniforms).
    fn normal(&mut self) -> f32 {
        let mut s = 0.0f32;
        for _ in 0..4 {
            s += (self.next() >> 8) as f32 / (1u32 << 24) as f32;
        }
        (s - 2.0) * 1.732_050_8
    }
}

fn sqrt(x: f32) -> f32 {
    if x <= 0.0 || !x.is_finite() {
        return 0.0;
    }
    let mut y = if x > 1.0 { x } else { 1.0 };
    for _ in 0..40 {
        y = 0.5 * (y + x / y);
    }
    y
}

// ---------------------------------------------------------------------------------------------
// The motion.

const A: [f32; 3] = [0.9, 0.4 / 1.54, -0.94];
const RATE: f32 = 1000.0;
const SECONDS: u32 = 20;
const NOISE: f32 = 1e-3;

struct Motion {
    w: [f32; 3],
    k: u32,
    rng: XorShift,
}

impl Motion {
    fn new(seed: u32) -> Self {
        Motion {
            w: [1.0, 1.0, 1.0],
            k: 0,
            rng: XorShift(seed | 1),
        }
    }
}

fn euler(w: [f32; 3]) -> [f32; 3] {
    [A[0] * w[1] * w[2], A[1] * w[2] * w[0], A[2] * w[0] * w[1]]
}

impl SampleSource for Motion {
    fn next_sample(&mut self) -> Option<[f32; 3]> {
        if self.k >= SECONDS * RATE as u32 {
            return None;
        }
        self.k += 1;
        let out = [
            self.w[0] + NOISE * self.rng.normal(),
            self.w[1] + NOISE * self.rng.normal(),
            self.w[2] + NOISE * self.rng.normal(),
        ];
        // Two RK4 substeps per sample.
        let h = 0.5 / RATE;
        for _ in 0..2 {
            let w = self.w;
            let add = |a: [f32; 3], b: [f32; 3], s: f32| {
                [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
            };
            let k1 = euler(w);
            let k2 = euler(add(w, k1, 0.5 * h));
            let k3 = euler(add(w, k2, 0.5 * h));
            let k4 = euler(add(w, k3, h));
            for i in 0..3 {
                self.w[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        Some(out)
    }
}

// ---------------------------------------------------------------------------------------------
// Fault injection between the driver and the simulated part: `icm42688::sim::FaultySpi`, the
// one implementation the host robustness test uses too, drawing from its `XorShift32`.

// ---------------------------------------------------------------------------------------------
// The flight firmware's own sample loop (`firmware::SampleLoop`: plausibility gate, dt from a
// sample clock, re-initialisation after repeated failures, a wrong WHO_AM_I or stalled data,
// periodic WHO_AM_I check), fed by the faulty part; the watchdog is fed once per iteration.

struct Outcome {
    rms: f32,
    final_err: f32,
    c: LoopCounters,
    injected: Injected,
}

fn replay(seed: u32, faults: Faults) -> Option<Outcome> {
    let spi = FaultySpi::new(
        SimIcm42688::new(Motion::new(seed)),
        faults,
        XorShift32::new(seed.wrapping_mul(2_654_435_761)),
    );
    let config = Config::identifier();
    // The simulated part models no time: the loop's clock is its count of latched samples.
    let period_us = config.odr.period_us();
    let clock = move |i: &SpiInterface<FaultySpi<Motion, XorShift32>>| {
        i.bus().inner.stats().samples.wrapping_mul(period_us)
    };
    let mut lp = match SampleLoop::new(Icm42688::new_spi(spi), &mut NoDelay, config, clock) {
        Ok(lp) => lp,
        Err(e) => {
            defmt::error!("gyro init: {}", e);
            return None;
        }
    };
    let latched = |lp: &SampleLoop<_, _>| -> u32 {
        let i: &SpiInterface<FaultySpi<Motion, XorShift32>> = lp.gyro().interface();
        i.bus().inner.stats().samples
    };
    let (mut sum, mut count) = (0.0f32, 0u32);
    let from = (SECONDS - 10) * RATE as u32;
    let mut reinits = 0;
    while !lp.gyro().interface().bus().inner.exhausted() {
        watchdog_feed();
        lp.poll(&mut NoDelay);
        let c = lp.counters();
        if c.reinits != reinits {
            reinits = c.reinits;
            if reinits <= 5 {
                defmt::warn!("the gyro was re-initialised: {}", c);
            }
        }
        if latched(&lp) >= from {
            let e = lp.identifier().estimate();
            for i in 0..3 {
                sum += (e[i] - A[i]) * (e[i] - A[i]);
            }
            count += 3;
        }
    }
    let e = lp.identifier().estimate();
    let mut final_err = 0.0f32;
    for i in 0..3 {
        final_err = final_err.max((e[i] - A[i]).abs());
    }
    Some(Outcome {
        rms: sqrt(sum / count.max(1) as f32),
        final_err,
        c: lp.counters(),
        injected: lp.gyro().interface().bus().injected(),
    })
}

// ---------------------------------------------------------------------------------------------

const SEED: u32 = 12345;
const AT: u32 = 12_000;

fn scenarios() -> [(&'static str, Faults); 7] {
    let none = Faults::default();
    [
        ("clean", none),
        (
            "1% corrupted + 1% dropped + 1% bus errors",
            Faults {
                bus_error_ppm: 10_000,
                corrupt_ppm: 10_000,
                drop_ppm: 10_000,
                ..none
            },
        ),
        (
            "bus dead for 200 transfers",
            Faults {
                bus_dead: Some((AT, AT + 200)),
                ..none
            },
        ),
        (
            "WHO_AM_I reads 0x00 for 2000 transfers",
            Faults {
                wrong_id: Some((AT, AT + 2000)),
                ..none
            },
        ),
        (
            // The firmware waits two sample periods for data-ready, 200 polls of 10 us; the
            // simulated part latches a sample per poll, so one wait takes 200 transfers.
            "no data-ready for 2000 transfers",
            Faults {
                no_data_ready: Some((AT, AT + 2000)),
                ..none
            },
        ),
        (
            "data stalled for 400 transfers",
            Faults {
                stalled: Some((AT, AT + 400)),
                ..none
            },
        ),
        (
            "SPI transfer hangs",
            Faults {
                hang: Some(AT),
                ..none
            },
        ),
    ]
}

const HANG: usize = 6;

/// The check for each scenario against the clean run's figures.
fn check(k: usize, o: &Outcome, clean: Option<(f32, f32)>) -> bool {
    let c = &o.c;
    let (clean_rms, clean_final) = clean.unwrap_or((o.rms, o.final_err));
    let seen = match k {
        0 => c.bus_errors == 0 && c.reinits == 0 && c.implausible == 0,
        1 => {
            o.injected.bus_errors > 100
                && o.injected.corrupted > 100
                && o.injected.dropped > 100
                && c.bus_errors >= o.injected.bus_errors / 2
                && o.rms <= 2.0 * clean_rms
        }
        2 => c.bus_errors >= 5 && c.reinits >= 1,
        3 => c.wrong_id >= 1 && c.reinits >= 1,
        4 => c.timeouts >= 5 && c.reinits >= 1,
        5 => c.stalled >= 1 && c.reinits >= 1,
        _ => false,
    };
    seen && o.final_err <= 2.0 * clean_final + 1e-3 && o.final_err.is_finite()
}

#[entry]
fn main() -> ! {
    stack_paint();
    let mark = mark_read();
    mark_write([0, 0]);
    watchdog_start();
    let ok = if mark[0] == MAGIC_HANG {
        // Second boot: the earlier scenarios ran in the first one, the last hung.
        defmt::warn!(
            "reset by the watchdog after the injected hang: the firmware is running again"
        );
        mark[1] == 1
    } else {
        run_scenarios()
    };
    defmt::info!(
        "fault injection: {=str}",
        if ok { "all checks passed" } else { "FAILED" }
    );
    semihosting::process::exit(if ok { 0 } else { 1 })
}

/// Runs every scenario; returns only if the hang scenario failed to hang.
fn run_scenarios() -> bool {
    let mut ok = true;
    let mut clean: Option<(f32, f32)> = None;
    for (k, (name, faults)) in scenarios().iter().enumerate() {
        if k == HANG {
            defmt::info!(
                "stack high-water over scenarios 0-{=usize}: {=usize} bytes of {=usize}",
                HANG - 1,
                stack_high_water(),
                stack_bounds().1 - stack_bounds().0
            );
            defmt::info!(
                "scenario {=usize}: {=str}: only the watchdog can end it",
                k,
                name
            );
            mark_write([MAGIC_HANG, u32::from(ok)]);
        }
        let Some(o) = replay(SEED, *faults) else {
            defmt::error!("scenario {=usize}: gyro init failed", k);
            ok = false;
            continue;
        };
        if k == HANG {
            defmt::error!("scenario {=usize}: the transfer did not hang", k);
            mark_write([0, 0]);
            return false;
        }
        let pass = check(k, &o, clean);
        ok &= pass;
        defmt::info!(
            "scenario {=usize}: {=str}: RMS error of a over the last 10 s {=f32}, final {=f32}; injected {}; loop {}; {=str}",
            k,
            name,
            o.rms,
            o.final_err,
            o.injected,
            o.c,
            if pass { "PASS" } else { "FAIL" }
        );
        if k == 0 {
            clean = Some((o.rms, o.final_err));
        }
        if let (1, Some((c, _))) = (k, clean) {
            defmt::info!(
                "FIGURE: clean RMS {=f32}, faulty RMS {=f32}, ratio {=f32}",
                c,
                o.rms,
                o.rms / c
            );
        }
    }
    false
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    semihosting::process::exit(101)
}
