//! Cramer-Rao bound for `a` from gyro samples of the torque-free motion (1), with white noise
//! `sigma` per sample and per axis, and the sensitivity equations the bound and the
//! output-error fit share.
//!
//! The parameters are `theta = (a1, a2, a3, w1(0), w2(0), w3(0))`: the output-error model is
//! the whole trajectory, so the initial state is unknown too. With `S = d omega / d theta`
//! (3x6), along the motion
//!
//! ```text
//! S' = J(omega) S + df/dtheta,   S(0) = [0 | I],
//! J = [[0, a1 w3, a1 w2], [a2 w3, 0, a2 w1], [a3 w2, a3 w1, 0]],
//! df/da = diag(w2 w3, w3 w1, w1 w2),
//! ```
//!
//! and the Fisher information is `F = sigma^-2 sum_k S_k^T S_k`. The bound on the standard
//! deviation of `a_i` is `sqrt((F^-1)_ii)`. Everything is RK4 in `f64`.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use nalgebra::{SMatrix, SVector};

/// 6x6 matrix.
pub type M6 = SMatrix<f64, 6, 6>;
/// 6-vector.
pub type V6 = SVector<f64, 6>;

/// State of the augmented system: omega and the 3x6 sensitivity, row major.
#[derive(Clone, Copy, Debug)]
pub struct Aug {
    /// Angular velocity.
    pub w: [f64; 3],
    /// `S[i][j] = d w_i / d theta_j`.
    pub s: [[f64; 6]; 3],
}

fn deriv(a: [f64; 3], x: &Aug) -> Aug {
    let w = x.w;
    let f = [w[1] * w[2], w[2] * w[0], w[0] * w[1]];
    let j = [
        [0.0, a[0] * w[2], a[0] * w[1]],
        [a[1] * w[2], 0.0, a[1] * w[0]],
        [a[2] * w[1], a[2] * w[0], 0.0],
    ];
    let mut s = [[0.0; 6]; 3];
    for i in 0..3 {
        for c in 0..6 {
            s[i][c] = j[i][0] * x.s[0][c] + j[i][1] * x.s[1][c] + j[i][2] * x.s[2][c];
        }
        s[i][i] += f[i];
    }
    Aug {
        w: [a[0] * f[0], a[1] * f[1], a[2] * f[2]],
        s,
    }
}

fn axpy(x: &Aug, k: &Aug, h: f64) -> Aug {
    let mut y = *x;
    for i in 0..3 {
        y.w[i] += h * k.w[i];
        for c in 0..6 {
            y.s[i][c] += h * k.s[i][c];
        }
    }
    y
}

/// The trajectory and its sensitivities at `n` samples spaced `dt`, from `omega0`, with
/// `substeps` RK4 steps per sample.
pub fn sensitivities(
    a: [f64; 3],
    omega0: [f64; 3],
    n: usize,
    dt: f64,
    substeps: usize,
) -> Vec<Aug> {
    let mut x = Aug {
        w: omega0,
        s: [[0.0; 6]; 3],
    };
    for i in 0..3 {
        x.s[i][3 + i] = 1.0;
    }
    let m = substeps.max(1);
    let h = dt / m as f64;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        out.push(x);
        if k + 1 == n {
            break;
        }
        for _ in 0..m {
            let k1 = deriv(a, &x);
            let k2 = deriv(a, &axpy(&x, &k1, h / 2.0));
            let k3 = deriv(a, &axpy(&x, &k2, h / 2.0));
            let k4 = deriv(a, &axpy(&x, &k3, h));
            for i in 0..3 {
                x.w[i] += h / 6.0 * (k1.w[i] + 2.0 * k2.w[i] + 2.0 * k3.w[i] + k4.w[i]);
                for c in 0..6 {
                    x.s[i][c] +=
                        h / 6.0 * (k1.s[i][c] + 2.0 * k2.s[i][c] + 2.0 * k3.s[i][c] + k4.s[i][c]);
                }
            }
        }
    }
    out
}

/// `sum_k S_k^T S_k` (the Fisher information times `sigma^2`).
pub fn gram(traj: &[Aug]) -> M6 {
    let mut f = M6::zeros();
    for x in traj {
        for r in 0..6 {
            for c in r..6 {
                let v = x.s[0][r] * x.s[0][c] + x.s[1][r] * x.s[1][c] + x.s[2][r] * x.s[2][c];
                f[(r, c)] += v;
            }
        }
    }
    for r in 0..6 {
        for c in 0..r {
            f[(r, c)] = f[(c, r)];
        }
    }
    f
}

/// The bound on the standard deviation of `(a1, a2, a3)`, using the first `n` samples
/// (`n = usize::MAX` for all).
pub fn bound_from(traj: &[Aug], n: usize, sigma: f64) -> Option<[f64; 3]> {
    let g = gram(&traj[..n.min(traj.len())]);
    let inv = g.try_inverse()?;
    let b = [0, 1, 2].map(|i| sigma * inv[(i, i)].max(0.0).sqrt());
    b.iter().all(|x| x.is_finite()).then_some(b)
}

/// Cramer-Rao bound on the standard deviation of `a_i` for the body with parameters `a`,
/// initial rate `omega0`, `n` samples at `rate_hz`, white noise `sigma` per sample.
pub fn bound(a: [f64; 3], omega0: [f64; 3], n: usize, rate_hz: f64, sigma: f64) -> [f64; 3] {
    let sub = if rate_hz < 500.0 { 20 } else { 2 };
    let traj = sensitivities(a, omega0, n, 1.0 / rate_hz, sub);
    bound_from(&traj, n, sigma).unwrap_or([f64::INFINITY; 3])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensitivity_matches_finite_difference() {
        let a = [0.9, 0.2597, -0.94];
        let w0 = [1.0, 1.0, 1.0];
        let tr = sensitivities(a, w0, 2001, 1e-3, 1);
        let e = 1e-6;
        let mut ap = a;
        ap[1] += e;
        let tp = sensitivities(ap, w0, 2001, 1e-3, 1);
        let k = 2000;
        for i in 0..3 {
            let fd = (tp[k].w[i] - tr[k].w[i]) / e;
            assert!(
                (fd - tr[k].s[i][1]).abs() < 1e-4,
                "{fd} vs {}",
                tr[k].s[i][1]
            );
        }
    }
}
