//! The driver against the datasheet's register map, on mocked buses: every byte the driver
//! puts on the bus is checked.

use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cT};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as SpiT};
use icm42688::registers as reg;
use icm42688::{
    raw_to_rad_s, Config, Error, GyroFullScale, GyroOdr, I2cAddress, Icm42688, RegisterInterface,
};

/// An SPI register write: one CS-framed transfer of address (bit 7 clear) and value.
fn w(addr: u8, value: u8) -> Vec<SpiT<u8>> {
    vec![
        SpiT::transaction_start(),
        SpiT::write_vec(vec![addr, value]),
        SpiT::transaction_end(),
    ]
}

/// An SPI register read: address with bit 7 set, then the data.
fn r(addr: u8, data: &[u8]) -> Vec<SpiT<u8>> {
    vec![
        SpiT::transaction_start(),
        SpiT::write_vec(vec![addr | 0x80]),
        SpiT::read_vec(data.to_vec()),
        SpiT::transaction_end(),
    ]
}

fn seq(parts: &[Vec<SpiT<u8>>]) -> Vec<SpiT<u8>> {
    parts.iter().flatten().cloned().collect()
}

fn reset_seq() -> Vec<Vec<SpiT<u8>>> {
    vec![
        w(0x76, 0x00),    // REG_BANK_SEL = bank 0
        w(0x11, 0x01),    // DEVICE_CONFIG.SOFT_RESET_CONFIG
        r(0x2D, &[0x00]), // INT_STATUS: not yet
        r(0x2D, &[0x10]), // INT_STATUS.RESET_DONE_INT
    ]
}

#[test]
fn init_over_spi_follows_the_datasheet() {
    let mut parts = reset_seq();
    parts.extend([
        r(0x75, &[0x47]), // WHO_AM_I
        w(0x4C, 0x33),    // INTF_CONFIG0: big-endian, I2C interface disabled
        r(0x4C, &[0x33]),
        w(0x14, 0x03), // INT_CONFIG: INT1 push-pull, active high, pulsed
        r(0x14, &[0x03]),
        r(0x64, &[0x10]), // INT_CONFIG1 reset value
        w(0x64, 0x00),    // INT_ASYNC_RESET cleared
        r(0x64, &[0x00]),
        w(0x65, 0x08), // INT_SOURCE0: UI_DRDY_INT1_EN
        r(0x65, &[0x08]),
        w(0x4F, (2 << 5) | 6), // GYRO_CONFIG0: +-500 dps, 1 kHz
        r(0x4F, &[0x46]),
        w(0x4E, 0x0C), // PWR_MGMT0: gyro low-noise, accel off
        r(0x4E, &[0x0C]),
    ]);
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(gyro.init(&mut NoopDelay, Config::identifier()), Ok(()));
    assert_eq!(gyro.full_scale(), GyroFullScale::Dps500);
    assert_eq!(gyro.odr(), GyroOdr::Hz1000);
    spi.done();
}

#[test]
fn init_without_int1_and_other_range() {
    let mut parts = reset_seq();
    parts.extend([
        r(0x75, &[0x47]),
        w(0x4C, 0x33),
        r(0x4C, &[0x33]),
        w(0x4F, 0x01), // +-2000 dps, 32 kHz
        r(0x4F, &[0x01]),
        w(0x4E, 0x0C),
        r(0x4E, &[0x0C]),
    ]);
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    let config = Config {
        full_scale: GyroFullScale::Dps2000,
        odr: GyroOdr::Hz32000,
        data_ready_int1: false,
    };
    assert_eq!(gyro.init(&mut NoopDelay, config), Ok(()));
    spi.done();
}

#[test]
fn wrong_identity_is_an_error_and_nothing_is_configured() {
    let mut parts = reset_seq();
    parts.push(r(0x75, &[0x6F])); // an ICM-42605 or similar
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(
        gyro.init(&mut NoopDelay, Config::identifier()),
        Err(Error::WrongId(0x6F))
    );
    spi.done();
}

#[test]
fn reset_that_never_completes_times_out() {
    let mut parts = vec![w(0x76, 0), w(0x11, 0x01)];
    for _ in 0..20 {
        parts.push(r(0x2D, &[0x00]));
    }
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(gyro.reset(&mut NoopDelay), Err(Error::Timeout));
    spi.done();
}

