//! The replay file `inertia export-replay` writes and the QEMU image reads (`--replay`): per
//! sample exactly the `f32` values `inertia identify` gives its `FlightPipeline`, so the
//! on-board result can be compared with the host tool's bit for bit. Little-endian:
//!
//! ```text
//! offset 0  magic  b"IRPL"
//!        4  u32    version (4)
//!        8  f32    sample rate, Hz (1 / median dt of the log)
//!       12  f32    gyro noise, rad/s
//!       16  f32    gyro full scale, rad/s (the estimator's saturation level)
//!       20  u32    flags: bit 0 accelerometer present, bit 1 rotor present
//!       24  f32    rotor inertia, kg m^2 (0 without a rotor)
//!       28  f32x3  rotor axis, unit vector in the gyro frame
//!       40  f32    rotor speed resolution, rad/s (the telemetry's step; 0: exact)
//!       44  f32    gyro averaging: the share of each sample interval a reading is the mean
//!                  over (0: readings at instants; 1: PX4's sensor_combined)
//!       48  f32    gyro smoothing: the time variance of the gyro's own low-pass filter, s^2
//!                  (0: an unfiltered gyro; Betaflight's filtered gyro)
//!       52  u32    number of samples n
//!       56  n x { f32x3 rate rad/s, f32x3 specific force m/s^2, f32 rotor speed rad/s,
//!                 f32 dt s }   (32 bytes each)
//! ```
//!
//! Why the header carries these: the resolution (from version 2), because the tensor's
//! uncertainty counts the rotor momentum's quantisation, so the replay gives the firmware the
//! figure `inertia identify` uses; the gyro averaging (from version 3), because the
//! output-error fits count a reading's window in their block means
//! (`identifier_core::PipelineSettings::with_averaging_gyro`), so the firmware must be given
//! it to match `inertia identify` on a PX4 log; the gyro smoothing (from version 4,
//! `identifier_core::PipelineSettings::with_filtered_gyro`), for Betaflight logs.

/// First four bytes.
pub const MAGIC: [u8; 4] = *b"IRPL";
/// Format version.
pub const VERSION: u32 = 4;
/// Header length, bytes.
pub const HEADER_LEN: usize = 56;
/// One sample, bytes.
pub const SAMPLE_LEN: usize = 32;

/// The replay's header.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplayHeader {
    /// Sample rate, Hz.
    pub rate_hz: f32,
    /// Gyro noise, rad/s.
    pub noise_std: f32,
    /// Gyro full scale, rad/s.
    pub full_scale: f32,
    /// The log has an accelerometer (the free-flight gate decides); else every sample is free.
    pub with_accel: bool,
    /// The rotor, when one was given: `(inertia kg m^2, axis)`.
    pub rotor: Option<(f32, [f32; 3])>,
    /// The rotor speed's resolution, rad/s (0: taken as exact).
    pub rotor_resolution: f32,
    /// The share of each sample interval a gyro reading is the mean over (0: instants).
    pub gyro_averaging: f32,
    /// The time variance of the gyro's own low-pass filter, s^2 (0: unfiltered).
    pub gyro_smoothing: f32,
    /// Samples that follow.
    pub samples: u32,
}

/// One replayed sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplaySample {
    /// Rate, rad/s.
    pub omega: [f32; 3],
    /// Specific force, m/s^2.
    pub accel: [f32; 3],
    /// Rotor speed, rad/s.
    pub rotor_rad_s: f32,
    /// Time step, s.
    pub dt: f32,
}

/// Why a header was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// Not a replay file.
    BadMagic,
    /// Another version.
    BadVersion(u32),
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    for (i, x) in w.iter_mut().enumerate() {
        *x = b.get(at + i).copied().unwrap_or(0);
    }
    u32::from_le_bytes(w)
}

impl ReplayHeader {
    /// Decodes a header.
    pub fn decode(b: &[u8; HEADER_LEN]) -> Result<Self, ReplayError> {
        if b.get(0..4) != Some(&MAGIC[..]) {
            return Err(ReplayError::BadMagic);
        }
        let v = u32_at(b, 4);
        if v != VERSION {
            return Err(ReplayError::BadVersion(v));
        }
        let flags = u32_at(b, 20);
        Ok(ReplayHeader {
            rate_hz: f32_at(b, 8),
            noise_std: f32_at(b, 12),
            full_scale: f32_at(b, 16),
            with_accel: flags & 1 != 0,
            rotor: (flags & 2 != 0)
                .then(|| (f32_at(b, 24), [f32_at(b, 28), f32_at(b, 32), f32_at(b, 36)])),
            rotor_resolution: f32_at(b, 40),
            gyro_averaging: f32_at(b, 44),
            gyro_smoothing: f32_at(b, 48),
            samples: u32_at(b, 52),
        })
    }
}

/// Decodes one sample.
pub fn decode_sample(b: &[u8; SAMPLE_LEN]) -> ReplaySample {
    let f = |k: usize| f32_at(b, 4 * k);
    ReplaySample {
        omega: [f(0), f(1), f(2)],
        accel: [f(3), f(4), f(5)],
        rotor_rad_s: f(6),
        dt: f(7),
    }
}
