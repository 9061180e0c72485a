//! The refined identifier with an unknown constant gyro bias.
//!
//! # Model
//!
//! A gyro reading `w~ = w + b` with a constant bias `b`, put into (1, integrated):
//!
//! ```text
//! w~_i(t) = c_i + a_i G~_i(t) - a_i b_j W~_k(t) - a_i b_k W~_j(t) + a_i b_j b_k t      (B1)
//! G~_i = integral w~_j w~_k dt,   W~ = integral w~ dt                 ((i, j, k) cyclic)
//! ```
//!
//! is linear in `theta_i = (c_i, a_i, beta_ij, beta_ik, gamma_i)` with the regressors
//! `x = (1, G~_i, -W~_k, -W~_j, t)`, all built from measured rates; `beta`, `gamma` are
//! nuisance parameters (`a_i b_j`, `a_i b_k`, `a_i b_j b_k`). Per axis a five-state
//! information filter, as in [`crate::Refined`]: the integral's own noise is a wandering
//! intercept `c_i`, the update is done once per block from the block's sums, and the residual
//! of each block at its updated estimate gives the noise seen in the data.
//!
//! With no bias the extra states cost information (their variance inflates that of `a`);
//! [`crate::Pipeline::ratios`] therefore uses this estimator only when an F-test on the two
//! residual sums says the bias terms explain the data.

// Indices are constants or bounded by the fixed state size; the link-time no-panic check
// (scripts/check-no-panic.sh) proves no bounds check survives.
#![allow(clippy::indexing_slicing, clippy::needless_range_loop)]

use crate::refined::integral_step;
use crate::symmetric::{cholesky_inverse, cholesky_rel, cholesky_solve, sqrt, Sym};

/// Pivot tolerance: the regressors are nearly collinear over a short block (all grow about
/// linearly in time); the priors keep the matrix positive definite.
const REL: f32 = 1e-10;

/// States per axis: `c, a, beta_ij, beta_ik, gamma`.
const K: usize = 5;

/// One axis's filter.
#[derive(Clone, Copy, Debug, PartialEq)]
struct BiasAxis {
    theta: [f32; K],
    /// Information matrix in units of `sigma^-2`.
    info: Sym<K>,
    /// Block sums: `x x^T`, `x e`, `e^2` with `e = w - theta . x` at the block's start.
    sxx: Sym<K>,
    sxe: [f32; K],
    see: f32,
}

impl BiasAxis {
    fn new(prior: &[f32; K]) -> Self {
        let mut info = [[0.0f32; K]; K];
        for i in 0..K {
            info[i][i] = prior[i];
        }
        BiasAxis {
            theta: [0.0; K],
            info,
            sxx: [[0.0; K]; K],
            sxe: [0.0; K],
            see: 0.0,
        }
    }

    #[inline(always)]
    fn add(&mut self, x: &[f32; K], w: f32) {
        let mut pred = 0.0;
        for i in 0..K {
            pred += self.theta[i] * x[i];
        }
        let e = w - pred;
        for i in 0..K {
            for j in i..K {
                self.sxx[i][j] += x[i] * x[j];
            }
            self.sxe[i] += x[i] * e;
        }
        self.see += e * e;
    }

    /// Wander of the intercept (variance `q` per `sigma^2`), then the block's information.
    /// Returns the block's residual sum of squares at the updated estimate, or `None` (and
    /// nothing changed) when the update is not finite.
    fn update(&mut self, q: f32) -> Option<f32> {
        let mut l = self.info;
        if q > 0.0 {
            // Information form of adding process noise q to state 0 (Sherman-Morrison).
            let l0 = [l[0][0], l[1][0], l[2][0], l[3][0], l[4][0]];
            let r = q / (1.0 + q * l0[0]);
            for i in 0..K {
                for j in 0..K {
                    l[i][j] -= r * l0[i] * l0[j];
                }
            }
        }
        for i in 0..K {
            for j in i..K {
                l[i][j] += self.sxx[i][j];
                if i != j {
                    l[j][i] = l[i][j];
                }
            }
        }
        let ch = cholesky_rel(&l, REL)?;
        let d = cholesky_solve(&ch, &self.sxe);
        let mut dsd = 0.0;
        let mut ds = 0.0;
        for i in 0..K {
            ds += d[i] * self.sxe[i];
            for j in 0..K {
                let s = if i <= j {
                    self.sxx[i][j]
                } else {
                    self.sxx[j][i]
                };
                dsd += d[i] * s * d[j];
            }
        }
        let rss = self.see - 2.0 * ds + dsd;
        let ok = d.iter().all(|x| x.is_finite()) && l.iter().flatten().all(|x| x.is_finite());
        if !ok {
            return None;
        }
        for i in 0..K {
            self.theta[i] += d[i];
        }
        self.info = l;
        self.clear();
        Some(if rss > 0.0 && rss.is_finite() {
            rss
        } else {
            0.0
        })
    }

