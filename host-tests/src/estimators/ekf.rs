//! Joint state and parameter extended Kalman filter on `x = (omega, a)`: (1) with `a' = 0`,
//! omega measured with white noise `sigma`.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::Method;
use crate::crb::{M6, V6};
use nalgebra::{SMatrix, SVector};

type M3 = SMatrix<f64, 3, 3>;
type M36 = SMatrix<f64, 3, 6>;
type M63 = SMatrix<f64, 6, 3>;

/// The EKF. Measurement noise is the scenario's `sigma` (passed by the benchmark through
/// [`EkfFilter::new`]; the [`Method`] impl assumes it from the data's first differences).
pub struct Ekf;

/// One running filter.
pub struct EkfFilter {
    /// State `(w1, w2, w3, a1, a2, a3)`.
    pub x: V6,
    /// Covariance.
    pub p: M6,
    r: f64,
    q: f64,
}

fn f(x: &V6) -> V6 {
    V6::new(
        x[3] * x[1] * x[2],
        x[4] * x[2] * x[0],
        x[5] * x[0] * x[1],
        0.0,
        0.0,
        0.0,
    )
}

impl EkfFilter {
    /// A filter started at `omega = y0`, `a = 0` with a wide prior on `a`.
    pub fn new(y0: [f64; 3], sigma: f64) -> Self {
        let x = V6::new(y0[0], y0[1], y0[2], 0.0, 0.0, 0.0);
        let mut p = M6::zeros();
        for i in 0..3 {
            p[(i, i)] = sigma * sigma;
            p[(3 + i, 3 + i)] = 1.0;
        }
        EkfFilter {
            x,
            p,
            r: sigma * sigma,
            q: (1e-3 * sigma).powi(2),
        }
    }

    /// Predict over `h` (RK4 for the state, second-order transition for the covariance), then
    /// update with the measurement `y`.
    pub fn step(&mut self, y: [f64; 3], h: f64) {
        let x = self.x;
        let k1 = f(&x);
        let k2 = f(&(x + k1 * (h / 2.0)));
        let k3 = f(&(x + k2 * (h / 2.0)));
        let k4 = f(&(x + k3 * h));
        self.x = x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        let (w, a) = ([x[0], x[1], x[2]], [x[3], x[4], x[5]]);
        let mut jac = M6::zeros();
        jac[(0, 1)] = a[0] * w[2];
        jac[(0, 2)] = a[0] * w[1];
        jac[(1, 0)] = a[1] * w[2];
        jac[(1, 2)] = a[1] * w[0];
        jac[(2, 0)] = a[2] * w[1];
        jac[(2, 1)] = a[2] * w[0];
        jac[(0, 3)] = w[1] * w[2];
        jac[(1, 4)] = w[2] * w[0];
        jac[(2, 5)] = w[0] * w[1];
        let jh = jac * h;
        let phi = M6::identity() + jh + jh * jh * 0.5;
        let mut p = phi * self.p * phi.transpose();
        for i in 0..3 {
            p[(i, i)] += self.q;
        }
        // Update: H = [I 0].
        let s: M3 = p.fixed_view::<3, 3>(0, 0).into_owned() + M3::identity() * self.r;
        let Some(si) = s.try_inverse() else {
            self.p = p;
            return;
        };
        let pht: M63 = p.fixed_view::<6, 3>(0, 0).into_owned();
        let k: M63 = pht * si;
        let innov = SVector::<f64, 3>::new(y[0] - self.x[0], y[1] - self.x[1], y[2] - self.x[2]);
        self.x += k * innov;
        let hp: M36 = p.fixed_view::<3, 6>(0, 0).into_owned();
        p -= k * hp;
        self.p = (p + p.transpose()) * 0.5;
    }

    /// The current `a`.
    pub fn a(&self) -> [f64; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }
}

/// The noise level from the data: std of second differences / sqrt(6).
pub fn noise_from_data(y: &[[f64; 3]]) -> f64 {
    if y.len() < 3 {
        return 1e-3;
    }
    let mut s = 0.0;
    let mut n = 0.0;
    for k in 1..y.len() - 1 {
        for i in 0..3 {
            let d = y[k + 1][i] - 2.0 * y[k][i] + y[k - 1][i];
            s += d * d;
            n += 1.0;
        }
    }
    (s / n / 6.0).sqrt().max(1e-9)
}

impl Method for Ekf {
    fn name(&self) -> &'static str {
        "EKF (omega, a)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        self.curve(t, y, &[t.len() - 1])[0]
    }
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        let sigma = noise_from_data(y);
        let mut flt = EkfFilter::new(y[0], sigma);
        let mut out = Vec::with_capacity(checkpoints.len());
        let mut next = checkpoints.iter().peekable();
        for k in 0..y.len() {
            if k > 0 {
                flt.step(y[k], t[k] - t[k - 1]);
            }
            while next.peek().is_some_and(|&&c| c == k) {
                out.push(flt.a());
                next.next();
            }
        }
        out
    }
}
