//! Output-error maximum likelihood of the ratios on board: the whole trajectory of (1) fitted
//! to block means of the gyro, all three axes jointly, with the rigid-body constraint built in.
//!
//! # Why
//!
//! [`crate::Refined`] fits each axis of the integrated (1) on its own. The information about
//! `a_i` that lives in the *other* axes' motion (a different `a_i` bends the whole trajectory)
//! and the correlation between one axis's integral noise and the other axes' measurement noise
//! are lost, which leaves it above the Cramer-Rao bound on near-symmetric bodies and short, fast
//! tosses (`scripts/bench-estimators.sh` measures both estimators). The efficient estimator for
//! white gyro noise is the output-error fit: the parameters whose trajectory is closest to the
//! samples. This module makes it fit on a Cortex-M4F: per sample it only adds to a block sum; the
//! fit runs once per free flight.
//!
//! # The model
//!
//! Principal moments up to scale, `A = (p1, p2, 1 - p1 - p2)` (trace 1: the constraint
//! `a1 + a2 + a3 + a1 a2 a3 = 0` holds by construction, and `a` is always a rigid body's),
//!
//! ```text
//! a1 = (A2 - A3)/A1,  a2 = (A3 - A1)/A2,  a3 = (A1 - A2)/A3
//! w' = f(w) = (a1 w2 w3, a2 w3 w1, a3 w1 w2)                                   (1)
//! y_k = w(t_k) + b + n_k,   n_k white, variance sigma^2 per axis                  (T1)
//! ```
//!
//! with `theta = (p1, p2, w(t_0), [b])`: the gyro bias `b` is a second model, chosen by a
//! likelihood-ratio test (below).
//!
//! # Block means
//!
//! Samples are summed into at most `N` blocks (`n_b` samples, their mean time `tbar_b` and time
//! variance `v_b`, the mean rate `ybar_b`); when the blocks are full, neighbours are merged and
//! the block length doubles. The mean of a smooth `w` over a block's samples is, by Taylor
//! expansion about the mean time,
//!
//! ```text
//! mean_k w(t_k) = w(tbar) + v/2 w''(tbar) + O(dt^3 w'''),   w'' = (df/dw) f       (T2)
//! ```
//!
//! and `ybar_b` has noise variance `sigma^2 / n_b`, so the log-likelihood is the weighted sum
//! `sum_b n_b |ybar_b - w(tbar_b) - v_b/2 w''(tbar_b) - b|^2`. While a block is short against
//! the motion almost no information is lost (the sensitivities are nearly constant over it).
//! A long, fast flight makes long blocks span a large angle; the expansion is then carried to
//! sixth order ((T2'), `block_mean_correction`), with the times' fourth and sixth moments of
//! equally spaced samples.
//!
//! # The fit
//!
//! `w` and the sensitivities `S = dw/dtheta` are integrated from `tbar_0` with classical RK4,
//! steps of at most `0.1 / (max|a_i| |w|)` seconds (the local error is then about 1e-7 of the
//! rate, the `f32` rounding of the rate itself), along
//!
//! ```text
//! S' = (df/dw) S + (df/da)(da/dp),   S(tbar_0) = [0 | I | 0]                       (T3)
//! df/dw = [[0, a1 w3, a1 w2], [a2 w3, 0, a2 w1], [a3 w2, a3 w1, 0]]
//! df/da = diag(w2 w3, w3 w1, w1 w2)
//! da_i/dp = (dA_j - dA_k - a_i dA_i) / A_i,   dA/dp1 = (1, 0, -1), dA/dp2 = (0, 1, -1)
//! ```
//!
//! and Gauss-Newton with Levenberg damping (Jacobi-scaled normal equations, solved by
//! Cholesky) minimises the weighted cost.
//!
//! `f32` and long flights: a trajectory of hundreds of radians must be integrated to better
//! than `f32` rounding, or the fit's cost moves by units of log-likelihood for one ulp of a
//! parameter and the optimum is lost in that noise. So the rates are a compensated sum (their
//! rounding carried from step to step), the initial rates are fitted as offsets from the first
//! block's mean (held in the compensated part), the two quadratic invariants of (1) are held
//! at their starting values every few blocks (`Invariants`: they set the motion's
//! frequencies, and rounding random-walks them), the block times are differenced in two parts
//! (`Block::since`), the residuals are taken from the block sums unrounded
//! (`Block::deviation`), and the step count comes from the data, not the parameters (so the
//! cost is a smooth function of them). What is left, the `f32` resolution of the ratios
//! themselves, is put into the reported uncertainty ((T7), `resolution_factor`). The whole
//! record is fitted at once, and on growing prefixes (16 blocks, then doubling, so that the
//! phase of the trajectory is never far from the data) only when that does not fit to twice
//! the noise (`output_error::whole_or_staged`, as the tensor fit); the start is the per-axis
//! least-squares fit of the integrated (1) on the block means, turned into the moments that
//! come closest to all three of its ratios ((T8), `moments_of`).
//!
//! # Uncertainty, bias, pooling
//!
//! `sigma^2 = cost / (3 B - P)` (B blocks, P parameters) from the fit's own residual; the
//! covariance is `sigma^2 F^-1`, `F = sum_b n_b S_b^T S_b`, times the factor of (T7) for the fit's
//! own `f32` resolution (1 on most flights, a little above on long, fast ones). The bias model
//! (`P = 8`) replaces the plain one (`P = 5`) when `(cost_5 - cost_8) / sigma_8^2 > 21.11`
//! (chi-square, 3 degrees of freedom, 0.01 %: a false alarm on a short noisy toss puts its ratios
//! many bounds off and shows in a scenario's RMS error, so the level is strict, while biases of
//! 1e-3 rad/s and more are still found; the test `gyro_bias_is_detected_and_the_std_stays_honest`
//! checks both); it is fitted only when the score statistic `g^T F^-1 g` of the bias model at the
//! plain optimum exceeds half that threshold (one evaluation instead of a fit when there is no
//! bias). Each closed stretch (a free flight) adds its information on `p` with the initial rates
//! and the bias marginalised (`(F^-1)_pp^-1`) to a pooled sum; the pooled estimate is the
//! information-weighted mean, its noise the pooled residual.
//!
//! `a` and its standard deviations follow by the chain rule, `cov(a) = (da/dp) cov(p)
//! (da/dp)^T`.
//!
//! # A torque the model lacks
//!
//! A free flight has no torque about the centre of mass; a tether, air drag or a hand has. The
//! alternative checked after every fit is the simplest one, a constant angular acceleration
//! `c` per axis:
//!
//! ```text
//! w' = f(w) + c,   S_c' = (df/dw) S_c + I,   S_c(tbar_0) = 0                       (T4)
//! ```
//!
//! At the chosen model's optimum (`c = 0`) the score statistic `g^T F^-1 g / s2` of the model
//! extended by `c` (`F`, `g` its normal equations: 8 parameters, 11 with the bias; `s2` the
//! chosen model's residual variance, at least the configured noise's), scored beyond the
//! model's own columns, is compared with 21.11 (chi-square, 3 degrees of freedom, 0.01 %): one
//! evaluation with 8 sensitivity columns. Only when it rejects is the model with `c` fitted,
//! and the likelihood ratio `(cost - cost_c) / s2` must reject too (the score is its
//! approximation at the exact optimum, which an `f32` fit of a fast flight reaches only to
//! its resolution). When both reject, [`RatioFitEstimate::torque`] is set and the pipeline
//! does not call the ratios `Converged`. The residual alone cannot show such an effect: a
//! small constant torque on a long flight moves `a` by many standard deviations while the
//! residual stays near the noise (`scripts/sweep-identify.sh`, row `trap-torque`). The same
//! sweep measures how often the test flags each row (`trap-drag`, `trap-bias-walk`,
//! `trap-scale`, and the free bodies, which it should not flag). A gyro scale error is mostly
//! absorbed by `a` itself and often escapes this test, which is why the rigid-body test below
//! and the tensor fit's scale test follow.
//!
//! # Ratios no rigid body has
//!
//! The model holds `a1 + a2 + a3 + a1 a2 a3 = 0` by construction. A gyro whose scale factors
//! are off by `k_i` measures `y_i = k_i w_i`, which satisfies (1) exactly with
//! `a_i k_i / (k_j k_k)`: ratios that break the identity by about `sum a_i e_i (1 + a_j a_k)`,
//! `e_i = dk_i - dk_j - dk_k`, while the residual stays at the noise. The alternative checked
//! after every fit is a step `delta` off the identity along its unit normal `n`:
//!
//! ```text
//! a = a(p1, p2) + delta n,   n ~ (1 + a2 a3, 1 + a3 a1, 1 + a1 a2),
//! S_delta' = (df/dw) S_delta + (n_i w_j w_k)_i,   S_delta(tbar_0) = 0              (T5)
//! ```
//!
//! scored at `delta = 0` beyond the fitted model's own columns (the gradient a fit stopped at
//! `f32` precision leaves along them is not counted) against 15.14 (chi-square, 1 degree of
//! freedom, 0.01 %); when it rejects, [`RatioFitEstimate::constraint_rejected`] is set and the
//! pipeline does not call the ratios `Converged`. The model is then fitted once more with the
//! gyro's scale-factor errors `kappa` free,
//!
//! ```text
//! ybar_i = (1 + kappa_i) (w_i(tbar) + v/2 w_i''(tbar)),   d ybar_i / d kappa_i = w_i + v/2 w_i''   (T6)
//! ```
//!
//! and its cost ([`RatioFitEstimate::cost_with_scale`]) is what the products of inertia of the
//! tensor must beat to be believed: they absorb part of a scale error too.
//!
//! Cost: per sample a block sum (and once in a while a merge of the blocks); one fit per free
//! flight, in which the bias's score and the tests (T4), (T5) are one evaluation with 12
//! columns at the plain optimum, and (T6), the bias model and the torque's refit run only where
//! their score test rejected. `bench-mcu` measures the per-sample and per-fit instruction
//! counts on the Cortex-M4F in the release and flight builds, after a long flight and after a
//! short toss.
#![allow(
    // Fixed-size loops over the 3 axes and the P <= 8 parameters read as the equations; the
    // crate's link-time no-panic check proves no bounds check survives.
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    // `!(x > 0.0)` is true for NaN too, which is the point.
    clippy::neg_cmp_op_on_partial_ord
)]

