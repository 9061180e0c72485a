//! The replay file `inertia export-replay` writes and the QEMU image reads (`--replay`): per
//! sample exactly the `f32` values `inertia identify` gives its `FlightPipeline` (the rotors'
//! speeds, from which both compute the momentum with `identifier_core::Rotors::momentum`), so
//! the on-board result can be compared with the host tool's bit for bit. Little-endian:
//!
//! ```text
//! offset 0  magic  b"IRPL"
//!        4  u32    version (6; version 5 files, the same without flag bit 1, are read too)
//!        8  f32    sample rate, Hz (1 / median dt of the log)
//!       12  f32    gyro noise, rad/s
//!       16  f32    gyro full scale, rad/s (the estimator's saturation level)
//!       20  u32    flags: bit 0 accelerometer present, bit 1 orbit (each sample carries its
//!                  time, attitude and position), bit 2 the gyro's readings moved to their
//!                  counts' centres (`inertia`'s (Q1): the tensor is at most ModelMismatch)
//!       24  f32    rotor momentum's quantum, kg m^2/s (inertia times the speed telemetry's
//!                  step, as `inertia identify` computes it; 0: exact)
//!       28  f32    gyro averaging: the share of each sample interval a reading is the mean
//!                  over (0: readings at instants; 1: PX4's sensor_combined)
//!       32  f32    gyro smoothing: the time variance of the gyro's own low-pass filter, s^2
//!                  (0: an unfiltered gyro; Betaflight's filtered gyro)
//!       36  u32    number of rotors r (0 to identifier_core::MAX_ROTORS = 8)
//!       40  u32    number of samples n
//!       44  r x { f32 inertia kg m^2, f32x3 axis (unit vector in the gyro frame) }
//!                  (16 bytes each; the rotor table, (R1) of identifier_core::Rotors)
//!  44 + 16r n x { f32x3 rate rad/s, f32x3 specific force m/s^2, f32 dt s,
//!                 u32 sample flags (bit 0: an actuator acted on the body, held out),
//!                 r x f32 rotor speed rad/s relative to the body,
//!                 with flag bit 1 only: f64 time s (the log's), f32x4 attitude quaternion
//!                 (w, x, y, z; v_N = R(q) v_B), f64x3 position m (Earth-centred inertial) }
//!                 (32 + 4r bytes each, 48 more with flag bit 1)
//! ```
//!
//! Why the header carries these: the momentum's quantum (from version 2, as the speed's
//! resolution until version 4), because the tensor's uncertainty counts the rotor momentum's
//! quantisation, so the replay gives the firmware the figure `inertia identify` uses; the gyro
//! averaging (from version 3), because the output-error fits count a reading's window in
//! their block means (`identifier_core::PipelineSettings::with_averaging_gyro`), so the
//! firmware must be given it to match `inertia identify` on a PX4 log; the gyro smoothing
//! (from version 4, `identifier_core::PipelineSettings::with_filtered_gyro`), for Betaflight
//! logs; the rotor table and a speed per rotor and sample (from version 5), for vehicles with
//! several wheels; the per-sample flags (version 5), for the samples a satellite's board marks
//! as actuated (thrusters, magnetorquers), which the firmware keeps out; the orbit (version 6,
//! flag bit 1), for the gravity-gradient torque `inertia identify` folds into the known
//! momentum on an orbiting vehicle's log ([`identifier_core::gravity`]): the firmware folds it
//! with the same function, from the log's own `f64` times, `f32` attitude and `f64` position
//! (what `identify` computes it from), at each pass's tensor.

use identifier_core::{Rotor, MAX_ROTORS};

