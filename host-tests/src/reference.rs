//! An `f64` evaluation of the paper's identifier in its literal form, for checking the `f32`
//! core: the joint system (1) + (3) with the controls (7) and `Phi` of (9), integrated by RK4 on
//! a fine step, with alpha shifted at each sign change of `w1 w2 w3` by the jump of `Phi` taken
//! with the opposite sign (the paper's correction).
//!
//! It shares no code with the core's discretisation: it integrates alpha, not the estimate,
//! and finds sign changes on its own fine grid.

use crate::rigid_body::Body;

/// `Phi` of (9) in `f64`.
pub fn phi(c: &[[f64; 3]; 3], w: [f64; 3]) -> [f64; 3] {
    let s = (w[0] * w[1] * w[2]).signum();
    let q = [w[0] * w[0], w[1] * w[1], w[2] * w[2]];
    std::array::from_fn(|i| 0.5 * s * (c[i][0] * q[0] + c[i][1] * q[1] + c[i][2] * q[2]))
}

/// The estimate (12) against time, sampled at `rate_hz`, for the torque-free `body` from
/// `omega0`, gain `c`, initial estimate `a0`, with `substeps` RK4 steps per sample.
pub fn estimate(
    body: &Body,
    c: [[f64; 3]; 3],
    omega0: [f64; 3],
    a0: [f64; 3],
    duration: f64,
    rate_hz: f64,
    substeps: usize,
) -> Vec<[f64; 3]> {
    let n = (duration * rate_hz).round() as usize + 1;
    let h = 1.0 / rate_hz / substeps as f64;
    let mut w = omega0;
    let f0 = phi(&c, w);
    let mut alpha: [f64; 3] = std::array::from_fn(|i| a0[i] + f0[i]);
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let f = phi(&c, w);
        out.push(std::array::from_fn(|i| alpha[i] - f[i]));
        for _ in 0..substeps {
            let s_before = (w[0] * w[1] * w[2]).signum();
            // Joint state x = (w, alpha); alpha' = u of (7) = |p| C (alpha - Phi).
            let rhs = |x: [f64; 6]| -> [f64; 6] {
                let w = [x[0], x[1], x[2]];
                let dw = body.rhs(w);
                let f = phi(&c, w);
                let p = (w[0] * w[1] * w[2]).abs();
                let d = [x[3] - f[0], x[4] - f[1], x[5] - f[2]];
                let mut out = [0.0; 6];
                out[..3].copy_from_slice(&dw);
                for i in 0..3 {
                    out[3 + i] = p * (c[i][0] * d[0] + c[i][1] * d[1] + c[i][2] * d[2]);
                }
                out
            };
            let x = rk4_6(rhs, [w[0], w[1], w[2], alpha[0], alpha[1], alpha[2]], h);
            let w_new = [x[0], x[1], x[2]];
            alpha = [x[3], x[4], x[5]];
            let s_after = (w_new[0] * w_new[1] * w_new[2]).signum();
            if s_after != s_before {
                // The paper's correction: shift alpha by the jump of Phi, opposite sign.
                let q = w_new.map(|v| v * v);
                for (i, a) in alpha.iter_mut().enumerate() {
                    let jump =
                        0.5 * (s_after - s_before) * (0..3).map(|j| c[i][j] * q[j]).sum::<f64>();
                    *a += jump;
                }
            }
            w = w_new;
        }
    }
    out
}

fn rk4_6<F: Fn([f64; 6]) -> [f64; 6]>(f: F, x: [f64; 6], h: f64) -> [f64; 6] {
    let add = |a: [f64; 6], b: [f64; 6], s: f64| std::array::from_fn(|k| a[k] + s * b[k]);
    let k1 = f(x);
    let k2 = f(add(x, k1, h / 2.0));
    let k3 = f(add(x, k2, h / 2.0));
    let k4 = f(add(x, k3, h));
    std::array::from_fn(|k| x[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]))
}
