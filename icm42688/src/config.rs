//! Full-scale ranges and output data rate of the gyro and the accelerometer, and the one
//! conversion from raw counts to rad/s (and to m/s^2) used everywhere (driver on the MCU,
//! driver on the host, simulated device).

/// `GYRO_FS_SEL` of `GYRO_CONFIG0`: the measurement range in degrees per second.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GyroFullScale {
    /// +-2000 dps (16.4 LSB/dps).
    Dps2000 = 0,
    /// +-1000 dps.
    Dps1000 = 1,
    /// +-500 dps.
    Dps500 = 2,
    /// +-250 dps.
    Dps250 = 3,
    /// +-125 dps.
    Dps125 = 4,
    /// +-62.5 dps.
    Dps62_5 = 5,
    /// +-31.25 dps.
    Dps31_25 = 6,
    /// +-15.625 dps.
    Dps15_625 = 7,
}

impl GyroFullScale {
    /// The range in degrees per second.
    pub const fn dps(self) -> f32 {
        match self {
            GyroFullScale::Dps2000 => 2000.0,
            GyroFullScale::Dps1000 => 1000.0,
            GyroFullScale::Dps500 => 500.0,
            GyroFullScale::Dps250 => 250.0,
            GyroFullScale::Dps125 => 125.0,
            GyroFullScale::Dps62_5 => 62.5,
            GyroFullScale::Dps31_25 => 31.25,
            GyroFullScale::Dps15_625 => 15.625,
        }
    }

    /// The range in rad/s.
    pub const fn rad_s(self) -> f32 {
        self.dps() * (core::f32::consts::PI / 180.0)
    }

    /// rad/s per count: full scale over 2^15. The datasheet's sensitivities (16.4 LSB/dps at
    /// 2000 dps, ...) are these values rounded; the part is trimmed to full scale = 2^15 counts.
    pub const fn rad_per_lsb(self) -> f32 {
        self.rad_s() / 32768.0
    }

    /// The `GYRO_FS_SEL` field value (bits 7:5 of `GYRO_CONFIG0`).
    pub const fn bits(self) -> u8 {
        self as u8
    }

    /// The range for a `GYRO_FS_SEL` field value (only the low three bits are used).
    pub const fn from_bits(bits: u8) -> Self {
        match bits & 0b111 {
            0 => GyroFullScale::Dps2000,
            1 => GyroFullScale::Dps1000,
            2 => GyroFullScale::Dps500,
            3 => GyroFullScale::Dps250,
            4 => GyroFullScale::Dps125,
            5 => GyroFullScale::Dps62_5,
            6 => GyroFullScale::Dps31_25,
            _ => GyroFullScale::Dps15_625,
        }
    }
}

/// Standard gravity, m/s^2: the unit `g` of the accelerometer's ranges.
pub const STANDARD_GRAVITY: f32 = 9.806_65;

/// `ACCEL_FS_SEL` of `ACCEL_CONFIG0`: the accelerometer's range in g.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AccelFullScale {
    /// +-16 g (2048 LSB/g).
    G16 = 0,
    /// +-8 g.
    G8 = 1,
    /// +-4 g.
    G4 = 2,
    /// +-2 g.
    G2 = 3,
}

impl AccelFullScale {
    /// The range in g.
    pub const fn g(self) -> f32 {
        match self {
            AccelFullScale::G16 => 16.0,
            AccelFullScale::G8 => 8.0,
            AccelFullScale::G4 => 4.0,
            AccelFullScale::G2 => 2.0,
        }
    }

    /// m/s^2 per count: full scale over 2^15.
    pub const fn m_s2_per_lsb(self) -> f32 {
        self.g() * STANDARD_GRAVITY / 32768.0
    }

    /// The `ACCEL_FS_SEL` field value (bits 7:5 of `ACCEL_CONFIG0`).
    pub const fn bits(self) -> u8 {
        self as u8
    }

