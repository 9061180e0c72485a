//! The model and its candidate extensions as regressors, and the block residual.
//!
//! The model is linear in its parameters `theta = (a1, a2, a3, effect parameters...)`:
//!
//! ```text
//! w' = sum_p theta_p phi_p(w)                                                        (M)
//! phi_a1 = (w2 w3, 0, 0),  phi_a2 = (0, w3 w1, 0),  phi_a3 = (0, 0, w1 w2)          Euler (1)
//! ```
//!
//! Each effect adds three columns (its signature in the residual):
//!
//! * `body_torque` (tau_i / A_i, rad/s^2): `e_i`, constant;
//! * `damping` (d_i / A_i, 1/s): `-w_i e_i`, viscous torque `-d_i w_i`;
//! * `gyro_bias` (b_j, rad/s): the sensor reads `w + b`, so `w' = f(w - b)`, linearised:
//!   `-J_f(w) e_j` with `J_f` the Jacobian of (1) at the current `a`;
//! * `products_of_inertia` (small angles eps_j, rad): the sensor frame is the principal frame
//!   turned by `R = I + [eps]x`, so `w' = R f(R^T w)`, linearised:
//!   `e_j x f(w) - J_f(w) (e_j x w)`;
//! * `rotor_momentum` (g_j = h_j / A1, rad/s): `I w' = (I w + h) x w`, i.e.
//!   `(A1 / A_i) (g x w)_i`, column `r (.) (e_j x w)` with `r = (1, A1/A2, A1/A3)` from `a`;
//! * `scale_factor` (one common factor `s`, reading = `s w`) only rescales `a` to `a / s`: the
//!   residual cannot see it; the consistency value `a1 + a2 + a3 + a1 a2 a3` does.
//!
//! The bilinear columns are evaluated at a linearisation point `a_lin` (Gauss-Newton: refit,
//! move `a_lin`, refit).
#![allow(clippy::needless_range_loop)]

use serde::Serialize;

/// A candidate effect the torque-free model may lack.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Constant gyro bias `b` (rad/s).
    GyroBias,
    /// Constant body-frame torque `tau_i / A_i` (rad/s^2).
    BodyTorque,
    /// Viscous damping `d_i / A_i` (1/s).
    Damping,
    /// Sensor axes turned by small angles `eps` (rad) from the principal axes.
    ProductsOfInertia,
    /// Constant internal rotor momentum `h / A1` (rad/s).
    RotorMomentum,
    /// Common gyro scale factor `s` (reading / truth).
    ScaleFactor,
}

impl Effect {
    /// The effects that show in the residual, in a fixed order.
    pub const RESIDUAL: [Effect; 5] = [
        Effect::GyroBias,
        Effect::BodyTorque,
        Effect::Damping,
        Effect::ProductsOfInertia,
        Effect::RotorMomentum,
    ];

    /// The JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Effect::GyroBias => "gyro_bias",
            Effect::BodyTorque => "body_torque",
            Effect::Damping => "damping",
            Effect::ProductsOfInertia => "products_of_inertia",
            Effect::RotorMomentum => "rotor_momentum",
            Effect::ScaleFactor => "scale_factor",
        }
    }

    /// Names of this effect's parameters.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            Effect::GyroBias => &["b1", "b2", "b3"],
            Effect::BodyTorque => &["tau1/A1", "tau2/A2", "tau3/A3"],
            Effect::Damping => &["d1/A1", "d2/A2", "d3/A3"],
            Effect::ProductsOfInertia => &["eps1", "eps2", "eps3"],
            Effect::RotorMomentum => &["h1/A1", "h2/A1", "h3/A1"],
            Effect::ScaleFactor => &["s"],
        }
    }
}

/// `f(w; a)` of (1).
pub fn euler(a: [f64; 3], w: [f64; 3]) -> [f64; 3] {
    [a[0] * w[1] * w[2], a[1] * w[2] * w[0], a[2] * w[0] * w[1]]
}