use crate::exact::{compensated_add, two_sum, weighted_squares};
use crate::linalg::Gram2;
use crate::output_error::{
    bias_found, bias_worth_fitting, higher_orders, levenberg, refit_cost, scaled_inverse, score,
    score_beyond, score_rejects, score_rejects_at, substeps, torque_confirmed, whole_or_staged,
    without, Block, FitState, Normal, NormalSums, Readings, Start, StretchOutcome, StretchResult,
    TOLERANCE,
};
use crate::symmetric::{eigen_symmetric3, sqrt, Sym};

/// The pooled estimate of [`RatioFit`]: ratios, moments and their uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RatioFitEstimate {
    /// `a` of (1) from the moments: `a1 = (A2 - A3)/A1` and cyclic.
    pub a: [f32; 3],
    /// Standard deviations of `a`: `sqrt(diag((da/dp) cov(p) (da/dp)^T) + r^2)`, `r`
    /// the rounding's `STD_A_ROUNDING`.
    pub std_a: [f32; 3],
    /// Principal moments scaled to trace 1, `(p1, p2, 1 - p1 - p2)`.
    pub moments: [f32; 3],
    /// Standard deviations of the moments.
    pub std_moments: [f32; 3],
    /// Gyro noise per sample seen in the fits' residuals, rad/s: `sqrt(cost / dof)`.
    pub noise: f32,
    /// Stretches (free flights) that gave a fit.
    pub stretches: u32,
    /// Samples in them.
    pub samples: u32,
    /// True when a constant gyro bias was found (the bias model was chosen) on any stretch.
    pub biased: bool,
    /// The bias of the last stretch fitted with the bias model, rad/s (zero otherwise).
    pub bias: [f32; 3],
    /// True when the score test of a constant torque ((T4)) rejected the torque-free model on
    /// any stretch: the motion is not free (air drag, a tether, a hand), or the sensor axes
    /// are not principal axes (this model lacks the products of inertia); `a` is not to be
    /// trusted however small its standard deviation.
    pub torque: bool,
    /// True when the score test of a step off the rigid-body constraint ((T5)) rejected the
    /// fitted model on any stretch: the rates are those of a torque-free body, but with ratios
    /// no rigid body has; the gyro's scale factors (or axes) are not what the data say (a scale
    /// error `k_i` turns `a_i` into `a_i k_i / (k_j k_k)`), or the sensor axes are not principal
    /// axes (this model lacks the products of inertia). `a` is not to be trusted however small
    /// its standard deviation.
    pub constraint_rejected: bool,
    /// [`RatioFitEstimate::cost`] with the gyro's scale factors fitted ((T6)) on the stretches
    /// whose rigid-body test rejected (the alternative the pipeline weighs against the
    /// tensor's products of inertia).
    pub cost_with_scale: f32,
    /// The fits' weighted cost `sum_b n_b |ybar_b - w_b|^2` summed over the stretches, (rad/s)^2.
    pub cost: f32,
    /// The same with the constant torque fitted on the stretches whose test rejected (the
    /// alternative the pipeline weighs against the tensor's products of inertia).
    pub cost_with_torque: f32,
}

/// Output-error fit of (1) over free flights, `N` blocks per flight (see the module docs).
///
/// ```
/// use identifier_core::{RatioFit, StretchOutcome};
///
/// // The paper's body (0.6, 1.54, 1.0) tumbling for 10 s, sampled at 1 kHz.
/// let m = [0.6f64, 1.54, 1.0];
/// let a = [(m[1] - m[2]) / m[0], (m[2] - m[0]) / m[1], (m[0] - m[1]) / m[2]];
/// let mut w = [1.0f64, 1.0, 1.0];
/// let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
/// for _ in 0..10_000 {
///     fit.step([w[0] as f32, w[1] as f32, w[2] as f32], 1e-3);
///     for _ in 0..100 {
///         // Euler's equations (1), small explicit steps (an example, not a reference).
///         let d = [a[0] * w[1] * w[2], a[1] * w[2] * w[0], a[2] * w[0] * w[1]];
///         for k in 0..3 {
///             w[k] += 1e-5 * d[k];
///         }
///     }
/// }
/// // The flight ends: one fit.
/// assert_eq!(fit.close(), StretchOutcome::Fitted);
/// let e = fit.estimate().unwrap();
/// for k in 0..3 {
///     assert!((e.a[k] as f64 - a[k]).abs() < 1e-3, "{:?}", e.a);
/// }
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatioFit<const N: usize> {
    /// The open stretch's blocks and the moments `(p1, p2)` pooled over closed stretches.
    state: FitState<N, 3, 2>,
    full_scale: f32,
    max_dt: f32,
    noise_std: f32,
    /// A pooled stretch's rigid-body test ((T5)) rejected its fit.
    constraint_rejected: bool,
    /// The pooled stretches' costs, each with the scale factors fitted ((T6)) where the
    /// rigid-body test rejected.
    scale_cost: f32,
    /// How each gyro reading spreads over time ([`RatioFit::with_reading_window`],
    /// [`RatioFit::with_reading_smoothing`]).
    readings: Readings,
}

/// The block buffer used by the pipeline: 256 blocks (10 KB in all). With 128 blocks (156 ms
/// each over a 20 s flight at 1 kHz) the block correction's neglected fourth-order term would
/// set the noise-free error of the paper's body, an order of magnitude above the rounding's.
pub type FlightRatioFit = RatioFit<256>;

/// Standard deviation of the `f32` fit's own error in `a` (rounding in the sums and the RK4
/// steps), added in quadrature to the noise's. On noise-free data the fit's residual is the
/// rounding's (about 1e-8 rad/s) and its covariance alone would claim `a` several times more
/// precisely than the rounding lets it be (`scripts/sweep-identify.sh`, row `noise-free-1k`,
/// measures the noise-free error). `|a_i| <= 1` for every rigid body: about 2.5 units in the
/// last place of `f32`.
pub const STD_A_ROUNDING: f32 = 3e-7;

/// Parameter count of the bias model (moments 2, initial rates 3, bias 3).
const P_MAX: usize = 8;

/// Sensitivity columns with the constant torque's (moments 2, initial rates 3, torque 3).
const C_TORQUE: usize = 8;

/// Parameters of the torque alternative to the bias model (bias model 8, torque 3).
const P_TORQUE_BIAS: usize = 11;

/// Sensitivity columns of the tests after a fit, in one pass: moments 2, initial rates 3, a
/// constant torque 3 ((T4)), the step off the rigid-body constraint 1 ((T5)).
const C_TESTS: usize = 9;

