//! Recursive least squares on (1) integrated over a short sliding window:
//! `w_i(t) - w_i(t - T) = a_i integral_{t-T}^t w_j w_k dt`, one scalar RLS per axis, no
//! forgetting. The window (about 0.1 s, at least 3 samples) replaces a differentiator.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::{products, Method};

/// The recursive least-squares estimator.
pub struct Rls;

impl Method for Rls {
    fn name(&self) -> &'static str {
        "recursive LS (sliding integral)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        self.curve(t, y, &[t.len() - 1])[0]
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let n = y.len();
        let dt = if n > 1 {
            (t[n - 1] - t[0]) / (n - 1) as f64
        } else {
            1.0
        };
        let m = ((0.1 / dt).round() as usize).max(3);
        // Cumulative trapezoid integral of f, so that each window's integral is a difference.
        let mut a = [0.0f64; 3];
        let mut p = [1e3f64; 3];
        let mut cum: Vec<[f64; 3]> = Vec::with_capacity(n);
        let mut out = Vec::with_capacity(checkpoints.len());
        let mut next = checkpoints.iter().peekable();
        for k in 0..n {
            let c = if k == 0 {
                [0.0; 3]
            } else {
                let (f0, f1) = (products(y[k - 1]), products(y[k]));
                let h = t[k] - t[k - 1];
                let prev = cum[k - 1];
                std::array::from_fn(|i| prev[i] + 0.5 * h * (f0[i] + f1[i]))
            };
            cum.push(c);
            if k >= m {
                for i in 0..3 {
                    let phi = c[i] - cum[k - m][i];
                    let z = y[k][i] - y[k - m][i];
                    let g = p[i] * phi / (1.0 + phi * p[i] * phi);
                    a[i] += g * (z - phi * a[i]);
                    p[i] -= g * phi * p[i];
                }
            }
            while next.peek().is_some_and(|&&cp| cp == k) {
                out.push(a);
                next.next();
            }
        }
        out
    }
}