/// Jacobian `J_f` of (1) at `w`, by rows.
pub fn jacobian(a: [f64; 3], w: [f64; 3]) -> [[f64; 3]; 3] {
    [
        [0.0, a[0] * w[2], a[0] * w[1]],
        [a[1] * w[2], 0.0, a[1] * w[0]],
        [a[2] * w[1], a[2] * w[0], 0.0],
    ]
}

/// `a x b`.
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(j: usize) -> [f64; 3] {
    std::array::from_fn(|i| if i == j { 1.0 } else { 0.0 })
}

/// `(1, A1/A2, A1/A3)` from `a`. Any two of the `a_i` give the ratios (with `A1 = 1`):
/// `(a1, a2)`: `A2 = (1+a1)/(1-a2)`, `A3 = (1+a1 a2)/(1-a2)`;
/// `(a3, a1)`: `A2 = (1+a1 a3)/(1+a3)`, `A3 = (1-a1)/(1+a3)`;
/// `(a2, a3)`: `A2 = (1-a3)/(1+a2 a3)`, `A3 = (1+a2)/(1+a2 a3)`.
/// The pair with the denominator farthest from zero is used (the others amplify errors of
/// `a`, e.g. `1 - a2 = 0.14` for a racquet); ones where the result is not positive.
pub fn inverse_ratios(a: [f64; 3]) -> [f64; 3] {
    let [a1, a2, a3] = a;
    let cands = [
        (1.0 - a2, 1.0 + a1, 1.0 + a1 * a2),
        (1.0 + a3, 1.0 + a1 * a3, 1.0 - a1),
        (1.0 + a2 * a3, 1.0 - a3, 1.0 + a2),
    ];
    let (d, n2, n3) = cands
        .iter()
        .copied()
        .max_by(|x, y| x.0.abs().total_cmp(&y.0.abs()))
        .unwrap_or((1.0, 1.0, 1.0));
    let ok = |r: f64| if r.is_finite() && r > 0.0 { r } else { 1.0 };
    [1.0, ok(d / n2), ok(d / n3)]
}

/// The regressor columns `phi_p(w)` of (M) for the residual effects `effects` (scale factor
/// ignored), with bilinear columns at `a_lin`.
pub fn regressors(effects: &[Effect], a_lin: [f64; 3], w: [f64; 3]) -> Vec<[f64; 3]> {
    let mut cols = vec![
        [w[1] * w[2], 0.0, 0.0],
        [0.0, w[2] * w[0], 0.0],
        [0.0, 0.0, w[0] * w[1]],
    ];
    for e in effects {
        for j in 0..3 {
            let col = match e {
                Effect::BodyTorque => unit(j),
                Effect::Damping => {
                    let mut c = [0.0; 3];
                    c[j] = -w[j];
                    c
                }
                Effect::GyroBias => {
                    let jf = jacobian(a_lin, w);
                    [-jf[0][j], -jf[1][j], -jf[2][j]]
                }
                Effect::ProductsOfInertia => {
                    let ef = cross(unit(j), euler(a_lin, w));
                    let ew = cross(unit(j), w);
                    let jf = jacobian(a_lin, w);
                    std::array::from_fn(|i| {
                        ef[i] - (jf[i][0] * ew[0] + jf[i][1] * ew[1] + jf[i][2] * ew[2])
                    })
                }
                Effect::RotorMomentum => {
                    let r = inverse_ratios(a_lin);
                    let c = cross(unit(j), w);
                    std::array::from_fn(|i| r[i] * c[i])
                }
                Effect::ScaleFactor => continue,
            };
            cols.push(col);
        }
    }
    cols
}

/// Number of parameters of (M) for `effects`.
pub fn n_params(effects: &[Effect]) -> usize {
    3 + 3 * effects
        .iter()
        .filter(|e| **e != Effect::ScaleFactor)
        .count()
}