/// Parameters of the tests of the bias model (bias model 8, torque 3, the step 1).
const P_TESTS_BIAS: usize = 12;

/// Chi-square with 1 degree of freedom that the score of a step off the rigid-body
/// constraint must exceed: 15.14, 0.01 %.
const RIGID_CHI2: f32 = 15.14;

/// One fit's result.
#[derive(Clone, Copy, Debug)]
struct Fit<const P: usize> {
    theta: [f32; P],
    cost: f32,
    /// `F^-1` (unit noise).
    cov: Sym<P>,
}

/// The augmented state of (T3): rates and their sensitivities to `(p1, p2, w0)` (`C = 5`),
/// and to a constant torque `c` (`C = 8`, (T4)).
#[derive(Clone, Copy, Debug)]
struct Aug<const C: usize> {
    w: [f32; 3],
    /// What the rounding of `w` left out, carried to the next step (compensated sum: the true
    /// state is `w - w_lo`).
    w_lo: [f32; 3],
    s: [[f32; C]; 3],
}

/// `a` and `da/dp` for moments `(p1, p2, 1 - p1 - p2)`; `None` unless all three are positive.
fn ratios_of(p1: f32, p2: f32) -> Option<([f32; 3], [[f32; 2]; 3])> {
    let m = [p1, p2, 1.0 - p1 - p2];
    if !m.iter().all(|x| *x > 0.0 && x.is_finite()) {
        return None;
    }
    let a = [
        (m[1] - m[2]) / m[0],
        (m[2] - m[0]) / m[1],
        (m[0] - m[1]) / m[2],
    ];
    // dA/dp1 = (1, 0, -1), dA/dp2 = (0, 1, -1).
    let da = [[1.0f32, 0.0, -1.0], [0.0, 1.0, -1.0]];
    let mut j = [[0.0f32; 2]; 3];
    for i in 0..3 {
        let (jj, kk) = ((i + 1) % 3, (i + 2) % 3);
        for c in 0..2 {
            j[i][c] = (da[c][jj] - da[c][kk] - a[i] * da[c][i]) / m[i];
        }
    }
    a.iter().all(|x| x.is_finite()).then_some((a, j))
}

/// The block mean of `w` minus `w(tbar)`, to sixth order in the block's time spread:
///
/// ```text
/// mean w = sum_k c_k E[tau^k] = c_0 + v c_2 + mu4 c_4 + mu6 c_6                  (T2')
/// c_0 = w(tbar),  c_(n+1),i = a_i / (n + 1) sum_(m=0..n) c_m,j c_(n-m),k   ((i, j, k) cyclic)
/// ```
///
/// (the Taylor coefficients of the solution of (1) through `w` at `tbar`, by the Cauchy product
/// of its quadratic right-hand side; `c_2 = w''/2`, so the first term is (T2)'s `v/2 w''`).
/// The terms beyond (T2) matter when a block spans a large angle: a body turning at 10 rad/s
/// over 20 s at 1 kHz fills the 256 blocks with 128 samples each, 0.8 rad, where (T2) alone
/// left a model error above the gyro noise.
fn block_mean_correction(a: &[f32; 3], w: &[f32; 3], moments: &[f32; 3]) -> [f32; 3] {
    let [v, mu4, mu6] = *moments;
    if !(v > 0.0) {
        return [0.0; 3];
    }
    let mut c = [[0.0f32; 3]; 7];
    c[0] = *w;
    let mut order = 6;
    for n in 0..6 {
        if n >= order {
            break;
        }
        let inv = 1.0 / (n + 1) as f32;
        // Cauchy product of the coefficients `0..=n` of w_j and w_k.
        let mut s = [0.0f32; 3];
        for (cm, cr) in c.iter().take(n + 1).zip(c.iter().take(n + 1).rev()) {
            s[0] += cm[1] * cr[2];
            s[1] += cm[2] * cr[0];
            s[2] += cm[0] * cr[1];
        }
        if let Some(next) = c.get_mut(n + 1) {
            *next = [a[0] * inv * s[0], a[1] * inv * s[1], a[2] * inv * s[2]];
        }
        if n == 1 {
            order = higher_orders(mu4, mu6, &c[0], &c[2]);
        }
    }
    let [_, _, c2, _, c4, _, c6] = c;
    [
        v * c2[0] + mu4 * c4[0] + mu6 * c6[0],
        v * c2[1] + mu4 * c4[1] + mu6 * c6[1],
        v * c2[2] + mu4 * c4[2] + mu6 * c6[2],
    ]
}

/// Two quadratic invariants of (1), held along the integrated trajectory.
///
/// `I_c(w) = sum c_i w_i^2` is constant along (1) for every `c` with `c . a = 0` (its
/// derivative is `2 w1 w2 w3 (c . a)`; for a rigid body `c = A` gives twice the energy, `c =
/// A^2` the squared angular momentum). In `f32` each RK4 step changes the invariants by a
/// rounding of the increment (about 1e-7 rad/s per step on a body turning at 12 rad/s); they
/// set the motion's frequencies, so the integrated phase drifts like `t^(3/2)` and the fit's
/// cost is noisy at the scale of a unit of log-likelihood on a long, fast flight. Every
/// [`RESTORE_EVERY`] blocks the state is moved back onto the invariants' values at the start
/// along their gradients (`c_k w`). The `c` are two of `(0, a3, -a2)`, `(a3, 0, -a1)`, `(a2, -a1, 0)` (the
/// two largest): orthogonal to the `f32` ratios actually integrated, exactly, with no rounding
/// in their entries (the invariants of the moments `A` are not quite conserved by the rounded
/// ratios, and holding those distorted a spin near the major axis, whose nutation is the small
/// difference of the two). The invariants are evaluated to twice the `f32` precision
/// ([`crate::exact`]; in plain `f32` their own rounding, with `|w|^2` in the hundreds, sets a
/// wrong orbit). Not used with a torque ((T4)), which has none.
struct Invariants {
    c: [[f32; 3]; 2],
    value: [(f32, f32); 2],
}

impl Invariants {
    fn new(a: &[f32; 3], w0: &[f32; 3], w0_lo: &[f32; 3]) -> Self {
        let u = [[0.0, a[2], -a[1]], [a[2], 0.0, -a[0]], [a[1], -a[0], 0.0]];
        // Drop the vector without the largest |a_i| (`u[k]` lacks `a_k`: the shortest).
        let [u0, u1, u2] = u;
        let c = if a[0].abs() >= a[1].abs() && a[0].abs() >= a[2].abs() {
            [u1, u2]
        } else if a[1].abs() >= a[2].abs() {
            [u0, u2]
        } else {
            [u0, u1]
        };
        let value = c.map(|c| weighted_squares(&c, w0, w0_lo));
        Invariants { c, value }
    }

    /// Moves the state `w - w_lo` by `alpha g_1 + beta g_2` (`g_k = c_k w`, half the
    /// gradients) so that both invariants take their values to first order. The 2x2 system
    /// is ill-conditioned for a spin about a principal axis (the gradients are then nearly
    /// parallel): a ridge of 1e-6 of its trace keeps the correction the least-norm one.
    fn restore(&self, w: &[f32; 3], w_lo: &mut [f32; 3]) {
        let [c0, c1] = &self.c;
        let [(v0h, v0l), (v1h, v1l)] = self.value;
        let (h0, l0) = weighted_squares(c0, w, w_lo);
        let (h1, l1) = weighted_squares(c1, w, w_lo);
        let r = [
            0.5 * ((v0h - h0) + (v0l - l0)),
            0.5 * ((v1h - h1) + (v1l - l1)),
        ];
        let g = self.c.map(|c| [c[0] * w[0], c[1] * w[1], c[2] * w[2]]);
        let Some(gram) = Gram2::new(g[0], g[1]) else {
            return;
        };
        let (alpha, beta) = gram.solve(r[0], r[1]);
        for i in 0..3 {
            // The true state is `w - w_lo`: moving it by `d` is `w_lo -= d`.
            w_lo[i] -= alpha * g[0][i] + beta * g[1][i];
        }
    }
}

