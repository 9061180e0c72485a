//! The firmware under QEMU (`-machine netduinoplus2`, an STM32F405 with the same memory map as
//! the real board): the ICM-42688-P is [`SimIcm42688`], answering the driver's SPI transfers
//! with samples from a gyro log read through semihosting; defmt goes out over semihosting; the
//! exit code tells the host how the run went.
//!
//! Semihosting command line: `firmware-qemu <log path> [bus error every n transfers]`, or
//! `firmware-qemu --replay <replay file>` (written by `inertia export-replay`): a real log's
//! own samples, at its own rate, into the sample loop's free-flight pipeline and both
//! identifiers ([`SampleLoop::replay_sample`]; the driver, the simulated part, the
//! plausibility gate and the sample clock are bypassed, since the part's 16-bit counts cannot
//! carry the log's `f32` values unchanged).
//! Exit codes: 0 log replayed, 1 gyro init failed, 2 log unreadable, 3 bad arguments,
//! 4 log shorter than its header says (truncated file or a read error).
//!
//! Every report also goes out as a `telemetry` frame on USART1 (QEMU: `-serial file:...`).
#![no_std]
#![no_main]

use core::ffi::CStr;

use cortex_m_rt::entry;
use defmt_semihosting as _;
use firmware::log_format::{decode_sample, Header, HEADER_LEN, SAMPLE_LEN};
use firmware::replay_format::{self, ReplayHeader};
use firmware::uplink::{send_report, ByteSink};
use firmware::{stack, InitError, NoDelay, Poll, RotorConfig, SampleLoop};
use icm42688::sim::{SampleSource, SimIcm42688};
use icm42688::{Config, GyroOdr, Icm42688, SpiInterface};
use semihosting::fs::File;
use semihosting::io::Read;

/// Samples read per semihosting call.
const CHUNK: usize = 64;

/// Samples from the log file, read in chunks.
struct LogSource {
    file: File,
    buf: [u8; CHUNK * SAMPLE_LEN],
    len: usize,
    pos: usize,
    left: u32,
}

impl LogSource {
    fn refill(&mut self) -> bool {
        // Keep a partial sample, then top up.
        let rest = self.len - self.pos;
        self.buf.copy_within(self.pos..self.len, 0);
        self.len = rest;
        self.pos = 0;
        while self.len < SAMPLE_LEN {
            match self.file.read(&mut self.buf[self.len..]) {
                Ok(0) | Err(_) => return false,
                Ok(n) => self.len += n,
            }
        }
        true
    }
}

impl SampleSource for LogSource {
    fn next_sample(&mut self) -> Option<[f32; 3]> {
        if self.left == 0 {
            return None;
        }
        if self.len - self.pos < SAMPLE_LEN && !self.refill() {
            self.left = 0;
            return None;
        }
        let mut s = [0u8; SAMPLE_LEN];
        s.copy_from_slice(&self.buf[self.pos..self.pos + SAMPLE_LEN]);
        self.pos += SAMPLE_LEN;
        self.left -= 1;
        Some(decode_sample(&s))
    }
}

/// USART1 of the STM32F405 by its registers (QEMU models its transmitter; the board image
/// uses the HAL).
struct Usart1;

impl Usart1 {
    const BASE: usize = 0x4001_1000;
    const SR: *mut u32 = Self::BASE as *mut u32;
    const DR: *mut u32 = (Self::BASE + 0x04) as *mut u32;
    const BRR: *mut u32 = (Self::BASE + 0x08) as *mut u32;
    const CR1: *mut u32 = (Self::BASE + 0x0C) as *mut u32;
    const RCC_APB2ENR: *mut u32 = 0x4002_3844 as *mut u32;

    /// Clock on, 921 600 baud at an 84 MHz APB2, 8N1, transmitter enabled.
    fn init() -> Self {
        // SAFETY: fixed STM32F405 register addresses; nothing else in this image uses them.
        unsafe {
            let en = core::ptr::read_volatile(Self::RCC_APB2ENR);
            core::ptr::write_volatile(Self::RCC_APB2ENR, en | (1 << 4));
            core::ptr::write_volatile(Self::BRR, 84_000_000 / 921_600);
            core::ptr::write_volatile(Self::CR1, (1 << 13) | (1 << 3));
        }
        Usart1
    }
}

