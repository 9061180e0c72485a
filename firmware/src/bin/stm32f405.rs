//! The firmware on an STM32F405 flight controller with the ICM-42688-P on SPI1 (SCK PA5, MISO
//! PA6, MOSI PA7, CS PA4: the usual F405 layout, e.g. Matek F405 boards), 8 MHz crystal,
//! core at 168 MHz. defmt goes out over RTT; `cargo flash-board` flashes and runs it with
//! probe-rs (see `.cargo/config.toml`).
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
};

/// SPI mode 3, 10 MHz (the part allows 24 MHz; 10 MHz leaves margin for board wiring).
const SPI_MODE: Mode = Mode {
    polarity: Polarity::IdleHigh,
    phase: Phase::CaptureOnSecondTransition,
};

#[entry]
fn main() -> ! {
    stack::paint();
    let (Some(dp), Some(cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        defmt::panic!("peripherals taken twice");
    };
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

    let config = Config::identifier();
    let gyro = Icm42688::new_spi(device);
    let mut app = match SampleLoop::new(gyro, &mut delay, config) {
        Ok(app) => app,
        Err(e) => {
            // A board can come up before the gyro is ready, or a connector is loose: report,
            // wait a second and start again from reset.
            defmt::error!(
                "gyro init failed: {}; resetting in 1 s",
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
    }
}
