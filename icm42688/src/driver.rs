//! The driver: reset, identity check, configuration, data-ready polling, sample and FIFO reads
//! (accelerometer and gyro of one sample together), saturation flags.

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use embedded_hal::spi::SpiDevice;

use crate::config::{
    clipped3, raw3_to_m_s2, raw3_to_rad_s, AccelFullScale, Config, GyroFullScale, GyroOdr,
};
use crate::interface::{I2cAddress, I2cInterface, RegisterInterface, SpiInterface};
use crate::registers as reg;

/// Everything that can go wrong talking to the part. No driver path panics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The bus reported an error.
    Bus(E),
    /// `WHO_AM_I` read this instead of 0x47: wrong part, wrong chip select, or a dead bus
    /// (0x00 / 0xFF).
    WrongId(u8),
    /// The part did not report what was waited for (reset done, data ready) in time.
    Timeout,
    /// A configuration register read back differently from what was written.
    ConfigMismatch {
        /// Register address.
        register: u8,
        /// Value written.
        expected: u8,
        /// Value read back.
        found: u8,
    },
    /// The part marked a sample invalid (-32768 on an axis: sensor off or still starting).
    InvalidSample,
    /// A FIFO packet header this driver did not configure (the FIFO is then flushed).
    FifoCorrupt(u8),
}

/// Which axes of a sample are at the clip level (`+-32767`): the true value may lie beyond the
/// range. Reported beside the sample, never as an error: a clipped reading is a real reading of
/// a fast motion (and identical clipped readings are not stalled data).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Saturation {
    /// Accelerometer X, Y, Z at the clip level.
    pub accel: [bool; 3],
    /// Gyro X, Y, Z at the clip level.
    pub gyro: [bool; 3],
}

impl Saturation {
    /// Any gyro axis clipped.
    pub fn gyro_any(&self) -> bool {
        self.gyro.iter().any(|&c| c)
    }

    /// Any accelerometer axis clipped.
    pub fn accel_any(&self) -> bool {
        self.accel.iter().any(|&c| c)
    }

    /// Any axis of either sensor clipped.
    pub fn any(&self) -> bool {
        self.gyro_any() || self.accel_any()
    }
}

/// One sample of both sensors in raw counts, sensor axes, as read in one burst or one FIFO
/// packet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RawImu {
    /// Accelerometer X, Y, Z.
    pub accel: [i16; 3],
    /// Gyro X, Y, Z.
    pub gyro: [i16; 3],
}

impl RawImu {
    /// Decodes 12 big-endian bytes: accel X Y Z then gyro X Y Z. [`Error::InvalidSample`] when
    /// an axis carries the part's invalid marker (-32768).
    fn decode<E>(b: &[u8; 12]) -> Result<Self, Error<E>> {
        let v = |i: usize| {
            let hi = b.get(2 * i).copied().unwrap_or(0);
            let lo = b.get(2 * i + 1).copied().unwrap_or(0);
            i16::from_be_bytes([hi, lo])
        };
        let s = RawImu {
            accel: [v(0), v(1), v(2)],
            gyro: [v(3), v(4), v(5)],
        };
        if s.accel.contains(&reg::INVALID_SAMPLE) || s.gyro.contains(&reg::INVALID_SAMPLE) {
            return Err(Error::InvalidSample);
        }
        Ok(s)
    }

    /// Which axes are at the clip level.
    pub fn saturation(&self) -> Saturation {
        Saturation {
            accel: clipped3(self.accel),
            gyro: clipped3(self.gyro),
        }
    }

    /// Converted at the given ranges.
    pub fn convert(&self, gyro_fs: GyroFullScale, accel_fs: AccelFullScale) -> Imu {
        Imu {
            accel: raw3_to_m_s2(self.accel, accel_fs),
            gyro: raw3_to_rad_s(self.gyro, gyro_fs),
            saturated: self.saturation(),
        }
    }
}

/// One sample of both sensors in SI units, with its saturation flags.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Imu {
    /// Specific force, m/s^2, sensor axes (zero in free fall).
    pub accel: [f32; 3],
    /// Angular rate, rad/s, sensor axes.
    pub gyro: [f32; 3],
    /// Axes at the clip level.
    pub saturated: Saturation,
}

