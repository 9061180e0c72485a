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
//! carry the log's `f32` values unchanged). An orbit log's replay (format version 6 with its
//! time, attitude and position) runs `inertia identify`'s passes with the gravity-gradient
//! torque folded in, one after another, and reports the one `identify` reports ([`replay`]).
//! Exit codes: 0 log replayed, 1 gyro init failed, 2 log unreadable, 3 bad arguments,
//! 4 log shorter than its header says (truncated file or a read error).
//!
//! Every report also goes out as a `telemetry` frame on USART1 (QEMU: `-serial file:...`).
#![no_std]
#![no_main]

use core::cell::RefCell;
use core::ffi::CStr;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m_rt::{entry, exception};
use critical_section::Mutex;
use defmt_semihosting as _;
use firmware::app::{read_into_ring, FitJob, FitKind, FitScheduler, RingRead, Stepper};
use firmware::log_format::{decode_sample, Header, HEADER_LEN, SAMPLE_LEN};
use firmware::replay_format::{self, OrbitSample, ReplayHeader};
use firmware::uplink::{send_report, ByteSink};
use firmware::{
    stack, InitError, NoBoardInputs, NoDelay, Report, SampleLoop, SampleRecord, TensorReport,
};
use heapless::spsc::{Consumer, Producer, Queue};
use icm42688::sim::{SampleSource, SimIcm42688};
use icm42688::{Config, GyroOdr, Icm42688, SpiInterface};
use identifier_core::gravity::{self, GravityFold};
use identifier_core::{FlightPipeline, Rotors};
use semihosting::fs::File;
use semihosting::io::Read;

/// Samples read per semihosting call.
const CHUNK: usize = 64;
/// The replay reader's buffer, bytes: whole samples read per semihosting call (16 of a
/// thrown flight controller's 36 bytes, 9 of an orbit log's 112 with 8 wheels).
const REPLAY_BUF: usize = 1024;

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
            defmt::error!("usage: firmware-qemu --replay <replay file> [--refit-every N]");
            exit(3)
        };
        let (mut refit_every, mut lossless) = (RefitEvery::Samples(0), false);
        while let Some(a) = it.next() {
            match (a, &mut it) {
                (Ok("--lossless"), _) => lossless = true,
                (Ok("--refit-every"), it) => match it.next().map(|n| n.map(str::parse::<u32>)) {
                    Some(Ok(Ok(n))) => refit_every = RefitEvery::Samples(n),
                    _ => exit(3),
                },
                (Ok("--refit-every-s"), it) => match it.next().map(|n| n.map(str::parse::<f32>)) {
                    Some(Ok(Ok(s))) if s > 0.0 => refit_every = RefitEvery::Seconds(s),
                    _ => exit(3),
                },
                _ => {
                    defmt::error!(
                        "usage: firmware-qemu --replay <replay file> [--refit-every N | --refit-every-s S] [--lossless]"
                    );
                    exit(3)
                }
            }
        }
        replay(file, refit_every, lossless, &mut uart)
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

/// The simulated part's bus in the log mode.
type LogBus = SpiInterface<SimIcm42688<LogSource>>;

/// The sample loop in the log mode.
type LogLoop = SampleLoop<LogBus, fn(&LogBus) -> u32, NoBoardInputs>;

/// The gyro's sample period in the log mode, us.
static PERIOD_US: AtomicU32 = AtomicU32::new(1000);

/// The log mode's clock. The simulated part models no time: the loop's clock is its count of
/// latched samples (one per data-ready poll) times the period, so a sample lost on the bus
/// lengthens the next step.
fn log_clock(i: &LogBus) -> u32 {
    i.bus()
        .stats()
        .samples
        .wrapping_mul(PERIOD_US.load(Ordering::Relaxed))
}

/// The log mode's sample interrupt state (the board's structure: read, ring and step in one
/// interrupt), handed to SysTick once and handed back at the end.
struct LogCtx {
    lp: &'static mut LogLoop,
    stepper: Stepper<'static>,
    ring_in: Producer<'static, SampleRecord>,
    ring_out: Consumer<'static, SampleRecord>,
    jobs: Producer<'static, FitJob<'static>>,
    done: Consumer<'static, FitJob<'static>>,
    reports: Producer<'static, Report>,
}

static LOG: Mutex<RefCell<Option<LogCtx>>> = Mutex::new(RefCell::new(None));
static LOG_BACK: Mutex<RefCell<Option<LogCtx>>> = Mutex::new(RefCell::new(None));