/// The variance factor for the `f32` representation of the fit itself ((T7)):
///
/// ```text
/// kappa^2 = eps^2 (p1^2 F_11 + p2^2 F_22) / sigma^2,   factor = 1 + RESOLUTION kappa^2     (T7)
/// ```
///
/// `F` the fit's information (unit noise), `sigma^2` its residual variance, `eps` the `f32`
/// epsilon: `kappa^2` is how many units of log-likelihood a relative change of `eps` in the
/// moments moves the cost by, the resolution below which the `f32` parameters (and the ratios
/// computed from them, a frequency) cannot place the optimum. It is negligible on most flights
/// and grows with the phase a long, fast flight accumulates. [`RESOLUTION`] is measured.
fn resolution_factor<const P: usize>(f: &Sym<P>, theta: &[f32; P], cost: f32, dof: f32) -> f32 {
    if !(cost > 0.0 && dof > 0.0) {
        return 1.0;
    }
    let s2 = cost / dof;
    let e2 = f32::EPSILON * f32::EPSILON;
    let k2 = e2 * (theta[0] * theta[0] * f[0][0] + theta[1] * theta[1] * f[1][1]) / s2;
    let k = 1.0 + RESOLUTION * k2;
    if k.is_finite() {
        k
    } else {
        1.0
    }
}

/// The constant of (T7): the excess of the fit's error variance over the `f64` constrained
/// maximum likelihood's on the same samples, per unit of `kappa^2`, as measured on a body
/// turning at 12 rad/s at 1 kHz for 4 s and 8 s (`bench-estimators --scenario fast-tumble`).
/// The paper's body spinning at 8 rad/s near its major axis for 20 s has `kappa^2 = 1.6`, the
/// benchmark's flights less, so the factor is 1 there to about 1e-3.
const RESOLUTION: f32 = 5e-4;

/// Blocks between restorations of the invariants (`Invariants::restore`).
const RESTORE_EVERY: usize = 8;

/// `|ybar|` of a block: with `|a_i| <= 1` a bound on how fast (1) turns there.
fn speed_bound(b: &Block<3>) -> f32 {
    let y = [b.mean(0), b.mean(1), b.mean(2)];
    sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
}

/// `df/dw` of (T3).
fn jac(a: &[f32; 3], w: &[f32; 3]) -> [[f32; 3]; 3] {
    [
        [0.0, a[0] * w[2], a[0] * w[1]],
        [a[1] * w[2], 0.0, a[1] * w[0]],
        [a[2] * w[1], a[2] * w[0], 0.0],
    ]
}

/// The right-hand side of (T3) (and of (T4) when `C = 8`: `w' = f(w) + c`, the torque's
/// sensitivity forced by the identity).
fn deriv<const C: usize>(a: &[f32; 3], dadp: &[[f32; 3]; 3], c: &[f32; 3], x: &Aug<C>) -> Aug<C> {
    let w = &x.w;
    let j = jac(a, w);
    let prod = [w[1] * w[2], w[2] * w[0], w[0] * w[1]];
    let mut s = [[0.0f32; C]; 3];
    for i in 0..3 {
        for k in 0..C {
            s[i][k] = j[i][0] * x.s[0][k] + j[i][1] * x.s[1][k] + j[i][2] * x.s[2][k];
        }
        s[i][0] += prod[i] * dadp[i][0];
        s[i][1] += prod[i] * dadp[i][1];
        if C == C_TORQUE || C == C_TESTS {
            s[i][5 + i] += 1.0;
        }
        if C == C_TESTS {
            s[i][8] += prod[i] * dadp[i][2];
        }
    }
    Aug {
        w_lo: [0.0; 3],
        w: [
            a[0] * prod[0] + c[0],
            a[1] * prod[1] + c[1],
            a[2] * prod[2] + c[2],
        ],
        s,
    }
}

/// `x + h k`.
fn axpy<const C: usize>(x: &Aug<C>, k: &Aug<C>, h: f32) -> Aug<C> {
    let mut y = *x;
    for i in 0..3 {
        y.w[i] += h * k.w[i];
        for c in 0..C {
            y.s[i][c] += h * k.s[i][c];
        }
    }
    y
}

/// One classical RK4 step of (T3) (or (T4)) with the constant torque `c`.
fn rk4<const C: usize>(
    a: &[f32; 3],
    dadp: &[[f32; 3]; 3],
    c: &[f32; 3],
    x: &Aug<C>,
    h: f32,
) -> Aug<C> {
    let k1 = deriv(a, dadp, c, x);
    let k2 = deriv(a, dadp, c, &axpy(x, &k1, 0.5 * h));
    let k3 = deriv(a, dadp, c, &axpy(x, &k2, 0.5 * h));
    let k4 = deriv(a, dadp, c, &axpy(x, &k3, h));
    let mut y = *x;
    let h6 = h / 6.0;
    for i in 0..3 {
        // Compensated: half an ulp of `w` lost per step random-walks the motion's invariants
        // (energy, momentum) and so its frequencies, and the integrated trajectory's phase drifts
        // like `t^(3/2)`; carried instead, only the increment's own rounding (a tenth of
        // that) is lost.
        let d = h6 * (k1.w[i] + 2.0 * k2.w[i] + 2.0 * k3.w[i] + k4.w[i]);
        compensated_add(&mut y.w[i], &mut y.w_lo[i], d);
        for k in 0..C {
            y.s[i][k] += h6 * (k1.s[i][k] + 2.0 * k2.s[i][k] + 2.0 * k3.s[i][k] + k4.s[i][k]);
        }
    }
    y
}

/// The weighted cost and normal equations of the first `limit` blocks at `theta`: `C = 5`
/// sensitivity columns `(p1, p2, w0)`, or `C = 8` with a constant torque in `theta[5..8]`
/// ((T4)), or `C = 9` with the torque and a step `theta[8]` off the rigid-body constraint
/// ((T5)); and when
/// `P = C + 3`, a gyro bias in `theta[C..C + 3]`. `None` when the moments
/// are not positive or anything is not finite.
fn normal<const P: usize, const C: usize>(
    blocks: &[Block<3>],
    limit: usize,
    theta: &[f32; P],
) -> Option<Normal<P>> {
    normal_with::<P, C>(blocks, limit, theta, false)
}

