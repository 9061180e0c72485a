//! What `inertia identify` reports for a gyro-only log, as a method of the ratio benchmark:
//! the shared [`FlightPipeline`] without accelerometer (every sample is free flight), its
//! recommended ratios ([`FlightPipeline::ratios`]: the trajectory fit once the record has
//! ended and the model fits, else the refined identifier, its bias-augmented twin or the
//! tensor) with their standard deviations.

use super::{ekf::noise_from_data, Method};
use identifier_core::{FlightPipeline, PipelineSettings, Ratios, TensorEstimate};

/// The pipeline's recommended ratios.
#[derive(Default)]
pub struct PipelineRatios;

/// The pipeline fed `y`, ended at each checkpoint as a log that stops there: its tensor
/// estimate and recommended ratios there.
fn run(
    t: &[f64],
    y: &[[f64; 3]],
    sigma: f64,
    checkpoints: &[usize],
) -> Vec<(TensorEstimate, Ratios)> {
    let dt = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
    let settings = PipelineSettings::for_rate((1.0 / dt) as f32, sigma as f32);
    let Some(mut p) = FlightPipeline::new(settings, false) else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(checkpoints.len());
    let mut next = checkpoints.iter().peekable();
    for (k, w) in y.iter().enumerate() {
        let step = if k == 0 { dt } else { t[k] - t[k - 1] };
        p.step(w.map(|x| x as f32), [0.0; 3], [0.0; 3], step as f32);
        while next.peek().is_some_and(|&&c| c == k) {
            let mut q = p;
            q.end_stretch();
            out.push(q.estimate_and_ratios());
            next.next();
        }
    }
    out
}

/// The pipeline's tensor estimate after feeding all of `y` and ending the flight (what
/// `inertia identify` reports for a gyro-only log).
pub fn normalized_tensor(t: &[f64], y: &[[f64; 3]], sigma: f64) -> Option<TensorEstimate> {
    let last = y.len().checked_sub(1)?;
    run(t, y, sigma, &[last]).first().map(|(e, _)| *e)
}

fn a_of(r: &Ratios) -> [f64; 3] {
    r.a.map_or([f64::NAN; 3], |a| a.map(f64::from))
}

impl Method for PipelineRatios {
    fn name(&self) -> &'static str {
        "pipeline ratios (what inertia identify reports)"
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
        match run(t, y, sigma, &[t.len() - 1]).first().map(|(_, r)| r) {
            Some(r) => (
                a_of(r),
                Some(r.std_a.map_or([f64::NAN; 3], |s| s.map(f64::from))),
            ),
            None => ([f64::NAN; 3], Some([f64::NAN; 3])),
        }
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let sigma = noise_from_data(y);
        let mut out: Vec<[f64; 3]> = run(t, y, sigma, checkpoints)
            .iter()
            .map(|(_, r)| a_of(r))
            .collect();
        out.resize(checkpoints.len(), [f64::NAN; 3]);
        out
    }
}
