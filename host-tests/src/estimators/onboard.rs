//! The two on-board identifiers from `identifier-core`, driven exactly as the firmware drives
//! them: one `step` per sample, `f32` in, `dt` from consecutive timestamps.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::Method;
use identifier_core::{Identifier, Refined, RefinedSettings, Settings};

/// `dt` for sample `k` (the nominal period for the first sample).
fn dt_at(t: &[f64], k: usize) -> f32 {
    let nominal = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
    if k == 0 {
        nominal as f32
    } else {
        (t[k] - t[k - 1]) as f32
    }
}

/// The paper's identifier as published: `C = -lambda E`, sign-change correction, the
/// estimate (14) at the last sample.
pub struct Paper {
    /// Settings (default `Settings::with_lambda(3.0)`).
    pub settings: Settings,
}

impl Default for Paper {
    fn default() -> Self {
        Paper {
            settings: Settings::with_lambda(3.0),
        }
    }
}

impl Method for Paper {
    fn name(&self) -> &'static str {
        "paper identifier (C=-3E)"
    }
    fn onboard(&self) -> bool {
        true
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        self.curve(t, y, &[t.len() - 1])[0]
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let Ok(mut id) = Identifier::new(self.settings) else {
            return vec![[f64::NAN; 3]; checkpoints.len()];
        };
        let mut out = Vec::with_capacity(checkpoints.len());
        let mut next = checkpoints.iter().peekable();
        for (k, w) in y.iter().enumerate() {
            let e = id.step(w.map(|x| x as f32), dt_at(t, k));
            while next.peek().is_some_and(|&&c| c == k) {
                out.push(e.a.map(f64::from));
                next.next();
            }
        }
        out
    }
}

/// The paper's identifier with its estimate averaged over the last quarter of the data (the
/// way the planning figure of about 1e-3 was taken: the last 5 s of 20 s). Not a method of the
/// paper; a context row.
#[derive(Default)]
pub struct PaperAveraged(pub Paper);

impl Method for PaperAveraged {
    fn name(&self) -> &'static str {
        "paper identifier, mean of last 25 %"
    }
    fn onboard(&self) -> bool {
        true
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        let Ok(mut id) = Identifier::new(self.0.settings) else {
            return [f64::NAN; 3];
        };
        let from = t.len() - t.len() / 4;
        let mut sum = [0.0f64; 3];
        let mut n = 0.0f64;
        for (k, w) in y.iter().enumerate() {
            let e = id.step(w.map(|x| x as f32), dt_at(t, k));
            if k >= from {
                for i in 0..3 {
                    sum[i] += f64::from(e.a[i]);
                }
                n += 1.0;
            }
        }
        sum.map(|s| s / n.max(1.0))
    }
}

/// The paper's identifier on omega low-passed by a second-order Butterworth filter (bilinear
/// transform, cut-off `cutoff_hz`; a filter the firmware could run too). The filter's delay is
/// harmless: a time-shifted motion satisfies (1) as well.
pub struct PaperLowPass {
    /// The identifier.
    pub paper: Paper,
    /// Cut-off frequency, Hz.
    pub cutoff_hz: f64,
}

impl Default for PaperLowPass {
    fn default() -> Self {
        PaperLowPass {
            paper: Paper::default(),
            cutoff_hz: 2.0,
        }
    }
}

/// Second-order Butterworth low-pass of each axis of `y` (uniform spacing `dt`), started at
/// rest on the first sample.
pub fn butterworth(y: &[[f64; 3]], dt: f64, cutoff_hz: f64) -> Vec<[f64; 3]> {
    let k = (std::f64::consts::PI * cutoff_hz * dt).tan();
    let q = std::f64::consts::SQRT_2;
    let norm = 1.0 / (1.0 + q * k + k * k);
    let (b0, b1, b2) = (k * k * norm, 2.0 * k * k * norm, k * k * norm);
    let (a1, a2) = (2.0 * (k * k - 1.0) * norm, (1.0 - q * k + k * k) * norm);
    let Some(first) = y.first() else {
        return Vec::new();
    };
    let (mut x1, mut x2, mut y1, mut y2) = (*first, *first, *first, *first);
    y.iter()
        .map(|x| {
            let out: [f64; 3] = std::array::from_fn(|i| {
                b0 * x[i] + b1 * x1[i] + b2 * x2[i] - a1 * y1[i] - a2 * y2[i]
            });
            x2 = x1;
            x1 = *x;
            y2 = y1;
            y1 = out;
            out
        })
        .collect()
}