impl ByteSink for Usart1 {
    fn send(&mut self, bytes: &[u8]) {
        for &b in bytes {
            // Wait for the data register (bounded: a transmitter that never frees it must not
            // hang the loop).
            for _ in 0..10_000 {
                // SAFETY: status register read.
                if unsafe { core::ptr::read_volatile(Self::SR) } & (1 << 7) != 0 {
                    break;
                }
            }
            // SAFETY: data register write.
            unsafe { core::ptr::write_volatile(Self::DR, u32::from(b)) };
        }
    }
}

fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

fn open_log(path: &str) -> Option<(LogSource, Header)> {
    let mut name = [0u8; 256];
    let bytes = path.as_bytes();
    if bytes.len() >= name.len() {
        return None;
    }
    name[..bytes.len()].copy_from_slice(bytes);
    let cpath = CStr::from_bytes_until_nul(&name).ok()?;
    let mut file = File::open(cpath).ok()?;
    let mut h = [0u8; HEADER_LEN];
    let mut got = 0;
    while got < HEADER_LEN {
        match file.read(&mut h[got..]) {
            Ok(0) | Err(_) => return None,
            Ok(n) => got += n,
        }
    }
    let header = match Header::decode(&h) {
        Ok(header) => header,
        Err(e) => {
            defmt::error!("log header refused: {}", e);
            return None;
        }
    };
    let source = LogSource {
        file,
        buf: [0; CHUNK * SAMPLE_LEN],
        len: 0,
        pos: 0,
        left: header.samples,
    };
    Some((source, header))
}

#[entry]
fn main() -> ! {
    stack::paint();

    let Ok(args) = semihosting::experimental::env::args::<512>() else {
        defmt::error!("no semihosting command line");
        exit(3)
    };
    let mut it = (&args).into_iter().skip(1);
    let Some(Ok(path)) = it.next() else {
        defmt::error!("usage: firmware-qemu <gyro log> [bus error every n] | --replay <file>");
        exit(3)
    };
    let mut uart = Usart1::init();
    if path == "--replay" {
        let Some(Ok(file)) = it.next() else {
            defmt::error!("usage: firmware-qemu --replay <replay file>");
            exit(3)
        };
        replay(file, &mut uart)
    }
    let fail_every = match it.next() {
        Some(Ok(n)) => match n.parse::<u32>() {
            Ok(n) => n,
            Err(_) => exit(3),
        },
        _ => 0,
    };
    run_log(path, fail_every, &mut uart)
}

