//! Sensor health: when the sensor is re-initialised or checked, and its state in a report.

/// Consecutive failures (bus errors, data-ready timeouts, samples the part marked invalid)
/// after which the sensor is re-initialised.
pub const REINIT_AFTER: u32 = 5;
/// Identical consecutive raw samples (all three gyro axes) after which the data counts as
/// stalled and the sensor is re-initialised. With the part's noise (about 1 count rms at 1 kHz
/// and 2000 dps, and the accelerometer's noise beside it) twenty repeats of all six axes
/// practically never happen on live data. Samples with a clipped gyro axis are saturated, not
/// stalled: they never count toward this (a body spinning beyond the range on all three axes
/// reads the same clipped counts again and again, and must not reset the part).
pub const STALLED_AFTER: u32 = 20;
/// `WHO_AM_I` is checked every this many accepted samples (10 times a second at 1 kHz).
pub const HEALTH_EVERY: u32 = 100;

/// The sensor's state in a report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorStatus {
    /// Samples are coming in.
    Ok,
    /// No sample for more than [`FAILED_REPORT_AFTER`] report periods: bus errors, timeouts,
    /// invalid samples or re-initialisations. Reports go on at [`REPORT_HZ`](super::REPORT_HZ) with the
    /// estimates held and the counters moving.
    Failed,
}

/// Report periods without a sample after which a report goes out anyway, marked
/// [`SensorStatus::Failed`] (1.5: the normal stream is late by half a period).
pub const FAILED_REPORT_AFTER: f32 = 1.5;