    /// The range for an `ACCEL_FS_SEL` field value (low three bits; codes 4-7 are reserved and
    /// read as +-2 g here).
    pub const fn from_bits(bits: u8) -> Self {
        match bits & 0b111 {
            0 => AccelFullScale::G16,
            1 => AccelFullScale::G8,
            2 => AccelFullScale::G4,
            _ => AccelFullScale::G2,
        }
    }
}

/// `GYRO_ODR` of `GYRO_CONFIG0`: output data rate. Low-noise mode supports all of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GyroOdr {
    /// 32 kHz.
    Hz32000 = 0b0001,
    /// 16 kHz.
    Hz16000 = 0b0010,
    /// 8 kHz.
    Hz8000 = 0b0011,
    /// 4 kHz.
    Hz4000 = 0b0100,
    /// 2 kHz.
    Hz2000 = 0b0101,
    /// 1 kHz (reset value).
    Hz1000 = 0b0110,
    /// 500 Hz.
    Hz500 = 0b1111,
    /// 200 Hz.
    Hz200 = 0b0111,
    /// 100 Hz.
    Hz100 = 0b1000,
    /// 50 Hz.
    Hz50 = 0b1001,
    /// 25 Hz.
    Hz25 = 0b1010,
    /// 12.5 Hz.
    Hz12_5 = 0b1011,
}

impl GyroOdr {
    /// The rate in Hz.
    pub const fn hz(self) -> f32 {
        match self {
            GyroOdr::Hz32000 => 32000.0,
            GyroOdr::Hz16000 => 16000.0,
            GyroOdr::Hz8000 => 8000.0,
            GyroOdr::Hz4000 => 4000.0,
            GyroOdr::Hz2000 => 2000.0,
            GyroOdr::Hz1000 => 1000.0,
            GyroOdr::Hz500 => 500.0,
            GyroOdr::Hz200 => 200.0,
            GyroOdr::Hz100 => 100.0,
            GyroOdr::Hz50 => 50.0,
            GyroOdr::Hz25 => 25.0,
            GyroOdr::Hz12_5 => 12.5,
        }
    }

    /// The nominal sample period in seconds, `1 / hz`.
    pub const fn period_s(self) -> f32 {
        1.0 / self.hz()
    }

    /// The nominal sample period in microseconds.
    pub const fn period_us(self) -> u32 {
        (1_000_000.0 / self.hz()) as u32
    }

    /// The `GYRO_ODR` field value (bits 3:0 of `GYRO_CONFIG0`).
    pub const fn bits(self) -> u8 {
        self as u8
    }

    /// The rate for a `GYRO_ODR` field value; `None` for reserved codes.
    pub const fn from_bits(bits: u8) -> Option<Self> {
        Some(match bits & 0x0F {
            0b0001 => GyroOdr::Hz32000,
            0b0010 => GyroOdr::Hz16000,
            0b0011 => GyroOdr::Hz8000,
            0b0100 => GyroOdr::Hz4000,
            0b0101 => GyroOdr::Hz2000,
            0b0110 => GyroOdr::Hz1000,
            0b1111 => GyroOdr::Hz500,
            0b0111 => GyroOdr::Hz200,
            0b1000 => GyroOdr::Hz100,
            0b1001 => GyroOdr::Hz50,
            0b1010 => GyroOdr::Hz25,
            0b1011 => GyroOdr::Hz12_5,
            _ => return None,
        })
    }
}

/// What [`crate::Icm42688::init`] configures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Gyro range.
    pub full_scale: GyroFullScale,
    /// Accelerometer range.
    pub accel_full_scale: AccelFullScale,
    /// Output data rate of the gyro and of the accelerometer.
    pub odr: GyroOdr,
    /// Route data-ready to the INT1 pin (push-pull, active high, pulsed), for boards that wire
    /// it to an EXTI line. Polling `INT_STATUS` works either way.
    pub data_ready_int1: bool,
}

