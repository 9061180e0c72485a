//! The firmware on an STM32F405 flight controller with the ICM-42688-P on SPI1 (SCK PA5, MISO
//! PA6, MOSI PA7, CS PA4: the usual F405 layout, e.g. Matek F405 boards), 8 MHz crystal,
//! core at 168 MHz. defmt goes out over RTT; `cargo flash-board` flashes and runs it with
//! probe-rs (see `.cargo/config.toml`).
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
use firmware::{stack, Poll, SampleLoop};
use icm42688::{Config, Icm42688};
use panic_probe as _;
use stm32f4xx_hal::{
    pac,
    prelude::*,
    spi::{Mode, Phase, Polarity, Spi},
    watchdog::IndependentWatchdog,
};

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
        if let Some(r) = app.take_failed_report() {
            firmware::app::log_report(&r);
        }
    }
}