/// One sample period of the log mode, in SysTick's interrupt, as the board's TIM2 does it:
/// read a sample through the driver and the simulated part into the ring, step the loop with
/// the ring's samples, hand fit jobs to thread mode. True once the log is exhausted and every
/// sample was stepped (a timeout alone is not the end: with injected bus errors a wait can
/// fail before it times out).
fn log_tick(c: &mut LogCtx) -> bool {
    let exhausted = c.lp.gyro().interface().bus().exhausted();
    if !exhausted {
        match read_into_ring(c.lp, &mut NoDelay, &mut c.ring_in, &mut c.reports) {
            RingRead::Queued(n) => {
                DELIVERED.fetch_add(1, Ordering::Relaxed);
                let n = n as u32;
                if n > PEAK.load(Ordering::Relaxed) {
                    PEAK.store(n, Ordering::Relaxed);
                }
            }
            RingRead::Dropped => {
                DELIVERED.fetch_add(1, Ordering::Relaxed);
                DROPPED.fetch_add(1, Ordering::Relaxed);
            }
            RingRead::Nothing => {}
        }
    }
    let now = DELIVERED.load(Ordering::Relaxed);
    c.stepper.run(
        c.lp,
        &mut c.ring_out,
        &mut c.jobs,
        &mut c.done,
        &mut c.reports,
        now,
    );
    if exhausted && c.ring_out.is_empty() && !c.stepper.job_out() {
        // SAFETY: SysTick's control register; only this handler and start-up touch it.
        unsafe { (*cortex_m::peripheral::SYST::PTR).csr.write(0) };
        return true;
    }
    false
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
    PERIOD_US.store(config.odr.period_us(), Ordering::Relaxed);
    let clock = log_clock as fn(&LogBus) -> u32;
    // Matched by reference, not moved out of the `Result`: a move would be a second copy of
    // the loop in this frame.
    let mut built = build_log_loop(sim, config, clock);
    let app = match &mut built {
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

    // The sample path in SysTick's interrupt at the ODR, the fits in thread mode on a copy of
    // the pipeline (the board's structure, `firmware-stm32f405`).
    let lp: &'static mut LogLoop = run_paced_log(app, config.odr.hz(), uart);
    let app = lp;

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
        core::mem::size_of_val(&*app)
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
    buf: [u8; REPLAY_BUF],
    len: usize,
    pos: usize,
    /// Bytes of one sample.
    sample_len: usize,
    /// Rotors per sample.
    rotors: usize,
    /// Each sample carries its orbit (time, attitude, position).
    orbit: bool,
}

impl ReplayReader {
    /// A reader of `file`'s samples, its header and rotor table read.
    fn new(file: File, header: &ReplayHeader) -> Self {
        ReplayReader {
            file,
            buf: [0; REPLAY_BUF],
            len: 0,
            pos: 0,
            sample_len: header.sample_len(),
            rotors: header.rotors as usize,
            orbit: header.orbit,
        }
    }

    /// The next sample and its orbit (zero without one).
    fn next(&mut self) -> Option<(replay_format::ReplaySample, OrbitSample)> {
        let l = self.sample_len;
        if self.len - self.pos < l {
            let rest = self.len - self.pos;
            self.buf.copy_within(self.pos..self.len, 0);
            self.len = rest;
            self.pos = 0;
            // Whole samples only, so that a chunk never ends inside one.
            let want = (self.buf.len() / l) * l;
            while self.len < l {
                match self.file.read(&mut self.buf[self.len..want]) {
                    Ok(0) | Err(_) => return None,
                    Ok(n) => self.len += n,
                }
            }
        }
        let b = &self.buf[self.pos..self.pos + l];
        let s = replay_format::decode_sample(b, self.rotors);
        let o = if self.orbit {
            replay_format::decode_orbit(b, self.rotors)
        } else {
            OrbitSample::default()
        };
        self.pos += l;
        Some((s, o))
    }
}

/// A sample source with no samples: in replay mode the simulated part only answers the
/// driver's initialisation.
fn no_samples() -> Option<[f32; 3]> {
    None
}

/// The simulated part's bus interface in replay mode.
type ReplayBus = SpiInterface<SimIcm42688<fn() -> Option<[f32; 3]>>>;

/// The sample loop in replay mode.
type ReplayLoop = SampleLoop<ReplayBus, fn(&ReplayBus) -> u32, NoBoardInputs>;

/// The replay mode's clock: unused (the replay gives each sample's dt).
fn no_clock(_: &ReplayBus) -> u32 {
    0
}

/// The ring between the sample interrupt and the stepper: 63 samples (about 8 ms at 8 kHz; at
/// 10 Hz, 6 s, longer than any fit waits).
const RING: usize = 64;
/// Reports waiting for thread mode (which sends them between fits).
const REPORTS: usize = 8;

/// Samples the sample interrupt read from the log and offered to the ring.
static DELIVERED: AtomicU32 = AtomicU32::new(0);
/// Samples that found the ring full (their time goes to the next sample's dt).
static DROPPED: AtomicU32 = AtomicU32::new(0);
/// Ticks on which a sample waited for room in the ring (`--lossless`).
static WAITS: AtomicU32 = AtomicU32::new(0);
/// The ring's largest occupancy seen right after a push.
static PEAK: AtomicU32 = AtomicU32::new(0);
/// The log has ended (or could not be read further): no more samples come.
static ENDED: AtomicBool = AtomicBool::new(false);

/// The sample interrupt's state, handed to it once.
struct Sampler {
    reader: ReplayReader,
    ring: Producer<'static, SampleRecord>,
    left: u32,
    /// Time of dropped samples, carried into the next one's dt.
    carry: f32,
    /// Wait instead of dropping (`--lossless`).
    lossless: bool,
    /// A sample that waits for room in the ring (lossless).
    waiting: Option<SampleRecord>,
    /// SysTick ticks since the last sample.
    tick: u32,
    /// The gravity-gradient torque's momentum (G2) at this pass's tensor, added to each
    /// sample's (an orbit log's passes after the first, [`replay`]).
    fold: Option<GravityFold>,
}

/// The stepper's state, handed to `PendSV` once and handed back at the end.
struct StepCtx {
    lp: &'static mut ReplayLoop,
    stepper: Stepper<'static>,
    ring: Consumer<'static, SampleRecord>,
    jobs: Producer<'static, FitJob<'static>>,
    done: Consumer<'static, FitJob<'static>>,
    reports: Producer<'static, Report>,
}

static SAMPLER: Mutex<RefCell<Option<&'static mut Sampler>>> = Mutex::new(RefCell::new(None));
static STEP: Mutex<RefCell<Option<StepCtx>>> = Mutex::new(RefCell::new(None));
/// The stepper's state once the log has ended and every sample was stepped.
static BACK: Mutex<RefCell<Option<StepCtx>>> = Mutex::new(RefCell::new(None));

/// The sample path, at the higher interrupt priority: the sensor's data-ready on a board;
/// here SysTick at the log's rate (deterministic under QEMU's `-icount`). Reads one sample
/// (through semihosting, which takes no virtual time; a board's SPI burst takes a few
/// microseconds), pushes it into the ring, and pends the stepper.
#[exception]
fn SysTick() {
    static mut S: Option<&'static mut Sampler> = None;
    static mut L: Option<LogCtx> = None;
    if S.is_none() && L.is_none() {
        critical_section::with(|cs| {
            *S = SAMPLER.borrow_ref_mut(cs).take();
            *L = LOG.borrow_ref_mut(cs).take();
        });
    }
    if let Some(l) = L.as_mut() {
        if log_tick(l) {
            let back = L.take();
            critical_section::with(|cs| *LOG_BACK.borrow_ref_mut(cs) = back);
        }
        return;
    }
    let Some(s) = S.as_deref_mut() else { return };
    s.tick += 1;
    if s.tick < TICKS_PER_SAMPLE.load(Ordering::Relaxed) {
        return;
    }
    s.tick = 0;
    if let Some(w) = s.waiting.take() {
        if let Err(w) = s.ring.enqueue(w) {
            s.waiting = Some(w);
            WAITS.fetch_add(1, Ordering::Relaxed);
            cortex_m::peripheral::SCB::set_pendsv();
            return;
        }
    }
    let sample = if s.left > 0 { s.reader.next() } else { None };
    let Some((x, o)) = sample else {
        if s.waiting.is_some() {
            return;
        }
        // The log has ended: no more ticks, and this pass's sampler is let go (a next pass
        // hands a new one through `SAMPLER`).
        // SAFETY: SysTick's control register; only this handler and start-up touch it.
        unsafe { (*cortex_m::peripheral::SYST::PTR).csr.write(0) };
        *S = None;
        ENDED.store(true, Ordering::Release);
        cortex_m::peripheral::SCB::set_pendsv();
        return;
    };
    s.left -= 1;
    // (G2) at this pass's tensor, from the log's own time, attitude and position: the
    // function `inertia identify` calls, on every sample in order (a sample lost to a full
    // ring keeps its share of the impulse).
    let external_momentum = s.fold.as_mut().map(|f| f.step(o.t, o.attitude, o.position));
    let rec = SampleRecord {
        omega: x.omega,
        accel: x.accel,
        dt: x.dt + s.carry,
        pipeline_dt: x.dt + s.carry,
        speeds: x.speeds,
        speeds_known: true,
        actuated: x.actuated,
        read_at_us: None,
        external_momentum,
    };
    DELIVERED.fetch_add(1, Ordering::Relaxed);
    match s.ring.enqueue(rec) {
        Ok(()) => {
            s.carry = 0.0;
            let n = s.ring.len() as u32;
            if n > PEAK.load(Ordering::Relaxed) {
                PEAK.store(n, Ordering::Relaxed);
            }
        }
        Err(w) if s.lossless => {
            s.waiting = Some(w);
            WAITS.fetch_add(1, Ordering::Relaxed);
        }
        Err(lost) => {
            s.carry = lost.dt;
            DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }
    cortex_m::peripheral::SCB::set_pendsv();
}

/// The stepper, below the sample path and above thread mode: steps what waits in the ring,
/// hands fit jobs to thread mode and adopts their results. Hands its state back once the log
/// has ended and every sample was stepped.
#[exception]
fn PendSV() {
    static mut C: Option<StepCtx> = None;
    if C.is_none() {
        *C = critical_section::with(|cs| STEP.borrow_ref_mut(cs).take());
    }
    let Some(c) = C else { return };
    let now = DELIVERED.load(Ordering::Relaxed);
    c.stepper.run(
        c.lp,
        &mut c.ring,
        &mut c.jobs,
        &mut c.done,
        &mut c.reports,
        now,
    );
    if ENDED.load(Ordering::Acquire) && c.ring.is_empty() && !c.stepper.job_out() {
        let back = C.take();
        critical_section::with(|cs| *BACK.borrow_ref_mut(cs) = back);
    }
}

/// A `'static` reference to `x`.
///
/// # Safety
/// `x` outlives every use of the reference returned: it is a local of a function that never
/// returns, or every copy of the reference is gone before its frame ends (handed back by the
/// interrupts and dropped). Meanwhile `x` is not used except through the reference returned.
unsafe fn forever<T>(x: &mut T) -> &'static mut T {
    // SAFETY: see above; no other reference is used while this one lives.
    unsafe { &mut *(x as *mut T) }
}

/// The sample ring, the fit jobs' two queues and the reports' queue, once (one set for
/// whichever mode runs).
#[allow(clippy::type_complexity)]
fn queues() -> Option<(
    &'static mut Queue<SampleRecord, RING>,
    &'static mut Queue<FitJob<'static>, 2>,
    &'static mut Queue<FitJob<'static>, 2>,
    &'static mut Queue<Report, REPORTS>,
)> {
    Some((
        cortex_m::singleton!(: Queue<SampleRecord, RING> = Queue::new())?,
        cortex_m::singleton!(: Queue<FitJob<'static>, 2> = Queue::new())?,
        cortex_m::singleton!(: Queue<FitJob<'static>, 2> = Queue::new())?,
        cortex_m::singleton!(: Queue<Report, REPORTS> = Queue::new())?,
    ))
}

/// The log mode's sample loop paced by SysTick at `rate_hz`: the fit slot, the queues, the
/// interrupt, and thread mode's fits and reports until the log is exhausted; returns the loop.
/// A function of its own: its frame (the slot) is on the stack only while it runs.
#[inline(never)]
fn run_paced_log(app: &mut LogLoop, rate_hz: f32, uart: &mut Usart1) -> &'static mut LogLoop {
    let mut slot: FlightPipeline = *app.pipeline();
    let Some((ring, jobs, done, reports)) = queues() else {
        exit(3)
    };
    let (ring_in, ring_out) = ring.split();
    let (jobs_in, mut jobs_out) = jobs.split();
    let (mut done_in, done_out) = done.split();
    let (reports_in, mut reports_out) = reports.split();
    // SAFETY: `app` lives in `run_log`'s frame and `slot` in this one; neither function
    // returns before the interrupt has handed its state back (`LOG_BACK`), and `run_log` never
    // returns at all; meanwhile they are reached only through the interrupt.
    let (lp, slot) = unsafe { (forever(app), forever(&mut slot)) };
    critical_section::with(|cs| {
        *LOG.borrow_ref_mut(cs) = Some(LogCtx {
            lp,
            stepper: Stepper::new(slot, 0, 1),
            ring_in,
            ring_out,
            jobs: jobs_in,
            done: done_out,
            reports: reports_in,
        });
    });
    start_sample_timer(rate_hz);
    let back = loop {
        if let Some(mut job) = jobs_out.dequeue() {
            job.run(|| DELIVERED.load(Ordering::Relaxed));
            if done_in.enqueue(job).is_err() {
                defmt::error!("fit job queue full");
            }
            continue;
        }
        if let Some(r) = reports_out.dequeue() {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(uart, &r, None);
            continue;
        }
        if let Some(back) = critical_section::with(|cs| LOG_BACK.borrow_ref_mut(cs).take()) {
            break back;
        }
        // Sleep until an interrupt, checked with interrupts masked (see `paced`).
        critical_section::with(|cs| {
            if !jobs_out.ready() && !reports_out.ready() && LOG_BACK.borrow_ref(cs).is_none() {
                cortex_m::asm::wfi();
            }
        });
    };
    while let Some(r) = reports_out.dequeue() {
        firmware::app::log_report(&r);
        firmware::app::log_tensor(&r, false);
        send_report(uart, &r, None);
    }
    let st = back.stepper.stats;
    defmt::info!(
        "paced rate={=f32} Hz delivered={=u32} stepped={=u32} dropped={=u32} ring_peak={=u32} ring_capacity={=u32} holds={=u32} fit_jobs={=u32} adopted={=u32} inline_fits={=u32} reports_dropped={=u32}",
        rate_hz,
        DELIVERED.load(Ordering::Relaxed),
        st.stepped,
        DROPPED.load(Ordering::Relaxed),
        PEAK.load(Ordering::Relaxed),
        (RING - 1) as u32,
        st.holds,
        st.jobs,
        st.adopted,
        st.inline_fits,
        st.reports_dropped
    );
    back.lp
}

/// The log mode's loop, built. Not inlined: the construction's temporaries (a pipeline of
/// tens of kilobytes among them) live in this frame, gone once it returns, not in
/// [`run_log`]'s for good.
#[inline(never)]
fn build_log_loop(
    sim: SimIcm42688<LogSource>,
    config: Config,
    clock: fn(&LogBus) -> u32,
) -> Result<LogLoop, InitError<<LogBus as icm42688::RegisterInterface>::Error>> {
    SampleLoop::new_with(
        Icm42688::new_spi(sim),
        &mut NoDelay,
        config,
        clock,
        NoBoardInputs,
        firmware::pipeline_settings(&config),
        true,
        Rotors::NONE,
    )
}

/// Continuous mode's re-fit period as given on the command line.
#[derive(Clone, Copy)]
enum RefitEvery {
    /// Samples fed (`--refit-every N`; 0: none).
    Samples(u32),
    /// Seconds of samples fed at the log's rate (`--refit-every-s S`).
    Seconds(f32),
}

/// The replay mode's loop, built in one go with the log's pipeline settings and rotors. Not
/// inlined: the construction's temporaries (a pipeline of tens of kilobytes among them) live
/// in this frame, gone once it returns, not in [`replay`]'s for good.
#[inline(never)]
fn build_replay_loop(
    settings: identifier_core::PipelineSettings,
    with_accel: bool,
    rotors: Rotors,
) -> Result<ReplayLoop, InitError<<ReplayBus as icm42688::RegisterInterface>::Error>> {
    let sim = SimIcm42688::new(no_samples as fn() -> Option<[f32; 3]>);
    SampleLoop::new_with(
        Icm42688::new_spi(sim),
        &mut NoDelay,
        Config::identifier(),
        no_clock as fn(&ReplayBus) -> u32,
        NoBoardInputs,
        settings,
        with_accel,
        rotors,
    )
}

/// Opens the replay file `cpath` and reads its header and rotor table (into `table`); `None`
/// when it cannot be opened or read, or its header is refused.
fn open_replay(
    cpath: &CStr,
    table: &mut [u8; replay_format::ROTOR_LEN * identifier_core::MAX_ROTORS],
) -> Option<(File, ReplayHeader)> {
    let mut file = File::open(cpath).ok()?;
    let mut h = [0u8; replay_format::HEADER_LEN];
    if !read_exact(&mut file, &mut h) {
        return None;
    }
    let header = match ReplayHeader::decode(&h) {
        Ok(hd) => hd,
        Err(e) => {
            defmt::error!("replay header refused: {}", e);
            return None;
        }
    };
    if !read_exact(&mut file, &mut table[..header.table_len()]) {
        return None;
    }
    Some((file, header))
}

/// The stepper's queue ends and the loop, handed to `PendSV` for a pass and back after it.
struct StepParts {
    lp: &'static mut ReplayLoop,
    ring: Consumer<'static, SampleRecord>,
    jobs: Producer<'static, FitJob<'static>>,
    done: Consumer<'static, FitJob<'static>>,
    reports: Producer<'static, Report>,
}

/// Thread mode's queue ends: fit jobs in, fitted jobs out, reports to send.
struct ThreadEnds {
    jobs: Consumer<'static, FitJob<'static>>,
    done: Producer<'static, FitJob<'static>>,
    reports: Consumer<'static, Report>,
}

/// How a pass over the replay ended.
#[derive(Clone, Copy)]
struct PassEnd {
    /// The loop's report once the log ended and its last flight was fitted.
    report: Report,
    /// The pipeline's tensor's standard deviations (with `report.tensor.tensor`).
    tensor_std: Option<[[f32; 3]; 3]>,
    /// The pipeline's residual over the gyro noise.
    residual_ratio: f32,
    /// Samples stepped.
    stepped: u32,
}

/// `--replay`: the log's samples into the sample loop at the log's own rate, delivered by the
/// SysTick interrupt into a ring, stepped by PendSV, the fits in thread mode on a copy of the
/// pipeline ([`firmware::app::fits`]). `refit_every`: continuous mode's re-fit period in
/// samples fed (0: none). `lossless`: a sample that finds the ring full waits for the next
/// tick instead of being lost (a file can wait, a sensor cannot: for the bit-for-bit checks
/// on logs whose flights follow each other faster than a fit runs).
///
/// An orbit log (header flag, [`OrbitSample`]) is replayed in the passes `inertia identify`
/// makes ((G3) of [`identifier_core::gravity`]): once torque-free, then again from its start
/// (the file read again through semihosting, the loop restarted) with the gravity-gradient
/// torque's momentum at the previous pass's tensor added to each sample's
/// ([`GravityFold`], computed in the sample interrupt), until the tensor has settled or after
/// [`gravity::MAX_PASSES`] such passes; the last one is reported when its residual is smaller
/// than the torque-free pass's ([`gravity::keep_folded`]), else the torque-free one. Each pass
/// is a whole paced replay with its fits off the sample path; they run one after another.
// Not inlined into `main`: the loop is tens of kilobytes, and the two modes' loops in one
// frame would need stack for both.
#[inline(never)]
fn replay(path: &str, refit_every: RefitEvery, lossless: bool, uart: &mut Usart1) -> ! {
    let mut name = [0u8; 256];
    let bytes = path.as_bytes();
    if bytes.len() >= name.len() {
        exit(2)
    }
    name[..bytes.len()].copy_from_slice(bytes);
    let Ok(cpath) = CStr::from_bytes_until_nul(&name) else {
        exit(2)
    };
    let mut table = [0u8; replay_format::ROTOR_LEN * identifier_core::MAX_ROTORS];
    let Some((file, header)) = open_replay(cpath, &mut table) else {
        defmt::error!("cannot read replay file {=str}", path);
        exit(2)
    };
    let n_rotors = header.rotors as usize;
    let mut list = [identifier_core::Rotor::new(0.0, [0.0; 3]); identifier_core::MAX_ROTORS];
    for (i, r) in list.iter_mut().take(n_rotors).enumerate() {
        *r = replay_format::decode_rotor(&table, i);
    }
    let refit_every = match refit_every {
        RefitEvery::Samples(n) => n,
        RefitEvery::Seconds(s) => FitScheduler::samples_for(s, header.rate_hz),
    };
    let rotors = match Rotors::new(&list[..n_rotors]) {
        Ok(r) => r,
        Err(e) => {
            defmt::error!("replay rotors refused: {}", e);
            exit(3)
        }
    };
    defmt::info!(
        "replay {=str}: {=u32} samples at {=f32} Hz, noise {=f32} rad/s, full scale {=f32} rad/s, accelerometer {=bool}, rotors {=u32}, momentum quantum {=f32} kg m^2/s, re-fit every {=u32} samples, orbit {=bool}",
        path,
        header.samples,
        header.rate_hz,
        header.noise_std,
        header.full_scale,
        header.with_accel,
        header.rotors,
        header.momentum_quantum,
        refit_every,
        header.orbit
    );
    for r in list.iter().take(n_rotors) {
        defmt::info!(
            "rotor inertia={=f32} kg m^2 axis=[{=f32}, {=f32}, {=f32}]",
            r.inertia_kg_m2,
            r.axis[0],
            r.axis[1],
            r.axis[2]
        );
    }
    let settings = identifier_core::PipelineSettings::for_rate(header.rate_hz, header.noise_std)
        .with_full_scale(header.full_scale)
        .with_momentum_resolution(header.momentum_quantum)
        .with_averaging_gyro(header.gyro_averaging)
        .with_filtered_gyro(header.gyro_smoothing)
        .with_centred_readings(header.centred);
    // Matched by reference, not moved out of the `Result`: a move would be a second copy of
    // the loop in this frame.
    let mut built = build_replay_loop(settings, header.with_accel, rotors);
    let app: &mut ReplayLoop = match &mut built {
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
    // SAFETY: `built` is a local of this function, which never returns; from here on it is
    // reached only through `lp`.
    let lp = unsafe { forever(app) };
    let Some((ring, jobs, done, reports)) = queues() else {
        exit(3)
    };
    let (ring_p, ring_c) = ring.split();
    let (jobs_p, jobs_c) = jobs.split();
    let (done_p, done_c) = done.split();
    let (reports_p, reports_c) = reports.split();
    let mut sampler = Sampler {
        reader: ReplayReader::new(file, &header),
        ring: ring_p,
        left: header.samples,
        carry: 0.0,
        lossless,
        waiting: None,
        tick: 0,
        fold: None,
    };
    let mut run = Passes {
        parts: Some(StepParts {
            lp,
            ring: ring_c,
            jobs: jobs_p,
            done: done_c,
            reports: reports_p,
        }),
        ends: ThreadEnds {
            jobs: jobs_c,
            done: done_p,
            reports: reports_c,
        },
        sampler: &mut sampler,
        header,
        refit_every,
    };
    let free = pass(&mut run, uart);
    if header.orbit {
        orbit_passes(&mut run, &free, cpath, path, &mut table, uart)
    }
    finish(&free, 1, false, uart)
}

/// What the passes of one replay share: the loop and the queue ends (handed to the interrupts
/// for a pass and back after it), the sample interrupt's state (its file read again for each
/// pass), the header and the re-fit period.
struct Passes<'a> {
    parts: Option<StepParts>,
    ends: ThreadEnds,
    sampler: &'a mut Sampler,
    header: ReplayHeader,
    refit_every: u32,
}

/// The passes with the gravity-gradient torque folded in, at the previous pass's tensor, after
/// the torque-free pass `free`, as `inertia identify` makes them ((G3) of
/// [`identifier_core::gravity`]), then the final report (see [`replay`]). Not inlined: its
/// frame (a pass's end kept) is on the stack only for an orbit log.
#[inline(never)]
fn orbit_passes(
    run: &mut Passes,
    free: &PassEnd,
    cpath: &CStr,
    path: &str,
    table: &mut [u8; replay_format::ROTOR_LEN * identifier_core::MAX_ROTORS],
    uart: &mut Usart1,
) -> ! {
    let header = run.header;
    let mut passes = 1u32;
    let mut last: Option<PassEnd> = None;
    let mut prev = free.report.tensor.tensor;
    for _ in 0..gravity::MAX_PASSES {
        let Some(j) = prev else {
            break;
        };
        let Some((file, again)) = open_replay(cpath, table) else {
            defmt::error!("cannot read replay file {=str} again", path);
            exit(2)
        };
        if (again.samples, again.sample_len()) != (header.samples, header.sample_len()) {
            defmt::error!("the replay file {=str} changed between passes", path);
            exit(2)
        }
        let s = &mut *run.sampler;
        s.reader = ReplayReader::new(file, &header);
        s.left = header.samples;
        s.carry = 0.0;
        s.waiting = None;
        s.tick = 0;
        s.fold = Some(GravityFold::new(j));
        let Some(parts) = run.parts.as_mut() else {
            exit(3)
        };
        // The restart's own stack high-water, painted (its new pipeline is a temporary of
        // tens of kilobytes under the replay's frame with the loop).
        stack::paint();
        let restarted = parts.lp.restart();
        let restart_high_water = stack::high_water();
        if let Err(e) = restarted {
            defmt::error!("restart failed: {}", e);
            exit(1)
        }
        passes += 1;
        defmt::info!(
            "pass {=u32}: the gravity-gradient torque folded in at J=[{=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}] kg m^2; the loop restarted (stack high-water {=usize} of {=usize} bytes)",
            passes,
            j[0][0],
            j[0][1],
            j[0][2],
            j[1][0],
            j[1][1],
            j[1][2],
            j[2][0],
            j[2][1],
            j[2][2],
            restart_high_water,
            stack::size()
        );
        let next = pass(run, uart);
        let moved = gravity::tensor_moved(&j, next.report.tensor.tensor, next.tensor_std);
        defmt::info!(
            "pass {=u32} ended: residual ratio {=f32} (torque-free {=f32}), tensor moved {=f32} of its std",
            passes,
            next.residual_ratio,
            free.residual_ratio,
            moved
        );
        prev = next.report.tensor.tensor;
        last = Some(next);
        if gravity::settled(moved) {
            break;
        }
    }
    match &last {
        Some(l) if gravity::keep_folded(l.residual_ratio, free.residual_ratio) => {
            finish(l, passes, true, uart)
        }
        _ => finish(free, passes, false, uart),
    }
}

/// The replay's final report: `end`'s, the one `inertia identify` reports, after `passes`
/// passes (`folded`: with the gravity gradient folded in).
fn finish(end: &PassEnd, passes: u32, folded: bool, uart: &mut Usart1) -> ! {
    let r = &end.report;
    firmware::app::log_report(r);
    defmt::info!(
        "final replay samples={=u32} passes={=u32} gravity_gradient={=bool}",
        end.stepped,
        passes,
        folded
    );
    firmware::app::log_tensor(r, true);
    send_report(uart, r, None);
    exit(0)
}

/// One paced pass of [`replay`] over the file `run`'s sampler reads: the fit slot, the two
/// interrupts and thread mode's fits until every sample was stepped, then the last flight's
/// fits. A function of its own so that its frame (the slot) and the loop's construction or
/// restart (in [`replay`]'s and [`orbit_passes`]') are not on the stack at the same time.
#[inline(never)]
fn pass(run: &mut Passes, uart: &mut Usart1) -> PassEnd {
    let header = run.header;
    let refit_every = run.refit_every;
    let ends = &mut run.ends;
    let Some(parts) = run.parts.take() else {
        exit(3)
    };
    // SAFETY: the sampler is a local of `replay`, which never returns; the sample interrupt
    // lets this reference go at the end of the pass, before the sampler is used again.
    let sampler: &'static mut Sampler = unsafe { forever(&mut *run.sampler) };
    // The fit slot: the fits' own copy of the pipeline.
    let mut slot: FlightPipeline = *parts.lp.pipeline();
    let loop_depth = stack::depth();
    let report_every = {
        let r = header.rate_hz / 10.0;
        if (1.0..1e6).contains(&r) {
            (r + 0.5) as u32
        } else {
            1
        }
    };
    for c in [&DELIVERED, &DROPPED, &WAITS, &PEAK] {
        c.store(0, Ordering::Relaxed);
    }
    ENDED.store(false, Ordering::Release);
    // SAFETY: `slot` is a local of this function, which returns only once the interrupts have
    // handed back the stepper holding its reference (`BACK`), dropped below with no fit job
    // out; meanwhile it is reached only through the stepper and its jobs.
    let slot = unsafe { forever(&mut slot) };
    let StepParts {
        lp,
        ring,
        jobs,
        done,
        reports,
    } = parts;
    critical_section::with(|cs| {
        *SAMPLER.borrow_ref_mut(cs) = Some(sampler);
        *STEP.borrow_ref_mut(cs) = Some(StepCtx {
            lp,
            stepper: Stepper::new(slot, refit_every, report_every),
            ring,
            jobs,
            done,
            reports,
        });
    });
    stack::paint();
    start_sample_timer(header.rate_hz);

    // Thread mode: the fits, and sending the reports between them.
    let rate = header.rate_hz;
    let mut latest: Option<TensorReport> = None;
    let mut fits = 0u32;
    let mut worst = (0u32, 0u32);
    let back = loop {
        if let Some(mut job) = ends.jobs.dequeue() {
            job.run(|| DELIVERED.load(Ordering::Relaxed));
            let l = job.latency();
            fits += 1;
            let which = if job.kind == FitKind::Refit { 1 } else { 0 };
            if which == 0 {
                worst.0 = worst.0.max(l);
            } else {
                worst.1 = worst.1.max(l);
            }
            defmt::info!(
                "fit {=u32} kind={} started at sample {=u32} latency {=u32} samples {=f32} s fed={=u32}",
                fits,
                job.kind,
                job.started,
                l,
                l as f32 / rate,
                job.report.map_or(0, |t| t.fed)
            );
            if refit_every > 0 {
                latest = job.report;
            }
            if ends.done.enqueue(job).is_err() {
                defmt::error!("fit job queue full");
            }
            cortex_m::peripheral::SCB::set_pendsv();
            continue;
        }
        if let Some(mut r) = ends.reports.dequeue() {
            // Continuous mode reports the latest fit of the window so far.
            if let Some(t) = latest {
                r.tensor = t;
            }
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(uart, &r, None);
            continue;
        }
        if let Some(back) = critical_section::with(|cs| BACK.borrow_ref_mut(cs).take()) {
            break back;
        }
        // Sleep until an interrupt, checked with interrupts masked so that none is missed
        // between the checks above and the sleep (WFI wakes on a pending interrupt).
        critical_section::with(|cs| {
            if !ends.jobs.ready() && !ends.reports.ready() && BACK.borrow_ref(cs).is_none() {
                cortex_m::asm::wfi();
            }
        });
    };
    let StepCtx {
        lp,
        stepper,
        ring,
        jobs,
        done,
        reports,
    } = back;
    // The stepper (the slot's last reference) is not used again.
    let st = stepper.stats;
    while let Some(r) = ends.reports.dequeue() {
        firmware::app::log_report(&r);
        firmware::app::log_tensor(&r, false);
        send_report(uart, &r, None);
    }
    // The log has ended: a flight still being fed ends with it and its fits run (here, in
    // thread mode: no sample comes any more), as `inertia identify` does at the end of a log,
    // so that no flight is reported without its fits.
    lp.end_flight();
    defmt::info!(
        "paced rate={=f32} Hz delivered={=u32} stepped={=u32} dropped={=u32} waits={=u32} ring_peak={=u32} ring_capacity={=u32} holds={=u32} held_for_fit={=u32} fit_jobs={=u32} adopted={=u32} inline_fits={=u32} reports_dropped={=u32} worst_fit_latency={=u32} samples {=f32} s worst_refit_latency={=u32} samples {=f32} s",
        rate,
        DELIVERED.load(Ordering::Relaxed),
        st.stepped,
        DROPPED.load(Ordering::Relaxed),
        WAITS.load(Ordering::Relaxed),
        PEAK.load(Ordering::Relaxed),
        (RING - 1) as u32,
        st.holds,
        st.held_for_fit,
        st.jobs,
        st.adopted,
        st.inline_fits,
        st.reports_dropped,
        worst.0,
        worst.0 as f32 / rate,
        worst.1,
        worst.1 as f32 / rate
    );
    let hw = stack::high_water();
    defmt::info!(
        "stack: {=usize} bytes reserved; high-water {=usize} bytes during the replay ({=usize} of them below the replay's frame); sample loop state {=usize} bytes (pipeline {=usize}), fit slot {=usize} bytes, ring {=usize} bytes",
        stack::size(),
        hw,
        hw.saturating_sub(loop_depth),
        core::mem::size_of::<ReplayLoop>(),
        core::mem::size_of::<FlightPipeline>(),
        core::mem::size_of::<FlightPipeline>(),
        core::mem::size_of::<Queue<SampleRecord, RING>>()
    );
    if DELIVERED.load(Ordering::Relaxed) != header.samples {
        defmt::error!(
            "the replay ended after {=u32} of {=u32} samples",
            DELIVERED.load(Ordering::Relaxed),
            header.samples
        );
        exit(4)
    }
    let end = pass_end(lp, st.stepped);
    run.parts = Some(StepParts {
        lp,
        ring,
        jobs,
        done,
        reports,
    });
    end
}

/// The end of a pass over the replay of `lp` (`stepped` samples): its report and its
/// pipeline's standard deviations and residual. Not inlined: the estimate (a few hundred bytes)
/// is in this frame only while it is taken.
#[inline(never)]
fn pass_end(lp: &ReplayLoop, stepped: u32) -> PassEnd {
    let e = lp.pipeline().estimate();
    PassEnd {
        report: lp.report(),
        tensor_std: e.tensor_std,
        residual_ratio: e.residual_ratio,
        stepped,
    }
}

/// Reads exactly `buf.len()` bytes; false at the end of the file or on an error.
fn read_exact(file: &mut File, buf: &mut [u8]) -> bool {
    let mut got = 0;
    while got < buf.len() {
        match file.read(&mut buf[got..]) {
            Ok(0) | Err(_) => return false,
            Ok(n) => got += n,
        }
    }
    true
}

/// The core's clock, Hz: the STM32F405 at 168 MHz, as QEMU's netduinoplus2 models it (its
/// SysTick reference clock is not modelled, so SysTick runs from the core's clock).
const CPU_HZ: f32 = 168_000_000.0;

/// SysTick ticks per sample (SysTick's 24-bit reload holds at most 0.1 s at 168 MHz: a slower
/// rate takes several ticks a sample).
static TICKS_PER_SAMPLE: AtomicU32 = AtomicU32::new(1);

/// SysTick at a whole multiple of `rate_hz` from the core's clock, its interrupt above
/// PendSV; the sample interrupt takes a sample every [`TICKS_PER_SAMPLE`] ticks.
fn start_sample_timer(rate_hz: f32) {
    let cycles = CPU_HZ / rate_hz;
    if !(64.0..1e12).contains(&cycles) {
        defmt::error!("sample rate {=f32} Hz out of SysTick's range", rate_hz);
        exit(3)
    }
    let k = (cycles / 16_777_216.0) as u32 + 1;
    let reload = (cycles / k as f32 + 0.5) as u32 - 1;
    TICKS_PER_SAMPLE.store(k, Ordering::Relaxed);
    // SAFETY: the system handler priorities and SysTick's registers, set once here before
    // the timer runs; lower numbers preempt higher ones.
    unsafe {
        let scb = &*cortex_m::peripheral::SCB::PTR;
        // SHPR3: PendSV (bits 16-23) 0xC0, SysTick (bits 24-31) 0x40.
        scb.shpr[10].write(0xC0);
        scb.shpr[11].write(0x40);
        let syst = &*cortex_m::peripheral::SYST::PTR;
        syst.rvr.write(reload);
        syst.cvr.write(0);
        // The core's clock (CLKSOURCE = 1), interrupt, enable.
        syst.csr.write(0b111);
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    exit(101)
}