    fn clear(&mut self) {
        self.sxx = [[0.0; K]; K];
        self.sxe = [0.0; K];
        self.see = 0.0;
    }

    /// A new integral starts at the measured `w`: the old intercept is marginalised out
    /// (Schur complement) and the new one is known to one `sigma`.
    fn anchor(&mut self, w: f32) {
        let l = self.info;
        if l[0][0] > 0.0 {
            let mut m = l;
            for i in 1..K {
                for j in 1..K {
                    m[i][j] = l[i][j] - l[i][0] * l[0][j] / l[0][0];
                }
            }
            if m.iter().flatten().all(|x| x.is_finite()) {
                self.info = m;
            }
        }
        for i in 0..K {
            self.info[0][i] = 0.0;
            self.info[i][0] = 0.0;
        }
        self.info[0][0] = 1.0;
        self.theta[0] = w;
        self.clear();
    }

    /// Variance of `a` per `sigma^2`.
    fn var_a(&self) -> f32 {
        match cholesky_rel(&self.info, REL) {
            Some(ch) => {
                let inv = cholesky_inverse(&ch);
                let v = inv[1][1];
                if v > 0.0 && v.is_finite() {
                    v
                } else {
                    f32::INFINITY
                }
            }
            None => f32::INFINITY,
        }
    }
}

/// The refined identifier with a constant gyro bias: one [`RefinedBias::step`] per sample.
///
/// ```
/// use identifier_core::RefinedBias;
///
/// // Blocks of 32 samples, steps up to 0.1 s, no clipping, 2e-3 rad/s of gyro noise.
/// let mut b = RefinedBias::new(32, 0.1, f32::INFINITY, 2e-3).unwrap();
/// for _ in 0..100 {
///     b.step([0.5, -0.2, 1.0], 1e-3);
/// }
/// assert!(b.std_a().is_none()); // fewer than 200 samples' residuals: no uncertainty yet
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefinedBias {
    axes: [BiasAxis; 3],
    /// Running integrals since the anchor: `G~` per axis, `W~`, time.
    g: [f32; 3],
    wsum: [f32; 3],
    t: f32,
    last: Option<[f32; 3]>,
    m: u16,
    block: u16,
    block_time: f32,
    max_dt: f32,
    full_scale: f32,
    rss: f32,
    rss_n: u32,
    used: u32,
}

impl RefinedBias {
    /// A new estimator: `block` samples per update (1 to 1024), `max_dt` the longest step
    /// integrated, `full_scale` the gyro's clip level (rad/s).
    pub fn new(block: u16, max_dt: f32, full_scale: f32, noise_std: f32) -> Option<Self> {
        let usable = (1..=1024).contains(&block)
            && max_dt.is_finite()
            && max_dt > 0.0
            && !full_scale.is_nan()
            && full_scale > 0.0
            && noise_std.is_finite()
            && noise_std > 0.0;
        if !usable {
            return None;
        }
        // Priors in units of sigma^-2: |a| < 1, a bias below 0.05 rad/s (uncalibrated MEMS
        // gyros are within 1-3 deg/s), so beta within 0.05 and gamma within 2.5e-3.
        let p = |std: f32| (noise_std / std) * (noise_std / std);
        let prior = [1.0, p(1.0), p(0.05), p(0.05), p(2.5e-3)];
        let ax = BiasAxis::new(&prior);
        Some(RefinedBias {
            axes: [ax; 3],
            g: [0.0; 3],
            wsum: [0.0; 3],
            t: 0.0,
            last: None,
            m: 0,
            block,
            block_time: 0.0,
            max_dt,
            full_scale,
            rss: 0.0,
            rss_n: 0,
            used: 0,
        })
    }

