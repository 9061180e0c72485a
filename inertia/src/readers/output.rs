//! What every reader gives: a [`Recording`] held whole, or a [`Source`] read sample by sample.
//! The layers above take them from here (re-exported as [`crate::recording`]'s and
//! [`crate::source`]'s).

use super::gyro_filters::GyroFilters;
use super::ReadError;

/// Rotor speed as a log gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum RotorSpeed {
    /// Electrical revolutions per minute (the ESC telemetry's eRPM, already scaled to true
    /// eRPM): mechanical rad/s = `erpm / (poles / 2) * 2 pi / 60`.
    Erpm(Vec<f32>),
    /// Mechanical speed, rad/s.
    RadPerSec(Vec<f32>),
}

impl RotorSpeed {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            RotorSpeed::Erpm(v) | RotorSpeed::RadPerSec(v) => v.len(),
        }
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Mechanical speed in rad/s; `poles` is needed for eRPM (`None` when it is missing or
    /// zero for an eRPM channel).
    pub fn rad_per_sec(&self, poles: Option<u32>) -> Option<Vec<f32>> {
        match self {
            RotorSpeed::RadPerSec(v) => Some(v.clone()),
            RotorSpeed::Erpm(v) => {
                let k = Self::erpm_factor(poles)?;
                Some(v.iter().map(|e| e * k).collect())
            }
        }
    }

    /// The factor from eRPM to mechanical rad/s, `2 pi / 60 / (poles / 2)` (`None` when
    /// `poles` is missing or below 2).
    pub fn erpm_factor(poles: Option<u32>) -> Option<f32> {
        let pairs = poles.filter(|&p| p >= 2)? as f32 / 2.0;
        Some(2.0 * core::f32::consts::PI / 60.0 / pairs)
    }
}

/// A gyro log in SI units: `t` in seconds (strictly increasing), `gyro` in rad/s, `accel` in
/// m/s^2 (specific force, as an accelerometer reads it), all in the log's sensor axes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// Where it came from (file and format), for messages.
    pub source: String,
    /// Sample times, seconds, strictly increasing.
    pub t: Vec<f64>,
    /// Angular rate, rad/s.
    pub gyro: Vec<[f32; 3]>,
    /// Specific force, m/s^2, same length as `gyro` when present.
    pub accel: Option<Vec<[f32; 3]>>,
    /// Rotor (flywheel, motor) speed of the first rotor, same length as `gyro` when present.
    pub rotor: Option<RotorSpeed>,
    /// The vehicle file's rotor columns, in its order, as logged (one vector per column, each
    /// as long as `gyro`; empty without a vehicle file).
    pub wheels: Vec<Vec<f32>>,
    /// Attitude quaternions `(qw, qx, qy, qz)`, `v_N = R(q) v_B`, when the log has them.
    pub attitude: Option<Vec<[f32; 4]>>,
    /// Positions in an Earth-centred inertial frame, m, when the log has them.
    pub position: Option<Vec<[f64; 3]>>,
    /// Magnetometer in the body frame, T, when the log has it.
    pub magnetic: Option<Vec<[f32; 3]>>,
    /// Gyro full scale in rad/s when the log states it (saturation detection), else infinite.
    pub gyro_full_scale: f32,
    /// Each gyro sample is the mean rate over a window of this fraction of the sample
    /// interval, centred on its time (PX4's `sensor_combined`: the rate integrated over the
    /// sampling period, 1 when every period is logged); 0 for readings at instants (every
    /// other format). The fits count the window's time spread
    /// (`identifier_core::PipelineSettings::with_averaging_gyro`).
    pub gyro_averaging: f32,
    /// The low-pass filters the logged gyro has passed through (`None` for an unfiltered
    /// gyro: every format but Betaflight's blackbox). The reader has already taken their delay
    /// out of the rates; the fits count their time variance in their block means
    /// ([`Recording::gyro_smoothing`]) and the noise the fits assume is their white
    /// equivalent ([`crate::recording::white_noise`]).
    pub gyro_filters: Option<GyroFilters>,
    /// The gyro's unit is known: fixed by the format (blackbox by its firmware, ULog, phyphox)
    /// or declared (`--gyro-unit`), not assumed (a CSV without it is taken as rad/s). Only an
    /// assumed unit is questioned by the ratios' unit check
    /// ([`crate::readers::ratios_warning`]).
    pub gyro_unit_stated: bool,
    /// Warnings raised while reading (unit guesses, skipped rows), for the user.
    pub warnings: Vec<String>,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// The most rotor-speed columns a vehicle file may name ([`crate::vehicle`]), as the core's
/// fixed bound.
pub const MAX_WHEELS: usize = identifier_core::MAX_ROTORS;

/// What a sample may carry beyond the gyro, the accelerometer and the first rotor: the speeds
/// of the columns a vehicle file names, and a spacecraft log's attitude, position and
/// magnetometer ([`Channels`] says which are present; absent ones are zero).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Extra {
    /// The vehicle file's rotor columns, in its order, as logged (its unit).
    pub wheels: [f32; MAX_WHEELS],
    /// Attitude quaternion `(qw, qx, qy, qz)`, scalar first: `v_N = R(q) v_B`.
    pub attitude: [f32; 4],
    /// Position in an Earth-centred inertial frame, m.
    pub position: [f64; 3],
    /// Magnetometer in the body frame, T.
    pub magnetic: [f32; 3],
}