#[test]
fn readback_mismatch_is_reported() {
    let mut parts = reset_seq();
    parts.extend([
        r(0x75, &[0x47]),
        w(0x4C, 0x33),
        r(0x4C, &[0x33]),
        w(0x4F, 0x46),
        r(0x4F, &[0x06]),
    ]);
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    let config = Config {
        data_ready_int1: false,
        ..Config::identifier()
    };
    assert_eq!(
        gyro.init(&mut NoopDelay, config),
        Err(Error::ConfigMismatch {
            register: 0x4F,
            expected: 0x46,
            found: 0x06
        })
    );
    spi.done();
}

#[test]
fn gyro_sample_is_big_endian_and_scaled_to_rad_s() {
    // X = +16384 (half scale), Y = -1, Z = +32767.
    let parts = [r(0x25, &[0x40, 0x00, 0xFF, 0xFF, 0x7F, 0xFF])];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone()); // default config: +-500 dps
    let w = gyro.read_gyro().unwrap();
    let half = 250.0f32.to_radians();
    assert!((w[0] - half).abs() < 1e-6, "{}", w[0]);
    assert_eq!(w[1], -GyroFullScale::Dps500.rad_per_lsb());
    assert_eq!(w[2], raw_to_rad_s(32767, GyroFullScale::Dps500));
    spi.done();
}

#[test]
fn invalid_sample_marker_is_an_error() {
    let parts = [r(0x25, &[0x00, 0x10, 0x80, 0x00, 0x00, 0x00])];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(gyro.read_gyro(), Err(Error::InvalidSample));
    spi.done();
}

#[test]
fn data_ready_is_polled_then_times_out() {
    let parts = [
        r(0x2D, &[0x10]), // RESET_DONE only
        r(0x2D, &[0x08]), // DATA_RDY
        r(0x2D, &[0x00]),
        r(0x2D, &[0x00]),
        r(0x2D, &[0x00]),
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(gyro.wait_data_ready(&mut NoopDelay, 10, 5), Ok(()));
    assert_eq!(
        gyro.wait_data_ready(&mut NoopDelay, 10, 3),
        Err(Error::Timeout)
    );
    spi.done();
}

#[test]
fn fifo_packets_are_parsed() {
    let parts = [
        w(0x5F, 0x06), // FIFO_CONFIG1: gyro + temperature
        r(0x5F, &[0x06]),
        w(0x16, 0x40), // FIFO_CONFIG: stream-to-FIFO
        r(0x16, &[0x40]),
        w(0x4B, 0x02),          // SIGNAL_PATH_RESET.FIFO_FLUSH
        r(0x2E, &[0x00, 0x18]), // 24 bytes: three packets
        r(0x30, &[0x21, 0x00, 0x01, 0x00, 0x02, 0xFF, 0xFD, 0x21]),
        r(0x30, &[0x21, 0x12, 0x34, 0x00, 0x00, 0x00, 0x00, 0x21]),
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    gyro.enable_fifo().unwrap();
    let mut out = [[0i16; 3]; 2]; // room for two of the three
    assert_eq!(gyro.read_fifo_raw(&mut out), Ok(2));
    assert_eq!(out, [[1, 2, -3], [0x1234, 0, 0]]);
    spi.done();
}

#[test]
fn fifo_empty_header_stops_and_foreign_header_flushes() {
    let parts = [
        r(0x2E, &[0x00, 0x10]),
        r(0x30, &[0x80, 0, 0, 0, 0, 0, 0, 0]), // empty
        r(0x2E, &[0x00, 0x10]),
        r(0x30, &[0x78, 0, 0, 0, 0, 0, 0, 0]), // accel + gyro: not configured
        w(0x4B, 0x02),
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    let mut out = [[0i16; 3]; 4];
    assert_eq!(gyro.read_fifo_raw(&mut out), Ok(0));
    assert_eq!(gyro.read_fifo_raw(&mut out), Err(Error::FifoCorrupt(0x78)));
    spi.done();
}

#[test]
fn i2c_identity_and_bus_error() {
    let expectations = [
        I2cT::write_read(0x69, vec![0x75], vec![0x47]),
        I2cT::write(0x69, vec![0x4E, 0x0C]),
        I2cT::write_read(0x69, vec![0x25], vec![0; 6])
            .with_error(embedded_hal::i2c::ErrorKind::Other),
    ];
    let mut i2c = I2cMock::new(&expectations);
    let mut gyro = Icm42688::new_i2c(i2c.clone(), I2cAddress::Ad0High);
    assert_eq!(gyro.who_am_i(), Ok(reg::WHO_AM_I_VALUE));
    gyro.interface_mut().write_register(0x4E, 0x0C).unwrap();
    assert_eq!(
        gyro.read_gyro(),
        Err(Error::Bus(embedded_hal::i2c::ErrorKind::Other))
    );
    i2c.done();
}