/// A gyro log through the simulated part and the whole sample loop (see the module docs).
#[inline(never)]
fn run_log(path: &str, fail_every: u32, uart: &mut Usart1) -> ! {
    let Some((source, header)) = open_log(path) else {
        defmt::error!("cannot read gyro log {=str}", path);
        exit(2)
    };
    // The part's ODR follows the log's rate when the part has that rate (1 kHz by default).
    let odr = [
        GyroOdr::Hz8000,
        GyroOdr::Hz4000,
        GyroOdr::Hz2000,
        GyroOdr::Hz1000,
        GyroOdr::Hz500,
        GyroOdr::Hz200,
        GyroOdr::Hz100,
    ]
    .into_iter()
    .find(|o| o.hz() == header.rate_hz)
    .unwrap_or(GyroOdr::Hz1000);
    let config = Config {
        odr,
        ..Config::identifier()
    };
    defmt::info!(
        "gyro log {=str}: {=u32} samples at {=f32} Hz; gyro {} at {} (simulated ICM-42688-P, bus error every {=u32} transfers)",
        path,
        header.samples,
        header.rate_hz,
        config.full_scale,
        config.odr,
        fail_every
    );
    if header.rate_hz != config.odr.hz() {
        defmt::warn!("log rate differs from the gyro ODR: dt is the ODR period");
    }

    let sim = SimIcm42688::new(source).with_bus_error_every(fail_every);
    let mut delay = NoDelay;
    // The simulated part models no time: the loop's clock is its count of latched samples
    // (one per data-ready poll), so a sample lost on the bus lengthens the next step.
    let period_us = config.odr.period_us();
    let clock = move |i: &SpiInterface<SimIcm42688<LogSource>>| {
        i.bus().stats().samples.wrapping_mul(period_us)
    };
    let mut app = match SampleLoop::new(Icm42688::new_spi(sim), &mut delay, config, clock) {
        Ok(app) => app,
        Err(e) => {
            defmt::error!("init failed: {}", e);
            exit(1)
        }
    };
    // Stack: the high-water mark so far (start-up, log open, gyro init), then repaint so the
    // mark at the end is the sample loop's alone (reports included).
    let init_high_water = stack::high_water();
    let loop_depth = stack::depth();
    stack::paint();
    firmware::bench::calibrate();

    // Until the log is exhausted (a timeout alone is not the end: with injected bus errors a
    // wait can fail before it times out).
    while !app.gyro().interface().bus().exhausted() {
        if let Poll::Stepped {
            report: Some(r), ..
        } = app.poll(&mut delay)
        {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(uart, &r, None);
        }
        if let Some(r) = app.take_failed_report() {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(uart, &r, None);
        }
        // A free flight ended: its output-error fits run here, between samples.
        if app.fits_pending() {
            app.fit_ended_flight();
        }
    }

    // The log has ended: a flight still being fed ends with it.
    app.end_flight();
    let r = app.report();
    firmware::app::log_report(&r);
    firmware::app::log_tensor(&r, true);
    send_report(uart, &r, None);
    let (p, f) = (r.a_paper, r.a_refined);
    let c = app.counters();
    let ic = app.identifier_counters();
    defmt::info!(
        "final a_paper=[{=f32}, {=f32}, {=f32}] bits_paper=[{=u32:#010x}, {=u32:#010x}, {=u32:#010x}] a_refined=[{=f32}, {=f32}, {=f32}] bits_refined=[{=u32:#010x}, {=u32:#010x}, {=u32:#010x}] samples={=u32} skipped={=u32} bus_errors={=u32} invalid={=u32} timeouts={=u32} implausible={=u32} missed={=u32} wrong_id={=u32} stalled={=u32} reinits={=u32} integrated={=u32} sign_changes={=u32} refined_integrated={=u32}",
        p[0],
        p[1],
        p[2],
        p[0].to_bits(),
        p[1].to_bits(),
        p[2].to_bits(),
        f[0],
        f[1],
        f[2],
        f[0].to_bits(),
        f[1].to_bits(),
        f[2].to_bits(),
        c.samples,
        c.skipped,
        c.bus_errors,
        c.invalid,
        c.timeouts,
        c.implausible,
        c.missed,
        c.wrong_id,
        c.stalled,
        c.reinits,
        ic.integrated,
        ic.sign_changes,
        app.refined_counters().integrated
    );
    let hw = stack::high_water();
    defmt::info!(
        "stack: {=usize} bytes reserved; high-water {=usize} bytes during start-up and init, {=usize} bytes during the sample loop ({=usize} of them below main's frame); identifier state {=usize} bytes (paper) + {=usize} bytes (refined), sample loop state {=usize} bytes",
        stack::size(),
        init_high_water,
        hw,
        hw.saturating_sub(loop_depth),
        core::mem::size_of::<identifier_core::Identifier>(),
        core::mem::size_of::<identifier_core::Refined>(),
        core::mem::size_of_val(&app)
    );
    let latched = app.gyro().interface().bus().stats().samples;
    if latched != header.samples {
        defmt::error!(
            "the log ended after {=u32} of {=u32} samples",
            latched,
            header.samples
        );
        exit(4)
    }
    exit(0)
}

/// The replay file's samples, read in chunks.
struct ReplayReader {
    file: File,
    buf: [u8; CHUNK * replay_format::SAMPLE_LEN],
    len: usize,
    pos: usize,
}

impl ReplayReader {
    fn next(&mut self) -> Option<replay_format::ReplaySample> {
        const L: usize = replay_format::SAMPLE_LEN;
        if self.len - self.pos < L {
            let rest = self.len - self.pos;
            self.buf.copy_within(self.pos..self.len, 0);
            self.len = rest;
            self.pos = 0;
            while self.len < L {
                match self.file.read(&mut self.buf[self.len..]) {
                    Ok(0) | Err(_) => return None,
                    Ok(n) => self.len += n,
                }
            }
        }
        let mut s = [0u8; L];
        s.copy_from_slice(&self.buf[self.pos..self.pos + L]);
        self.pos += L;
        Some(replay_format::decode_sample(&s))
    }
}

/// A sample source with no samples: in replay mode the simulated part only answers the
/// driver's initialisation.
fn no_samples() -> Option<[f32; 3]> {
    None
}

/// The simulated part's bus interface in replay mode.
type ReplayBus = SpiInterface<SimIcm42688<fn() -> Option<[f32; 3]>>>;

