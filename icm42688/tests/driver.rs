//! The driver against the datasheet's register map, on mocked buses: every byte the driver
//! puts on the bus is checked.

use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cT};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as SpiT};
use icm42688::registers as reg;
use icm42688::{
    raw_to_rad_s, AccelFullScale, Config, Error, GyroFullScale, GyroOdr, I2cAddress, Icm42688,
    RawImu, RegisterInterface, Saturation,
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
        w(0x4F, 6), // GYRO_CONFIG0: +-2000 dps (the default), 1 kHz
        r(0x4F, &[0x06]),
        w(0x50, 6), // ACCEL_CONFIG0: +-16 g, 1 kHz
        r(0x50, &[0x06]),
        w(0x4E, 0x0F), // PWR_MGMT0: gyro and accel low-noise
        r(0x4E, &[0x0F]),
    ]);
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    assert_eq!(gyro.init(&mut NoopDelay, Config::identifier()), Ok(()));
    assert_eq!(gyro.full_scale(), GyroFullScale::Dps2000);
    assert_eq!(gyro.accel_full_scale(), AccelFullScale::G16);
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
        w(0x4F, (7 << 5) | 0x01), // +-15.625 dps, 32 kHz
        r(0x4F, &[0xE1]),
        w(0x50, (3 << 5) | 0x01), // +-2 g, 32 kHz
        r(0x50, &[0x61]),
        w(0x4E, 0x0F),
        r(0x4E, &[0x0F]),
    ]);
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    let config = Config {
        full_scale: GyroFullScale::Dps15_625,
        accel_full_scale: AccelFullScale::G2,
        odr: GyroOdr::Hz32000,
        data_ready_int1: false,
    };
    assert_eq!(gyro.init(&mut NoopDelay, config), Ok(()));
    assert_eq!(gyro.full_scale().dps(), 15.625);
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
        w(0x4F, 0x06),
        r(0x4F, &[0x46]),
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
            expected: 0x06,
            found: 0x46
        })
    );
    spi.done();
}

#[test]
fn gyro_sample_is_big_endian_and_scaled_to_rad_s() {
    // X = +16384 (half scale), Y = -1, Z = +32767.
    let parts = [r(0x25, &[0x40, 0x00, 0xFF, 0xFF, 0x7F, 0xFF])];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone()); // default config: +-2000 dps
    let w = gyro.read_gyro().unwrap();
    let half = 1000.0f32.to_radians();
    assert!((w[0] - half).abs() < 1e-5, "{}", w[0]);
    assert_eq!(w[1], -GyroFullScale::Dps2000.rad_per_lsb());
    assert_eq!(w[2], raw_to_rad_s(32767, GyroFullScale::Dps2000));
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

/// A 16-byte FIFO packet 3: header, accel X Y Z, gyro X Y Z (big-endian), temperature,
/// timestamp.
fn packet(header: u8, accel: [i16; 3], gyro: [i16; 3]) -> Vec<u8> {
    let mut p = vec![header];
    for v in accel.iter().chain(gyro.iter()) {
        p.extend_from_slice(&v.to_be_bytes());
    }
    p.extend_from_slice(&[0x21, 0x12, 0x34]);
    p
}

