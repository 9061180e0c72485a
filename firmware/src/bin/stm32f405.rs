//! The firmware on an STM32F405 flight controller with the ICM-42688-P on SPI1 (SCK PA5, MISO
//! PA6, MOSI PA7, CS PA4: the usual F405 layout, e.g. Matek F405 boards), 8 MHz crystal,
//! core at 168 MHz. defmt goes out over RTT; `cargo flash-board` flashes and runs it with
//! probe-rs (see `.cargo/config.toml`). Without a probe: every report also goes out as a
//! `telemetry` frame (postcard + COBS) on USART1 TX (PA9), 921 600 baud 8N1, decoded on the
//! host by `inertia telemetry --input CAPTURE`. The frames are sent blocking from thread mode
//! (about 1.3 ms for a frame of 120 bytes, 10 times a second), which the sample interrupt
//! preempts.
//!
//! The last good estimate (`Converged` or usable, new samples since the last save) is saved to
//! flash sectors 10-11 (`firmware::persist`, a sequential-storage map) and restored at boot;
//! every report then carries it as `restored`. A sector erase (up to 2 s) stalls the core's
//! fetches from flash, the sample interrupt's too: the watchdog is stretched meanwhile, and the
//! samples lost are counted as missed by the sample clock.
//!
//! The sample path runs in TIM2's interrupt at the gyro's output data rate: it reads the
//! sample ([`SampleLoop::read_record`]), pushes it into a ring and steps the loop with what
//! the ring holds ([`firmware::app::Stepper`]); the end-of-flight fits run in thread mode on
//! a copy of the pipeline, so they never stall the sample path (`docs/firmware.md`, "Fits off
//! the sample path"). Thread mode also sends the reports and saves the estimate.
//!
//! The independent watchdog (IWDG, [`WATCHDOG_MS`]) runs from before the gyro's
//! initialisation and is fed by the sample interrupt: a sample path stuck on the bus, in a
//! re-initialisation or anywhere else resets the board. (QEMU's `netduinoplus2` machine, on
//! which `firmware-qemu` runs, does not model the IWDG; `checks/firmware-faults` exercises a
//! watchdog on a machine that models one.) The sample loop's time base is the core's cycle
//! counter (DWT), extended in software so that it never wraps between two samples.
#![no_std]
#![no_main]

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_rt::entry;
use critical_section::Mutex;
use defmt_rtt as _;
use embedded_hal_bus::spi::ExclusiveDevice;
use firmware::app::{read_into_ring, FitJob, RingRead, Stepper};
use firmware::persist::{EstimateStore, SavePolicy, STM32F405_RANGE};
use firmware::uplink::{persisted, send_report, ByteSink};
use firmware::{stack, NoBoardInputs, Report, SampleClock, SampleLoop, SampleRecord};
use heapless::spsc::{Consumer, Producer, Queue};
use icm42688::{Config, Icm42688, SpiInterface};
use identifier_core::FlightPipeline;
use panic_probe as _;
use stm32f4xx_hal::{
    flash::{FlashExt, LockedFlash},
    gpio::{Output, PushPull, PA4},
    interrupt, pac,
    prelude::*,
    serial::{config::Config as SerialConfig, Tx},
    spi::{Mode, Phase, Polarity, Spi},
    timer::{CounterHz, DelayUs, Event, Flag, SysDelay},
    watchdog::IndependentWatchdog,
};

/// Watchdog period while an estimate is saved: a sector erase (once every few hundred saves)
/// takes up to 2 s on the STM32F405 (datasheet, 128 KiB sector, x32 parallelism).
const WATCHDOG_SAVE_MS: u32 = 4000;

/// The on-chip flash for the estimate store (sectors 10 and 11, reserved in `memory.x`):
/// the HAL's blocking flash behind the async traits `sequential-storage` takes (every
/// operation completes before it returns).
struct BoardFlash(LockedFlash);

impl embedded_storage_async::nor_flash::ErrorType for BoardFlash {
    type Error = stm32f4xx_hal::flash::Error;
}

impl embedded_storage_async::nor_flash::ReadNorFlash for BoardFlash {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        embedded_storage::nor_flash::ReadNorFlash::read(&mut self.0, offset, bytes)
    }
    fn capacity(&self) -> usize {
        embedded_storage::nor_flash::ReadNorFlash::capacity(&self.0)
    }
}

