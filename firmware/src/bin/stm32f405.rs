//! The firmware on an STM32F405 flight controller with the ICM-42688-P on SPI1 (SCK PA5, MISO
//! PA6, MOSI PA7, CS PA4: the usual F405 layout, e.g. Matek F405 boards), 8 MHz crystal,
//! core at 168 MHz. defmt goes out over RTT; `cargo flash-board` flashes and runs it with
//! probe-rs (see `.cargo/config.toml`). Without a probe: every report also goes out as a
//! `telemetry` frame (postcard + COBS) on USART1 TX (PA9), 921 600 baud 8N1, decoded on the
//! host by `inertia telemetry --input CAPTURE`. The frames are sent blocking from the loop: a
//! frame of about 120 bytes takes 1.3 ms at this rate, 10 times a second, so a sample or two at
//! 1 kHz is late and counted as missed (its time goes to the next step).
//!
//! The last good estimate (tensor `Converged`, new samples since the last save) is saved to
//! flash sectors 10-11 (`firmware::persist`, a sequential-storage map) and restored at boot;
//! every report then carries it as `restored`. Saving blocks the loop (a page erase up to 2 s,
//! with the watchdog stretched meanwhile).
//!
//! The independent watchdog (IWDG, [`WATCHDOG_MS`]) runs from before the gyro's
//! initialisation and is fed once per sample-loop iteration: a loop stuck on the bus, in a
//! re-initialisation or anywhere else resets the board. (QEMU's `netduinoplus2` machine, on
//! which `firmware-qemu` runs, does not model the IWDG; `checks/firmware-faults` exercises a
//! watchdog on a machine that models one.) The sample loop's time base is the core's cycle
//! counter (DWT), extended in software so that it never wraps between two samples.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use defmt_rtt as _;
use embedded_hal_bus::spi::ExclusiveDevice;
use firmware::persist::{EstimateStore, SavePolicy, STM32F405_RANGE};
use firmware::uplink::{persisted, send_report, ByteSink};
use firmware::{stack, Poll, SampleLoop};
use icm42688::{Config, Icm42688};
use panic_probe as _;
use stm32f4xx_hal::{
    flash::{FlashExt, LockedFlash},
    pac,
    prelude::*,
    serial::{config::Config as SerialConfig, Tx},
    spi::{Mode, Phase, Polarity, Spi},
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

    // The sample clock: the cycle counter, accumulated into 64 bits at every read (it wraps
    // every 25 s at 168 MHz; the loop reads it at the ODR), in microseconds.
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let cycles_per_us = u64::from((clocks.sysclk().raw() / 1_000_000).max(1));
    let mut last_cycles = cortex_m::peripheral::DWT::cycle_count();
    let mut cycles: u64 = 0;
    let clock = move |_: &_| {
        let now = cortex_m::peripheral::DWT::cycle_count();
        cycles = cycles.wrapping_add(u64::from(now.wrapping_sub(last_cycles)));
        last_cycles = now;
        // Wrapping at 2^32 us, as the loop expects.
        (cycles / cycles_per_us) as u32
    };

    let config = Config::identifier();
    let gyro = Icm42688::new_spi(device);
    let mut app = match SampleLoop::new(gyro, &mut delay, config, clock) {
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
    let loop_depth = stack::depth();
    let mut reports: u32 = 0;
    loop {
        watchdog.feed();
        if let Poll::Stepped {
            report: Some(r), ..
        } = app.poll(&mut delay)
        {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(&mut telemetry, &r, restored);
            if policy.due(&r) {
                if let Some(s) = &mut store {
                    watchdog.start(WATCHDOG_SAVE_MS.millis());
                    if !s.save(&persisted(&r)) {
                        defmt::warn!("saving the estimate to flash failed");
                    }
                    watchdog.start(WATCHDOG_MS.millis());
                }
            }
            reports = reports.wrapping_add(1);
            if reports.is_multiple_of(100) {
                let hw = stack::high_water();
                defmt::info!(
                    "stack high-water {=usize} bytes; sample loop {=usize} bytes",
                    hw,
                    hw.saturating_sub(loop_depth)
                );
            }
        }
        // A free flight ended: its output-error fits (up to about 0.4 s, the longest when the model
        // does not fit and the fit is repeated from the rotor's spin-up; `bench-mcu` measures each
        // case) run between samples, with the watchdog stretched as for a flash save. The gyro's
        // FIFO overflows meanwhile; the samples lost after a catch are counted as missed.
        if app.fits_pending() {
            watchdog.start(WATCHDOG_SAVE_MS.millis());
            app.fit_ended_flight();
            watchdog.start(WATCHDOG_MS.millis());
        }
        if let Some(r) = app.take_failed_report() {
            firmware::app::log_report(&r);
            firmware::app::log_tensor(&r, false);
            send_report(&mut telemetry, &r, restored);
        }
    }
}