#[test]
fn fifo_packets_are_parsed() {
    let parts = [
        w(0x5F, 0x07), // FIFO_CONFIG1: accel + gyro + temperature (packet 3)
        r(0x5F, &[0x07]),
        w(0x16, 0x40), // FIFO_CONFIG: stream-to-FIFO
        r(0x16, &[0x40]),
        w(0x4B, 0x02),          // SIGNAL_PATH_RESET.FIFO_FLUSH
        r(0x2E, &[0x00, 0x30]), // 48 bytes: three packets
        r(0x30, &packet(0x68, [10, -20, 2048], [1, 2, -3])),
        r(0x30, &packet(0x6C, [0, 0, -2048], [0x1234, 32767, 0])),
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    gyro.enable_fifo().unwrap();
    let mut out = [RawImu::default(); 2]; // room for two of the three
    assert_eq!(gyro.read_fifo_raw(&mut out), Ok(2));
    assert_eq!(out[0].accel, [10, -20, 2048]);
    assert_eq!(out[0].gyro, [1, 2, -3]);
    assert_eq!(out[1].gyro, [0x1234, 32767, 0]);
    assert_eq!(out[0].saturation(), Saturation::default());
    assert_eq!(out[1].saturation().gyro, [false, true, false]);
    // 2048 counts at +-16 g is 1 g.
    let imu = out[0].convert(GyroFullScale::Dps2000, AccelFullScale::G16);
    assert!((imu.accel[2] - icm42688::STANDARD_GRAVITY).abs() < 1e-5);
    spi.done();
}

#[test]
fn fifo_empty_header_stops_and_foreign_header_flushes() {
    let parts = [
        r(0x2E, &[0x00, 0x20]),
        r(0x30, &packet(0x80, [0; 3], [0; 3])), // empty
        r(0x2E, &[0x00, 0x20]),
        r(0x30, &packet(0x20, [0; 3], [0; 3])), // gyro only: not configured
        w(0x4B, 0x02),
        r(0x2E, &[0x00, 0x10]),
        r(0x30, &packet(0x78, [0; 3], [0; 3])), // 20-bit packet: not configured
        w(0x4B, 0x02),
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut gyro = Icm42688::new_spi(spi.clone());
    let mut out = [RawImu::default(); 4];
    assert_eq!(gyro.read_fifo_raw(&mut out), Ok(0));
    assert_eq!(gyro.read_fifo_raw(&mut out), Err(Error::FifoCorrupt(0x20)));
    assert_eq!(gyro.read_fifo_raw(&mut out), Err(Error::FifoCorrupt(0x78)));
    spi.done();
}

#[test]
fn imu_burst_reads_accel_and_gyro_together_and_flags_saturation() {
    // Accel X = +2048 (1 g at +-16 g), Y = -32767 (clipped), Z = 0; gyro X = 32767 (clipped),
    // Y = -1, Z = 100: one 12-byte burst from ACCEL_DATA_X1 (0x1F).
    let parts = [
        r(
            0x1F,
            &[
                0x08, 0x00, 0x80, 0x01, 0x00, 0x00, 0x7F, 0xFF, 0xFF, 0xFF, 0x00, 0x64,
            ],
        ),
        r(
            0x1F,
            &[0, 0, 0, 0, 0, 0, 0x7F, 0xFF, 0x7F, 0xFF, 0x80, 0x01],
        ),
        r(0x1F, &[0, 0, 0x80, 0x00, 0, 0, 0, 0, 0, 0, 0, 0]), // accel Y invalid
    ];
    let mut spi = SpiMock::new(&seq(&parts));
    let mut imu = Icm42688::new_spi(spi.clone());
    let s = imu.read_imu().unwrap();
    assert!((s.accel[0] - icm42688::STANDARD_GRAVITY).abs() < 1e-5);
    assert_eq!(s.accel[2], 0.0);
    assert_eq!(s.gyro[1], -GyroFullScale::Dps2000.rad_per_lsb());
    assert_eq!(s.saturated.accel, [false, true, false]);
    assert_eq!(s.saturated.gyro, [true, false, false]);
    assert!(s.saturated.any() && s.saturated.gyro_any() && s.saturated.accel_any());
    // All three gyro axes clipped: a reading, flagged, not an error.
    let raw = imu.read_imu_raw().unwrap();
    assert_eq!(raw.gyro, [32767, 32767, -32767]);
    assert_eq!(raw.saturation().gyro, [true; 3]);
    assert!(!raw.saturation().accel_any());
    assert_eq!(imu.read_imu_raw(), Err(Error::InvalidSample));
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