    /// Adds one sample (`omega` rad/s, `dt` s since the previous one). Non-finite or
    /// saturated samples and bad time steps start a new integral at the next good sample.
    pub fn step(&mut self, omega: [f32; 3], dt: f32) {
        let good = omega
            .iter()
            .all(|w| w.is_finite() && w.abs() < self.full_scale)
            && dt.is_finite()
            && dt > 0.0;
        if !good {
            self.restart();
            return;
        }
        let Some(u) = self.last.replace(omega) else {
            self.anchor(omega);
            return;
        };
        if dt > self.max_dt {
            self.anchor(omega);
            return;
        }
        let half = 0.5 * dt;
        let v = omega;
        // The refined identifier's integral with its end correction (fourth order: at
        // 100-200 Hz the plain trapezoid leaves a bias that would look like a gyro bias), and
        // the same correction for W with w' from (1).
        let a = self.estimate();
        let dg = integral_step(u, v, dt, Some(a));
        for i in 0..3 {
            self.g[i] += dg[i];
            self.wsum[i] += half * (u[i] + v[i]);
        }
        let k = dt * dt * (1.0 / 12.0);
        self.wsum[0] += k * a[0] * (u[1] * u[2] - v[1] * v[2]);
        self.wsum[1] += k * a[1] * (u[2] * u[0] - v[2] * v[0]);
        self.wsum[2] += k * a[2] * (u[0] * u[1] - v[0] * v[1]);
        self.t += dt;
        for i in 0..3 {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            let x = [1.0, self.g[i], -self.wsum[k], -self.wsum[j], self.t];
            self.axes[i].add(&x, v[i]);
        }
        self.m += 1;
        self.used = self.used.saturating_add(1);
        self.block_time += dt;
        if self.m >= self.block {
            self.flush();
        }
    }

    /// Ends the current stretch: the open block is folded in, the next sample anchors.
    pub fn restart(&mut self) {
        self.flush();
        self.last = None;
    }

    fn anchor(&mut self, omega: [f32; 3]) {
        self.flush();
        for (ax, w) in self.axes.iter_mut().zip(omega.iter()) {
            ax.anchor(*w);
        }
        self.g = [0.0; 3];
        self.wsum = [0.0; 3];
        self.t = 0.0;
        self.used = self.used.saturating_add(1);
    }

    fn flush(&mut self) {
        if self.m == 0 {
            return;
        }
        let w = self.last.unwrap_or([0.0; 3]);
        let m = f32::from(self.m);
        let k = self.block_time * self.block_time / m;
        let q2 = [w[0] * w[0], w[1] * w[1], w[2] * w[2]];
        let sq = [
            k * (q2[1] + q2[2]),
            k * (q2[2] + q2[0]),
            k * (q2[0] + q2[1]),
        ];
        let mut total = 0.0;
        let mut ok = true;
        let before = self.axes;
        for (ax, s) in self.axes.iter_mut().zip(sq.iter()) {
            let a = ax.theta[1];
            match ax.update(a * a * s) {
                Some(r) => total += r,
                None => ok = false,
            }
        }
        if ok {
            self.rss += total;
            self.rss_n = self.rss_n.saturating_add(3 * u32::from(self.m));
        } else {
            self.axes = before;
            for ax in self.axes.iter_mut() {
                ax.clear();
            }
        }
        self.m = 0;
        self.block_time = 0.0;
    }

    /// `a` as of the last completed block.
    pub fn estimate(&self) -> [f32; 3] {
        self.axes.map(|x| x.theta[1])
    }

    /// Residual sum of squares of the completed blocks and the number of residuals.
    pub fn rss(&self) -> (f32, u32) {
        (self.rss, self.rss_n)
    }

    /// The gyro noise seen in the residuals (`None` before 600 residuals):
    /// `sqrt(rss / (n - 15))`.
    pub fn noise_estimate(&self) -> Option<f32> {
        if self.rss_n < 600 {
            return None;
        }
        let v = self.rss / (self.rss_n - 15) as f32;
        (v > 0.0 && v.is_finite()).then(|| sqrt(v))
    }

    /// Standard deviation of each `a_i` with the noise seen in the data.
    pub fn std_a(&self) -> Option<[f32; 3]> {
        let s = self.noise_estimate()?;
        let v = self.axes.map(|x| x.var_a());
        v.iter()
            .all(|x| x.is_finite())
            .then(|| v.map(|x| sqrt(x) * s))
    }

    /// Samples used.
    pub fn used(&self) -> u32 {
        self.used
    }
}