/// `w'` of (M).
pub fn rhs(effects: &[Effect], a_lin: [f64; 3], theta: &[f64], w: [f64; 3]) -> [f64; 3] {
    let cols = regressors(effects, a_lin, w);
    std::array::from_fn(|i| cols.iter().zip(theta).map(|(c, t)| c[i] * t).sum())
}

/// A block of `4 m + 1` consecutive samples `k0..=k0+4m` inside one segment; its equation is
/// the integral of (M) over the block:
///
/// ```text
/// w(t_{k0+4m}) - w(t_{k0}) = sum_{j=0..4m} q_j phi(w(t_{k0+j})) theta + r                (B)
/// ```
///
/// with `q_j` the weights of the composite degree-4 interpolatory quadrature (the rule on
/// each run of five nodes, uneven nodes allowed; Boole's rule on even ones). Consecutive
/// blocks are one sample apart, so no sample enters two blocks and `r` is independent from
/// block to block for white gyro noise. `m` comes from [`runs_per_block`].
#[derive(Clone, Debug)]
pub struct Block {
    /// Segment index.
    pub segment: usize,
    /// First sample index.
    pub k0: usize,
    /// Block mid-time, seconds.
    pub t_mid: f64,
    /// Quadrature weights, one per sample of the block.
    pub q: Vec<f64>,
}

impl Block {
    /// Index of the last sample.
    pub fn k1(&self) -> usize {
        self.k0 + self.q.len() - 1
    }
}

/// Longest block of (B), seconds.
pub const MAX_BLOCK_TIME: f64 = 0.2;

/// Quadrature runs per block, `m` of [`Block`]: the block is made as long as possible, since
/// the information a block carries on the parameters grows with its length while the noise of
/// its two end samples does not, subject to
/// (i) the noise the regressors carry, about `h T_b mean|w|^2 sigma^2` for `|a| ~ 1`, staying
///     below a quarter of the end-point noise `2 sigma^2`: `T_b <= 0.5 / (h mean|w|^2)`;
/// (ii) each segment keeping at least 15 blocks (whiteness test, plots);
/// (iii) `T_b <= MAX_BLOCK_TIME`;
/// and at least one run of four intervals. At 100 Hz and 20 rad/s this gives `m = 1`
/// (5 samples, 40 ms), at 1 kHz and 1 rad/s `m = 50` (0.2 s).
pub fn runs_per_block(t: &[f64], omega: &[[f64; 3]], ranges: &[(usize, usize)]) -> usize {
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let h = dts.get(dts.len() / 2).copied().unwrap_or(1.0);
    let (mut w2, mut n) = (0.0, 0usize);
    let mut shortest = f64::INFINITY;
    for &(i0, i1) in ranges {
        if i1 > i0 + 1 {
            shortest = shortest.min(t[i1 - 1] - t[i0]);
        }
        for w in &omega[i0..i1] {
            w2 += w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
            n += 1;
        }
    }
    let w2 = w2 / n.max(1) as f64;
    let tb = (0.5 / (h * w2.max(1e-12)))
        .min(shortest / 15.0)
        .min(MAX_BLOCK_TIME);
    let m = (tb / (4.0 * h)).floor();
    if m.is_finite() && m >= 1.0 {
        (m as usize).min(10_000)
    } else {
        1
    }
}

/// Weights of the interpolatory quadrature of degree 4 on nodes `x` over `[x0, x4]`:
/// `sum q_m x_m^p = (x4^(p+1) - x0^(p+1)) / (p+1)`, p = 0..4 (nodes shifted to `x0 = 0`).
pub fn quadrature(x: [f64; 5]) -> Option<[f64; 5]> {
    let span = x[4] - x[0];
    if span.is_nan() || span <= 0.0 {
        return None;
    }
    // Work in u = (x - x0) / span on [0, 1].
    let u: [f64; 5] = std::array::from_fn(|m| (x[m] - x[0]) / span);
    let rows: Vec<Vec<f64>> = (0..5)
        .map(|p| (0..5).map(|m| u[m].powi(p)).collect())
        .collect();
    let inv = super::stats::invert(&rows)?;
    let mom: Vec<f64> = (0..5).map(|p| 1.0 / (p as f64 + 1.0)).collect();
    let q: [f64; 5] =
        std::array::from_fn(|m| span * (0..5).map(|p| inv[m][p] * mom[p]).sum::<f64>());
    q.iter().all(|v| v.is_finite()).then_some(q)
}