/// `--replay`: the log's samples into the sample loop at the log's own rate.
// Not inlined into `main`: the loop is tens of kilobytes, and the two modes' loops in one
// frame would need stack for both.
#[inline(never)]
fn replay(path: &str, uart: &mut Usart1) -> ! {
    let mut name = [0u8; 256];
    let bytes = path.as_bytes();
    if bytes.len() >= name.len() {
        exit(2)
    }
    name[..bytes.len()].copy_from_slice(bytes);
    let Ok(cpath) = CStr::from_bytes_until_nul(&name) else {
        exit(2)
    };
    let Ok(mut file) = File::open(cpath) else {
        defmt::error!("cannot open replay file {=str}", path);
        exit(2)
    };
    let mut h = [0u8; replay_format::HEADER_LEN];
    let mut got = 0;
    while got < h.len() {
        match file.read(&mut h[got..]) {
            Ok(0) | Err(_) => exit(2),
            Ok(n) => got += n,
        }
    }
    let header = match ReplayHeader::decode(&h) {
        Ok(hd) => hd,
        Err(e) => {
            defmt::error!("replay header refused: {}", e);
            exit(2)
        }
    };
    defmt::info!(
        "replay {=str}: {=u32} samples at {=f32} Hz, noise {=f32} rad/s, full scale {=f32} rad/s, accelerometer {=bool}, rotor {}",
        path,
        header.samples,
        header.rate_hz,
        header.noise_std,
        header.full_scale,
        header.with_accel,
        header.rotor
    );
    // The rotor momentum's quantum as `inertia identify` computes it: inertia times the
    // speed's resolution.
    let quantum = header
        .rotor
        .map_or(0.0, |(inertia, _)| inertia * header.rotor_resolution);
    let settings = identifier_core::PipelineSettings::for_rate(header.rate_hz, header.noise_std)
        .with_full_scale(header.full_scale)
        .with_momentum_resolution(quantum)
        .with_averaging_gyro(header.gyro_averaging)
        .with_filtered_gyro(header.gyro_smoothing);
    let rotor = header
        .rotor
        .map(|(inertia, axis)| RotorConfig { inertia, axis });
    let speed = core::cell::Cell::new(None::<f32>);
    let mut delay = NoDelay;
    let sim = SimIcm42688::new(no_samples as fn() -> Option<[f32; 3]>);
    let clock = |_: &ReplayBus| 0u32;
    // Built in one go (rotor input, the log's pipeline settings): the loop is tens of
    // kilobytes, and each move of it by value is a copy on the stack.
    let mut app = match SampleLoop::new_with(
        Icm42688::new_spi(sim),
        &mut delay,
        Config::identifier(),
        clock,
        || speed.get(),
        settings,
        header.with_accel,
        rotor,
    ) {
        Ok(app) => app,
        Err(InitError::PipelineSettings) => {
            defmt::error!("pipeline settings refused");
            exit(3)
        }
        Err(e) => {
            defmt::error!("init failed: {}", e);
            exit(1)
        }
    };
    let loop_depth = stack::depth();
    stack::paint();
    let report_every = {
        let r = header.rate_hz / 10.0;
        if (1.0..1e6).contains(&r) {
            (r + 0.5) as u32
        } else {
            1
        }
    };
    let mut reader = ReplayReader {
        file,
        buf: [0; CHUNK * replay_format::SAMPLE_LEN],
        len: 0,
        pos: 0,
    };
    let mut n = 0u32;
    while n < header.samples {
        let Some(s) = reader.next() else { break };
        n += 1;
        speed.set(rotor.map(|_| s.rotor_rad_s));
        if let Some(r) = app.replay_sample(s.omega, s.accel, s.dt, report_every) {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(uart, &r, None);
        }
        // A free flight ended: its output-error fits run here, between samples, as on the
        // board.
        if app.fits_pending() {
            app.fit_ended_flight();
        }
    }
    // The log has ended: a flight still being fed ends with it and its fits run, as
    // `inertia identify` does at the end of a log, so that no flight is reported without its
    // fits.
    app.end_flight();
    let r = app.report();
    firmware::app::log_report(&r);
    defmt::info!("final replay samples={=u32}", n);
    firmware::app::log_tensor(&r, true);
    send_report(uart, &r, None);
    let hw = stack::high_water();
    defmt::info!(
        "stack: {=usize} bytes reserved; high-water {=usize} bytes during the replay loop ({=usize} of them below main's frame); sample loop state {=usize} bytes (pipeline {=usize})",
        stack::size(),
        hw,
        hw.saturating_sub(loop_depth),
        core::mem::size_of_val(&app),
        core::mem::size_of::<identifier_core::FlightPipeline>()
    );
    if n != header.samples {
        defmt::error!(
            "the replay ended after {=u32} of {=u32} samples",
            n,
            header.samples
        );
        exit(4)
    }
    exit(0)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    exit(101)
}