impl embedded_storage_async::nor_flash::NorFlash for BoardFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = 128 * 1024;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let mut f = self.0.unlocked();
        embedded_storage::nor_flash::NorFlash::erase(&mut f, from, to)
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let mut f = self.0.unlocked();
        embedded_storage::nor_flash::NorFlash::write(&mut f, offset, bytes)
    }
}

/// Telemetry UART baud rate.
const TELEMETRY_BAUD: u32 = 921_600;

/// USART1's transmitter as the telemetry sink.
struct Telemetry(Option<Tx<pac::USART1>>);

impl ByteSink for Telemetry {
    fn send(&mut self, bytes: &[u8]) {
        if let Some(tx) = &mut self.0 {
            // Blocking; the HAL's error type for a transmitter never occurs on a write.
            let _ =
                stm32f4xx_hal::prelude::_embedded_hal_blocking_serial_Write::bwrite_all(tx, bytes);
        }
    }
}

/// Independent watchdog period, ms: several times the longest legitimate iteration (a
/// re-initialisation of the gyro, up to five resets of about 32 ms each).
const WATCHDOG_MS: u32 = 500;

/// SPI mode 3, 10 MHz (the part allows 24 MHz; 10 MHz leaves margin for board wiring).
const SPI_MODE: Mode = Mode {
    polarity: Polarity::IdleHigh,
    phase: Phase::CaptureOnSecondTransition,
};

/// The gyro's bus as the driver sees it.
type Bus = SpiInterface<ExclusiveDevice<Spi<pac::SPI1>, PA4<Output<PushPull>>, DelayUs<pac::TIM5>>>;

/// The sample loop on this board.
type BoardLoop = SampleLoop<Bus, DwtClock, NoBoardInputs>;

/// The sample clock: the core's cycle counter, accumulated into 64 bits at every read (it
/// wraps every 25 s at 168 MHz; the loop reads it at the ODR), in microseconds wrapping at
/// 2^32, as the loop expects.
struct DwtClock {
    last: u32,
    cycles: u64,
    per_us: u64,
}

impl SampleClock<Bus> for DwtClock {
    fn now_us(&mut self, _: &Bus) -> u32 {
        let now = cortex_m::peripheral::DWT::cycle_count();
        self.cycles = self
            .cycles
            .wrapping_add(u64::from(now.wrapping_sub(self.last)));
        self.last = now;
        (self.cycles / self.per_us) as u32
    }
}

/// Continuous mode's re-fit period, samples fed (0: none; this board gates throws by its
/// accelerometer). A satellite's board builds its loop with `with_accel = false` and sets it.
const REFIT_EVERY: u32 = 0;
/// The ring between reading and stepping (both in the sample interrupt; samples wait in it
/// only while a fit they could start runs).
const RING: usize = 64;
/// Reports waiting for thread mode.
const REPORTS: usize = 8;

/// Samples that found the ring full.
static DROPPED: AtomicU32 = AtomicU32::new(0);
/// Samples read.
static READ: AtomicU32 = AtomicU32::new(0);
/// The watchdog, fed by the sample interrupt, stretched by thread mode around a flash save.
static WATCHDOG: Mutex<RefCell<Option<IndependentWatchdog>>> = Mutex::new(RefCell::new(None));

/// The sample interrupt's state, handed to it once.
struct SampleCtx {
    lp: &'static mut BoardLoop,
    delay: SysDelay,
    timer: CounterHz<pac::TIM2>,
    stepper: Stepper<'static>,
    ring_in: Producer<'static, SampleRecord>,
    ring_out: Consumer<'static, SampleRecord>,
    jobs: Producer<'static, FitJob<'static>>,
    done: Consumer<'static, FitJob<'static>>,
    reports: Producer<'static, Report>,
}

static SAMPLE: Mutex<RefCell<Option<SampleCtx>>> = Mutex::new(RefCell::new(None));