/// The blocks of the segments `ranges` (`[i0, i1)` sample ranges), `4 m` intervals each
/// (`m` from [`runs_per_block`]). A block is skipped when one of its steps exceeds `2.5` times
/// the median step (a gap).
pub fn blocks(t: &[f64], ranges: &[(usize, usize)], m: usize) -> Vec<Block> {
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let med = dts.get(dts.len() / 2).copied().unwrap_or(1.0);
    let m = m.max(1);
    let len = 4 * m;
    let mut out = Vec::new();
    for (s, &(i0, i1)) in ranges.iter().enumerate() {
        let mut k = i0;
        while k + len < i1 {
            let even = t[k..=k + len].windows(2).all(|w| w[1] - w[0] <= 2.5 * med);
            let mut q = vec![0.0; len + 1];
            let mut ok = even;
            for r in 0..m {
                let x: [f64; 5] = std::array::from_fn(|j| t[k + 4 * r + j]);
                match quadrature(x) {
                    Some(w) if ok => {
                        for j in 0..5 {
                            q[4 * r + j] += w[j];
                        }
                    }
                    _ => ok = false,
                }
            }
            if ok {
                out.push(Block {
                    segment: s,
                    k0: k,
                    t_mid: 0.5 * (t[k] + t[k + len]),
                    q,
                });
                k += len + 1;
            } else {
                k += 1;
            }
        }
    }
    out
}

/// The rows of (B) for `blocks`: per block three rows (one per axis) of `X` and `y`.
pub fn block_rows(
    blocks: &[Block],
    omega: &[[f64; 3]],
    effects: &[Effect],
    a_lin: [f64; 3],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let p = n_params(effects);
    let mut x = Vec::with_capacity(3 * blocks.len());
    let mut y = Vec::with_capacity(3 * blocks.len());
    for b in blocks {
        let mut xb = vec![[0.0f64; 3]; p];
        for (j, qj) in b.q.iter().enumerate() {
            let cols = regressors(effects, a_lin, omega[b.k0 + j]);
            for (acc, c) in xb.iter_mut().zip(&cols) {
                for i in 0..3 {
                    acc[i] += qj * c[i];
                }
            }
        }
        for i in 0..3 {
            x.push(xb.iter().map(|c| c[i]).collect());
            y.push(omega[b.k1()][i] - omega[b.k0][i]);
        }
    }
    (x, y)
}

/// The residual `r` of (B), per block, for parameters `theta`.
pub fn block_residuals(
    blocks: &[Block],
    omega: &[[f64; 3]],
    effects: &[Effect],
    a_lin: [f64; 3],
    theta: &[f64],
) -> Vec<[f64; 3]> {
    let (x, y) = block_rows(blocks, omega, effects, a_lin);
    y.chunks(3)
        .zip(x.chunks(3))
        .map(|(yb, xb)| {
            std::array::from_fn(|i| {
                yb[i] - xb[i].iter().zip(theta).map(|(a, b)| a * b).sum::<f64>()
            })
        })
        .collect()
}