/// First four bytes.
pub const MAGIC: [u8; 4] = *b"IRPL";
/// Format version written.
pub const VERSION: u32 = 6;
/// The oldest version read (no orbit).
pub const OLDEST_VERSION: u32 = 5;
/// The header's fixed part, bytes (the rotor table follows).
pub const HEADER_LEN: usize = 44;
/// One rotor of the table, bytes.
pub const ROTOR_LEN: usize = 16;
/// One sample without rotor speeds, bytes (4 more per rotor).
pub const SAMPLE_BASE_LEN: usize = 32;
/// A sample's orbit (header flag bit 1), bytes.
pub const ORBIT_LEN: usize = 48;
/// The longest sample, bytes.
pub const SAMPLE_MAX_LEN: usize = SAMPLE_BASE_LEN + 4 * MAX_ROTORS + ORBIT_LEN;

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
    /// Each sample carries its time, attitude and position ([`OrbitSample`], version 6): the
    /// log is an orbiting vehicle's with a known rotor momentum, which `inertia identify`
    /// identifies with the gravity gradient folded in.
    pub orbit: bool,
    /// The gyro's readings were moved to their counts' centres from a truncation toward zero
    /// (version 6; `identifier_core::PipelineSettings::centred_readings`).
    pub centred: bool,
    /// The rotor momentum's quantum, kg m^2/s (0: taken as exact).
    pub momentum_quantum: f32,
    /// The share of each sample interval a gyro reading is the mean over (0: instants).
    pub gyro_averaging: f32,
    /// The time variance of the gyro's own low-pass filter, s^2 (0: unfiltered).
    pub gyro_smoothing: f32,
    /// Number of rotors (at most [`MAX_ROTORS`]); their table follows the fixed part.
    pub rotors: u32,
    /// Samples that follow.
    pub samples: u32,
}

impl ReplayHeader {
    /// Bytes of one sample of this replay.
    pub fn sample_len(&self) -> usize {
        let orbit = if self.orbit { ORBIT_LEN } else { 0 };
        SAMPLE_BASE_LEN + 4 * (self.rotors as usize).min(MAX_ROTORS) + orbit
    }

    /// Bytes of the rotor table.
    pub fn table_len(&self) -> usize {
        ROTOR_LEN * (self.rotors as usize).min(MAX_ROTORS)
    }
}

/// One replayed sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplaySample {
    /// Rate, rad/s.
    pub omega: [f32; 3],
    /// Specific force, m/s^2.
    pub accel: [f32; 3],
    /// Time step, s.
    pub dt: f32,
    /// An actuator acted on the body (held out).
    pub actuated: bool,
    /// Rotor speeds, rad/s, in the table's order (zero past the header's count).
    pub speeds: [f32; MAX_ROTORS],
}

/// One replayed sample's orbit (header flag bit 1): what `inertia identify` computes the
/// gravity-gradient torque from ([`identifier_core::gravity::GravityFold::step`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OrbitSample {
    /// The log's time, s.
    pub t: f64,
    /// Attitude quaternion `(w, x, y, z)`, `v_N = R(q) v_B`.
    pub attitude: [f32; 4],
    /// Position in an Earth-centred inertial frame, m.
    pub position: [f64; 3],
}

/// Why a header was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// Not a replay file.
    BadMagic,
    /// Another version.
    BadVersion(u32),
    /// More rotors than [`MAX_ROTORS`].
    TooManyRotors(u32),
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

fn put(out: &mut [u8], at: usize, word: u32) {
    for (i, x) in word.to_le_bytes().into_iter().enumerate() {
        if let Some(b) = out.get_mut(at + i) {
            *b = x;
        }
    }
}

impl ReplayHeader {
    /// Decodes the header's fixed part.
    pub fn decode(b: &[u8; HEADER_LEN]) -> Result<Self, ReplayError> {
        if b.get(0..4) != Some(&MAGIC[..]) {
            return Err(ReplayError::BadMagic);
        }
        let v = u32_at(b, 4);
        if !(OLDEST_VERSION..=VERSION).contains(&v) {
            return Err(ReplayError::BadVersion(v));
        }
        let rotors = u32_at(b, 36);
        if rotors as usize > MAX_ROTORS {
            return Err(ReplayError::TooManyRotors(rotors));
        }
        Ok(ReplayHeader {
            rate_hz: f32_at(b, 8),
            noise_std: f32_at(b, 12),
            full_scale: f32_at(b, 16),
            with_accel: u32_at(b, 20) & 1 != 0,
            // Version 5 had no bit 1.
            orbit: v >= 6 && u32_at(b, 20) & 2 != 0,
            centred: v >= 6 && u32_at(b, 20) & 4 != 0,
            momentum_quantum: f32_at(b, 24),
            gyro_averaging: f32_at(b, 28),
            gyro_smoothing: f32_at(b, 32),
            rotors,
            samples: u32_at(b, 40),
        })
    }

    /// Encodes the fixed part into `out`.
    pub fn encode(&self, out: &mut [u8; HEADER_LEN]) {
        put(out, 0, u32::from_le_bytes(MAGIC));
        put(out, 4, VERSION);
        put(out, 8, self.rate_hz.to_bits());
        put(out, 12, self.noise_std.to_bits());
        put(out, 16, self.full_scale.to_bits());
        put(
            out,
            20,
            u32::from(self.with_accel) | u32::from(self.orbit) << 1 | u32::from(self.centred) << 2,
        );
        put(out, 24, self.momentum_quantum.to_bits());
        put(out, 28, self.gyro_averaging.to_bits());
        put(out, 32, self.gyro_smoothing.to_bits());
        put(out, 36, self.rotors);
        put(out, 40, self.samples);
    }
}

