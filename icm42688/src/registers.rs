//! Register map of the ICM-42688-P (TDK InvenSense datasheet DS-000347, section 13/14):
//! only what this driver uses. Every address here is in user bank 0, except `REG_BANK_SEL`,
//! which is reachable from every bank.

/// SPI: bit 7 of the address byte set means read.
pub const SPI_READ: u8 = 0x80;

/// `DEVICE_CONFIG`: bit 0 `SOFT_RESET_CONFIG`; the part resets its registers and clears the
/// bit itself. Wait 1 ms before the next access.
pub const DEVICE_CONFIG: u8 = 0x11;
/// `SOFT_RESET_CONFIG` bit of `DEVICE_CONFIG`.
pub const DEVICE_CONFIG_SOFT_RESET: u8 = 1 << 0;

/// `INT_CONFIG`: INT1/INT2 pin polarity, drive and mode.
pub const INT_CONFIG: u8 = 0x14;
/// `INT1_POLARITY` (active high) | `INT1_DRIVE_CIRCUIT` (push-pull); `INT1_MODE` 0 = pulsed.
pub const INT_CONFIG_INT1_ACTIVE_HIGH_PUSH_PULL: u8 = 0b0000_0011;

/// `FIFO_CONFIG`: bits 7:6 `FIFO_MODE` (00 bypass, 01 stream-to-FIFO, 1x stop-on-full).
pub const FIFO_CONFIG: u8 = 0x16;
/// Stream-to-FIFO mode in `FIFO_CONFIG`.
pub const FIFO_CONFIG_STREAM: u8 = 0b01 << 6;
/// Bypass mode in `FIFO_CONFIG` (FIFO off, its reset value).
pub const FIFO_CONFIG_BYPASS: u8 = 0;

/// `TEMP_DATA1`: temperature, big-endian, before the accelerometer data.
pub const TEMP_DATA1: u8 = 0x1D;

/// `ACCEL_DATA_X1`: first of six accelerometer data registers X1 X0 Y1 Y0 Z1 Z0, directly
/// followed by the six gyro data registers: one 12-byte burst from here reads both sensors
/// of the same sample.
pub const ACCEL_DATA_X1: u8 = 0x1F;
/// Length of the accelerometer + gyro burst from [`ACCEL_DATA_X1`].
pub const IMU_BURST_LEN: usize = 12;

/// `GYRO_DATA_X1`: first of six data registers X1 X0 Y1 Y0 Z1 Z0, big-endian two's complement
/// (`INTF_CONFIG0.SENSOR_DATA_ENDIAN` = 1 after reset). A burst read auto-increments.
pub const GYRO_DATA_X1: u8 = 0x25;

/// `INT_STATUS`: clear-on-read status bits.
pub const INT_STATUS: u8 = 0x2D;
/// `DATA_RDY_INT`: a new sample is in the data registers.
pub const INT_STATUS_DATA_RDY: u8 = 1 << 3;
/// `RESET_DONE_INT`: the soft reset has completed.
pub const INT_STATUS_RESET_DONE: u8 = 1 << 4;
/// `FIFO_FULL_INT`.
pub const INT_STATUS_FIFO_FULL: u8 = 1 << 1;

/// `FIFO_COUNTH`; with `FIFO_COUNTL` the number of bytes in the FIFO, big-endian after reset.
pub const FIFO_COUNTH: u8 = 0x2E;
/// `FIFO_DATA`: reading it pops the FIFO.
pub const FIFO_DATA: u8 = 0x30;

/// `SIGNAL_PATH_RESET`: bit 1 `FIFO_FLUSH`.
pub const SIGNAL_PATH_RESET: u8 = 0x4B;
/// `FIFO_FLUSH` bit of `SIGNAL_PATH_RESET`.
pub const SIGNAL_PATH_RESET_FIFO_FLUSH: u8 = 1 << 1;

/// `INTF_CONFIG0`: bit 5 `FIFO_COUNT_ENDIAN`, bit 4 `SENSOR_DATA_ENDIAN` (1 = big-endian, the
/// reset value), bits 1:0 `UI_SIFS_CFG` (11 = disable the I2C interface).
pub const INTF_CONFIG0: u8 = 0x4C;
/// Big-endian count and data (as after reset) with I2C disabled: on an SPI bus, a pattern that
/// looks like an I2C start can otherwise put the part's serial interface in I2C mode.
pub const INTF_CONFIG0_SPI_ONLY: u8 = 0b0011_0011;