/// [`normal`], with `scale` the gyro's scale-factor errors `kappa` as the last three
/// parameters ((T6): the gyro reads `(1 + kappa_i)` times the block mean of `w_i`).
fn normal_with<const P: usize, const C: usize>(
    blocks: &[Block<3>],
    limit: usize,
    theta: &[f32; P],
    scale: bool,
) -> Option<Normal<P>> {
    let (mut a, d2) = ratios_of(theta[0], theta[1])?;
    // Third column: the unit normal `n` of the rigid-body constraint at `a` ((T5)), and `a`
    // moved by `delta n` (`delta = theta[5]`) when that column is asked for.
    let mut dadp = [[0.0f32; 3]; 3];
    for (row, d) in dadp.iter_mut().zip(d2.iter()) {
        row[0] = d[0];
        row[1] = d[1];
    }
    if C == C_TESTS {
        let n = constraint_normal(&a);
        for ((row, ai), ni) in dadp.iter_mut().zip(a.iter_mut()).zip(n.iter()) {
            row[2] = *ni;
            *ai += theta[8] * ni;
        }
    }
    let amax = a
        .iter()
        .fold(0.0f32, |m, x| if x.abs() > m { x.abs() } else { m });
    // The initial rates are `theta[2..5]` added to the first block's mean: as a compensated
    // state (`w - w_lo`) they keep the digits an `f32` rate of 12 rad/s would round away (one
    // ulp of an initial rate moved the cost of an 8 s flight at that speed by one unit of
    // log-likelihood: the optimum could not be represented).
    let start = blocks
        .first()
        .map_or([0.0; 3], |b| [b.mean(0), b.mean(1), b.mean(2)]);
    // `w = start + offset` rounded, `w_lo` what the rounding left (the derivatives are taken
    // at `w`, so it must be the sum itself, not `start`).
    let sum = [
        two_sum(start[0], theta[2]),
        two_sum(start[1], theta[3]),
        two_sum(start[2], theta[4]),
    ];
    let mut x = Aug::<C> {
        w: sum.map(|(s, _)| s),
        w_lo: sum.map(|(_, e)| -e),
        s: [[0.0; C]; 3],
    };
    x.s[0][2] = 1.0;
    x.s[1][3] = 1.0;
    x.s[2][4] = 1.0;
    let mut torque = [0.0f32; 3];
    if C == C_TORQUE || C == C_TESTS {
        torque = [theta[5], theta[6], theta[7]];
    }
    let invariants = torque
        .iter()
        .all(|c| *c == 0.0)
        .then(|| Invariants::new(&a, &x.w, &x.w_lo));
    let sc = if scale { 3 } else { 0 };
    let has_bias = P == C + 3 + sc;
    let mut kappa = [0.0f32; 3];
    if scale {
        kappa = [theta[P - 3], theta[P - 2], theta[P - 1]];
    }
    let mut bias = [0.0f32; 3];
    if has_bias {
        bias = [theta[C], theta[C + 1], theta[C + 2]];
    }
    let mut sums = NormalSums::<P>::EMPTY;
    let mut prev: Option<&Block<3>> = None;
    let mut speed_prev = 0.0f32;
    for (index, b) in blocks.iter().take(limit).enumerate() {
        let speed_here = speed_bound(b);
        if let Some(bp) = prev {
            let span = b.since(bp);
            if span > 0.0 {
                // The step count from the data (the faster of the two block means, `|a_i| <= 1`
                // for a rigid body), not from the parameters: a count that changed with them
                // would make the cost jump (the RK4 error of one step count against another)
                // where the fit needs it smooth; with the count from `x.w`, one ulp of an
                // initial rate would move the cost by percents on a fast flight.
                let speed = speed_prev.max(speed_here) * amax.max(1.0);
                let steps = substeps(span, speed);
                let h = span / steps as f32;
                for _ in 0..steps {
                    x = rk4(&a, &dadp, &torque, &x, h);
                }
                // Every `RESTORE_EVERY` blocks: the drift of so few steps is far below what
                // would matter, and each restoration costs about two RK4 steps.
                if let (Some(inv), 0) = (&invariants, index % RESTORE_EVERY) {
                    inv.restore(&x.w, &mut x.w_lo);
                }
            }
        }
        prev = Some(b);
        speed_prev = speed_here;
        // (T2): the block mean of w is w(tbar) + v/2 w''(tbar) + ... (the torque's part of
        // the derivatives is left out: it is zero where the test evaluates it).
        let corr = block_mean_correction(&a, &x.w, &b.time_moments());
        for i in 0..3 {
            // The state is `w - w_lo` (compensated: the initial rates' offsets live in `w_lo`),
            // the block mean `y0 + dy / n`: the residual from the deviation keeps both.
            let mean_w = (x.w[i] - x.w_lo[i]) + corr[i];
            let plain = (b.deviation(i, x.w[i]) + x.w_lo[i]) - corr[i] - bias[i];
            let mut row = [0.0f32; P];
            let r = if scale {
                // (T6): y - (1 + kappa) mean_w - b.
                let gain = 1.0 + kappa[i];
                for (dst, src) in row.iter_mut().zip(x.s[i].iter()) {
                    *dst = gain * src;
                }
                plain - kappa[i] * mean_w
            } else {
                row[..C].copy_from_slice(&x.s[i]);
                plain
            };
            if has_bias {
                row[C + i] = 1.0;
            }
            if scale {
                row[P - 3 + i] = mean_w;
            }
            sums.add(b.n, r, &row);
        }
    }
    sums.finish()
}

/// Calls `visit(ybar, G)` for each block in order, `G_i` the trapezoid integral of
/// `ybar_j ybar_k` over the block mean times up to that block.
fn for_each_integral(blocks: &[Block<3>], mut visit: impl FnMut(&[f32; 3], &[f32; 3])) {
    let mut g = [0.0f32; 3];
    let mut prev: Option<(f32, [f32; 3])> = None;
    for b in blocks {
        let (t, y) = (b.mean_time(), [b.mean(0), b.mean(1), b.mean(2)]);
        let p = [y[1] * y[2], y[2] * y[0], y[0] * y[1]];
        if let Some((tp, pp)) = prev {
            for i in 0..3 {
                g[i] += 0.5 * (pp[i] + p[i]) * (t - tp);
            }
        }
        prev = Some((t, p));
        visit(&y, &g);
    }
}

/// Per-axis least squares of the integrated (1), `ybar_i = c_i + a_i G_i`, on the block means
/// (two passes: means, then centred sums): a start for the fit.
fn initial_a(blocks: &[Block<3>]) -> Option<[f32; 3]> {
    let nb = blocks.len() as f32;
    if nb < 3.0 {
        return None;
    }
    let (mut sg, mut sy) = ([0.0f32; 3], [0.0f32; 3]);
    for_each_integral(blocks, |y, g| {
        for i in 0..3 {
            sg[i] += g[i];
            sy[i] += y[i];
        }
    });
    let (mg, my) = (sg.map(|x| x / nb), sy.map(|x| x / nb));
    let (mut sxx, mut sxy) = ([0.0f32; 3], [0.0f32; 3]);
    for_each_integral(blocks, |y, g| {
        for i in 0..3 {
            let (dx, dy) = (g[i] - mg[i], y[i] - my[i]);
            sxx[i] += dx * dx;
            sxy[i] += dx * dy;
        }
    });
    let mut a = [0.0f32; 3];
    for i in 0..3 {
        if !(sxx[i] > 0.0) {
            return None;
        }
        a[i] = sxy[i] / sxx[i];
    }
    a.iter().all(|x| x.is_finite()).then_some(a)
}

/// Trace-1 moments `(p1, p2)` from `a` (the per-axis start, which need not be a rigid body's),
/// the three ratios weighed alike: by the definition of `a` the moments solve
///
/// ```text
/// M A = 0,   M = [[a1, -1, 1], [1, a2, -1], [-1, 1, a3]]                           (T8)
/// ```
///
/// (`a1 A1 - A2 + A3 = 0` and cyclic), so `A` is taken as the eigenvector of `M^T M` with the
/// smallest eigenvalue, scaled to trace 1; the sphere when that is not a body.
///
/// Why all three: `A2/A1 = (1 + a1)/(1 - a2)` from two of them is a small difference of noisy
/// numbers on a flat body (`A3` close to `A1 + A2`, `a1` close to -1: a racquet, a plate, a
/// flight controller's board): on a short toss it often gives no body at all or one far off,
/// and the fit then takes about twice the evaluations of its trajectory for the same
/// estimates (`bench-mcu` measures the fit's cost after the benchmark's 85-sample toss).
fn moments_of(a: [f32; 3]) -> [f32; 2] {
    let m = [[a[0], -1.0, 1.0], [1.0, a[1], -1.0], [-1.0, 1.0, a[2]]];
    let mut n = [[0.0f32; 3]; 3];
    for (i, row) in n.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m[0][i] * m[0][j] + m[1][i] * m[1][j] + m[2][i] * m[2][j];
        }
    }
    let sphere = [1.0 / 3.0, 1.0 / 3.0];
    let Some(e) = eigen_symmetric3(&n) else {
        return sphere;
    };
    let v = e.vectors[0];
    let trace = v[0] + v[1] + v[2];
    let (p1, p2) = (v[0] / trace, v[1] / trace);
    if ratios_of(p1, p2).is_some() {
        [p1, p2]
    } else {
        sphere
    }
}

/// The unit normal of the rigid-body constraint `a1 + a2 + a3 + a1 a2 a3 = 0` at `a`:
/// `(1 + a2 a3, 1 + a3 a1, 1 + a1 a2)` over its length (`(1, 1, 1) / sqrt 3` if that is 0).
fn constraint_normal(a: &[f32; 3]) -> [f32; 3] {
    let g = [1.0 + a[1] * a[2], 1.0 + a[2] * a[0], 1.0 + a[0] * a[1]];
    let len = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if len > 0.0 && len.is_finite() {
        [g[0] / len, g[1] / len, g[2] / len]
    } else {
        let k = 1.0 / sqrt(3.0);
        [k, k, k]
    }
}

/// The score tests after a fit, from one evaluation `normal` at the fitted model's optimum
/// in the layout of [`P_TESTS_BIAS`] (the plain model's five, a zero torque, a zero step off
/// the constraint, the bias last), with the columns `drop` taken out (the bias's, when the
/// plain model is tested), `cost` and `dof` the model's: whether a constant torque ((T4):
/// `g^T F^-1 g` of the model with the torque, against 21.11) and whether a step off the
/// rigid-body constraint ((T5): scored beyond the model's own columns, against 15.14) reject it.
fn tests_reject(
    normal: Option<&Normal<P_TESTS_BIAS>>,
    drop: &[usize],
    cost: f32,
    dof: f32,
    noise_floor: f32,
) -> (bool, bool) {
    let Some((_, f, g)) = normal else {
        return (false, false);
    };
    let (f, g) = without(f, g, drop);
    let (ft, gt) = without(&f, &g, &[STEP_COLUMN]);
    let torque = score_beyond(&ft, &gt, &TORQUE_COLUMNS)
        .is_some_and(|sc| score_rejects(sc, cost, dof, noise_floor));
    let (fr, gr) = without(&f, &g, &TORQUE_COLUMNS);
    let rigid = score_beyond(&fr, &gr, &[STEP_COLUMN])
        .is_some_and(|sc| score_rejects_at(sc, RIGID_CHI2, cost, dof, noise_floor));
    (torque, rigid)
}