impl Method for PaperLowPass {
    fn name(&self) -> &'static str {
        "paper identifier on low-passed omega (2 Hz, filter in f64)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        self.curve(t, y, &[t.len() - 1])[0]
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let dt = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
        let f = butterworth(y, dt, self.cutoff_hz);
        self.paper.curve(t, &f, checkpoints)
    }
}

/// The refined on-board identifier ([`identifier_core::Refined`]) with its default settings
/// except two set from the sample rate: blocks of about 32 ms but at least 8 samples (32 at
/// 1 kHz, 8 at 100 Hz) and the end correction of the integral below 200 Hz.
pub struct RefinedMethod {
    /// Settings (default [`RefinedSettings::new`]).
    pub settings: RefinedSettings,
    /// [`Refined::set_torque_noise`] (default 0).
    pub torque_noise: f32,
    /// Name in tables.
    pub label: &'static str,
}

impl Default for RefinedMethod {
    fn default() -> Self {
        RefinedMethod {
            settings: RefinedSettings::new(),
            torque_noise: 0.0,
            label: "refined identifier",
        }
    }
}

impl RefinedMethod {
    /// The setting for real tosses: the phone gyro's noise (0.01 rad/s) and an unmodelled
    /// torque of 0.03 rad/s per sqrt(s) (air drag; chosen by scanning 0, 0.03, 0.1, 0.3, 1, 3
    /// on the racquet data themselves, so it is tuned, not predicted).
    pub fn with_torque_noise() -> Self {
        RefinedMethod {
            settings: RefinedSettings {
                noise_std: 0.01,
                ..RefinedSettings::new()
            },
            torque_noise: 0.03,
            label: "refined identifier, torque_noise 0.03",
        }
    }
}

impl Method for RefinedMethod {
    fn name(&self) -> &'static str {
        self.label
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
        // The same run as `estimate`; the standard deviation is `Refined::std_per_sigma`
        // times the declared gyro noise (what `std_a` reports with `noise_std = sigma`).
        let Some(id) = self.run(t, y, &mut |_, _| {}) else {
            return ([f64::NAN; 3], Some([f64::NAN; 3]));
        };
        (
            id.estimate().map(f64::from),
            Some(id.std_per_sigma().map(|x| f64::from(x) * sigma)),
        )
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(checkpoints.len());
        let mut next = checkpoints.iter().peekable();
        let done = self.run(t, y, &mut |k, id| {
            while next.peek().is_some_and(|&&c| c == k) {
                // The estimate including the open block (`step` reports the last full one).
                out.push(id.estimate().map(f64::from));
                next.next();
            }
        });
        if done.is_none() {
            return vec![[f64::NAN; 3]; checkpoints.len()];
        }
        out
    }
}

impl RefinedMethod {
    /// One pass over the samples, `visit(k, &id)` after each step; the identifier at the end.
    fn run(
        &self,
        t: &[f64],
        y: &[[f64; 3]],
        visit: &mut dyn FnMut(usize, &Refined),
    ) -> Option<Refined> {
        // Configured for the sample rate as a deployment would be, by the core's
        // `RefinedSettings::for_rate` (blocks of about 32 ms, at least 8 samples; end
        // correction on), keeping this method's noise, prior and limits.
        let dt = if t.len() > 1 { t[1] - t[0] } else { 1e-3 };
        let rated = RefinedSettings::for_rate((1.0 / dt) as f32, self.settings.noise_std);
        let mut settings = self.settings;
        settings.end_correction = rated.end_correction;
        settings.block = rated.block;
        let mut id = Refined::new(settings)?;
        id.set_torque_noise(self.torque_noise);
        for (k, w) in y.iter().enumerate() {
            id.step(w.map(|x| x as f32), dt_at(t, k));
            visit(k, &id);
        }
        Some(id)
    }
}