/// Bounded waits, in microseconds of `DelayNs`.
const RESET_DELAY_US: u32 = 1_000;
const RESET_POLL_US: u32 = 100;
const RESET_POLLS: u32 = 20;
/// No register write for 200 us after turning the gyro on (datasheet, `PWR_MGMT0`).
const POWER_ON_QUIET_US: u32 = 200;
/// Gyro start-up time from off to low-noise mode (datasheet, table 1: 30 ms typical).
const GYRO_STARTUP_US: u32 = 30_000;

/// An ICM-42688-P on `IF` (see [`SpiInterface`], [`I2cInterface`]).
#[derive(Debug)]
pub struct Icm42688<IF> {
    iface: IF,
    config: Config,
}

impl<SPI: SpiDevice> Icm42688<SpiInterface<SPI>> {
    /// A driver on an SPI device. Nothing is sent until [`Icm42688::init`].
    pub const fn new_spi(spi: SPI) -> Self {
        Icm42688::new(SpiInterface::new(spi))
    }
}

impl<I2C: I2c> Icm42688<I2cInterface<I2C>> {
    /// A driver on an I2C bus. Nothing is sent until [`Icm42688::init`].
    pub const fn new_i2c(i2c: I2C, address: I2cAddress) -> Self {
        Icm42688::new(I2cInterface::new(i2c, address))
    }
}

impl<IF> Icm42688<IF> {
    /// A driver on any [`RegisterInterface`].
    pub const fn new(iface: IF) -> Self {
        Icm42688 {
            iface,
            config: Config::identifier(),
        }
    }

    /// The bus interface (for a simulated device: its state).
    pub fn interface(&self) -> &IF {
        &self.iface
    }

    /// The bus interface, mutably.
    pub fn interface_mut(&mut self) -> &mut IF {
        &mut self.iface
    }

    /// Gives the interface back.
    pub fn release(self) -> IF {
        self.iface
    }

    /// The configuration last applied by [`Icm42688::init`] (or the default before).
    pub fn config(&self) -> Config {
        self.config
    }

    /// Full scale in force, which the conversion to rad/s uses.
    pub fn full_scale(&self) -> GyroFullScale {
        self.config.full_scale
    }

    /// Accelerometer range in force, which the conversion to m/s^2 uses.
    pub fn accel_full_scale(&self) -> AccelFullScale {
        self.config.accel_full_scale
    }

    /// Output data rate in force.
    pub fn odr(&self) -> GyroOdr {
        self.config.odr
    }
}

impl<IF: RegisterInterface> Icm42688<IF> {
    fn write(&mut self, register: u8, value: u8) -> Result<(), Error<IF::Error>> {
        self.iface
            .write_register(register, value)
            .map_err(Error::Bus)
    }

    fn read(&mut self, register: u8) -> Result<u8, Error<IF::Error>> {
        let mut b = [0u8; 1];
        self.iface
            .read_registers(register, &mut b)
            .map_err(Error::Bus)?;
        Ok(b[0])
    }

    fn write_checked(&mut self, register: u8, value: u8) -> Result<(), Error<IF::Error>> {
        self.write(register, value)?;
        let found = self.read(register)?;
        if found == value {
            Ok(())
        } else {
            Err(Error::ConfigMismatch {
                register,
                expected: value,
                found,
            })
        }
    }

    /// Selects user bank `bank` (0..=4). Every register this driver uses is in bank 0;
    /// [`Icm42688::init`] selects it because an MCU reset does not reset the part.
    pub fn select_bank(&mut self, bank: u8) -> Result<(), Error<IF::Error>> {
        self.write(reg::REG_BANK_SEL, bank & 0b111)
    }

    /// Reads `WHO_AM_I`.
    pub fn who_am_i(&mut self) -> Result<u8, Error<IF::Error>> {
        self.read(reg::WHO_AM_I)
    }