/// The sample path, at the gyro's output data rate: reads a sample into the ring, steps the
/// loop with the ring's samples, hands fit jobs to thread mode and adopts their results.
#[interrupt]
fn TIM2() {
    static mut C: Option<SampleCtx> = None;
    if C.is_none() {
        *C = critical_section::with(|cs| SAMPLE.borrow_ref_mut(cs).take());
    }
    let Some(c) = C else { return };
    c.timer.clear_flags(Flag::Update);
    critical_section::with(|cs| {
        if let Some(w) = WATCHDOG.borrow_ref_mut(cs).as_mut() {
            w.feed();
        }
    });
    match read_into_ring(c.lp, &mut c.delay, &mut c.ring_in, &mut c.reports) {
        RingRead::Queued(_) => {
            READ.fetch_add(1, Ordering::Relaxed);
        }
        RingRead::Dropped => {
            READ.fetch_add(1, Ordering::Relaxed);
            DROPPED.fetch_add(1, Ordering::Relaxed);
        }
        RingRead::Nothing => {}
    }
    let now = READ.load(Ordering::Relaxed);
    c.stepper.run(
        c.lp,
        &mut c.ring_out,
        &mut c.jobs,
        &mut c.done,
        &mut c.reports,
        now,
    );
}

/// The watchdog's period set to `ms`.
fn watchdog_period(ms: u32) {
    critical_section::with(|cs| {
        if let Some(w) = WATCHDOG.borrow_ref_mut(cs).as_mut() {
            w.start(ms.millis());
        }
    });
}

/// A `'static` reference to `x`.
///
/// # Safety
/// `x` is a local of a function that never returns, and that function does not use it again
/// except through the reference returned.
unsafe fn forever<T>(x: &mut T) -> &'static mut T {
    // SAFETY: the caller's frame outlives the program (see above); no other reference is used.
    unsafe { &mut *(x as *mut T) }
}

/// The sample loop, built. Not inlined: the construction's temporaries (a pipeline of tens
/// of kilobytes among them) live in this frame, gone once it returns, not in `main`'s for
/// good.
#[inline(never)]
fn build_loop(
    gyro: Icm42688<Bus>,
    delay: &mut SysDelay,
    config: Config,
    clock: DwtClock,
) -> Result<BoardLoop, firmware::InitError<<Bus as icm42688::RegisterInterface>::Error>> {
    SampleLoop::new(gyro, delay, config, clock)
}