/// One sample: time (s), rate (rad/s), specific force (m/s^2; zero without an accelerometer)
/// and the rotor speed in the channel's own unit ([`Channels::rotor`]; zero without one).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// Rate, rad/s.
    pub gyro: [f32; 3],
    /// Specific force, m/s^2.
    pub accel: [f32; 3],
    /// Rotor speed as logged (eRPM or rad/s).
    pub rotor: f32,
    /// Vehicle rotors and spacecraft columns.
    pub extra: Extra,
}

/// The unit of a rotor-speed channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotorUnit {
    /// Electrical revolutions per minute (see [`RotorSpeed::Erpm`]).
    Erpm,
    /// Mechanical rad/s.
    RadPerSec,
}

impl RotorUnit {
    /// The unit of a channel.
    pub fn of(r: &RotorSpeed) -> Self {
        match r {
            RotorSpeed::Erpm(_) => RotorUnit::Erpm,
            RotorSpeed::RadPerSec(_) => RotorUnit::RadPerSec,
        }
    }

    /// A channel of this unit holding `v`.
    pub fn wrap(self, v: Vec<f32>) -> RotorSpeed {
        match self {
            RotorUnit::Erpm => RotorSpeed::Erpm(v),
            RotorUnit::RadPerSec => RotorSpeed::RadPerSec(v),
        }
    }

    /// How a logged value becomes mechanical rad/s: `Some(None)` as it is, `Some(Some(k))`
    /// times `k` (the factor [`RotorSpeed::rad_per_sec`] uses), `None` for eRPM without
    /// usable `poles`.
    pub fn factor(self, poles: Option<u32>) -> Option<Option<f32>> {
        match self {
            RotorUnit::RadPerSec => Some(None),
            RotorUnit::Erpm => RotorSpeed::erpm_factor(poles).map(Some),
        }
    }
}

/// Which channels a log has besides time and gyro.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Channels {
    /// An accelerometer.
    pub accel: bool,
    /// A rotor-speed channel, and its unit.
    pub rotor: Option<RotorUnit>,
    /// The vehicle file's rotor columns read ([`Extra::wheels`]).
    pub wheels: usize,
    /// Attitude quaternion columns ([`Extra::attitude`]).
    pub attitude: bool,
    /// Position columns ([`Extra::position`]).
    pub position: bool,
    /// Magnetometer columns ([`Extra::magnetic`]).
    pub magnetic: bool,
}

/// What one reading found beyond the samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reading {
    /// Samples given.
    pub samples: usize,
    /// The warning about dropped duplicate timestamps, if any were dropped.
    pub duplicates: Option<String>,
}

/// Whether a reading goes on after a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// The next sample, please.
    Continue,
    /// Enough: the reading ends here (without the end-of-log checks).
    Stop,
}

/// A sample visitor.
pub type Visit<'a> = dyn FnMut(&Sample) -> Result<Flow, ReadError> + 'a;

/// A log that can be read sample by sample, any number of times, with the same samples each
/// time (from any thread).
pub trait Source: Sync {
    /// The file and format, for messages and the report (`"FILE (csv)"`).
    fn name(&self) -> String;
    /// The channels besides time and gyro.
    fn channels(&self) -> Channels;
    /// The gyro's full scale, rad/s (infinite when the log does not state it).
    fn full_scale(&self) -> f32;
    /// [`Recording::gyro_averaging`]: the fraction of each sample interval the gyro's reading
    /// is the mean over (0, the default: readings at instants).
    fn gyro_averaging(&self) -> f32 {
        0.0
    }
    /// [`Recording::gyro_filters`]: the filters the logged gyro has passed through (`None`,
    /// the default: an unfiltered gyro).
    fn gyro_filters(&self) -> Option<GyroFilters> {
        None
    }
    /// [`Recording::gyro_unit_stated`]: whether the gyro's unit is known (fixed by the format
    /// or declared by the user) rather than assumed (a CSV without `--gyro-unit`). True by
    /// default.
    fn gyro_unit_stated(&self) -> bool {
        true
    }
    /// Whether the gyro's readings come moved to their counts' centres ((Q1) of
    /// [`crate::grid`]). False by default.
    fn gyro_centred(&self) -> bool {
        false
    }
    /// One reading: `visit` gets every sample in order (until it says [`Flow::Stop`]);
    /// `progress` now and then the fraction of the log read. A malformed log fails with the
    /// error [`crate::read`] gives for it; an error of `visit` ends the reading with that
    /// error.
    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError>;
    /// The warnings [`crate::read`] puts in [`Recording::warnings`], given `found`: the
    /// duplicates warning of a reading (if any) followed by the unit warnings.
    fn warnings(&self, found: Vec<String>) -> Vec<String>;
}