    /// Soft reset through `DEVICE_CONFIG`, then waits for `RESET_DONE_INT`. All registers
    /// (bank selection included) return to their reset values; the gyro is off afterwards.
    pub fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), Error<IF::Error>> {
        self.select_bank(0)?;
        self.write(reg::DEVICE_CONFIG, reg::DEVICE_CONFIG_SOFT_RESET)?;
        delay.delay_us(RESET_DELAY_US);
        for _ in 0..RESET_POLLS {
            if self.read(reg::INT_STATUS)? & reg::INT_STATUS_RESET_DONE != 0 {
                return Ok(());
            }
            delay.delay_us(RESET_POLL_US);
        }
        Err(Error::Timeout)
    }

    /// Resets the part, checks its identity and configures it: on SPI the I2C interface off
    /// (`INTF_CONFIG0`), gyro full scale and ODR (`GYRO_CONFIG0`), accelerometer full scale
    /// and the same ODR (`ACCEL_CONFIG0`), optionally data-ready on INT1, gyro and
    /// accelerometer in low-noise mode (`PWR_MGMT0`). Configuration registers are read back and compared.
    /// Returns once the gyro's start-up time has passed.
    pub fn init(
        &mut self,
        delay: &mut impl DelayNs,
        config: Config,
    ) -> Result<(), Error<IF::Error>> {
        self.reset(delay)?;
        let id = self.who_am_i()?;
        if id != reg::WHO_AM_I_VALUE {
            return Err(Error::WrongId(id));
        }
        if IF::IS_SPI {
            self.write_checked(reg::INTF_CONFIG0, reg::INTF_CONFIG0_SPI_ONLY)?;
        }
        if config.data_ready_int1 {
            self.write_checked(reg::INT_CONFIG, reg::INT_CONFIG_INT1_ACTIVE_HIGH_PUSH_PULL)?;
            let c1 = self.read(reg::INT_CONFIG1)?;
            self.write_checked(reg::INT_CONFIG1, c1 & !reg::INT_CONFIG1_ASYNC_RESET)?;
            self.write_checked(reg::INT_SOURCE0, reg::INT_SOURCE0_DRDY_INT1)?;
        }
        self.write_checked(reg::GYRO_CONFIG0, config.gyro_config0())?;
        self.write_checked(reg::ACCEL_CONFIG0, config.accel_config0())?;
        let power = reg::PWR_MGMT0_GYRO_LN | reg::PWR_MGMT0_ACCEL_LN;
        self.write(reg::PWR_MGMT0, power)?;
        delay.delay_us(POWER_ON_QUIET_US);
        let found = self.read(reg::PWR_MGMT0)?;
        if found != power {
            return Err(Error::ConfigMismatch {
                register: reg::PWR_MGMT0,
                expected: power,
                found,
            });
        }
        delay.delay_us(GYRO_STARTUP_US);
        self.config = config;
        Ok(())
    }

    /// Reads (and thereby clears) `INT_STATUS`; true when `DATA_RDY_INT` was set.
    pub fn data_ready(&mut self) -> Result<bool, Error<IF::Error>> {
        Ok(self.read(reg::INT_STATUS)? & reg::INT_STATUS_DATA_RDY != 0)
    }

    /// Polls [`Icm42688::data_ready`] every `poll_us` until it is set, at most `max_polls`
    /// times; [`Error::Timeout`] otherwise.
    pub fn wait_data_ready(
        &mut self,
        delay: &mut impl DelayNs,
        poll_us: u32,
        max_polls: u32,
    ) -> Result<(), Error<IF::Error>> {
        for _ in 0..max_polls {
            if self.data_ready()? {
                return Ok(());
            }
            delay.delay_us(poll_us);
        }
        Err(Error::Timeout)
    }

    /// One burst read of the six gyro data registers: raw counts X, Y, Z.
    pub fn read_gyro_raw(&mut self) -> Result<[i16; 3], Error<IF::Error>> {
        let mut b = [0u8; 6];
        self.iface
            .read_registers(reg::GYRO_DATA_X1, &mut b)
            .map_err(Error::Bus)?;
        let raw = [
            i16::from_be_bytes([b[0], b[1]]),
            i16::from_be_bytes([b[2], b[3]]),
            i16::from_be_bytes([b[4], b[5]]),
        ];
        if raw.contains(&reg::INVALID_SAMPLE) {
            return Err(Error::InvalidSample);
        }
        Ok(raw)
    }

    /// The latest sample in rad/s, sensor axes (see [`crate::raw_to_rad_s`]).
    pub fn read_gyro(&mut self) -> Result<[f32; 3], Error<IF::Error>> {
        let raw = self.read_gyro_raw()?;
        Ok(raw3_to_rad_s(raw, self.config.full_scale))
    }

    /// One 12-byte burst read of `ACCEL_DATA_X1..GYRO_DATA_Z0`: accelerometer and gyro of the
    /// same sample, raw counts. [`Error::InvalidSample`] when an axis reads -32768 (a sensor
    /// off or starting); clipped axes are flagged by [`RawImu::saturation`], not refused.
    pub fn read_imu_raw(&mut self) -> Result<RawImu, Error<IF::Error>> {
        let mut b = [0u8; reg::IMU_BURST_LEN];
        self.iface
            .read_registers(reg::ACCEL_DATA_X1, &mut b)
            .map_err(Error::Bus)?;
        RawImu::decode(&b)
    }

    /// The latest sample of both sensors in SI units with its saturation flags.
    pub fn read_imu(&mut self) -> Result<Imu, Error<IF::Error>> {
        let raw = self.read_imu_raw()?;
        Ok(raw.convert(self.config.full_scale, self.config.accel_full_scale))
    }

    /// Puts accelerometer, gyro and temperature samples (16-byte "packet 3" with a
    /// timestamp) into the FIFO in stream-to-FIFO mode, and flushes it. For loops that cannot
    /// keep up with every data-ready: read batches with [`Icm42688::read_fifo_raw`].
    pub fn enable_fifo(&mut self) -> Result<(), Error<IF::Error>> {
        self.write_checked(reg::FIFO_CONFIG1, reg::FIFO_CONFIG1_ACCEL_GYRO_TEMP)?;
        self.write_checked(reg::FIFO_CONFIG, reg::FIFO_CONFIG_STREAM)?;
        self.flush_fifo()
    }

    /// Back to bypass mode (FIFO off).
    pub fn disable_fifo(&mut self) -> Result<(), Error<IF::Error>> {
        self.write_checked(reg::FIFO_CONFIG, reg::FIFO_CONFIG_BYPASS)
    }

    /// Empties the FIFO (`SIGNAL_PATH_RESET.FIFO_FLUSH`).
    pub fn flush_fifo(&mut self) -> Result<(), Error<IF::Error>> {
        self.write(reg::SIGNAL_PATH_RESET, reg::SIGNAL_PATH_RESET_FIFO_FLUSH)
    }

    /// Bytes in the FIFO (`FIFO_COUNTH:FIFO_COUNTL`, big-endian).
    pub fn fifo_count(&mut self) -> Result<u16, Error<IF::Error>> {
        let mut b = [0u8; 2];
        self.iface
            .read_registers(reg::FIFO_COUNTH, &mut b)
            .map_err(Error::Bus)?;
        Ok(u16::from_be_bytes(b))
    }

    /// Pops up to `out.len()` 16-byte packets (header, accel, gyro, temperature, timestamp)
    /// from the FIFO into `out` (raw counts) and returns how many. A header that is not a
    /// 16-bit accel + gyro packet flushes the FIFO and gives [`Error::FifoCorrupt`]; an invalid
    /// sample gives [`Error::InvalidSample`] after the packets before it were stored.
    pub fn read_fifo_raw(&mut self, out: &mut [RawImu]) -> Result<usize, Error<IF::Error>> {
        let available = usize::from(self.fifo_count()?) / reg::FIFO_PACKET3_LEN;
        let mut n = 0;
        for slot in out.iter_mut().take(available) {
            let mut p = [0u8; reg::FIFO_PACKET3_LEN];
            self.iface
                .read_registers(reg::FIFO_DATA, &mut p)
                .map_err(Error::Bus)?;
            let header = p[0];
            if header & reg::FIFO_HEADER_EMPTY != 0 {
                break;
            }
            let wanted = reg::FIFO_HEADER_GYRO | reg::FIFO_HEADER_ACCEL;
            if header & wanted != wanted || header & reg::FIFO_HEADER_20BIT != 0 {
                self.flush_fifo()?;
                return Err(Error::FifoCorrupt(header));
            }
            let mut data = [0u8; 12];
            for (d, b) in data.iter_mut().zip(p.iter().skip(1)) {
                *d = *b;
            }
            *slot = RawImu::decode(&data)?;
            n += 1;
        }
        Ok(n)
    }
}
