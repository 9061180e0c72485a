//! The inertia-ratio identifier in one Embassy task on an STM32F405 flight controller.
//!
//! Hardware: the ICM-42688-P on SPI1 (SCK PA5, MISO PA6, MOSI PA7, CS PA4), 8 MHz crystal,
//! core at 168 MHz; defmt over RTT. `cargo run --release` in this directory flashes it with
//! probe-rs.
//!
//! One task, 1 kHz: the gyro runs at a 1 kHz output data rate; a [`Ticker`] wakes the task at
//! the same rate, the task reads the sample through the `icm42688` driver when data-ready is
//! set and gives it to one step of [`identifier_core::Refined`] (the estimator to use on a real,
//! noisy gyro). Every 100 ms the estimate goes out over defmt.
//!
//! `dt` comes from the time between two samples read, rounded to whole sample periods: a
//! sample missed (the ticker late, a bus error) lengthens the next step instead of shrinking
//! the time base. The flight firmware (`firmware::SampleLoop` in this repository) adds further
//! defences: a plausibility gate, re-initialisation of the sensor, a watchdog.
#![no_std]
#![no_main]

use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_time::{Delay, Duration, Instant, Ticker};
use embedded_hal_bus::spi::ExclusiveDevice;
use icm42688::{Config, Icm42688, SpiInterface};
use identifier_core::{Refined, RefinedSettings};
use panic_probe as _;

/// The gyro behind its SPI device (exclusive bus, CS on PA4).
type Gyro = Icm42688<
    SpiInterface<
        ExclusiveDevice<Spi<'static, Blocking, spi::mode::Master>, Output<'static>, Delay>,
    >,
>;

/// Samples between two reports (10 Hz at 1 kHz).
const REPORT_EVERY: u32 = 100;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(clock_config());

    let mut spi_config = spi::Config::default();
    spi_config.mode = spi::MODE_3;
    spi_config.frequency = Hertz(10_000_000);
    let spi = Spi::new_blocking(p.SPI1, p.PA5, p.PA7, p.PA6, spi_config);
    let cs = Output::new(p.PA4, Level::High, Speed::VeryHigh);
    // Setting a GPIO output cannot fail on this HAL (the error type is uninhabited).
    let Ok(device) = ExclusiveDevice::new(spi, cs, Delay);

    let config = Config::identifier();
    let mut gyro = Icm42688::new_spi(device);
    if let Err(e) = gyro.init(&mut Delay, config) {
        defmt::panic!("ICM-42688-P init failed: {}", defmt::Debug2Format(&e));
    }
    defmt::info!("ICM-42688-P up: {} at {}", config.full_scale, config.odr);

    // Refined's settings for this gyro: noise per sample at 1 kHz (2.8 mdps/sqrt(Hz) over a
    // 500 Hz bandwidth, about 1.1 mrad/s) and the gyro's clip level as full scale, so that a
    // clipped reading is rejected instead of integrated.
    let mut settings = RefinedSettings::new();
    settings.noise_std = 1.1e-3;
    settings.full_scale = icm42688::raw_to_rad_s(32767, config.full_scale);
    let Some(refined) = Refined::new(settings) else {
        defmt::panic!("invalid RefinedSettings");
    };

    match sample_loop(gyro, refined) {
        Ok(task) => spawner.spawn(task),
        Err(_) => defmt::panic!("sample loop already running"),
    }
}

/// The sample loop: one gyro sample, one step of the identifier, at the gyro's 1 kHz.
#[embassy_executor::task]
async fn sample_loop(mut gyro: Gyro, mut refined: Refined) {
    let period_us = gyro.odr().period_us().max(1);
    let period_s = gyro.odr().period_s();
    let mut ticker = Ticker::every(Duration::from_micros(u64::from(period_us)));
    let mut last = Instant::now();
    let (mut samples, mut errors) = (0u32, 0u32);
    loop {
        ticker.next().await;
        // Read only a new sample: the part's clock and the MCU's drift apart slowly, so now and
        // then a tick finds no new data.
        match gyro.data_ready() {
            Ok(true) => {}
            Ok(false) => continue,
            Err(_) => {
                errors = errors.wrapping_add(1);
                continue;
            }
        }
        let raw = match gyro.read_gyro_raw() {
            Ok(raw) => raw,
            Err(_) => {
                errors = errors.wrapping_add(1);
                continue;
            }
        };
        let now = Instant::now();
        let elapsed_us = now.duration_since(last).as_micros();
        last = now;
        let periods = ((elapsed_us + u64::from(period_us) / 2) / u64::from(period_us)).max(1);
        let dt = periods as f32 * period_s;

        let omega = icm42688::raw3_to_rad_s(raw, gyro.full_scale());
        let step = refined.step(omega, dt);
        samples = samples.wrapping_add(1);
        if samples % REPORT_EVERY == 0 {
            defmt::info!(
                "t={=u64}ms a={} {} status={} ratios={} errors={=u32}",
                now.as_millis(),
                refined.estimate(),
                step.convergence,
                step.status,
                step.ratios(),
                errors
            );
        }
    }
}

/// 168 MHz from the 8 MHz crystal: PLL 8 / 4 * 168 / 2; APB1 42 MHz, APB2 84 MHz (SPI1).
fn clock_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv,
        PllSource, Sysclk,
    };
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    config.rcc.pll_src = PllSource::HSE;
    config.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV4;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.sys = Sysclk::PLL1_P;
    config
}