/// The columns of a constant torque ((T4)) in the layout of [`P_TESTS_BIAS`].
const TORQUE_COLUMNS: [usize; 3] = [5, 6, 7];

/// The column of the step off the rigid-body constraint ((T5)) in that layout.
const STEP_COLUMN: usize = 8;

/// The columns of the bias in that layout.
const BIAS_COLUMNS: [usize; 3] = [9, 10, 11];

/// What [`fit_stretch`] found in one stretch.
struct StretchFit {
    /// The chosen fit (unit-noise covariance).
    fit: Fit<P_MAX>,
    /// Whether it has the bias.
    biased: bool,
    /// Its parameter count.
    params: usize,
    /// The cost with a constant torque when the torque's score test ((T4)) rejected the fit
    /// and the refit confirmed it ([`torque_confirmed`]).
    torque: Option<f32>,
    /// The cost with the gyro's scale factors free ((T6)) when the rigid-body test ((T5))
    /// rejected the fit.
    scale: Option<f32>,
    /// The variance factor of (T7).
    resolution: f32,
}

/// Fits the stretch in `blocks`: the plain model on all the blocks (on growing prefixes too
/// when that does not fit, [`whole_or_staged`]), then the bias model from its result, then the
/// tests of what the model lacks.
fn fit_stretch(blocks: &[Block<3>], noise_floor: f32) -> Option<StretchFit> {
    let total = blocks.len();
    blocks.first()?;
    let p0 = initial_a(blocks).map_or([1.0 / 3.0, 1.0 / 3.0], moments_of);
    // Initial rates as offsets from the first block's mean (see `normal_with`).
    let theta5 = [p0[0], p0[1], 0.0, 0.0, 0.0];
    let (theta5, cost5, f5) = whole_or_staged(
        |th, limit| normal::<5, 5>(blocks, limit, th),
        theta5,
        total,
        noise_floor,
    )?;
    let cov5 = scaled_inverse(&f5)?;
    let mut theta8 = [0.0f32; P_MAX];
    theta8[..5].copy_from_slice(&theta5);
    let dof8 = (3 * total) as f32 - 8.0;
    let dof5 = (3 * total) as f32 - 5.0;
    // One evaluation at the plain optimum, with the columns of the bias, a constant torque and
    // a step off the constraint, decides whether the bias model is worth its fit (its score
    // without the torque's and the step's columns) and gives the plain model's tests (without
    // the bias's). Each of those columns is integrated on its own, so the two are what
    // separate evaluations would give, for the cost of one.
    let mut plain12 = [0.0f32; P_TESTS_BIAS];
    plain12[..5].copy_from_slice(&theta5);
    let at_plain = normal::<P_TESTS_BIAS, C_TESTS>(blocks, total, &plain12);
    let worth = at_plain
        .as_ref()
        .and_then(|(_, f, g)| {
            let (f, g) = without(f, g, &TORQUE_COLUMNS);
            let (f, g) = without(&f, &g, &[STEP_COLUMN]);
            score(&f, &g)
        })
        .is_none_or(|sc| bias_worth_fitting(sc, cost5, dof5, noise_floor));
    let with_bias = if worth {
        levenberg(
            |th| normal::<P_MAX, 5>(blocks, total, th),
            theta8,
            30,
            dof8,
            TOLERANCE,
            Start::Warm,
        )
        .and_then(|(th, cost, f)| {
            let k = resolution_factor(&f, &th, cost, dof8);
            scaled_inverse(&f).map(|c| (th, cost, c, k))
        })
    } else {
        None
    };
    if let Some((th8, cost8, cov8, k8)) = with_bias {
        if bias_found(cost5, cost8, dof8, noise_floor) && ratios_of(th8[0], th8[1]).is_some() {
            // The tests at the bias model's optimum: bias moved to theta[9..12].
            let mut th12 = [0.0f32; P_TESTS_BIAS];
            th12[..5].copy_from_slice(&th8[..5]);
            th12[9..].copy_from_slice(&th8[5..]);
            let at_bias = normal::<P_TESTS_BIAS, C_TESTS>(blocks, total, &th12);
            let (torque, rigid) = tests_reject(at_bias.as_ref(), &[], cost8, dof8, noise_floor);
            let torque = torque
                .then(|| {
                    // The torque's layout: bias at theta[8..11].
                    let mut th11 = [0.0f32; P_TORQUE_BIAS];
                    th11[..5].copy_from_slice(&th8[..5]);
                    th11[8..].copy_from_slice(&th8[5..]);
                    let refit = refit_cost(
                        |th| normal::<P_TORQUE_BIAS, C_TORQUE>(blocks, blocks.len(), th),
                        th11,
                        cost8,
                        dof8,
                    );
                    torque_confirmed(refit, cost8, dof8, noise_floor)
                })
                .flatten();
            let rigid = rigid.then(|| {
                // The scale factors' layout: the bias model's eight, then kappa.
                let mut th11 = [0.0f32; P_TORQUE_BIAS];
                th11[..8].copy_from_slice(&th8);
                refit_cost(
                    |th| normal_with::<P_TORQUE_BIAS, 5>(blocks, blocks.len(), th, true),
                    th11,
                    cost8,
                    dof8,
                )
                .unwrap_or(cost8)
            });
            return Some(StretchFit {
                fit: Fit {
                    theta: th8,
                    cost: cost8,
                    cov: cov8,
                },
                biased: true,
                params: 8,
                torque,
                scale: rigid,
                resolution: k8,
            });
        }
    }
    // The plain model's tests, from the evaluation at its optimum above; `theta` is that
    // optimum in the bias model's layout (a zero bias), where the refits below start.
    let theta = theta8;
    let (torque, rigid) = tests_reject(at_plain.as_ref(), &BIAS_COLUMNS, cost5, dof5, noise_floor);
    let torque = torque
        .then(|| {
            let normal_torque = |th: &[f32; P_MAX]| normal::<P_MAX, C_TORQUE>(blocks, total, th);
            let refit = refit_cost(normal_torque, theta, cost5, dof5);
            torque_confirmed(refit, cost5, dof5, noise_floor)
        })
        .flatten();
    let rigid = rigid.then(|| {
        let normal_scale = |th: &[f32; P_MAX]| normal_with::<P_MAX, 5>(blocks, total, th, true);
        refit_cost(normal_scale, theta, cost5, dof5).unwrap_or(cost5)
    });
    let mut cov = [[0.0f32; P_MAX]; P_MAX];
    for i in 0..5 {
        cov[i][..5].copy_from_slice(&cov5[i]);
    }
    Some(StretchFit {
        fit: Fit {
            theta,
            cost: cost5,
            cov,
        },
        biased: false,
        params: 5,
        torque,
        scale: rigid,
        resolution: resolution_factor(&f5, &theta5, cost5, dof5),
    })
}

impl<const N: usize> RatioFit<N> {
    /// An empty fit. Samples at or beyond `full_scale` (rad/s) are skipped (their time kept);
    /// a time step that is not finite, not positive or longer than `max_dt` ends what the
    /// stretch takes (the following samples wait for [`RatioFit::close`]). `noise_std` is the
    /// gyro's white noise per sample (rad/s): the bias test never assumes less. `N` must be at
    /// least 16 (fewer blocks are not enough to fit).
    pub const fn new(full_scale: f32, max_dt: f32, noise_std: f32) -> Self {
        RatioFit {
            state: FitState::EMPTY,
            full_scale,
            max_dt,
            noise_std,
            constraint_rejected: false,
            scale_cost: 0.0,
            readings: Readings::INSTANTS,
        }
    }

    /// The same fit for a gyro whose every reading is the mean of the rate over a window (a
    /// driver that integrates the rate over the sample interval, as PX4's `sensor_combined`
    /// does), `window` the window's time variance over the interval squared: `1/12` for the
    /// mean over the whole interval, 0 (the default) for a reading at an instant. It adds to
    /// each block's time variance ((B0)); a fit that took such readings for instants would
    /// miss `v/2 w''` in every block mean, on a fast tumble many times the noise. Values
    /// outside `[0, 1)` count as 0.
    pub const fn with_reading_window(mut self, window: f32) -> Self {
        self.readings = self.readings.with_window(window);
        self
    }

