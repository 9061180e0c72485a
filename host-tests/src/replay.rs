//! Drives the on-board `identifier-core` over a sampled log, exactly as the firmware does:
//! one `step` per sample, `f32` in, `dt` from consecutive timestamps.

use identifier_core::{Estimate, Identifier, Settings};

/// Every step's output, with the sample time.
pub struct Run {
    /// Sample times, seconds.
    pub t: Vec<f64>,
    /// The identifier's output after each sample.
    pub estimates: Vec<Estimate>,
    /// The identifier at the end (counters, monitor).
    pub identifier: Identifier,
}

impl Run {
    /// The final estimate as `f64`.
    pub fn final_a(&self) -> [f64; 3] {
        self.identifier.estimate().map(f64::from)
    }

    /// Largest `|a_hat_i - a_i|` over the samples with `t >= from`.
    pub fn max_error_after(&self, a: [f64; 3], from: f64) -> f64 {
        self.t
            .iter()
            .zip(&self.estimates)
            .filter(|(t, _)| **t >= from)
            .flat_map(|(_, e)| (0..3).map(move |i| (f64::from(e.a[i]) - a[i]).abs()))
            .fold(0.0, f64::max)
    }
}

/// Runs a new identifier with `settings` over the samples `(t, omega)`. The first sample's
/// `dt` is the nominal period (it only anchors the integration).
pub fn run(settings: Settings, t: &[f64], omega: &[[f64; 3]]) -> Run {
    let mut id = Identifier::new(settings).expect("valid settings");
    let mut estimates = Vec::with_capacity(t.len());
    let nominal = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
    let mut prev = None;
    for (&tk, w) in t.iter().zip(omega) {
        let dt = prev.map_or(nominal, |p: f64| tk - p);
        prev = Some(tk);
        estimates.push(id.step(w.map(|x| x as f32), dt as f32));
    }
    Run {
        t: t.to_vec(),
        estimates,
        identifier: id,
    }
}