/// Free-run prediction from the first sample of `[i0, i1)`: (M) integrated by RK4 (8 steps per
/// sample interval) from the measured `w(t_i0)`; the RMS over samples and axes of measured
/// minus predicted.
pub fn free_run_rms(
    t: &[f64],
    omega: &[[f64; 3]],
    (i0, i1): (usize, usize),
    effects: &[Effect],
    a_lin: [f64; 3],
    theta: &[f64],
) -> f64 {
    let f = |w: [f64; 3]| rhs(effects, a_lin, theta, w);
    // A prediction that leaves 10x the measured range has diverged: it is held there, so the
    // RMS stays a finite measure of "lost".
    let bound = 10.0
        * omega[i0..i1]
            .iter()
            .flat_map(|w| w.iter())
            .fold(1.0f64, |m, v| m.max(v.abs()));
    let mut w = omega[i0];
    let mut sum = 0.0;
    let mut n = 0usize;
    for k in i0..i1 {
        if k > i0 {
            let h = (t[k] - t[k - 1]) / 8.0;
            for _ in 0..8 {
                let next = rk4(f, w, h);
                if next.iter().all(|v| v.is_finite() && v.abs() <= bound) {
                    w = next;
                }
            }
        }
        for i in 0..3 {
            let e = omega[k][i] - w[i];
            sum += e * e;
        }
        n += 3;
    }
    (sum / n.max(1) as f64).sqrt()
}

/// One classical Runge-Kutta step of `x' = f(x)` of length `h`.
fn rk4<F: Fn([f64; 3]) -> [f64; 3]>(f: F, x: [f64; 3], h: f64) -> [f64; 3] {
    let add = |a: [f64; 3], b: [f64; 3], s: f64| std::array::from_fn(|k| a[k] + s * b[k]);
    let k1 = f(x);
    let k2 = f(add(x, k1, h / 2.0));
    let k3 = f(add(x, k2, h / 2.0));
    let k4 = f(add(x, k3, h));
    std::array::from_fn(|k| x[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]))
}

/// The alternative residual, for comparison: the smoothing-differentiated `w'` (Savitzky-Golay:
/// a cubic fitted by least squares to the `2 half + 1` samples around each sample, on their
/// actual times) minus the right-hand side (1) at the smoothed `w`, rad/s^2, one per sample
/// whose window lies inside its segment. Returned as `(segment, residual)`.
pub fn sg_residual(
    t: &[f64],
    omega: &[[f64; 3]],
    ranges: &[(usize, usize)],
    half: usize,
    a: [f64; 3],
) -> Vec<(usize, [f64; 3])> {
    let mut out = Vec::new();
    for (s, &(i0, i1)) in ranges.iter().enumerate() {
        for k in (i0 + half)..i1.saturating_sub(half) {
            let rows: Vec<Vec<f64>> = (k - half..=k + half)
                .map(|j| {
                    let x = t[j] - t[k];
                    vec![1.0, x, x * x, x * x * x]
                })
                .collect();
            let mut w = [0.0; 3];
            let mut dw = [0.0; 3];
            let mut ok = true;
            for i in 0..3 {
                let y: Vec<f64> = (k - half..=k + half).map(|j| omega[j][i]).collect();
                match super::stats::lstsq(&rows, &y) {
                    Some(f) => {
                        w[i] = f.theta[0];
                        dw[i] = f.theta[1];
                    }
                    None => ok = false,
                }
            }
            if ok {
                let f = euler(a, w);
                out.push((s, std::array::from_fn(|i| dw[i] - f[i])));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrature_is_boole_on_even_nodes_and_exact_for_quartics() {
        let q = quadrature([0.0, 1.0, 2.0, 3.0, 4.0]).unwrap();
        let boole = [14.0, 64.0, 24.0, 64.0, 14.0].map(|v| v / 45.0);
        for m in 0..5 {
            assert!((q[m] - boole[m]).abs() < 1e-12);
        }
        let x = [0.0, 0.01, 0.023, 0.03, 0.041];
        let q = quadrature(x).unwrap();
        let s: f64 = (0..5).map(|m| q[m] * x[m].powi(4)).sum();
        assert!((s - 0.041f64.powi(5) / 5.0).abs() < 1e-15);
    }
}
