//! Output-error maximum likelihood: `theta = (a, omega0)` minimising
//! `sum_k |y_k - omega(t_k; theta)|^2` (white Gaussian noise), by Gauss-Newton with
//! Levenberg damping on the sensitivity equations of [`crate::crb`]; started from the batch
//! least-squares fit. This is the accuracy reference: it is efficient, so it should sit on
//! the Cramer-Rao bound.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::{batch_ls, Method};
use crate::crb::{sensitivities, M6, V6};

/// The output-error fit.
pub struct Ml;

/// Sum of squared residuals and the normal equations at `theta`.
fn normal(theta: &V6, y: &[[f64; 3]], dt: f64, sub: usize) -> (f64, M6, V6) {
    let a = [theta[0], theta[1], theta[2]];
    let w0 = [theta[3], theta[4], theta[5]];
    let tr = sensitivities(a, w0, y.len(), dt, sub);
    let mut jtj = M6::zeros();
    let mut jtr = V6::zeros();
    let mut cost = 0.0;
    for (x, yk) in tr.iter().zip(y) {
        for i in 0..3 {
            let r = yk[i] - x.w[i];
            cost += r * r;
            for c in 0..6 {
                jtr[c] += x.s[i][c] * r;
                for d in c..6 {
                    jtj[(c, d)] += x.s[i][c] * x.s[i][d];
                }
            }
        }
    }
    for c in 0..6 {
        for d in 0..c {
            jtj[(c, d)] = jtj[(d, c)];
        }
    }
    (cost, jtj, jtr)
}

/// Fits `(a, omega0)` to uniformly sampled `y` with period `dt`, from the initial `a0`.
pub fn fit(y: &[[f64; 3]], dt: f64, a0: [f64; 3]) -> [f64; 6] {
    let sub = if dt > 2e-3 { 4 } else { 1 };
    let mut theta = V6::new(a0[0], a0[1], a0[2], y[0][0], y[0][1], y[0][2]);
    let (mut cost, mut jtj, mut jtr) = normal(&theta, y, dt, sub);
    let mut mu = 1e-6;
    for _ in 0..30 {
        let mut m = jtj;
        for i in 0..6 {
            m[(i, i)] *= 1.0 + mu;
        }
        let Some(step) = m.cholesky().map(|c| c.solve(&jtr)) else {
            mu *= 10.0;
            continue;
        };
        let cand = theta + step;
        let (c2, j2, r2) = normal(&cand, y, dt, sub);
        if c2.is_finite() && c2 <= cost {
            let done = (cost - c2) <= 1e-10 * cost;
            theta = cand;
            cost = c2;
            jtj = j2;
            jtr = r2;
            mu = (mu * 0.1).max(1e-9);
            if done {
                break;
            }
        } else {
            mu *= 10.0;
            if mu > 1e6 {
                break;
            }
        }
    }
    std::array::from_fn(|i| theta[i])
}

impl Method for Ml {
    fn name(&self) -> &'static str {
        "output-error ML (batch)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        if t.len() < 8 {
            return [0.0; 3];
        }
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        let a0 = batch_ls::BatchLs.estimate(t, y);
        let th = fit(y, dt, a0);
        [th[0], th[1], th[2]]
    }
}
