//! The rate-jump check on gyro samples (called the plausibility gate in the counters and the
//! docs; not identifier-core's free-flight gate).

use icm42688::Config;

/// The plausibility gate's noise margin, rad/s: about 20 times the gyro's noise at 1 kHz.
pub const GATE_MARGIN: f32 = 0.02;
/// Margin on the last accepted rates in the gate's bound, rad/s: `|w_i'| <= (max |w| +
/// margin)^2` (at most the full-scale bound [`gate_rate_bound`]). With +-2000 dps the
/// full-scale bound alone (1218 rad/s^2) lets flipped bits up to 1.2 rad/s through.
pub const GATE_RATE_MARGIN: f32 = 2.0;
/// Consecutive gate refusals after which the sample is accepted as real motion.
pub const GATE_RELEARN: u32 = 3;

/// The plausibility gate's bound on the rate of change of each gyro component, rad/s^2, for a
/// gyro configured with `config`: torque-free, `|w_i'| = |a_i w_j w_k| <= fs^2` since
/// `|a_i| <= 1` and every rate is within the full scale `fs` (76 rad/s^2 at 500 dps). A sample
/// whose change from the last accepted one exceeds `bound * (time since it) + GATE_MARGIN`
/// cannot come from the motion: a flipped bit, a glitch on the bus.
pub fn gate_rate_bound(config: &Config) -> f32 {
    let fs = icm42688::raw_to_rad_s(32767, config.full_scale);
    fs * fs
}
