//! One [`Recording`] comes out of every reader: time, gyro, and the optional accelerometer and
//! rotor-speed channels, in SI units and in the log's own sensor axes (as logged, never
//! re-oriented: the tensor is reported in that frame). Here too the statistics the layers
//! above take from a recording: its median time step ([`median_dt`]) and its gyro noise
//! ([`estimate_noise`], [`white_noise`]).

use crate::readers::gyro_filters::GyroFilters;

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
    /// equivalent ([`white_noise`]).
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
    /// The time variance of the gyro's filters and of the reader's interpolation, s^2 (0
    /// without filters), as the fits take it
    /// (`identifier_core::PipelineSettings::with_filtered_gyro`; [`GyroFilters::smoothing`]
    /// at the median time step).
    pub fn gyro_smoothing(&self) -> f32 {
        self.gyro_filters
            .as_ref()
            .map_or(0.0, |f| f.smoothing(median_dt(&self.t)) as f32)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Median time step of the recording, s.
pub fn median_dt(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    d[d.len() / 2]
}

/// Gyro white noise estimated from the data: the median absolute third difference per axis
/// (third differences cancel any quadratic motion; for white noise their variance is
/// `20 sigma^2`), turned into a standard deviation, smallest over the axes. Floored at
/// `1e-4 rad/s`.
pub fn estimate_noise(gyro: &[[f32; 3]]) -> f32 {
    noise_from_medians((0..3).map(|ax| {
        let mut d: Vec<f32> = gyro
            .windows(4)
            .map(|w| (w[3][ax] - 3.0 * w[2][ax] + 3.0 * w[1][ax] - w[0][ax]).abs())
            .filter(|x| x.is_finite())
            .collect();
        d.sort_by(|a, b| a.total_cmp(b));
        d.get(d.len() / 2).copied()
    }))
}

/// The white noise the fits assume, from the noise `measured` by [`estimate_noise`] on a log
/// of step `log_dt` whose gyro has passed through `filters` ((G2) of
/// [`GyroFilters::white_noise`]); `measured` itself without filters.
pub fn white_noise(measured: f32, filters: Option<&GyroFilters>, log_dt: f64) -> f32 {
    match filters {
        Some(f) => f.white_noise(f64::from(measured), log_dt) as f32,
        None => measured,
    }
}

/// The noise from each axis's median absolute third difference (`None` for an axis without
/// one): the median turned into a standard deviation (third differences of white noise have
/// variance `20 sigma^2`), smallest over the axes, floored at `1e-4 rad/s`; `2e-3` when no axis
/// has a difference. Shared by [`estimate_noise`] and the streaming survey, so both give the
/// same bits.
pub(crate) fn noise_from_medians(medians: impl IntoIterator<Item = Option<f32>>) -> f32 {
    let mut best = f32::INFINITY;
    for mad in medians.into_iter().flatten() {
        let s = mad / 0.6745 / 20f32.sqrt();
        if s < best {
            best = s;
        }
    }
    if best.is_finite() {
        best.max(1e-4)
    } else {
        2e-3
    }
}
