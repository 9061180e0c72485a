//! The inertia-ratio identifier in one RTIC task on an STM32F405 flight controller.
//!
//! Hardware: the ICM-42688-P on SPI1 (SCK PA5, MISO PA6, MOSI PA7, CS PA4), 8 MHz crystal,
//! core at 168 MHz; defmt over RTT. `cargo run --release` in this directory flashes it with
//! probe-rs.
//!
//! One software task, 1 kHz: the gyro runs at a 1 kHz output data rate; the task wakes every
//! period on the SysTick monotonic, reads the sample through the `icm42688` driver when
//! data-ready is set and gives it to one step of [`identifier_core::Refined`] (the estimator to
//! use on a real, noisy gyro). Every 100 ms the estimate goes out over defmt.
//!
//! `dt` comes from the monotonic's time between two samples read, in whole sample periods: a
//! missed sample lengthens the next step instead of shrinking the time base. The flight
//! firmware (`firmware::SampleLoop` in this repository) adds further defences: a plausibility
//! gate, re-initialisation of the sensor, a watchdog.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [USART1])]
mod app {
    use embedded_hal_bus::spi::ExclusiveDevice;
    use icm42688::{Config, Icm42688, SpiInterface};
    use identifier_core::{Refined, RefinedSettings};
    use rtic_monotonics::systick::prelude::{systick_monotonic, Timebase};
    use stm32f4xx_hal::{
        gpio::{Output, PinState, PA4},
        pac,
        prelude::*,
        spi::{Mode, Phase, Polarity, Spi},
        timer::Delay,
    };

    // SysTick at 1 kHz: one tick per gyro sample period.
    systick_monotonic!(Mono, 1_000);

    /// The gyro behind its SPI device (exclusive bus, CS on PA4).
    type Gyro = Icm42688<
        SpiInterface<ExclusiveDevice<Spi<pac::SPI1>, PA4<Output>, Delay<pac::TIM5, 1_000_000>>>,
    >;

    /// Samples between two reports (10 Hz at 1 kHz).
    const REPORT_EVERY: u32 = 100;

    /// SPI mode 3, the ICM-42688-P's.
    const SPI_MODE: Mode = Mode {
        polarity: Polarity::IdleHigh,
        phase: Phase::CaptureOnSecondTransition,
    };

    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        gyro: Gyro,
        refined: Refined,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let dp = cx.device;
        let rcc = dp.RCC.constrain();
        let clocks = rcc
            .cfgr
            .use_hse(8.MHz())
            .sysclk(168.MHz())
            .pclk2(84.MHz())
            .freeze();
        Mono::start(cx.core.SYST, clocks.sysclk().raw());

        let gpioa = dp.GPIOA.split();
        let sck = gpioa.pa5.into_alternate();
        let miso = gpioa.pa6.into_alternate();
        let mosi = gpioa.pa7.into_alternate();
        let cs = gpioa.pa4.into_push_pull_output_in_state(PinState::High);
        let spi = Spi::new(dp.SPI1, (sck, miso, mosi), SPI_MODE, 10.MHz(), &clocks);
        // Setting a GPIO output cannot fail on this HAL (the error type is uninhabited).
        let Ok(device) = ExclusiveDevice::new(spi, cs, dp.TIM5.delay_us(&clocks));

        let config = Config::identifier();
        let mut gyro = Icm42688::new_spi(device);
        let mut delay = dp.TIM2.delay_us(&clocks);
        if let Err(e) = gyro.init(&mut delay, config) {
            defmt::panic!("ICM-42688-P init failed: {}", defmt::Debug2Format(&e));
        }
        defmt::info!("ICM-42688-P up: {} at {}", config.full_scale, config.odr);

        // Refined's settings for this gyro: noise per sample at 1 kHz (2.8 mdps/sqrt(Hz) over
        // a 500 Hz bandwidth, about 1.1 mrad/s) and the gyro's clip level as full scale, so
        // that a clipped reading is rejected instead of integrated.
        let mut settings = RefinedSettings::new();
        settings.noise_std = 1.1e-3;
        settings.full_scale = icm42688::raw_to_rad_s(32767, config.full_scale);
        let Some(refined) = Refined::new(settings) else {
            defmt::panic!("invalid RefinedSettings");
        };

        if sample_loop::spawn().is_err() {
            defmt::panic!("sample loop already running");
        }
        (Shared {}, Local { gyro, refined })
    }

    /// The sample loop: one gyro sample, one step of the identifier, at the gyro's 1 kHz.
    #[task(local = [gyro, refined], priority = 1)]
    async fn sample_loop(cx: sample_loop::Context) {
        let sample_loop::LocalResources { gyro, refined, .. } = cx.local;
        let period_s = gyro.odr().period_s();
        let mut next = Mono::now();
        let mut last = next;
        let (mut samples, mut errors) = (0u32, 0u32);
        loop {
            // One tick is one millisecond, one sample period.
            next += <Mono as Timebase>::Duration::from_ticks(1);
            Mono::delay_until(next).await;
            // Read only a new sample: the part's clock and the MCU's drift apart slowly, so
            // now and then a tick finds no new data.
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
            let now = Mono::now();
            // One tick is one sample period.
            let periods = (now - last).as_millis().max(1);
            last = now;
            let dt = periods as f32 * period_s;

            let omega = icm42688::raw3_to_rad_s(raw, gyro.full_scale());
            let step = refined.step(omega, dt);
            samples = samples.wrapping_add(1);
            if samples % REPORT_EVERY == 0 {
                defmt::info!(
                    "t={=u32}ms a={} {} status={} ratios={} errors={=u32}",
                    now.duration_since_epoch().as_millis(),
                    refined.estimate(),
                    step.convergence,
                    step.status,
                    step.ratios(),
                    errors
                );
            }
        }
    }
}