impl Config {
    /// The identifier's configuration: 1 kHz, +-2000 dps and +-16 g. +-2000 dps (34.9 rad/s)
    /// covers a hand toss (about 12 rad/s) and the racquet data (35 rad/s peaks), with
    /// 1.07 mrad/s counts, about the part's noise at 1 kHz; +-16 g covers the throw and the
    /// catch.
    pub const fn identifier() -> Self {
        Config {
            full_scale: GyroFullScale::Dps2000,
            accel_full_scale: AccelFullScale::G16,
            odr: GyroOdr::Hz1000,
            data_ready_int1: true,
        }
    }

    /// The value written to `GYRO_CONFIG0`.
    pub const fn gyro_config0(&self) -> u8 {
        (self.full_scale.bits() << 5) | self.odr.bits()
    }

    /// The value written to `ACCEL_CONFIG0`: range and the gyro's ODR code (the codes this
    /// driver offers mean the same rates for both sensors).
    pub const fn accel_config0(&self) -> u8 {
        (self.accel_full_scale.bits() << 5) | self.odr.bits()
    }
}

impl Default for Config {
    fn default() -> Self {
        Config::identifier()
    }
}

/// Converts one raw count to rad/s at `fs`. The only conversion in the project: the driver on
/// the MCU, the same driver on the host, and the simulated device's inverse all go through
/// [`GyroFullScale::rad_per_lsb`], so host and firmware see bit-identical `f32` rates.
pub fn raw_to_rad_s(raw: i16, fs: GyroFullScale) -> f32 {
    f32::from(raw) * fs.rad_per_lsb()
}

/// Converts three raw counts to rad/s.
pub fn raw3_to_rad_s(raw: [i16; 3], fs: GyroFullScale) -> [f32; 3] {
    [
        raw_to_rad_s(raw[0], fs),
        raw_to_rad_s(raw[1], fs),
        raw_to_rad_s(raw[2], fs),
    ]
}

/// Converts three raw accelerometer counts to m/s^2 at `fs`.
pub fn raw3_to_m_s2(raw: [i16; 3], fs: AccelFullScale) -> [f32; 3] {
    raw.map(|r| f32::from(r) * fs.m_s2_per_lsb())
}

/// True when a raw count is at the clip level (`+-32767`, or `-32768`): the true value may be
/// beyond the range.
pub const fn is_clipped(raw: i16) -> bool {
    raw == crate::registers::CLIP || raw <= -crate::registers::CLIP
}

/// Which axes of a raw triple are at the clip level ([`is_clipped`]).
pub const fn clipped3(raw: [i16; 3]) -> [bool; 3] {
    [is_clipped(raw[0]), is_clipped(raw[1]), is_clipped(raw[2])]
}

/// The count an accelerometer at `fs` reports for `a` m/s^2: rounded, clipped to `+-32767`;
/// NaN gives the invalid marker. Used by the simulated device.
pub fn m_s2_to_raw(a: f32, fs: AccelFullScale) -> i16 {
    counts_to_raw(a, fs.m_s2_per_lsb())
}

/// The count a gyro at `fs` reports for `rate` rad/s: rounded to nearest, clipped to
/// `+-32767` (full scale). NaN gives [`crate::registers::INVALID_SAMPLE`], as the real part
/// reports for an invalid sample. Used by the simulated device.
pub fn rad_s_to_raw(rate: f32, fs: GyroFullScale) -> i16 {
    counts_to_raw(rate, fs.rad_per_lsb())
}

fn counts_to_raw(x: f32, per_lsb: f32) -> i16 {
    if x.is_nan() {
        return crate::registers::INVALID_SAMPLE;
    }
    let counts = x / per_lsb;
    let rounded = if counts >= 0.0 {
        counts + 0.5
    } else {
        counts - 0.5
    };
    // `as` saturates (and truncates toward zero, completing the rounding); the clamp keeps
    // -32768 reserved for "invalid".
    (rounded as i32).clamp(-32767, 32767) as i16
}
