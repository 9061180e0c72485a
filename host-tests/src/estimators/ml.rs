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

type Mat<const N: usize> = nalgebra::SMatrix<f64, N, N>;
type Vector<const N: usize> = nalgebra::SVector<f64, N>;

/// Sum of squared residuals and the normal equations of a model whose trajectory is that of
/// `(a, omega0)`, each sample's sensitivity row (`d omega_i / d(a, omega0)`, six entries)
/// turned into the model's `N` parameters by `row`.
fn normal_rows<const N: usize>(
    a: [f64; 3],
    w0: [f64; 3],
    y: &[[f64; 3]],
    dt: f64,
    sub: usize,
    row: impl Fn(&[f64; 6]) -> [f64; N],
) -> (f64, Mat<N>, Vector<N>) {
    let tr = sensitivities(a, w0, y.len(), dt, sub);
    let mut jtj = Mat::<N>::zeros();
    let mut jtr = Vector::<N>::zeros();
    let mut cost = 0.0;
    for (x, yk) in tr.iter().zip(y) {
        for i in 0..3 {
            let r = yk[i] - x.w[i];
            cost += r * r;
            let s = row(&x.s[i]);
            for c in 0..N {
                jtr[c] += s[c] * r;
                for d in 0..N {
                    jtj[(c, d)] += s[c] * s[d];
                }
            }
        }
    }
    (cost, jtj, jtr)
}

/// Gauss-Newton with Levenberg damping from `theta` on `normal` (cost and normal equations),
/// at most `iterations` steps, stopping once an accepted step gains at most `tol` of the cost.
fn levenberg<const N: usize>(
    mut theta: Vector<N>,
    normal: impl Fn(&Vector<N>) -> (f64, Mat<N>, Vector<N>),
    iterations: usize,
    tol: f64,
) -> Vector<N> {
    let (mut cost, mut jtj, mut jtr) = normal(&theta);
    let mut mu = 1e-6;
    for _ in 0..iterations {
        let mut m = jtj;
        for i in 0..N {
            m[(i, i)] *= 1.0 + mu;
        }
        let Some(step) = m.cholesky().map(|c| c.solve(&jtr)) else {
            mu *= 10.0;
            continue;
        };
        let cand = theta + step;
        let (c2, j2, r2) = normal(&cand);
        if c2.is_finite() && c2 <= cost {
            let done = (cost - c2) <= tol * cost;
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
    theta
}

/// Sum of squared residuals and the normal equations at `theta`.
fn normal(theta: &V6, y: &[[f64; 3]], dt: f64, sub: usize) -> (f64, M6, V6) {
    let a = [theta[0], theta[1], theta[2]];
    let w0 = [theta[3], theta[4], theta[5]];
    normal_rows(a, w0, y, dt, sub, |s| *s)
}

/// Fits `(a, omega0)` to uniformly sampled `y` with period `dt`, from the initial `a0`.
pub fn fit(y: &[[f64; 3]], dt: f64, a0: [f64; 3]) -> [f64; 6] {
    let sub = if dt > 2e-3 { 4 } else { 1 };
    let theta = V6::new(a0[0], a0[1], a0[2], y[0][0], y[0][1], y[0][2]);
    let theta = levenberg(theta, |th| normal(th, y, dt, sub), 30, 1e-10);
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

/// Output-error maximum likelihood with the ratios' constraint built in: `a` from two moment
/// ratios `r1 = A1/A2`, `r3 = A3/A2`, `a1 = (1 - r3)/r1`, `a2 = r3 - r1`, `a3 = (r1 - 1)/r3`
/// (so `a1 + a2 + a3 + a1 a2 a3 = 0` holds exactly), and `omega0`: five parameters. The
/// reference for the pipeline's ratio fit, which has the same model: the constrained bound is
/// what both aim at, and where neither reaches it the excess is the maximum likelihood's own
/// at that sample size, not the pipeline's.
pub struct MlConstrained;

/// `a` at `(r1, r3)` and its Jacobian `da / d(r1, r3)`.
fn a_of_ratios(r1: f64, r3: f64) -> ([f64; 3], [[f64; 2]; 3]) {
    let a = [(1.0 - r3) / r1, r3 - r1, (r1 - 1.0) / r3];
    let d = [
        [-(1.0 - r3) / (r1 * r1), -1.0 / r1],
        [-1.0, 1.0],
        [1.0 / r3, -(r1 - 1.0) / (r3 * r3)],
    ];
    (a, d)
}

/// Cost and normal equations of the constrained model at `theta = (r1, r3, omega0)`.
fn normal5(theta: &Vector<5>, y: &[[f64; 3]], dt: f64, sub: usize) -> (f64, Mat<5>, Vector<5>) {
    let (a, d) = a_of_ratios(theta[0], theta[1]);
    let w0 = [theta[2], theta[3], theta[4]];
    normal_rows(a, w0, y, dt, sub, |s6| {
        let mut s = [0.0; 5];
        for k in 0..2 {
            s[k] = (0..3).map(|j| s6[j] * d[j][k]).sum();
        }
        s[2..5].copy_from_slice(&s6[3..6]);
        s
    })
}

/// Fits the constrained model from the unconstrained fit `start = (a, omega0)`; `None` when
/// `a` gives no finite moment ratios to start from.
pub fn fit_constrained(y: &[[f64; 3]], dt: f64, start: [f64; 6]) -> Option<[f64; 3]> {
    let sub = if dt > 2e-3 { 4 } else { 1 };
    // From a2 = r3 - r1 and a3 = (r1 - 1)/r3 (well conditioned where a1 = -1, a2 = 1 are
    // not: the racquet's two large moments make A1/A2 and A3/A2 large and a1 + 1 small).
    let [_, a2, a3] = [start[0], start[1], start[2]];
    let r1 = (1.0 + a2 * a3) / (1.0 - a3);
    let r3 = r1 + a2;
    if !(r1.is_finite() && r3.is_finite() && r1 != 0.0 && r3 != 0.0) {
        return None;
    }
    let theta = Vector::<5>::new(r1, r3, start[3], start[4], start[5]);
    let theta = levenberg(theta, |th| normal5(th, y, dt, sub), 50, 1e-12);
    Some(a_of_ratios(theta[0], theta[1]).0)
}

impl Method for MlConstrained {
    fn name(&self) -> &'static str {
        "output-error ML, constrained (batch)"
    }
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3] {
        if t.len() < 8 {
            return [0.0; 3];
        }
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        let a0 = batch_ls::BatchLs.estimate(t, y);
        let th = fit(y, dt, a0);
        fit_constrained(y, dt, th).unwrap_or([f64::NAN; 3])
    }
}
