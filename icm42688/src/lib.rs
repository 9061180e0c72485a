//! Driver for the TDK InvenSense ICM-42688-P 6-axis IMU (gyro and accelerometer), generic over
//! embedded-hal 1.0 ([`embedded_hal::spi::SpiDevice`] or [`embedded_hal::i2c::I2c`]).
//!
//! Why this part: it is the gyro on most current flight-controller boards (and a direct
//! successor of the MPU-6000 on older ones), it has low noise (2.8 mdps/sqrt(Hz)) and an
//! output data rate up to 32 kHz, and its register interface is simple enough to check
//! against the datasheet (DS-000347) register by register.
//!
//! What the driver does, all from the datasheet:
//! * [`Icm42688::reset`]: `DEVICE_CONFIG.SOFT_RESET_CONFIG`, 1 ms, then `INT_STATUS.RESET_DONE`;
//! * identity: `WHO_AM_I` = 0x47, anything else is [`Error::WrongId`];
//! * [`Icm42688::init`]: bank 0, `GYRO_CONFIG0` full scale (+-15.625 to +-2000 dps, default
//!   +-2000 dps) and ODR, `ACCEL_CONFIG0` range (default +-16 g), data-ready on INT1,
//!   `PWR_MGMT0` gyro and accelerometer in low-noise mode, read-back of what was written,
//!   start-up wait;
//! * samples: poll `INT_STATUS.DATA_RDY` ([`Icm42688::wait_data_ready`]) and burst-read both
//!   sensors, `ACCEL_DATA_X1..GYRO_DATA_Z0` in 12 bytes ([`Icm42688::read_imu`]), or the gyro
//!   alone ([`Icm42688::read_gyro`]), or batch through the FIFO's 16-byte packets
//!   ([`Icm42688::enable_fifo`], [`Icm42688::read_fifo_raw`]);
//! * saturation: every axis at the clip level is flagged ([`Saturation`]) beside the sample;
//! * [`raw_to_rad_s`] and [`raw3_to_m_s2`]: the one conversion from counts to SI units.
//!
//! Every failure is a value of [`Error`]: bus errors, a wrong identity, timeouts of the
//! bounded waits, read-back mismatches, samples the part marks invalid. Nothing panics.
//!
//! With the `sim` feature, [`sim::SimIcm42688`] is a simulated part: an `SpiDevice` that
//! answers this driver's register accesses with samples from any [`sim::SampleSource`]. The
//! firmware uses it under QEMU and the host uses it for the reference run, so both go through
//! the same encoding and the same driver code.
#![no_std]
#![deny(missing_docs)]
#![deny(
    clippy::panic,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

pub mod config;
mod driver;
pub mod interface;
pub mod registers;
#[cfg(feature = "sim")]
pub mod sim;

pub use config::{
    clipped3, is_clipped, raw3_to_m_s2, raw3_to_rad_s, raw_to_rad_s, AccelFullScale, Config,
    GyroFullScale, GyroOdr, STANDARD_GRAVITY,
};
pub use driver::{Error, Icm42688, Imu, RawImu, Saturation};
pub use interface::{I2cAddress, I2cInterface, RegisterInterface, SpiInterface};