/// Decodes rotor `i` of the table `b` (the bytes after the fixed part).
pub fn decode_rotor(b: &[u8], i: usize) -> Rotor {
    let at = ROTOR_LEN * i;
    Rotor::new(
        f32_at(b, at),
        [f32_at(b, at + 4), f32_at(b, at + 8), f32_at(b, at + 12)],
    )
}

/// Encodes `rotor` as entry `i` of the table `out`.
pub fn encode_rotor(rotor: &Rotor, i: usize, out: &mut [u8]) {
    let at = ROTOR_LEN * i;
    put(out, at, rotor.inertia_kg_m2.to_bits());
    for (k, a) in rotor.axis.iter().enumerate() {
        put(out, at + 4 + 4 * k, a.to_bits());
    }
}

/// Decodes one sample of a replay with `rotors` rotors (`b`: its [`ReplayHeader::sample_len`]
/// bytes).
pub fn decode_sample(b: &[u8], rotors: usize) -> ReplaySample {
    let f = |k: usize| f32_at(b, 4 * k);
    let mut speeds = [0.0f32; MAX_ROTORS];
    for (k, s) in speeds.iter_mut().take(rotors).enumerate() {
        *s = f(8 + k);
    }
    ReplaySample {
        omega: [f(0), f(1), f(2)],
        accel: [f(3), f(4), f(5)],
        dt: f(6),
        actuated: u32_at(b, 28) & 1 != 0,
        speeds,
    }
}

/// Encodes one sample with `rotors` rotors into `out` (at least [`SAMPLE_BASE_LEN`] + 4 per
/// rotor bytes); returns its length.
pub fn encode_sample(s: &ReplaySample, rotors: usize, out: &mut [u8]) -> usize {
    let rotors = rotors.min(MAX_ROTORS);
    let dt = [s.dt];
    let words = s.omega.iter().chain(s.accel.iter()).chain(dt.iter());
    for (k, x) in words.enumerate() {
        put(out, 4 * k, x.to_bits());
    }
    put(out, 28, u32::from(s.actuated));
    for (k, x) in s.speeds.iter().take(rotors).enumerate() {
        put(out, SAMPLE_BASE_LEN + 4 * k, x.to_bits());
    }
    SAMPLE_BASE_LEN + 4 * rotors
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_bits(u64::from(u32_at(b, at)) | u64::from(u32_at(b, at + 4)) << 32)
}

fn put64(out: &mut [u8], at: usize, word: u64) {
    put(out, at, word as u32);
    put(out, at + 4, (word >> 32) as u32);
}

/// Decodes the orbit of one sample of a replay with `rotors` rotors and the orbit flag (`b`:
/// its [`ReplayHeader::sample_len`] bytes).
pub fn decode_orbit(b: &[u8], rotors: usize) -> OrbitSample {
    let at = SAMPLE_BASE_LEN + 4 * rotors.min(MAX_ROTORS);
    OrbitSample {
        t: f64_at(b, at),
        attitude: [
            f32_at(b, at + 8),
            f32_at(b, at + 12),
            f32_at(b, at + 16),
            f32_at(b, at + 20),
        ],
        position: [f64_at(b, at + 24), f64_at(b, at + 32), f64_at(b, at + 40)],
    }
}

