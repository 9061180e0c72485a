//! Batch least squares of (1), `w_i' = a_i w_j w_k`, with omega and its derivative from a
//! Savitzky-Golay filter: the fit people reach for first.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::{products, savgol, Method};

/// Batch least squares on Savitzky-Golay derivatives (cubic, half-width about 40 ms, at least
/// 3 samples), one independent fit per axis: `a_i = sum d_i f_i / sum f_i^2`.
pub struct BatchLs;

/// Half-width of the filter for the sample period `dt`.
pub fn half_width(dt: f64) -> usize {
    ((0.04 / dt).round() as usize).max(3)
}

/// Smoothed omega and its derivative at samples `m..n-m` (uniform spacing `dt` assumed).
pub fn smooth(y: &[[f64; 3]], dt: f64, m: usize) -> Vec<([f64; 3], [f64; 3])> {
    let n = y.len();
    if n < 2 * m + 1 {
        return Vec::new();
    }
    let cv = savgol(m, 3, 0);
    let cd = savgol(m, 3, 1);
    (m..n - m)
        .map(|k| {
            let mut v = [0.0; 3];
            let mut d = [0.0; 3];
            for (j, (a, b)) in cv.iter().zip(&cd).enumerate() {
                let w = y[k + j - m];
                for i in 0..3 {
                    v[i] += a * w[i];
                    d[i] += b * w[i] / dt;
                }
            }
            (v, d)
        })
        .collect()
}

/// The least-squares `a` from smoothed values and derivatives.
pub fn fit(sd: &[([f64; 3], [f64; 3])]) -> [f64; 3] {
    let mut num = [0.0; 3];
    let mut den = [0.0; 3];
    for (v, d) in sd {
        let f = products(*v);
        for i in 0..3 {
            num[i] += d[i] * f[i];
            den[i] += f[i] * f[i];
        }
    }
    std::array::from_fn(|i| if den[i] > 0.0 { num[i] / den[i] } else { 0.0 })
}

impl Method for BatchLs {
    fn name(&self) -> &'static str {
        "batch LS (Savitzky-Golay)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        if t.len() < 2 {
            return [0.0; 3];
        }
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        let m = half_width(dt).min((y.len().saturating_sub(1)) / 2).max(2);
        fit(&smooth(y, dt, m))
    }
}
