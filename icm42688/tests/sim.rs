//! The simulated part answers the real driver: identity, reset, configuration, samples
//! quantised at the configured full scale, end of stream, injected bus errors.

use embedded_hal_mock::eh1::delay::NoopDelay;
use icm42688::config::m_s2_to_raw;
use icm42688::config::rad_s_to_raw;
use icm42688::sim::{SampleSource, SimBusError, SimIcm42688};
use icm42688::{raw_to_rad_s, AccelFullScale, Config, Error, GyroFullScale, Icm42688};

fn source(samples: Vec<[f32; 3]>) -> impl FnMut() -> Option<[f32; 3]> {
    let mut it = samples.into_iter();
    move || it.next()
}

#[test]
fn driver_reads_back_quantised_samples_then_times_out_at_the_end() {
    let samples = vec![[1.0, -2.0, 0.5], [0.0, 3.0, -3.0], [1e-4, -1e-4, 8.0]];
    let sim = SimIcm42688::new(source(samples.clone()));
    let mut gyro = Icm42688::new_spi(sim);
    gyro.init(&mut NoopDelay, Config::identifier()).unwrap();
    let fs = GyroFullScale::Dps2000;
    for s in &samples {
        gyro.wait_data_ready(&mut NoopDelay, 1, 3).unwrap();
        let w = gyro.read_gyro().unwrap();
        for i in 0..3 {
            // Within half a count, and exactly the driver's conversion of the encoded count.
            assert!((w[i] - s[i]).abs() <= 0.5 * fs.rad_per_lsb() * 1.0001);
            assert_eq!(w[i], raw_to_rad_s(rad_s_to_raw(s[i], fs), fs));
        }
    }
    assert!(!gyro.interface().bus().exhausted());
    assert_eq!(
        gyro.wait_data_ready(&mut NoopDelay, 1, 3),
        Err(Error::Timeout)
    );
    assert!(gyro.interface().bus().exhausted());
    assert_eq!(gyro.interface().bus().stats().samples, 3);
}

#[test]
fn clipping_and_invalid_marker() {
    let fs = GyroFullScale::Dps500;
    assert_eq!(rad_s_to_raw(100.0, fs), 32767);
    assert_eq!(rad_s_to_raw(-100.0, fs), -32767);
    assert_eq!(rad_s_to_raw(f32::NAN, fs), i16::MIN);
    assert_eq!(rad_s_to_raw(0.6 * fs.rad_per_lsb(), fs), 1);
    assert_eq!(rad_s_to_raw(-0.6 * fs.rad_per_lsb(), fs), -1);
    let sim = SimIcm42688::new(source(vec![[f32::NAN, 0.0, 0.0]]));
    let mut gyro = Icm42688::new_spi(sim);
    gyro.init(&mut NoopDelay, Config::identifier()).unwrap();
    gyro.wait_data_ready(&mut NoopDelay, 1, 1).unwrap();
    assert_eq!(gyro.read_gyro(), Err(Error::InvalidSample));
}

#[test]
fn gyro_off_reads_invalid_and_full_scale_follows_config() {
    let sim = SimIcm42688::new(source(vec![[1.0, 1.0, 1.0]]));
    let mut gyro = Icm42688::new_spi(sim);
    assert_eq!(gyro.read_gyro(), Err(Error::InvalidSample));
    let config = Config {
        full_scale: GyroFullScale::Dps2000,
        ..Config::identifier()
    };
    gyro.init(&mut NoopDelay, config).unwrap();
    gyro.wait_data_ready(&mut NoopDelay, 1, 1).unwrap();
    let raw = gyro.read_gyro_raw().unwrap();
    assert_eq!(raw, [rad_s_to_raw(1.0, GyroFullScale::Dps2000); 3]);
    assert_eq!(raw[0], 939); // 1 rad/s = 57.30 dps at 16.384 LSB/dps = 938.7
}

#[test]
fn identity_and_injected_bus_errors() {
    let sim = SimIcm42688::new(source(vec![])).with_bus_error_every(2);
    let mut gyro = Icm42688::new_spi(sim);
    assert_eq!(gyro.who_am_i(), Ok(0x47));
    assert_eq!(gyro.who_am_i(), Err(Error::Bus(SimBusError)));
    assert_eq!(gyro.interface().bus().stats().injected_errors, 1);
}

/// A source with accelerometer data.
struct Imu(Vec<([f32; 3], [f32; 3])>);

impl SampleSource for Imu {
    fn next_sample(&mut self) -> Option<[f32; 3]> {
        self.next_imu().map(|(g, _)| g)
    }
    fn next_imu(&mut self) -> Option<([f32; 3], [f32; 3])> {
        if self.0.is_empty() {
            None
        } else {
            Some(self.0.remove(0))
        }
    }
}

#[test]
fn accelerometer_is_served_with_the_gyro_and_clipping_is_flagged() {
    let g = icm42688::STANDARD_GRAVITY;
    let sim = SimIcm42688::new(Imu(vec![
        ([1.0, 0.0, -1.0], [0.0, 0.0, g]),
        ([100.0, -100.0, 100.0], [200.0, -1.0, 0.0]),
    ]));
    let mut imu = Icm42688::new_spi(sim);
    // Accelerometer off before init: invalid.
    assert_eq!(imu.read_imu_raw(), Err(Error::InvalidSample));
    imu.init(&mut NoopDelay, Config::identifier()).unwrap();
    imu.wait_data_ready(&mut NoopDelay, 1, 1).unwrap();
    let s = imu.read_imu().unwrap();
    let afs = AccelFullScale::G16;
    assert_eq!(
        imu.read_imu_raw().unwrap().accel[2],
        m_s2_to_raw(g, afs) // 2048
    );
    assert!((s.accel[2] - g).abs() <= afs.m_s2_per_lsb());
    assert_eq!(
        s.gyro[0],
        raw_to_rad_s(
            rad_s_to_raw(1.0, GyroFullScale::Dps2000),
            GyroFullScale::Dps2000
        )
    );
    assert!(!s.saturated.any());
    imu.wait_data_ready(&mut NoopDelay, 1, 1).unwrap();
    let s = imu.read_imu().unwrap();
    assert_eq!(s.saturated.gyro, [true; 3]);
    assert_eq!(s.saturated.accel, [true, false, false]);
    // The default source (gyro only) serves a zero specific force: free fall.
    let sim = SimIcm42688::new(source(vec![[0.5, 0.5, 0.5]]));
    let mut imu = Icm42688::new_spi(sim);
    imu.init(&mut NoopDelay, Config::identifier()).unwrap();
    imu.wait_data_ready(&mut NoopDelay, 1, 1).unwrap();
    assert_eq!(imu.read_imu_raw().unwrap().accel, [0; 3]);
}