/// `PWR_MGMT0`: bits 3:2 `GYRO_MODE`, bits 1:0 `ACCEL_MODE` (00 = off), bit 5 `TEMP_DIS`.
pub const PWR_MGMT0: u8 = 0x4E;
/// `GYRO_MODE` = 11, low-noise mode, in `PWR_MGMT0`.
pub const PWR_MGMT0_GYRO_LN: u8 = 0b11 << 2;
/// `ACCEL_MODE` = 11, low-noise mode, in `PWR_MGMT0`.
pub const PWR_MGMT0_ACCEL_LN: u8 = 0b11;
/// Mask of `ACCEL_MODE` in `PWR_MGMT0`.
pub const PWR_MGMT0_ACCEL_MASK: u8 = 0b11;
/// Mask of `GYRO_MODE` in `PWR_MGMT0`.
pub const PWR_MGMT0_GYRO_MASK: u8 = 0b11 << 2;

/// `GYRO_CONFIG0`: bits 7:5 `GYRO_FS_SEL`, bits 3:0 `GYRO_ODR`.
pub const GYRO_CONFIG0: u8 = 0x4F;

/// `ACCEL_CONFIG0`: bits 7:5 `ACCEL_FS_SEL`, bits 3:0 `ACCEL_ODR` (same codes as `GYRO_ODR`
/// for the rates this driver configures).
pub const ACCEL_CONFIG0: u8 = 0x50;

/// `FIFO_CONFIG1`: bit 1 `FIFO_GYRO_EN`, bit 0 `FIFO_ACCEL_EN`, bit 2 `FIFO_TEMP_EN`.
pub const FIFO_CONFIG1: u8 = 0x5F;
/// Gyro and temperature into the FIFO, accelerometer not: 8-byte "packet 1".
pub const FIFO_CONFIG1_GYRO_TEMP: u8 = (1 << 2) | (1 << 1);
/// Accelerometer, gyro and temperature into the FIFO: 16-byte "packet 3".
pub const FIFO_CONFIG1_ACCEL_GYRO_TEMP: u8 = (1 << 2) | (1 << 1) | 1;

/// `INT_CONFIG1`: bit 4 `INT_ASYNC_RESET` must be cleared for proper INT1/INT2 operation
/// (datasheet, register description of `INT_CONFIG1`).
pub const INT_CONFIG1: u8 = 0x64;
/// `INT_ASYNC_RESET` bit of `INT_CONFIG1`.
pub const INT_CONFIG1_ASYNC_RESET: u8 = 1 << 4;

/// `INT_SOURCE0`: bit 3 `UI_DRDY_INT1_EN` routes data-ready to INT1.
pub const INT_SOURCE0: u8 = 0x65;
/// `UI_DRDY_INT1_EN` bit of `INT_SOURCE0`.
pub const INT_SOURCE0_DRDY_INT1: u8 = 1 << 3;

/// `WHO_AM_I`.
pub const WHO_AM_I: u8 = 0x75;
/// `WHO_AM_I` value of the ICM-42688-P.
pub const WHO_AM_I_VALUE: u8 = 0x47;

/// `REG_BANK_SEL`: bits 2:0 select user bank 0..4; present in every bank.
pub const REG_BANK_SEL: u8 = 0x76;

/// Length of a FIFO "packet 1" with gyro data: header, X, Y, Z (16 bit each), temperature.
pub const FIFO_PACKET1_LEN: usize = 8;
/// Length of a FIFO "packet 3": header, accel X Y Z, gyro X Y Z (16 bit each), temperature
/// (8 bit), timestamp (16 bit).
pub const FIFO_PACKET3_LEN: usize = 16;
/// FIFO header bit 7: the FIFO is empty (the read returned no packet).
pub const FIFO_HEADER_EMPTY: u8 = 1 << 7;
/// FIFO header bit 6: the packet holds accelerometer data.
pub const FIFO_HEADER_ACCEL: u8 = 1 << 6;
/// FIFO header bit 5: the packet holds gyro data.
pub const FIFO_HEADER_GYRO: u8 = 1 << 5;
/// FIFO header bit 4: 20-bit (high-resolution) packet.
pub const FIFO_HEADER_20BIT: u8 = 1 << 4;

/// The largest count: a reading at `+32767` or `-32767` (or `-32768`) is at the sensor's
/// clip level, the true value may be beyond it.
pub const CLIP: i16 = i16::MAX;

/// The value a data register pair reads when the sample is invalid (sensor off or starting,
/// or an empty FIFO slot): -32768.
pub const INVALID_SAMPLE: i16 = i16::MIN;