/// Encodes the orbit `o` after the rotor speeds of a sample with `rotors` rotors in `out`
/// (at least [`SAMPLE_BASE_LEN`] + 4 per rotor + [`ORBIT_LEN`] bytes); returns the sample's
/// length.
pub fn encode_orbit(o: &OrbitSample, rotors: usize, out: &mut [u8]) -> usize {
    let at = SAMPLE_BASE_LEN + 4 * rotors.min(MAX_ROTORS);
    put64(out, at, o.t.to_bits());
    for (k, q) in o.attitude.iter().enumerate() {
        put(out, at + 8 + 4 * k, q.to_bits());
    }
    for (k, r) in o.position.iter().enumerate() {
        put64(out, at + 24 + 8 * k, r.to_bits());
    }
    at + ORBIT_LEN
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn header_rotors_and_samples_round_trip() {
        let h = ReplayHeader {
            rate_hz: 10.0,
            noise_std: 1e-4,
            full_scale: 34.9,
            with_accel: false,
            orbit: false,
            centred: false,
            momentum_quantum: 2.5e-7,
            gyro_averaging: 0.0,
            gyro_smoothing: 1e-6,
            rotors: 3,
            samples: 72_000,
        };
        let mut b = [0u8; HEADER_LEN];
        h.encode(&mut b);
        assert_eq!(ReplayHeader::decode(&b), Ok(h));
        assert_eq!((h.sample_len(), h.table_len()), (44, 48));
        let r = Rotor::new(2.4e-5, [0.0, 0.6, -0.8]);
        let mut t = [0u8; 48];
        encode_rotor(&r, 2, &mut t);
        assert_eq!(decode_rotor(&t, 2), r);
        let mut speeds = [0.0; MAX_ROTORS];
        speeds[..3].copy_from_slice(&[100.0, -5.5, 0.25]);
        let s = ReplaySample {
            omega: [0.1, -0.2, 0.3],
            accel: [0.0; 3],
            dt: 0.1,
            actuated: true,
            speeds,
        };
        let mut out = [0u8; SAMPLE_MAX_LEN];
        assert_eq!(encode_sample(&s, 3, &mut out), 44);
        assert_eq!(decode_sample(&out[..44], 3), s);
        // Wrong magic, version, rotor count: refused.
        let mut bad = b;
        bad[0] = b'X';
        assert_eq!(ReplayHeader::decode(&bad), Err(ReplayError::BadMagic));
        let mut bad = b;
        bad[4] = 4;
        assert_eq!(ReplayHeader::decode(&bad), Err(ReplayError::BadVersion(4)));
        let mut bad = b;
        bad[36] = 9;
        assert_eq!(
            ReplayHeader::decode(&bad),
            Err(ReplayError::TooManyRotors(9))
        );
        let mut bad = b;
        bad[4] = 7;
        assert_eq!(ReplayHeader::decode(&bad), Err(ReplayError::BadVersion(7)));
    }

    #[test]
    fn orbit_round_trips_and_version_5_is_read() {
        let h = ReplayHeader {
            rate_hz: 1.0,
            noise_std: 1e-4,
            full_scale: f32::INFINITY,
            with_accel: false,
            orbit: true,
            centred: false,
            momentum_quantum: 0.0,
            gyro_averaging: 0.0,
            gyro_smoothing: 0.0,
            rotors: 4,
            samples: 11_355,
        };
        let mut b = [0u8; HEADER_LEN];
        h.encode(&mut b);
        assert_eq!(ReplayHeader::decode(&b), Ok(h));
        assert_eq!(h.sample_len(), 32 + 16 + ORBIT_LEN);
        let o = OrbitSample {
            t: 11_354.000_000_1,
            attitude: [0.866_275_6, 0.376_985_44, 0.174_203_62, -0.277_671_86],
            position: [5_491_727.76, 4_032_680.86, -941_899.308],
        };
        let mut speeds = [0.0; MAX_ROTORS];
        speeds[..4].copy_from_slice(&[100.0, -149.6, 200.0, -49.7]);
        let s = ReplaySample {
            omega: [0.012, -0.018, 0.015],
            accel: [0.0; 3],
            dt: 1.0,
            actuated: false,
            speeds,
        };
        let mut out = [0u8; SAMPLE_MAX_LEN];
        assert_eq!(encode_sample(&s, 4, &mut out), 48);
        assert_eq!(encode_orbit(&o, 4, &mut out), h.sample_len());
        let l = h.sample_len();
        assert_eq!(decode_sample(&out[..l], 4), s);
        assert_eq!(decode_orbit(&out[..l], 4), o);
        // A version 5 file: its flag bit 1 (unused then) does not make it an orbit.
        let mut v5 = b;
        v5[4] = 5;
        let d = ReplayHeader::decode(&v5).unwrap();
        assert!(!d.orbit);
        assert_eq!(d.sample_len(), 48);
        assert_eq!(ReplayHeader { orbit: true, ..d }, h);
        // Centred readings (flag bit 2) round-trip, and do not change a sample's length.
        let c = ReplayHeader { centred: true, ..h };
        c.encode(&mut b);
        assert_eq!(b[20], 0b110);
        assert_eq!(ReplayHeader::decode(&b), Ok(c));
        assert_eq!(c.sample_len(), h.sample_len());
    }
}
