//! One [`Recording`] comes out of every reader: time, gyro, and the optional accelerometer and
//! rotor-speed channels, in SI units and in the log's own sensor axes (as logged, never
//! re-oriented: the tensor is reported in that frame). The type is the readers' own
//! ([`crate::readers`] make it), re-exported here with the statistics the layers
//! above take from a recording: its median time step ([`median_dt`]) and its gyro noise
//! ([`estimate_noise`], [`white_noise`]).

use crate::readers::gyro_filters::GyroFilters;
pub use crate::readers::{Recording, RotorSpeed};

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
