//! The on-board tensor estimator ([`identifier_core::TensorEstimator`]) as a method of the
//! ratio benchmark: fed omega with no rotor momentum (`h = 0`), settings from
//! [`TensorSettings::for_rate`] (the sample rate and the gyro's noise), the model (full tensor
//! or principal axes) chosen by the estimator itself; its `a` and `std_a` are reported.

use super::{ekf::noise_from_data, Method};
use identifier_core::{TensorEstimate, TensorEstimator, TensorModel, TensorSettings};

/// `dt` for sample `k` (the nominal period for the first sample).
fn dt_at(t: &[f64], k: usize) -> f32 {
    let nominal = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
    if k == 0 {
        nominal as f32
    } else {
        (t[k] - t[k - 1]) as f32
    }
}

/// [`TensorEstimator`] with `h = 0` on every sample.
#[derive(Default)]
pub struct TensorMethod;

/// One run: the estimates at `checkpoints` (ascending sample indices) with the gyro noise
/// `sigma` (rad/s) given to [`TensorSettings::for_rate`].
pub fn run(t: &[f64], y: &[[f64; 3]], sigma: f64, checkpoints: &[usize]) -> Vec<TensorEstimate> {
    let dt = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
    let settings = TensorSettings::for_rate((1.0 / dt) as f32, sigma as f32);
    let Some(mut e) = TensorEstimator::new(settings) else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(checkpoints.len());
    let mut next = checkpoints.iter().peekable();
    for (k, w) in y.iter().enumerate() {
        e.step(w.map(|x| x as f32), [0.0; 3], dt_at(t, k));
        while next.peek().is_some_and(|&&c| c == k) {
            out.push(e.estimate());
            next.next();
        }
    }
    out
}

/// `a` of an estimate, NaN when none was given.
pub fn a_of(e: &TensorEstimate) -> [f64; 3] {
    e.a.map_or([f64::NAN; 3], |a| a.map(f64::from))
}

/// `std_a` of an estimate, NaN when none was given.
pub fn std_a_of(e: &TensorEstimate) -> [f64; 3] {
    e.std_a.map_or([f64::NAN; 3], |a| a.map(f64::from))
}

/// True when the estimate used the principal-axis model.
pub fn is_principal(e: &TensorEstimate) -> bool {
    e.model == TensorModel::Principal
}

impl Method for TensorMethod {
    fn name(&self) -> &'static str {
        "tensor estimator (h = 0, model chosen)"
    }
    fn onboard(&self) -> bool {
        true
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        self.curve(t, y, &[t.len() - 1])[0]
    }
    fn estimate_with_std(
        &self,
        t: &[f64],
        y: &[[f64; 3]],
        sigma: f64,
    ) -> ([f64; 3], Option<[f64; 3]>) {
        match run(t, y, sigma, &[t.len() - 1]).first() {
            Some(e) => (a_of(e), Some(std_a_of(e))),
            None => ([f64::NAN; 3], Some([f64::NAN; 3])),
        }
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        // Without a declared noise level, the noise from the data (as the EKF peer does).
        let sigma = noise_from_data(y);
        let mut out: Vec<[f64; 3]> = run(t, y, sigma, checkpoints).iter().map(a_of).collect();
        out.resize(checkpoints.len(), [f64::NAN; 3]);
        out
    }
}
