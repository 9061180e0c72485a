//! The sample loop and what goes with it: one gyro sample, one step of each identifier (the
//! paper's and the refined one beside it); a report of both every 100 ms.
//!
//! One concern per module, all re-exported here (`crate::app::X`):
//! * [`settings`]: the estimators' settings for the configured gyro;
//! * [`rotor`]: the board's inputs besides the IMU (rotor speeds, actuator flags);
//! * [`clock`]: the sample clock and a delay that does not wait;
//! * [`health`]: when the sensor is re-initialised or checked;
//! * [`rate_check`]: the rate-jump check on samples (the plausibility gate);
//! * [`sample_loop`]: the loop itself;
//! * [`fits`]: the end-of-flight fits off the sample path (a fit slot, a stepper);
//! * [`report`]: what it reports; `log` writes a report as defmt lines.

pub mod clock;
pub mod fits;
pub mod health;
#[cfg(feature = "defmt")]
pub mod log;
pub mod rate_check;
pub mod report;
pub mod rotor;
pub mod sample_loop;
pub mod settings;

pub use clock::{NoDelay, SampleClock};
pub use fits::{read_into_ring, FitJob, FitKind, FitScheduler, RingRead, StepStats, Stepper};
pub use health::{SensorStatus, HEALTH_EVERY, REINIT_AFTER, STALLED_AFTER};
#[cfg(feature = "defmt")]
pub use log::{log_report, log_tensor};
pub use rate_check::{gate_rate_bound, GATE_MARGIN, GATE_RATE_MARGIN, GATE_RELEARN};
pub use report::{LoopCounters, Report, TensorReport, FAILED_REPORT_AFTER, REPORT_HZ};
pub use rotor::{BoardInputs, NoBoardInputs};
pub use sample_loop::{
    InitError, Poll, SampleInputs, SampleLoop, SampleRecord, Unread, INIT_ATTEMPTS, POLL_US,
};
pub use settings::{
    identifier_settings, pipeline_settings, refined_settings, GYRO_NOISE_DENSITY_DPS,
};