#[entry]
fn main() -> ! {
    stack::paint();
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        defmt::panic!("peripherals taken twice");
    };
    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.start(WATCHDOG_MS.millis());
    let rcc = dp.RCC.constrain();
    let clocks = rcc
        .cfgr
        .use_hse(8.MHz())
        .sysclk(168.MHz())
        .pclk2(84.MHz())
        .freeze();
    let gpioa = dp.GPIOA.split();
    let sck = gpioa.pa5.into_alternate();
    let miso = gpioa.pa6.into_alternate();
    let mosi = gpioa.pa7.into_alternate();
    let cs = gpioa
        .pa4
        .into_push_pull_output_in_state(stm32f4xx_hal::gpio::PinState::High);
    let spi = Spi::new(dp.SPI1, (sck, miso, mosi), SPI_MODE, 10.MHz(), &clocks);
    // Telemetry on USART1 TX = PA9 (no RX). A configuration the clocks cannot give leaves the
    // board without telemetry, not without its loop.
    let tx = dp
        .USART1
        .tx(
            gpioa.pa9.into_alternate(),
            SerialConfig::default().baudrate(TELEMETRY_BAUD.bps()),
            &clocks,
        )
        .ok();
    if tx.is_none() {
        defmt::warn!("USART1 refused {=u32} baud: no telemetry", TELEMETRY_BAUD);
    }
    let mut telemetry = Telemetry(tx);
    // The last good estimate of an earlier boot, sent with every report.
    let mut store = EstimateStore::new(BoardFlash(LockedFlash::new(dp.FLASH)), STM32F405_RANGE);
    let restored = store.as_mut().and_then(|s| s.restore());
    if let Some(e) = &restored {
        defmt::info!(
            "restored from flash: estimate of {=u32} samples, tensor {}",
            e.samples,
            e.tensor.map(|t| t.status_name())
        );
    }
    let mut policy = SavePolicy::new();
    let mut delay = cp.SYST.delay(&clocks);
    let timer_delay = dp.TIM5.delay_us(&clocks);
    // Setting a GPIO output cannot fail on this HAL (the error type is uninhabited).
    let Ok(device) = ExclusiveDevice::new(spi, cs, timer_delay);

    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let clock = DwtClock {
        last: cortex_m::peripheral::DWT::cycle_count(),
        cycles: 0,
        per_us: u64::from((clocks.sysclk().raw() / 1_000_000).max(1)),
    };

    let config = Config::identifier();
    let gyro = Icm42688::new_spi(device);
    // Matched by reference, not moved out of the `Result`: a move would be a second copy of
    // the loop (tens of kilobytes) in this frame.
    let mut built = build_loop(gyro, &mut delay, config, clock);
    let app: &mut BoardLoop = match &mut built {
        Ok(app) => app,
        Err(e) => {
            // A board can come up before the gyro is ready, or a connector is loose: report,
            // and let the watchdog start again from reset (the system reset after the wait
            // is a fallback).
            defmt::error!(
                "gyro init failed: {}; the watchdog resets the board",
                defmt::Debug2Format(&e)
            );
            delay.delay_ms(1000);
            cortex_m::peripheral::SCB::sys_reset();
        }
    };
    defmt::info!("ICM-42688-P up: {} at {}", config.full_scale, config.odr);
    // The fit slot: the fits' own copy of the pipeline.
    let mut slot: FlightPipeline = *app.pipeline();
    let loop_depth = stack::depth();
    let (Some(ring), Some(jobs), Some(done), Some(reports)) = (
        cortex_m::singleton!(: Queue<SampleRecord, RING> = Queue::new()),
        cortex_m::singleton!(: Queue<FitJob<'static>, 2> = Queue::new()),
        cortex_m::singleton!(: Queue<FitJob<'static>, 2> = Queue::new()),
        cortex_m::singleton!(: Queue<Report, REPORTS> = Queue::new()),
    ) else {
        defmt::panic!("queues made twice");
    };
    let (ring_in, ring_out) = ring.split();
    let (jobs_in, mut jobs_out) = jobs.split();
    let (mut done_in, done_out) = done.split();
    let (reports_in, mut reports_out) = reports.split();
    let mut timer = dp.TIM2.counter_hz(&clocks);
    if timer.start((config.odr.hz() as u32).Hz()).is_err() {
        defmt::panic!("TIM2 cannot run at the ODR");
    }
    timer.listen(Event::Update);
    // SAFETY: `app` and `slot` live in this function's frame, and it never returns; from here
    // on it reaches them only through the sample interrupt.
    let (lp, slot) = unsafe { (forever(app), forever(&mut slot)) };
    critical_section::with(|cs| {
        *WATCHDOG.borrow_ref_mut(cs) = Some(watchdog);
        *SAMPLE.borrow_ref_mut(cs) = Some(SampleCtx {
            lp,
            delay,
            timer,
            stepper: Stepper::new(slot, REFIT_EVERY, 1),
            ring_in,
            ring_out,
            jobs: jobs_in,
            done: done_out,
            reports: reports_in,
        });
    });
    // SAFETY: the sample interrupt's state is in place; its priority is the only one set.
    unsafe {
        cp.NVIC.set_priority(pac::Interrupt::TIM2, 0x40);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIM2);
    }

    // Thread mode: the fits (up to about 0.4 s; `scripts/firmware-paced.sh` measures them
    // under QEMU), the reports, the flash saves.
    let mut reports_sent: u32 = 0;
    loop {
        if let Some(mut job) = jobs_out.dequeue() {
            job.run(|| READ.load(Ordering::Relaxed));
            defmt::info!(
                "fit {} ran off the sample path: latency {=u32} samples, {=u32} samples lost so far",
                job.kind,
                job.latency(),
                DROPPED.load(Ordering::Relaxed)
            );
            if done_in.enqueue(job).is_err() {
                defmt::error!("fit job queue full");
            }
            continue;
        }
        if let Some(r) = reports_out.dequeue() {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(&mut telemetry, &r, restored);
            if policy.due(&r) {
                if let Some(s) = &mut store {
                    watchdog_period(WATCHDOG_SAVE_MS);
                    if !s.save(&persisted(&r)) {
                        defmt::warn!("saving the estimate to flash failed");
                    }
                    watchdog_period(WATCHDOG_MS);
                }
            }
            reports_sent = reports_sent.wrapping_add(1);
            if reports_sent.is_multiple_of(100) {
                let hw = stack::high_water();
                defmt::info!(
                    "stack high-water {=usize} bytes; sample loop {=usize} bytes; samples lost to a full ring {=u32}",
                    hw,
                    hw.saturating_sub(loop_depth),
                    DROPPED.load(Ordering::Relaxed)
                );
            }
            continue;
        }
        // Sleep until an interrupt, checked with interrupts masked so that none is missed
        // between the checks above and the sleep (WFI wakes on a pending interrupt).
        critical_section::with(|_| {
            if !jobs_out.ready() && !reports_out.ready() {
                cortex_m::asm::wfi();
            }
        });
    }
}
