//! The rate-jump check on gyro samples: a sample whose rates jumped further from the last
//! accepted ones than a torque-free motion could is refused. Its public names keep the older
//! word "gate" (`GATE_*`, [`gate_rate_bound`], the `implausible` counter); it is not
//! identifier-core's free-flight gate, which the pipeline runs on the accepted samples.

use icm42688::Config;

/// The rate-jump check's noise margin, rad/s: about 20 times the gyro's noise at 1 kHz.
pub const GATE_MARGIN: f32 = 0.02;
/// Margin on the last accepted rates in the check's bound, rad/s: `|w_i'| <= (max |w| +
/// margin)^2` (at most the full-scale bound [`gate_rate_bound`]). With +-2000 dps the
/// full-scale bound alone (1218 rad/s^2) lets flipped bits up to 1.2 rad/s through.
pub const GATE_RATE_MARGIN: f32 = 2.0;
/// Consecutive refusals by the rate-jump check after which the sample is accepted as real motion.
pub const GATE_RELEARN: u32 = 3;

/// The rate-jump check's bound on the rate of change of each gyro component, rad/s^2, for a
/// gyro configured with `config`: torque-free, `|w_i'| = |a_i w_j w_k| <= fs^2` since
/// `|a_i| <= 1` and every rate is within the full scale `fs` (76 rad/s^2 at 500 dps). A sample
/// whose change from the last accepted one exceeds `bound * (time since it) + GATE_MARGIN`
/// cannot come from the motion: a flipped bit, a glitch on the bus.
pub fn gate_rate_bound(config: &Config) -> f32 {
    let fs = icm42688::raw_to_rad_s(32767, config.full_scale);
    fs * fs
}

/// The rate-jump check's state: the last accepted rates, the time since them and the refusals
/// in a row. A sample whose change from the last accepted one no torque-free motion within the
/// full scale could make is refused, unless [`GATE_RELEARN`] refusals in a row say that the
/// motion is real (a torque the bound did not foresee).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RateCheck {
    /// The full-scale bound, rad/s^2 ([`gate_rate_bound`]).
    bound: f32,
    last_accepted: Option<[f32; 3]>,
    /// Seconds since the last accepted sample.
    since_accepted: f32,
    /// Consecutive refusals.
    refusals: u32,
}

impl RateCheck {
    /// A check with nothing accepted yet, for a gyro configured with `config`.
    pub(crate) fn new(config: &Config) -> Self {
        RateCheck {
            bound: gate_rate_bound(config),
            last_accepted: None,
            since_accepted: 0.0,
            refusals: 0,
        }
    }

    /// Checks the rates `omega` read `dt` s after the previous sample: `None` when refused
    /// (its time is carried to the next sample), else the seconds since the last accepted
    /// sample (refused ones included), the step the free-flight pipeline gets.
    pub(crate) fn check(&mut self, omega: [f32; 3], dt: f32) -> Option<f32> {
        self.since_accepted += dt;
        if let Some(prev) = self.last_accepted {
            // Torque-free, |w_i'| <= |w_j| |w_k|: bounded by the last accepted rates (plus
            // GATE_RATE_MARGIN for their growth), and by the full scale.
            let m = prev.iter().fold(0.0f32, |m, p| m.max(p.abs())) + GATE_RATE_MARGIN;
            let limit = self.bound.min(m * m) * self.since_accepted + GATE_MARGIN;
            let refused = omega.iter().zip(prev).any(|(w, p)| (w - p).abs() > limit);
            self.refusals = if refused {
                self.refusals.saturating_add(1)
            } else {
                0
            };
            // A glitch is one sample; GATE_RELEARN refusals in a row are a real motion the
            // bound did not foresee (a torque): accepted, and the check starts from there.
            if refused && self.refusals < GATE_RELEARN {
                return None;
            }
        }
        self.refusals = 0;
        self.last_accepted = Some(omega);
        let since = self.since_accepted;
        self.since_accepted = 0.0;
        Some(since)
    }

    /// Forgets the last accepted sample (the sensor was re-initialised): the next sample is
    /// accepted and the check starts from it.
    pub(crate) fn restart(&mut self) {
        self.last_accepted = None;
        self.since_accepted = 0.0;
    }
}
