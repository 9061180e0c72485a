//! The paper's numerical experiment (section 4, Fig. 1), shared by the tests and the figure.
//!
//! The paper gives the body, `C = -lambda E` and the two gains but not the initial angular
//! velocity; we use `omega0 = (1, 1, 1)` rad/s. From there the body (intermediate axis `A3`)
//! tumbles and `w1 w2 w3` changes sign four times in `[0, 7]` s.

use crate::gyro::GyroModel;
use crate::replay::{self, Run};
use crate::rigid_body::Body;
use identifier_core::{Settings, SignChangeCorrection};

/// `A = (0.6, 1.54, 1.0)`: `a = (0.9, 0.2597, -0.94)`.
pub const INERTIA: [f64; 3] = [0.6, 1.54, 1.0];
/// Our choice of initial angular velocity, rad/s.
pub const OMEGA0: [f64; 3] = [1.0, 1.0, 1.0];
/// Fig. 1 spans `t` in `[0, 7]` s.
pub const DURATION: f64 = 7.0;
/// Sample rate of the simulated gyro, Hz.
pub const RATE_HZ: f64 = 1000.0;
/// Accuracy `eps` of the criterion used for Fig. 1 (the paper states none).
pub const EPS: f32 = 5e-3;
/// Interval `h` of the criterion, seconds.
pub const H: f32 = 1.0;

/// The paper's body.
pub fn body() -> Body {
    Body::free(INERTIA)
}

/// Settings of Fig. 1 for a gain `lambda` and a choice of sign-change treatment.
pub fn settings(lambda: f32, sign_change: SignChangeCorrection) -> Settings {
    Settings {
        sign_change,
        eps: EPS,
        h: H,
        ..Settings::with_lambda(lambda)
    }
}

/// Runs the identifier on the noise-free Fig. 1 motion.
pub fn fig1_run(lambda: f32, sign_change: SignChangeCorrection) -> Run {
    let tr = body().simulate(OMEGA0, DURATION, RATE_HZ, 10);
    let meas = GyroModel::ideal().measure(&tr);
    replay::run(settings(lambda, sign_change), &tr.t, &meas)
}