    /// The same fit for a gyro whose readings have passed through a low-pass filter (a flight
    /// controller's gyro filters), `smoothing` the second cumulant of the filter's impulse
    /// response in s^2 (`tau^2` for a first-order stage of time constant `tau`; the sum over
    /// stages in series). It adds to each block's time variance ((B0')); the filter's delay
    /// (its first cumulant) is the caller's to take out of the sample times. Betaflight's
    /// default gyro filters (first-order stages at 250 and 500 Hz at an 8 kHz loop) are
    /// 6e-7 s^2: enough that fast tosses logged at 2 kHz through them, taken for instants,
    /// come out `Converged` several standard deviations off.
    /// Values outside `[0, 1e-4]` count as 0.
    pub const fn with_reading_smoothing(mut self, smoothing: f32) -> Self {
        self.readings = self.readings.with_smoothing(smoothing);
        self
    }

    /// The same fit with the readings' spread of another fit.
    const fn with_readings(mut self, readings: Readings) -> Self {
        self.readings = readings;
        self
    }

    /// Adds one sample of the open stretch: rate (rad/s) and the time since the previous
    /// sample (s; ignored for the stretch's first sample).
    pub fn step(&mut self, omega: [f32; 3], dt: f32) {
        self.step_mean(omega, dt, 1);
    }

    /// [`RatioFit::step`] for a sample that is the mean of `inputs` equally spaced readings
    /// spanning `dt` (a decimated gyro): their time spread, `(m^2 - 1)/12 (dt/m)^2` plus the
    /// readings' own window's ((B0)), enters the block's time variance of (B1).
    pub fn step_mean(&mut self, omega: [f32; 3], dt: f32, inputs: u8) {
        let usable = omega
            .iter()
            .all(|w| w.is_finite() && w.abs() < self.full_scale);
        let [centres, own] = self.readings.spread(dt, inputs);
        let spread = centres + own;
        self.state.buf.add(&omega, usable, dt, self.max_dt, spread);
    }

    /// Ends the open stretch: fits it (see the module docs), adds its information to the
    /// pooled estimate and starts a new stretch. What happened is returned and kept
    /// ([`RatioFit::last_outcome`]).
    pub fn close(&mut self) -> StretchOutcome {
        let noise = self.noise_std;
        let mut rigid: Option<(Option<f32>, f32)> = None;
        let outcome = self.state.close(|blocks| {
            let StretchFit {
                fit,
                biased,
                params,
                torque,
                scale,
                resolution: k,
            } = fit_stretch(blocks, noise)?;
            rigid = Some((scale, fit.cost));
            Some(StretchResult {
                p: [fit.theta[0], fit.theta[1]],
                cov: [
                    [k * fit.cov[0][0], k * fit.cov[0][1]],
                    [k * fit.cov[1][0], k * fit.cov[1][1]],
                ],
                input: None,
                cost: fit.cost,
                params,
                bias: biased.then_some([fit.theta[5], fit.theta[6], fit.theta[7]]),
                lag1: 0.0,
                coloured: false,
                torque,
                scale: false,
                alt: None,
                walk: None,
            })
        });
        if matches!(
            outcome,
            StretchOutcome::Fitted | StretchOutcome::FittedWithBias
        ) {
            if let Some((scale, cost)) = rigid {
                self.constraint_rejected |= scale.is_some();
                self.scale_cost += scale.unwrap_or(cost);
            }
        }
        outcome
    }

    /// Drops the open stretch without fitting it.
    pub fn discard(&mut self) {
        self.state.buf.clear();
    }

    /// What the last [`RatioFit::close`] did.
    pub fn last_outcome(&self) -> StretchOutcome {
        self.state.last
    }

    /// Samples in the open stretch (not yet fitted).
    pub fn open_samples(&self) -> u32 {
        self.state.buf.samples()
    }

    /// The pooled estimate of the closed stretches: `p = p_1 + (sum M_s)^-1 sum M_s (p_s - p_1)`
    /// (the information-weighted mean, referred to the first stretch's `p_1`) with `M_s`
    /// each stretch's marginal information, `cov(p) = sigma^2 (sum M_s)^-1`,
    /// `sigma^2 = sum cost_s / sum dof_s`. `None` before a stretch was fitted.
    pub fn estimate(&self) -> Option<RatioFitEstimate> {
        // The ratio fit's pool reports its covariance as fitted ((P2) is the tensor fit's).
        let (p, cov, noise, _) = self.state.pooled.mean()?;
        let (a, dadp) = ratios_of(p[0], p[1])?;
        let mut std_a = [0.0f32; 3];
        for i in 0..3 {
            let j = dadp[i];
            let v = j[0] * (cov[0][0] * j[0] + cov[0][1] * j[1])
                + j[1] * (cov[1][0] * j[0] + cov[1][1] * j[1]);
            std_a[i] = sqrt(v + STD_A_ROUNDING * STD_A_ROUNDING);
        }
        // Moments: d(p1, p2, 1 - p1 - p2)/dp.
        let v3 = cov[0][0] + cov[1][1] + cov[0][1] + cov[1][0];
        let std_m = [sqrt(cov[0][0]), sqrt(cov[1][1]), sqrt(v3)];
        Some(RatioFitEstimate {
            a,
            std_a,
            moments: [p[0], p[1], 1.0 - p[0] - p[1]],
            std_moments: std_m,
            noise,
            stretches: self.state.pooled.stretches,
            samples: self.state.pooled.samples,
            biased: self.state.biased,
            bias: self.state.bias,
            torque: self.state.torque,
            constraint_rejected: self.constraint_rejected,
            cost_with_scale: self.scale_cost,
            cost: self.state.pooled.cost(),
            cost_with_torque: self.state.torque_cost,
        })
    }

