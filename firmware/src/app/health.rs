//! Sensor health: when the sensor is re-initialised or checked, and its state in a report.

use icm42688::RawImu;

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

/// The sensor's health as the loop tracks it: consecutive failures, the run of identical raw
/// samples (stalled data) and the samples since the last `WHO_AM_I` check.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SensorHealth {
    /// Consecutive failures.
    fails: u32,
    last_raw: Option<RawImu>,
    /// Repeats of `last_raw` in a row.
    repeats: u32,
    /// Accepted samples since the last `WHO_AM_I` check.
    since_check: u32,
}

impl SensorHealth {
    /// One more consecutive failure; true when there have been [`REINIT_AFTER`] of them.
    pub(crate) fn failure(&mut self) -> bool {
        self.fails = self.fails.saturating_add(1);
        self.fails >= REINIT_AFTER
    }

    /// A sample went through: the failures in a row end.
    pub(crate) fn sample_ok(&mut self) {
        self.fails = 0;
    }

    /// True when `imu` makes the data stalled: [`STALLED_AFTER`] repeats of the same six
    /// counts. A clipped gyro axis (`gyro_saturated`) is saturation, not a stall: such samples
    /// neither count nor break a run.
    pub(crate) fn stalled(&mut self, imu: RawImu, gyro_saturated: bool) -> bool {
        if gyro_saturated {
            self.repeats = 0;
            self.last_raw = None;
        } else if self.last_raw == Some(imu) {
            self.repeats = self.repeats.saturating_add(1);
            if self.repeats >= STALLED_AFTER {
                return true;
            }
        } else {
            self.repeats = 0;
            self.last_raw = Some(imu);
        }
        false
    }

    /// One more accepted sample; true when the `WHO_AM_I` check is due (every
    /// [`HEALTH_EVERY`]).
    pub(crate) fn check_due(&mut self) -> bool {
        self.since_check = self.since_check.saturating_add(1);
        if self.since_check >= HEALTH_EVERY {
            self.since_check = 0;
            true
        } else {
            false
        }
    }

    /// The sensor was re-initialised: failures and the stall run start afresh (the `WHO_AM_I`
    /// schedule runs on).
    pub(crate) fn restart(&mut self) {
        self.last_raw = None;
        self.repeats = 0;
        self.fails = 0;
    }
}

/// The sensor's state in a report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorStatus {
    /// Samples are coming in.
    Ok,
    /// No sample for more than [`FAILED_REPORT_AFTER`](super::FAILED_REPORT_AFTER) report
    /// periods: bus errors, timeouts, invalid samples or re-initialisations. Reports go on at
    /// [`REPORT_HZ`](super::REPORT_HZ) with the estimates held and the counters moving.
    Failed,
}