    /// Forgets everything: the open stretch and the pooled estimate.
    pub fn reset(&mut self) {
        *self = RatioFit::new(self.full_scale, self.max_dt, self.noise_std)
            .with_readings(self.readings);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RK4 in f64 at 1/20 of the sample period: the reference trajectory.
    fn simulate(m: [f64; 3], w0: [f64; 3], rate: f64, n: usize) -> Vec<[f32; 3]> {
        simulate_with_torque(m, w0, rate, n, [0.0; 3])
    }

    /// `a` of (1) for the moments `m`.
    fn ratios(m: [f64; 3]) -> [f64; 3] {
        [
            (m[1] - m[2]) / m[0],
            (m[2] - m[0]) / m[1],
            (m[0] - m[1]) / m[2],
        ]
    }

    /// One classical RK4 step of `x' = f(x)` over `h`.
    fn rk4_step<const K: usize>(f: impl Fn([f64; K]) -> [f64; K], x: &mut [f64; K], h: f64) {
        let k1 = f(*x);
        let k2 = f(core::array::from_fn(|i| x[i] + 0.5 * h * k1[i]));
        let k3 = f(core::array::from_fn(|i| x[i] + 0.5 * h * k2[i]));
        let k4 = f(core::array::from_fn(|i| x[i] + h * k3[i]));
        for i in 0..K {
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }

    /// [`simulate`] with a constant angular acceleration `c` added to (1).
    fn simulate_with_torque(
        m: [f64; 3],
        w0: [f64; 3],
        rate: f64,
        n: usize,
        c: [f64; 3],
    ) -> Vec<[f32; 3]> {
        let a = ratios(m);
        let f = |w: [f64; 3]| {
            [
                a[0] * w[1] * w[2] + c[0],
                a[1] * w[2] * w[0] + c[1],
                a[2] * w[0] * w[1] + c[2],
            ]
        };
        let h = 1.0 / rate / 20.0;
        let mut w = w0;
        let mut out = Vec::new();
        for _ in 0..n {
            out.push(w.map(|x| x as f32));
            for _ in 0..20 {
                rk4_step(f, &mut w, h);
            }
        }
        out
    }

    extern crate std;
    use std::vec::Vec;

    /// Readings that are each the mean of the rate over the sample interval before them (a
    /// gyro that integrates, as PX4's `sensor_combined` reports): RK4 in `f64` of (1) and of
    /// its integral together, 20 steps per interval, the reading the integral's increment
    /// over the interval.
    fn simulate_means(m: [f64; 3], w0: [f64; 3], rate: f64, n: usize) -> Vec<[f32; 3]> {
        let a = ratios(m);
        // State (w, W), W' = w.
        let f = |x: [f64; 6]| {
            [
                a[0] * x[1] * x[2],
                a[1] * x[2] * x[0],
                a[2] * x[0] * x[1],
                x[0],
                x[1],
                x[2],
            ]
        };
        let dt = 1.0 / rate;
        let h = dt / 20.0;
        let mut x = [w0[0], w0[1], w0[2], 0.0, 0.0, 0.0];
        let mut out = Vec::new();
        for _ in 0..n {
            let start = [x[3], x[4], x[5]];
            for _ in 0..20 {
                rk4_step(f, &mut x, h);
            }
            out.push(core::array::from_fn(|i| {
                ((x[3 + i] - start[i]) / dt) as f32
            }));
        }
        out
    }

    /// A fast tumble logged at 250 Hz as interval means: with the readings' window counted
    /// ((B0), `1/12`) the noise-free error stays below 1e-5; taken for instants it is
    /// hundreds of times larger (the block means miss `dt^2/24 w''`).
    #[test]
    fn readings_that_are_interval_means() {
        let m = [12.3, 1.0, 13.3];
        let (rate, n) = (250.0, 250);
        let ys = simulate_means(m, [23.7, -5.4, 1.5], rate, n);
        let t = truth(m);
        let mut worst = [0.0f32; 2];
        for (k, window) in [0.0, 1.0 / 12.0].into_iter().enumerate() {
            let mut fit =
                RatioFit::<256>::new(f32::INFINITY, 0.1, 1e-4).with_reading_window(window);
            for y in &ys {
                fit.step(*y, (1.0 / rate) as f32);
            }
            let outcome = fit.close();
            std::println!("window {window}: {outcome:?}");
            // Taken for instants the model error looks like a bias to the fit's test.
            assert!(k == 0 || outcome == StretchOutcome::Fitted, "{outcome:?}");
            let e = fit.estimate().unwrap();
            worst[k] = (0..3).map(|i| (e.a[i] - t[i]).abs()).fold(0.0, f32::max);
        }
        std::println!(
            "interval means: error {:.1e} as instants, {:.1e} as means",
            worst[0],
            worst[1]
        );
        assert!(worst[1] < 1e-5, "{worst:?}");
        assert!(worst[0] > 100.0 * worst[1], "{worst:?}");
    }

    fn truth(m: [f64; 3]) -> [f32; 3] {
        ratios(m).map(|x| x as f32)
    }

    #[test]
    fn noise_free_paper_body_at_100_hz_and_1_khz() {
        for (rate, secs) in [(100.0, 20.0), (1000.0, 20.0)] {
            let m = [0.6, 1.54, 1.0];
            let ys = simulate(m, [1.0, 1.0, 1.0], rate, (rate * secs) as usize);
            let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
            for y in &ys {
                fit.step(*y, (1.0 / rate) as f32);
            }
            assert_eq!(fit.close(), StretchOutcome::Fitted);
            let e = fit.estimate().unwrap();
            assert!(!e.torque, "{rate} Hz: a torque found on a free body");
            let t = truth(m);
            std::println!(
                "{rate} Hz: error {:?}",
                core::array::from_fn::<f32, 3, _>(|i| e.a[i] - t[i])
            );
            for i in 0..3 {
                assert!(
                    (e.a[i] - t[i]).abs() < 1e-5,
                    "{rate} Hz: {:?} vs {t:?}",
                    e.a
                );
            }
        }
    }

    #[test]
    fn fast_toss_at_100_hz() {
        let m = [12.3, 1.0, 13.3];
        let ys = simulate(m, [7.9, -1.8, 0.5], 100.0, 85);
        let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
        for y in &ys {
            fit.step(*y, 0.01);
        }
        assert_eq!(fit.close(), StretchOutcome::Fitted);
        let e = fit.estimate().unwrap();
        let t = truth(m);
        for i in 0..3 {
            assert!((e.a[i] - t[i]).abs() < 1e-5, "{:?} vs {t:?}", e.a);
        }
    }

    #[test]
    fn a_constant_bias_is_found_and_removed() {
        let m = [0.6, 1.54, 1.0];
        let ys = simulate(m, [1.0, 1.0, 1.0], 1000.0, 10_000);
        let b = [2e-3f32, -1.5e-3, 1e-3];
        let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
        // Deterministic pseudo-noise so the test sees a residual.
        let mut s = 1u32;
        let mut noise = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for y in &ys {
            let z = [
                y[0] + b[0] + 4e-3 * noise(),
                y[1] + b[1] + 4e-3 * noise(),
                y[2] + b[2] + 4e-3 * noise(),
            ];
            fit.step(z, 1e-3);
        }
        assert_eq!(fit.close(), StretchOutcome::FittedWithBias);
        let e = fit.estimate().unwrap();
        assert!(!e.torque, "a torque found on a free body with a gyro bias");
        let t = truth(m);
        for i in 0..3 {
            assert!(
                (e.a[i] - t[i]).abs() < 5.0 * e.std_a[i],
                "{:?} vs {t:?} ({:?})",
                e.a,
                e.std_a
            );
            assert!((e.bias[i] - b[i]).abs() < 2e-4, "{:?}", e.bias);
        }
    }

    /// A noisy pseudo-random sequence, uniform in [-0.5, 0.5).
    fn uniform(seed: u32) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        }
    }

    #[test]
    fn a_constant_torque_is_found_and_its_absence_is_not() {
        let m = [0.8, 1.3, 1.7];
        for (c, with_bias, found) in [
            ([0.0; 3], false, false),
            ([0.0; 3], true, false),
            ([2e-3, -1e-3, 1.5e-3], false, true),
            ([2e-3, -1e-3, 1.5e-3], true, true),
        ] {
            let ys = simulate_with_torque(m, [1.2, 0.4, 0.9], 500.0, 3000, c);
            let b = if with_bias {
                [2e-3f32, -1.5e-3, 1e-3]
            } else {
                [0.0; 3]
            };
            let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 2e-3);
            let mut noise = uniform(7);
            for y in &ys {
                // Uniform noise of standard deviation 2e-3 (7e-3 / sqrt(12)).
                let z: [f32; 3] = core::array::from_fn(|i| y[i] + b[i] + 7e-3 * noise());
                fit.step(z, 2e-3);
            }
            fit.close();
            let e = fit.estimate().unwrap();
            assert_eq!(e.torque, found, "torque {c:?}, bias {with_bias}");
        }
    }

    #[test]
    fn ratios_no_rigid_body_has_are_found_and_a_rigid_body_passes() {
        let m = [0.8, 1.3, 1.7];
        let ys = simulate(m, [1.2, 0.4, 0.9], 500.0, 3000);
        for (k, with_bias, found) in [
            ([1.0f32; 3], false, false),
            ([1.0; 3], true, false),
            ([1.0, 1.005, 0.997], false, true),
            ([1.0, 1.005, 0.997], true, true),
        ] {
            let b = if with_bias {
                [2e-3f32, -1.5e-3, 1e-3]
            } else {
                [0.0; 3]
            };
            let mut fit = RatioFit::<256>::new(f32::INFINITY, 0.1, 2e-3);
            let mut noise = uniform(11);
            for y in &ys {
                let z: [f32; 3] = core::array::from_fn(|i| k[i] * y[i] + b[i] + 7e-3 * noise());
                fit.step(z, 2e-3);
            }
            fit.close();
            let e = fit.estimate().unwrap();
            assert_eq!(
                e.constraint_rejected, found,
                "scale {k:?}, bias {with_bias}"
            );
        }
    }

    #[test]
    fn still_gyro_and_bad_time_give_no_estimate() {
        let mut fit = RatioFit::<64>::new(f32::INFINITY, 0.1, 1e-3);
        for _ in 0..1000 {
            fit.step([0.01, 0.0, 0.0], 1e-3);
        }
        let o = fit.close();
        assert!(matches!(o, StretchOutcome::Failed), "{o:?}");
        assert!(fit.estimate().is_none());
        for k in 0..100 {
            fit.step([1.0, 1.0, 1.0], if k == 3 { f32::NAN } else { 1e-3 });
        }
        // Three samples before the bad step: too short to fit.
        assert_eq!(fit.close(), StretchOutcome::TooShort);
        for _ in 0..5 {
            fit.step([f32::NAN; 3], 1e-3);
        }
        assert_eq!(fit.close(), StretchOutcome::Empty);
    }
}
