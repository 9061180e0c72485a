//! Output-error maximum likelihood of the whole inertia tensor in kg m^2, with a known rotor
//! momentum: the trajectory of Euler's equation fitted to block means of the gyro.
//!
//! # Why
//!
//! [`crate::TensorEstimator`] solves Euler's equation integrated per stretch by least squares:
//! one pass, no iteration, cheap per sample, but the measured rates enter its regressors, so
//! their noise is in both sides of the equations and the estimate is not efficient (1.5-2.2x
//! the Cramer-Rao bound per entry on the simulated flywheel throw). The output-error fit is the
//! efficient estimator for white gyro noise; like [`crate::RatioFit`] it only sums blocks per
//! sample and fits once per free flight.
//!
//! # The model
//!
//! In the body (sensor) frame, with the rotor momentum `h(t)` known (rotor inertia times rotor
//! speed along its axis) and `L = J w + h` the body's total angular momentum,
//!
//! ```text
//! L' = L x w,   w = J^-1 (L - h(t))                                              (F1)
//! y_k = w(t_k) + b + n_k,   n_k white, variance sigma^2 per axis                   (F2)
//! ```
//!
//! which is `J w' + w x (J w + h) = -h'` (torque-free). `theta = (Jxx, Jyy, Jzz, Jxy, Jxz,
//! Jyz, w(t_0), [b])`: with a rotor whose momentum changes or is not parallel to `w`, the scale
//! of `J` is observable and `J` comes out in kg m^2.
//!
//! # Sensitivities
//!
//! With `E_c` the symmetric unit direction of entry `c` and `Sigma = dL/dtheta`,
//!
//! ```text
//! dw/dtheta_c = J^-1 (Sigma_c - E_c w)      (E_c = 0 for the initial rates)
//! Sigma_c'    = Sigma_c x w + L x dw/dtheta_c                                      (F3)
//! Sigma_c(t_0) = E_c w(t_0) (entries of J),  J e_k (initial rate k)
//! ```
//!
//! integrated with (F1) by RK4 between block means (steps of at most `0.1 / rate`, `rate =
//! max(1, a_max) |w| + sqrt(h^T J h / det J)` from the data and the first guess: how fast Euler's
//! equation turns the rates and the rotor's nutation, see `StepRule`), `h(t)` quadratic between
//! block means (through the block means corrected by (B1), with their second
//! differences as curvature). A block's mean rate is predicted by (B1) of the block buffer
//! with `w'' = J^-1 ((L x w) x w + L x w')`, `w' = J^-1 (L x w - h')` (`h''` neglected). The
//! bias model (`b`, three more parameters) replaces the plain one by the likelihood-ratio test;
//! stretches are pooled by the information on the six entries (see `output_error`). Without
//! rotor momentum the integrated momentum is held on the two invariants `|L|^2` and `L . J^-1 L`
//! of (F1) ((F6), every eight blocks, evaluated to twice the `f32` precision): on a fast 8 s
//! tumble the `f32` drift of the motion's phase had left the fit up to scale 1.1-1.4x its bound.
//! The sensitivities are moved with the state, so the invariants' derivatives keep their
//! start's and the Jacobian stays that of the restored trajectory.
//!
//! Up to scale (below), each fit is followed by the score test of a constant torque `q` that
//! the free flight should not have (as [`crate::RatioFit`]'s, see there):
//!
//! ```text
//! L' = L x w + q,   Sigma_q' = Sigma_q x w + L x dw/dq + I,   Sigma_q(t_0) = 0        (F4)
//! ```
//!
//! at `q = 0`, against 21.11 (chi-square, 3 degrees of freedom, 0.01 %), a rejection confirmed
//! by the likelihood ratio of the model refitted with the torque. And by the score test
//! of the gyro's scale-factor errors `kappa`, the gyro reading `(1 + kappa_i) w_i`:
//!
//! ```text
//! ybar_i = (1 + kappa_i) (w_i(tbar) + v/2 w_i''(tbar)),   d ybar_i / d kappa_i = w_i + v/2 w_i''   (F5)
//! ```
//!
//! at `kappa = 0`, scored beyond the fitted model's own columns, against 21.11. A scale error
//! keeps the rates of a torque-free body with other ratios (see [`crate::RatioFit`]), which the
//! products of inertia partly absorb: on a principal body with the gyro 0.5 % and 0.3 % off on
//! two axes the products were found and the tensor's `a` said `Converged` 10-35 standard
//! deviations off (`scripts/sweep-identify.sh`, row `trap-scale`); a sensor turned off the
//! principal axes is the tensor's own model and passes.
//!
//! With a rotor, the momentum `h` is only as good as the speed telemetry: quantised (DShot's 100
//! eRPM, 1.75 rad/s for a 12-pole motor), with an error that stays one constant wherever the
//! speed is steady (an idle speed between two steps). Given the quantum
//! ([`TensorFit::with_momentum_resolution`]), the absolute fit takes one unknown offset of the
//! momentum along its direction `u` per steady run of the speed (up to four runs of at least
//! three blocks within one quantum, `steady_cells`) and fits it with the rest, under a prior of
//! a quantum's uniform variance `q^2 / 12` (a pseudo-observation of weight `sigma^2 / (q^2 /
//! 12)` in the cost):
//!
//! ```text
//! L = J w + h + d_c u (over run c),   dw/dd_c = J^-1 (Sigma_c - u) (on) or J^-1 Sigma_c,
//! Sigma_c' = A Sigma_c - M u (on) or A Sigma_c,   Sigma_c(t_0) = u if on at t_0        (F7)
//! ```
//!
//! (`A`, `M` as in `deriv`). Why fitted and not only counted in the covariance: the offsets
//! are well determined by the flight (the gyroscopic coupling sees them), so fitting them costs
//! the tensor little (its variance 1-3x the exact momentum's, where taking them as errors of
//! uniform variance would have made it tens of times larger). On simulated board throws at the
//! logged resolution (`tensor-bench`) the errors went from 46-115x the white-noise bound to
//! 1.6-10x; the errors along the ramps, where the reading changes from block to block, are
//! left (they also act on later blocks through the integrated momentum, which neither the
//! residual's level nor the offsets count: the reported standard deviation is up to 2.3x too
//! small there). The fit is kept only when every offset came out within one quantum (a
//! quantisation's error is at most half of one): on the thrown-FC logs, whose model error is
//! tens of times the gyro's noise, free offsets came out at 5-20 quanta, soaking up that error,
//! and the fit without them is taken. A first version (2026-11-26) only added the offsets'
//! effect to the covariance: as honest, ten times less accurate.
//!
//! Elsewhere (along the ramps, on runs too short for an offset, and everywhere when the
//! offsets were not kept) the reading's error is counted in the covariance ((F8),
//! `input_cov`). An error `e_b` of block `b`'s momentum enters its residual directly and every
//! later one through the integrated momentum (`delta L' = A delta L - (L x J^-1 u) e`, as
//! (F7)), so the gradient `g = sum_b n_b R_b^T r_b` (`R_b` the block's rows `dw/dtheta`) moves
//! by `sum_b gamma_b e_b` with
//!
//! ```text
//! gamma_b = a_b u - (sum_(b' > b) a_b' Phi_b') c_b,   a_b = n_b R_b^T J^-1,
//! c_b = Phi_b^-1 beta_b,   beta_b = -(L_b x J^-1 u) Delta_b,   Phi_b = Phi(t_b, t_0)   (F8)
//! cov += F^-1 (sum_groups v_g gamma_g gamma_g^T) F^-1
//! ```
//!
//! (`Phi` the transition of (F3), read from the initial rates' columns, `Sigma_w0 = Phi J`;
//! `Delta_b` the half spans either side of the node). Blocks within one quantum of a group's
//! first share its error (a held reading); a group's variance is `q^2 / 12` times
//! `ramp_share`, which the sawtooth of a moving reading averages down. The residual's
//! variance that scales the rest of the covariance is taken without the cost those errors are
//! expected to leave (`sum_b n_b (v_b |J^-1 u|^2 + tr(J^-1 Phi_b C_b Phi_b^T J^-1))`, the
//! direct part and the integrated momentum's, `C_b = sum_(k < b) v_k c_k c_k^T`, less what the
//! fit takes up, `tr(F^-1 K)`; not below the gyro's noise), so they are not counted twice: on
//! the light board they are several times the gyro's noise per block, and the products'
//! standard deviation was twice their errors. On simulated light board throws
//! (`tensor-bench`, 100 seeds) the pipeline's reported standard deviation went from 0.67-1.95
//! of its errors to 0.59-1.09 with the errors counted, 0.77-1.19 once the residual's variance
//! no longer counted them too (Jxx 1.00, Jyy 1.19, Jzz 1.02, Jxy 0.77, Jxz 0.99, Jyz 1.05); on
//! assembly throws through `inertia identify` (`calibrate_sim`) RMS 1.32 -> 0.97; the
//! thrown-FC logs' are set by their model error and did not move.
//!
//! The fit starts from an estimate of `J` the caller gives (the pipeline gives
//! [`crate::TensorEstimator`]'s) and the first block's rate, on all the blocks at once, and on
//! growing prefixes of them only when that does not fit to twice the noise.
//!
//! # Up to scale
//!
//! Without rotor momentum (`h = 0`), `w(t)` of (F1) does not change when `J` is multiplied by
//! any constant: only `J / trace J` is determined. [`TensorFit::close_normalized`] then holds
//! the trace at the first guess's, `Jzz = tr - Jxx - Jyy`, fits the five free entries (the
//! sensitivity to `Jxx` is `dw/dJxx - dw/dJzz`, the same for `Jyy`) with `w(t_0)` and the
//! optional bias, and reports them divided by the trace, their covariance by its square
//! (rank 5 over the six entries: `dJzz = -dJxx - dJyy`). It is the tensor's counterpart of
//! [`crate::RatioFit`] (which assumes principal axes) and is pooled apart from the absolute
//! fits.
//!
//! Cost (measured by `bench-mcu` on the Cortex-M4F, release / flight build): 225 / 308
//! instructions per sample; one fit of a 0.6 s throw at 2 kHz 11.9 M / 11.4 M instructions
//! (16.8 M / 19.7 M with the rotor telemetry's offsets of (F7): four more parameters),
//! about 0.07 s at 168 MHz (28 M / 27 M when the model does not fit to the noise and
//! the fit from the rotor's spin-up follows); up to scale, 20 s of a slow tumble at 1 kHz from a
//! first guess 2 % off 13.4 M / 13.5 M (0.08 s; about 8.6 M from the pipeline's own first
//! guesses) and a 0.85 s toss at 100 Hz 3.0 M / 3.1 M
//! (34, 50, 43 and 30 M in release before 2026-11-26): too long for one gyro period, which is
//! why the pipeline runs it in [`crate::Pipeline::fit_ended_flight`], outside its per-sample
//! step.
#![allow(
    // Fixed-size loops over the 3 axes and the parameters read as the equations; the crate's
    // link-time no-panic check proves no bounds check survives.
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    // `!(x > 0.0)` is true for NaN too, which is the point.
    clippy::neg_cmp_op_on_partial_ord
)]

use crate::exact::{compensated_add, quadratic_form, weighted_squares};
use crate::linalg::{det, dot, solve, Gram2};
use crate::output_error::{
    bias_found, bias_worth_fitting, higher_orders, levenberg, mean_spread, refit_cost,
    scaled_inverse, score, score_beyond, score_rejects, staged_fit, substeps, torque_confirmed,
    without, Block, FitState, Normal, NormalSums, Pooled, Start, StretchResult, TOLERANCE,
};
use crate::symmetric::{eigen_symmetric3, sqrt, Sym};
use crate::trajectory::StretchOutcome;

type Mat3 = [[f32; 3]; 3];

/// Parameters without the bias: six entries and the initial rate.
const P0: usize = 9;
/// With the bias.
const P1: usize = 12;

/// The pooled estimate of [`TensorFit`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorFitEstimate {
    /// `J` in kg m^2, sensor frame.
    pub tensor: [[f32; 3]; 3],
    /// Covariance of the entries `(Jxx, Jyy, Jzz, Jxy, Jxz, Jyz)`, (kg m^2)^2.
    pub cov: [[f32; 6]; 6],
    /// Gyro noise per sample seen in the fits' residuals, rad/s.
    pub noise: f32,
    /// Stretches (free flights) that gave a fit.
    pub stretches: u32,
    /// Samples in them.
    pub samples: u32,
    /// True when a constant gyro bias was found on any stretch.
    pub biased: bool,
    /// The bias of the last stretch fitted with the bias model, rad/s.
    pub bias: [f32; 3],
    /// True when the score test of a constant torque ((F4)) rejected the torque-free model on
    /// any stretch fitted up to scale ([`TensorFit::close_normalized`]; the absolute fits are
    /// not tested).
    pub torque: bool,
    /// True when the score test of the gyro's scale-factor errors ((F5)) rejected the model on
    /// any stretch fitted up to scale: the rates fit no rigid body read by a gyro with exact
    /// scale factors (an uncalibrated gyro, typically 0.5-1 % off, or a body that is not
    /// rigid); the tensor's products of inertia may be soaking it up.
    pub scale_rejected: bool,
    /// The fits' weighted cost `sum_b n_b |ybar_b - w_b|^2` summed over the pooled stretches,
    /// (rad/s)^2.
    pub cost: f32,
}

/// Output-error fit of (F1) over free flights, `N` blocks per flight (see the module docs).
///
/// ```
/// use identifier_core::{StretchOutcome, TensorFit};
///
/// // A body of diagonal inertia (2, 3, 4)e-4 kg m^2 with a flywheel of 1.7e-6 kg m^2 on z
/// // spinning up from 200 to 1200 rad/s, sampled at 1 kHz for 0.8 s.
/// let j = [2e-4f64, 3e-4, 4e-4];
/// let hz = |t: f64| 1.7e-6 * (200.0 + 1250.0 * t);
/// let mut l = [2e-4 * 9.0, 3e-4 * -6.0, 4e-4 * 14.0 + hz(0.0)];
/// let mut fit = TensorFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
/// let mut t = 0.0;
/// for _ in 0..800 {
///     let w = [l[0] / j[0], l[1] / j[1], (l[2] - hz(t)) / j[2]];
///     fit.step(w.map(|x| x as f32), [0.0, 0.0, hz(t) as f32], 1e-3);
///     for _ in 0..100 {
///         // L' = L x w, midpoint steps of 10 us (an example, not a reference).
///         let f = |l: [f64; 3], t: f64| {
///             let w = [l[0] / j[0], l[1] / j[1], (l[2] - hz(t)) / j[2]];
///             [l[1] * w[2] - l[2] * w[1], l[2] * w[0] - l[0] * w[2], l[0] * w[1] - l[1] * w[0]]
///         };
///         let d = f(l, t);
///         let mid = [l[0] + 5e-6 * d[0], l[1] + 5e-6 * d[1], l[2] + 5e-6 * d[2]];
///         let d = f(mid, t + 5e-6);
///         for k in 0..3 {
///             l[k] += 1e-5 * d[k];
///         }
///         t += 1e-5;
///     }
/// }
/// // The flight ends: one fit, from a first guess 10 % off.
/// let guess = [[2.2e-4, 0.0, 0.0], [0.0, 2.7e-4, 0.0], [0.0, 0.0, 4.4e-4]];
/// let outcome = fit.close(Some(guess));
/// assert_eq!(outcome, StretchOutcome::Fitted);
/// let e = fit.estimate().unwrap();
/// for k in 0..3 {
///     assert!((e.tensor[k][k] as f64 - j[k]).abs() < 0.01 * j[k], "{:?}", e.tensor);
/// }
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorFit<const N: usize> {
    /// The open stretch's blocks (rate, rotor momentum) and the six entries pooled over closed
    /// stretches.
    state: FitState<N, 6, 6>,
    /// The five free entries of `J / trace J` pooled over stretches fitted up to scale.
    normalized: Pooled<5>,
    full_scale: f32,
    max_dt: f32,
    noise_std: f32,
    /// Quantum of the rotor momentum as read, kg m^2/s ([`TensorFit::with_momentum_resolution`]).
    momentum_resolution: f32,
    /// The most inputs averaged into one sample ([`TensorFit::step_mean`]): the readings a
    /// block's sample stands for in (F8).
    inputs: u8,
}

/// The block buffer used by the pipeline: 256 blocks of rate and rotor momentum (16.7 KB in
/// all).
pub type FlightTensorFit = TensorFit<256>;

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn mul(m: &Mat3, v: [f32; 3]) -> [f32; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `J` from its six entries.
fn tensor_of(e: &[f32]) -> Mat3 {
    let g = |i: usize| e.get(i).copied().unwrap_or(0.0);
    [[g(0), g(3), g(4)], [g(3), g(1), g(5)], [g(4), g(5), g(2)]]
}

/// `J^-1` by the adjugate, `None` unless `J` is positive definite (leading minors).
fn inverse_pd(j: &Mat3) -> Option<Mat3> {
    let m1 = j[0][0];
    let m2 = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let c00 = j[1][1] * j[2][2] - j[1][2] * j[2][1];
    let c01 = j[1][2] * j[2][0] - j[1][0] * j[2][2];
    let c02 = j[1][0] * j[2][1] - j[1][1] * j[2][0];
    let det = j[0][0] * c00 + j[0][1] * c01 + j[0][2] * c02;
    if !(m1 > 0.0 && m2 > 0.0 && det > 0.0 && det.is_finite()) {
        return None;
    }
    let k = 1.0 / det;
    let inv = [
        [
            c00 * k,
            (j[0][2] * j[2][1] - j[0][1] * j[2][2]) * k,
            (j[0][1] * j[1][2] - j[0][2] * j[1][1]) * k,
        ],
        [
            c01 * k,
            (j[0][0] * j[2][2] - j[0][2] * j[2][0]) * k,
            (j[0][2] * j[1][0] - j[0][0] * j[1][2]) * k,
        ],
        [
            c02 * k,
            (j[0][1] * j[2][0] - j[0][0] * j[2][1]) * k,
            (j[0][0] * j[1][1] - j[0][1] * j[1][0]) * k,
        ],
    ];
    inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
}

/// `E_c w` for the symmetric unit direction of entry `c` (xx, yy, zz, xy, xz, yz).
fn e_times(c: usize, w: [f32; 3]) -> [f32; 3] {
    match c {
        0 => [w[0], 0.0, 0.0],
        1 => [0.0, w[1], 0.0],
        2 => [0.0, 0.0, w[2]],
        3 => [w[1], w[0], 0.0],
        4 => [w[2], 0.0, w[0]],
        5 => [0.0, w[2], w[1]],
        _ => [0.0; 3],
    }
}

/// Sensitivity columns with a constant torque's ((F4)): six entries, three initial rates,
/// three torques.
const C_TORQUE: usize = P0 + 3;

/// Steady stretches of the rotor speed whose momentum errors (F7) follows.
const CELLS: usize = 4;

/// Whether a fit of `P` parameters holds the rotor momentum's offsets of (F7): the absolute
/// fits with [`CELLS`] more (the steady runs are given exactly when they are). Decided by `P`,
/// not by the runs, so each parameter count integrates one layout and only that one is built.
const fn has_offsets(p: usize) -> bool {
    p == P0 + CELLS || p == P1 + CELLS
}

/// Sensitivity columns with the rotor momentum's errors of (F7): six entries, three initial
/// rates, one error per steady stretch ([`Cells`]).
const C_OFFSET: usize = P0 + CELLS;

/// `L` and `Sigma = dL/dtheta` (columns: six entries, three initial rates, and when `C =
/// 12` a constant torque, when `C = 13` the rotor momentum's errors of (F7)).
#[derive(Clone, Copy, Debug)]
struct Aug<const C: usize> {
    l: [f32; 3],
    /// Compensation of `l`'s running sum (Kahan): the increments are a few percent of `L`,
    /// and `f32` rounding of `L` is amplified by `J^-1` in `w`.
    lc: [f32; 3],
    s: [[f32; C]; 3],
}

/// `dw/dtheta` (3 x C) at `w`: `J^-1 (Sigma_c - E_c w)`.
fn rate_sens<const C: usize>(k: &Mat3, x: &Aug<C>, w: [f32; 3]) -> [[f32; C]; 3] {
    let mut u = [[0.0f32; C]; 3];
    for c in 0..C {
        let col = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let v = if c < 6 { sub(col, e_times(c, w)) } else { col };
        let d = mul(k, v);
        for i in 0..3 {
            u[i][c] = d[i];
        }
    }
    u
}

/// The right-hand side of (F1) and (F3) at rotor momentum `h` (and of (F4) when `C = 12`:
/// `L' = L x w + q`, the torque's sensitivity forced by the identity). With `u_c = J^-1
/// (Sigma_c - E_c w)`, (F3)'s `Sigma_c' = Sigma_c x w + L x u_c` is
///
/// ```text
/// Sigma_c' = A Sigma_c - M E_c w,   M = [L]x J^-1,   A = M - [w]x
/// ```
///
/// one 3x3 product per column and stage (`M` and `A` once per stage) instead of a product and
/// two cross products: about a third fewer multiply-adds in the fit's inner loop (counted).
fn deriv<const C: usize>(k: &Mat3, h: [f32; 3], f: &Forcing, x: &Aug<C>) -> Aug<C> {
    let q = &f.torque;
    let w = mul(k, sub(x.l, h));
    let l = x.l;
    // M = [L]x K: row i of [L]x has the two entries (L_j, -L_k) of `L x v`.
    let mut m = [[0.0f32; 3]; 3];
    for c in 0..3 {
        m[0][c] = l[1] * k[2][c] - l[2] * k[1][c];
        m[1][c] = l[2] * k[0][c] - l[0] * k[2][c];
        m[2][c] = l[0] * k[1][c] - l[1] * k[0][c];
    }
    // A = M - [w]x (`S x w = -[w]x S`).
    let mut a = m;
    a[0][1] += w[2];
    a[0][2] -= w[1];
    a[1][0] -= w[2];
    a[1][2] += w[0];
    a[2][0] += w[1];
    a[2][1] -= w[0];
    // M E_c w for the six entries (`E_c w` has one or two entries of `w`).
    let col = |i: usize, s: f32| [m[0][i] * s, m[1][i] * s, m[2][i] * s];
    let add = |p: [f32; 3], q: [f32; 3]| [p[0] + q[0], p[1] + q[1], p[2] + q[2]];
    let forcing = [
        col(0, w[0]),
        col(1, w[1]),
        col(2, w[2]),
        add(col(0, w[1]), col(1, w[0])),
        add(col(0, w[2]), col(2, w[0])),
        add(col(1, w[2]), col(2, w[1])),
    ];
    let mut s = [[0.0f32; C]; 3];
    for c in 0..C {
        let sc = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let mut v = mul(&a, sc);
        if let Some(f) = forcing.get(c) {
            v = sub(v, *f);
        }
        for i in 0..3 {
            s[i][c] = v[i];
        }
    }
    if C == C_TORQUE {
        for (i, row) in s.iter_mut().enumerate() {
            if let Some(v) = row.get_mut(P0 + i) {
                *v += 1.0;
            }
        }
    }
    if C == C_OFFSET {
        // (F7): `Sigma_d' = A Sigma_d - M u` while the error is on.
        let mu = mul(&m, f.offset);
        for (c, on) in f.on.iter().enumerate() {
            if *on {
                for (row, v) in s.iter_mut().zip(mu) {
                    if let Some(x) = row.get_mut(P0 + c) {
                        *x -= v;
                    }
                }
            }
        }
    }
    let lw = cross(x.l, w);
    Aug {
        l: [lw[0] + q[0], lw[1] + q[1], lw[2] + q[2]],
        lc: [0.0; 3],
        s,
    }
}

fn axpy<const C: usize>(x: &Aug<C>, k: &Aug<C>, h: f32) -> Aug<C> {
    let mut y = *x;
    for i in 0..3 {
        y.l[i] += h * k.l[i];
        for c in 0..C {
            y.s[i][c] += h * k.s[i][c];
        }
    }
    y
}

/// `(K + K^T) / 2`: the inverse's rounding leaves the two triangles a few ulps apart, and
/// `L . K L` is conserved along (F1) only for a symmetric `K`.
fn symmetric(k: Mat3) -> Mat3 {
    let mut s = k;
    for i in 0..3 {
        for j in (i + 1)..3 {
            let v = 0.5 * (k[i][j] + k[j][i]);
            s[i][j] = v;
            s[j][i] = v;
        }
    }
    s
}

/// Blocks between restorations of the invariants ([`Invariants::restore`]).
const RESTORE_EVERY: usize = 8;

/// The two quadratic invariants of (F1) without rotor momentum or torque, held along the
/// integrated trajectory (the tensor's analogue of the ratio fit's, see
/// [`crate::trajectory`]):
///
/// ```text
/// |L|^2 = const,   L . K L = 2 E = const,   K = J^-1 symmetric          (F6)
/// ```
///
/// (`d|L|^2/dt = 2 L . (L x w) = 0`, `d(L . K L)/dt = 2 w . (L x w) = 0` for `w = K L`). In
/// `f32` every RK4 step changes them by a rounding of its increment; they set the motion's
/// frequencies, so over a long, fast flight the integrated phase drifts and the fit's cost is
/// noisy on the scale of a unit of log-likelihood. Every [`RESTORE_EVERY`] blocks the state is
/// moved back onto their values at the start along their gradients (`L` and `K L`), evaluated
/// to twice the `f32` precision ([`crate::exact`]).
struct Invariants<const C: usize> {
    value: [(f32, f32); 2],
    /// The invariants' derivatives with respect to the integrated columns at the start, halved:
    /// `L . Sigma_c` and `w . Sigma_c - w^T E_c w / 2` (`d(L . K L) = 2 w . dL - w^T dJ w`).
    slope: [[f32; C]; 2],
}

/// Half the derivatives of the two invariants with respect to each integrated column at the
/// state `x` (rate `w`): `L . Sigma_c` and `w . Sigma_c - w^T E_c w / 2`.
fn invariant_slopes<const C: usize>(x: &Aug<C>, w: [f32; 3]) -> [[f32; C]; 2] {
    let mut d = [[0.0f32; C]; 2];
    for c in 0..C {
        let sc = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let ewe = if c < 6 { dot(w, e_times(c, w)) } else { 0.0 };
        d[0][c] = dot(x.l, sc);
        d[1][c] = dot(w, sc) - 0.5 * ewe;
    }
    d
}

impl<const C: usize> Invariants<C> {
    fn new(k: &Mat3, x: &Aug<C>) -> Self {
        Invariants {
            value: [
                weighted_squares(&[1.0; 3], &x.l, &x.lc),
                quadratic_form(k, &x.l, &x.lc),
            ],
            slope: invariant_slopes(x, mul(k, x.l)),
        }
    }

    /// Moves the momentum `l - lc` by `alpha L + beta K L` so both invariants take their
    /// values to first order (a ridge of 1e-6 of the 2x2 system's trace for a spin about a
    /// principal axis, where the gradients are parallel), and each column of the sensitivities
    /// the same way so that the invariants' derivatives keep their start's: the Jacobian stays
    /// that of the restored trajectory (with the state alone moved, the Gauss-Newton steps near
    /// the optimum were mispredicted and refused).
    fn restore(&self, k: &Mat3, x: &mut Aug<C>) {
        let [(v0h, v0l), (v1h, v1l)] = self.value;
        let (h0, l0) = weighted_squares(&[1.0; 3], &x.l, &x.lc);
        let (h1, l1) = quadratic_form(k, &x.l, &x.lc);
        let r = [
            0.5 * ((v0h - h0) + (v0l - l0)),
            0.5 * ((v1h - h1) + (v1l - l1)),
        ];
        let w = mul(k, x.l);
        let g = [x.l, w];
        let Some(gram) = Gram2::new(g[0], g[1]) else {
            return;
        };
        let (alpha, beta) = gram.solve(r[0], r[1]);
        for i in 0..3 {
            // The true momentum is `l - lc`: moving it by `d` is `lc -= d`.
            x.lc[i] -= alpha * g[0][i] + beta * g[1][i];
        }
        let now = invariant_slopes(x, w);
        for c in 0..C {
            let (a, b) = gram.solve(self.slope[0][c] - now[0][c], self.slope[1][c] - now[1][c]);
            for i in 0..3 {
                x.s[i][c] += a * g[0][i] + b * g[1][i];
            }
        }
    }
}

/// The rotor momentum over one interval between block means, `tau` from its start:
/// `h(tau) = h0 + tau s + tau (tau - span) c / 2` (through the two nodes, curvature `c`).
#[derive(Clone, Copy, Debug)]
struct RotorSegment {
    h0: [f32; 3],
    s: [f32; 3],
    c: [f32; 3],
    span: f32,
}

impl RotorSegment {
    fn at(&self, tau: f32) -> [f32; 3] {
        let q = 0.5 * tau * (tau - self.span);
        [
            self.h0[0] + tau * self.s[0] + q * self.c[0],
            self.h0[1] + tau * self.s[1] + q * self.c[1],
            self.h0[2] + tau * self.s[2] + q * self.c[2],
        ]
    }

    /// `h'` at the segment's end.
    fn rate_at_end(&self) -> [f32; 3] {
        let m = 0.5 * self.span;
        [
            self.s[0] + m * self.c[0],
            self.s[1] + m * self.c[1],
            self.s[2] + m * self.c[2],
        ]
    }
}

/// The block mean of `w` minus `w(tbar)`, to sixth order in the block's time spread (the
/// same expansion as the ratio fit's (T2')):
///
/// ```text
/// mean w = w_0 + v w_2 + mu4 w_4 + mu6 w_6,   w_n = J^-1 (L_n - h_n)
/// L_(n+1) = 1/(n + 1) sum_(m=0..n) L_m x w_(n-m)          (the Taylor coefficients of L' = L x w)
/// ```
///
/// with `L_0` the momentum at the block's mean time and the rotor's `h_0 = h`, `h_1 = h'`,
/// `h_2 = h''/2` (its model is quadratic between nodes). `2 w_2` is (B1)'s `w''`. A constant
/// torque's part is left out (zero where the test evaluates it).
fn block_mean_correction(k: &Mat3, l0: [f32; 3], h: [[f32; 3]; 3], moments: &[f32; 3]) -> [f32; 3] {
    let [v, mu4, mu6] = *moments;
    if !(v > 0.0) {
        return [0.0; 3];
    }
    let [h0, h1, h2] = h;
    let hn = [h0, h1, [0.5 * h2[0], 0.5 * h2[1], 0.5 * h2[2]]];
    let mut l = [[0.0f32; 3]; 7];
    let mut w = [[0.0f32; 3]; 7];
    l[0] = l0;
    let mut order = 6;
    for n in 0..7 {
        let hcoef = hn.get(n).copied().unwrap_or([0.0; 3]);
        let ln = l.get(n).copied().unwrap_or([0.0; 3]);
        if let Some(wn) = w.get_mut(n) {
            *wn = mul(k, sub(ln, hcoef));
        }
        if n == 2 {
            order = higher_orders(mu4, mu6, &w[0], &w[2]);
        }
        if n >= order || n >= 6 {
            break;
        }
        // Cauchy product of the coefficients `0..=n` of L and w.
        let mut next = [0.0f32; 3];
        for (lm, wr) in l.iter().take(n + 1).zip(w.iter().take(n + 1).rev()) {
            let c = cross(*lm, *wr);
            for (x, y) in next.iter_mut().zip(c.iter()) {
                *x += y;
            }
        }
        let inv = 1.0 / (n + 1) as f32;
        if let Some(dst) = l.get_mut(n + 1) {
            *dst = next.map(|x| x * inv);
        }
    }
    let [_, _, c2, _, c4, _, c6] = w;
    [
        v * c2[0] + mu4 * c4[0] + mu6 * c6[0],
        v * c2[1] + mu4 * c4[1] + mu6 * c6[1],
        v * c2[2] + mu4 * c4[2] + mu6 * c6[2],
    ]
}

/// What drives the extended models' sensitivities besides the rates: a constant torque `q`
/// ((F4), also in the trajectory) and the direction `u` of the rotor momentum's errors of
/// (F7) with the ones on in the step (in their columns only).
#[derive(Clone, Copy, Debug)]
struct Forcing {
    torque: [f32; 3],
    offset: [f32; 3],
    on: [bool; CELLS],
}

/// The rotor's steady stretches of (F7): the direction `u` of its momentum and up to
/// [`CELLS`] runs of blocks `[a, b)` over which its error is taken as one constant (empty
/// runs: none).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cells {
    u: [f32; 3],
    runs: [(usize, usize); CELLS],
    /// The prior's weight on each offset in the cost's units, `sigma^2 / (q^2 / 12)` (the
    /// gyro's white-noise variance per sample over the offset's, uniform over one quantum).
    prior: f32,
    /// The momentum's quantum `q`, kg m^2/s.
    quantum: f32,
}

impl Cells {
    const NONE: Cells = Cells {
        u: [0.0; 3],
        runs: [(0, 0); CELLS],
        prior: 0.0,
        quantum: 0.0,
    };

    /// Whether the fitted offsets `d` (the last [`CELLS`] of `theta`) are a quantisation's:
    /// each within one quantum (the reading's error is at most half of one; the other half
    /// leaves room for the fit's own error). On the thrown-FC logs, whose model error is tens
    /// of times the gyro's noise, free offsets came out at 5-20 quanta: soaking up that error,
    /// not the telemetry's steps.
    fn plausible(&self, theta: &[f32]) -> bool {
        let first = theta.len().saturating_sub(CELLS);
        self.runs.iter().enumerate().all(|(c, run)| {
            run.0 >= run.1
                || theta
                    .get(first + c)
                    .is_some_and(|d| d.abs() <= self.quantum)
        })
    }

    /// Which errors are on at block node `b` (`[a, b)` holds it).
    fn at(&self, b: usize) -> [bool; CELLS] {
        self.runs.map(|(lo, hi)| lo <= b && b < hi)
    }

    /// Which are on over the integration from node `b - 1` to node `b` (both in the run).
    fn between(&self, b: usize) -> [bool; CELLS] {
        self.runs.map(|(lo, hi)| b > lo && b < hi)
    }
}

/// One RK4 step of length `dt` from `tau` within the segment `seg`.
fn rk4<const C: usize>(
    k: &Mat3,
    seg: &RotorSegment,
    q: &Forcing,
    x: &Aug<C>,
    tau: f32,
    dt: f32,
) -> Aug<C> {
    let k1 = deriv(k, seg.at(tau), q, x);
    let k2 = deriv(k, seg.at(tau + 0.5 * dt), q, &axpy(x, &k1, 0.5 * dt));
    let k3 = deriv(k, seg.at(tau + 0.5 * dt), q, &axpy(x, &k2, 0.5 * dt));
    let k4 = deriv(k, seg.at(tau + dt), q, &axpy(x, &k3, dt));
    let mut y = *x;
    let d6 = dt / 6.0;
    for i in 0..3 {
        let inc = d6 * (k1.l[i] + 2.0 * k2.l[i] + 2.0 * k3.l[i] + k4.l[i]);
        compensated_add(&mut y.l[i], &mut y.lc[i], inc);
        for c in 0..C {
            y.s[i][c] += d6 * (k1.s[i][c] + 2.0 * k2.s[i][c] + 2.0 * k3.s[i][c] + k4.s[i][c]);
        }
    }
    y
}

/// `h''` at block `b` by the second difference of the block means with its neighbours (the
/// nearest interior value at the ends; zero with fewer than three blocks).
fn rotor_curvature(blocks: &[Block<6>], b: usize) -> [f32; 3] {
    let n = blocks.len();
    if n < 3 {
        return [0.0; 3];
    }
    let m = if b == 0 {
        1
    } else if b + 1 >= n {
        n - 2
    } else {
        b
    };
    let (Some(p), Some(c), Some(q)) = (blocks.get(m - 1), blocks.get(m), blocks.get(m + 1)) else {
        return [0.0; 3];
    };
    let (d1, d2) = (c.since(p), q.since(c));
    if !(d1 > 0.0 && d2 > 0.0) {
        return [0.0; 3];
    }
    let (hp, hc, hq) = (rotor_of(p), rotor_of(c), rotor_of(q));
    let mut out = [0.0f32; 3];
    for i in 0..3 {
        out[i] = 2.0 * ((hq[i] - hc[i]) / d2 - (hc[i] - hp[i]) / d1) / (d1 + d2);
    }
    out
}

/// The rotor momentum at block `b`'s mean time: its block mean less `v/2 h''` by (B1).
fn rotor_node(blocks: &[Block<6>], b: usize) -> ([f32; 3], [f32; 3]) {
    let c = rotor_curvature(blocks, b);
    let Some(blk) = blocks.get(b) else {
        return ([0.0; 3], c);
    };
    let hv = 0.5 * blk.time_var();
    let m = rotor_of(blk);
    ([m[0] - hv * c[0], m[1] - hv * c[1], m[2] - hv * c[2]], c)
}

fn norm(v: [f32; 3]) -> f32 {
    sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

/// How finely (F1) is integrated between two block means: RK4 steps of at most `0.1 / rate`
/// ([`substeps`]), `rate` a bound on how fast the motion turns there,
///
/// ```text
/// rate = max(1, a_max) |w| + sqrt(h^T J h / det J)
/// ```
///
/// from Euler's `w_i' = a_i w_j w_k` in the principal frame (`|a_i| = |J_j - J_k| / J_i <= 1`
/// for a rigid body) and the nutation the rotor momentum gives the body (the non-zero
/// eigenvalues of the gyroscopic term `J^-1 (h x .)` of (F1)'s linearisation are `+-i` that;
/// for `h` along `z` of a diagonal `J`, `|h| / sqrt(Jxx Jyy)`), with `|w|` and `|h|` the larger
/// of the two block means'. `J` is the fit's first guess, held for the whole fit: a step count
/// that changed with the parameters would make the cost jump by the RK4 error of one count
/// against another, and the fit, which needs the cost smooth to a few 1e-4 of itself, refused
/// its last steps on those jumps (a simulated board throw: 30 evaluations with the current
/// `J`'s nutation, 6 with the first guess's). The bound `|J^-1| |L|` the fit used until
/// 2026-11-26 took 1.9 times the steps on the paper's 20 s flight and 8.5 times on a racquet's
/// 85-sample toss (its `J^-1` is ill-conditioned), for the same estimates to 1e-7.
#[derive(Clone, Copy, Debug)]
struct StepRule {
    /// `max(1, a_max)`: infinite (the most steps) when `J`'s moments are not positive.
    turn: f32,
    j: Mat3,
    det: f32,
}

impl StepRule {
    fn new(j: &Mat3) -> Self {
        let turn = match eigen_symmetric3(j) {
            // Ascending: `(l1 - l0) / l2` is never the largest ratio.
            Some(e) if e.values[0] > 0.0 => {
                let [l0, l1, l2] = e.values;
                ((l2 - l1) / l0).max((l2 - l0) / l1).max(1.0)
            }
            _ => f32::INFINITY,
        };
        StepRule {
            turn,
            j: *j,
            det: det(j),
        }
    }

    /// The rate between two block means whose larger `|w|` is `w_max` and rotor momenta
    /// `h0`, `h1`.
    fn speed(&self, w_max: f32, h0: [f32; 3], h1: [f32; 3]) -> f32 {
        let nutation = |h: [f32; 3]| {
            if self.det > 0.0 {
                sqrt(dot(h, mul(&self.j, h)).max(0.0) / self.det)
            } else {
                f32::INFINITY
            }
        };
        self.turn * w_max + nutation(h0).max(nutation(h1))
    }
}

fn rate_of(b: &Block<6>) -> [f32; 3] {
    [b.mean(0), b.mean(1), b.mean(2)]
}

fn rotor_of(b: &Block<6>) -> [f32; 3] {
    [b.mean(3), b.mean(4), b.mean(5)]
}

/// Entries of `J` fitted by a parameter vector of length `P`: the six entries in kg m^2 (`P`
/// = 9, or 12 with the bias), or five with the trace held (`P` = 8 or 11: `Jzz = trace - Jxx -
/// Jyy`, the tensor up to scale).
const fn entries_of(p: usize) -> usize {
    if p == P0 - 1 || p == P1 - 1 {
        5
    } else {
        6
    }
}

/// The six entries `(xx, yy, zz, xy, xz, yz)` from the first `m` of `theta` (`m` = 6, or 5
/// with the trace held at `trace`).
fn six<const P: usize>(theta: &[f32; P], trace: f32, m: usize) -> [f32; 6] {
    let g = |i: usize| theta.get(i).copied().unwrap_or(0.0);
    if m == 6 {
        [g(0), g(1), g(2), g(3), g(4), g(5)]
    } else {
        [g(0), g(1), trace - g(0) - g(1), g(2), g(3), g(4)]
    }
}

/// Cost and normal equations of the first `limit` blocks at `theta`: `P` = 9 (six entries,
/// initial rate) or 12 (and the bias), or 8 and 11 with the trace held at `trace` (the tensor up
/// to scale: the sensitivity to `Jxx` is `d/dJxx - d/dJzz`, and the same for `Jyy`).
///
/// With [`has_offsets`]`(P)` the last [`CELLS`] parameters are the rotor momentum's offsets of
/// (F7) over `cells`' runs; one whose run is empty or starts beyond the first `limit` blocks has no
/// column, and is held where it is (its row and column of the normal matrix the identity's).
fn normal<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
) -> Option<Normal<P>> {
    let fitted = visit_fit::<P, P0>(blocks, rule, limit, theta, trace, cells, &mut ());
    if !has_offsets(P) {
        return fitted;
    }
    let (mut cost, mut f, mut g) = fitted?;
    let mut idle = [0usize; CELLS];
    let mut n = 0;
    for (c, run) in cells.runs.iter().enumerate() {
        let k = P - CELLS + c;
        if run.0 >= run.1 || run.0 >= limit {
            if let Some(slot) = idle.get_mut(n) {
                *slot = k;
                n += 1;
            }
        } else if let (Some(d), Some(fk), Some(gk)) = (
            theta.get(k),
            f.get_mut(k).and_then(|row| row.get_mut(k)),
            g.get_mut(k),
        ) {
            // The offset's prior ((F7)): a pseudo-observation `0 = sqrt(w) d`.
            let w = cells.prior;
            cost += w * d * d;
            *fk += w;
            *gk -= w * d;
        }
    }
    let (f, g) = without(&f, &g, idle.get(..n).unwrap_or(&[]));
    Some((cost, f, g))
}

/// [`normal_visit`] in the layout the parameter count implies ([`has_offsets`]): `C_PLAIN`
/// sensitivity columns without the offsets of (F7) (0 when only the residuals are wanted),
/// [`C_OFFSET`] with them, over `cells`' runs.
fn visit_fit<const P: usize, const C_PLAIN: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
    seen: &mut impl Visitor<P>,
) -> Option<Normal<P>> {
    if has_offsets(P) {
        let layout = Layout {
            offset: *cells,
            ..Layout::PLAIN
        };
        normal_visit::<P, C_OFFSET>(blocks, rule, limit, theta, trace, layout, seen)
    } else {
        normal_visit::<P, C_PLAIN>(blocks, rule, limit, theta, trace, Layout::PLAIN, seen)
    }
}

/// [`normal`] of the fit up to scale extended for its tests: `C = 12` a constant torque
/// ((F4)), inserted after the initial rate; `scale` the gyro's scale-factor errors ((F5)),
/// last. `theta` is the plain or bias model's parameters with those added.
fn normal_extended<const P: usize, const C: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    scale: bool,
) -> Option<Normal<P>> {
    normal_visit::<P, C>(
        blocks,
        rule,
        blocks.len(),
        theta,
        trace,
        Layout {
            normalized: true,
            scale,
            offset: Cells::NONE,
        },
        &mut (),
    )
}

/// What the parameters beyond the plain or bias model hold, where their count cannot tell.
#[derive(Clone, Copy, Debug)]
struct Layout {
    /// The trace is held (five entries; else six).
    normalized: bool,
    /// The last three are the gyro's scale-factor errors of (F5).
    scale: bool,
    /// With `C = 13`: the rotor momentum's errors of (F7), the last [`CELLS`] parameters.
    offset: Cells,
}

impl Layout {
    /// The plain or bias model's own parameters.
    const PLAIN: Layout = Layout {
        normalized: false,
        scale: false,
        offset: Cells::NONE,
    };
}

/// [`normal`], showing `seen` each block's residual on each axis in turn and then its node. With
/// `C = 12` the parameters hold a constant torque after the initial rate (`normalized`: the
/// trace is held, five entries; else six); with `scale` the last three are the gyro's
/// scale-factor errors `kappa` of (F5); with `C = 13` the last [`CELLS`] are the rotor
/// momentum's errors `d_c` of (F7) over `layout.offset`'s runs (six entries).
///
/// Never inlined: each instantiation's frame (its RK4 stages of `C` columns, its normal
/// sums) then lives only while it runs; inlined into [`normal`], which holds two of them, the
/// frames added up and the flight build's bench overflowed its stack (2026-11-26).
#[inline(never)]
fn normal_visit<const P: usize, const C: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    layout: Layout,
    seen: &mut impl Visitor<P>,
) -> Option<Normal<P>> {
    let Layout {
        normalized,
        scale,
        offset,
    } = layout;
    let torque = C == C_TORQUE;
    let oc = if C == C_OFFSET { CELLS } else { 0 };
    // The entry count is told by `normalized` wherever the parameter count cannot tell it: a
    // torque (F4) or scale factors (F5) beyond the plain or bias layout (before 2026-11-25 the
    // torque test of a biased fit up to scale, 14 parameters, read the layout as six entries
    // and its tensor from the wrong slots, so it never ran there).
    let m = if torque || scale || oc > 0 {
        if normalized {
            5
        } else {
            6
        }
    } else {
        entries_of(P)
    };
    let e6 = six(theta, trace, m);
    let j = tensor_of(&e6);
    let k = symmetric(inverse_pd(&j)?);
    let g = |i: usize| theta.get(i).copied().unwrap_or(0.0);
    let w0 = [g(m), g(m + 1), g(m + 2)];
    // (F7): the rotor momentum's offsets over the steady runs, the last `CELLS` parameters;
    // the model's momentum is the logged one plus `u sum_c d_c` over the runs that are on.
    let d: [f32; CELLS] = core::array::from_fn(|c| if oc > 0 { g(P - oc + c) } else { 0.0 });
    let shift = |on: [bool; CELLS]| {
        let mut t = 0.0f32;
        for (dc, o) in d.iter().zip(on) {
            if o {
                t += *dc;
            }
        }
        offset.u.map(|x| x * t)
    };
    // The model's momentum where the runs `on` are on: the logged one and their offsets.
    let shifted = |h: [f32; 3], on: [bool; CELLS]| if oc > 0 { add3(h, shift(on)) } else { h };
    let (h_first, _) = rotor_node(blocks, 0);
    let h_first = shifted(h_first, offset.at(0));
    let jw = mul(&j, w0);
    let mut x = Aug::<C> {
        l: [jw[0] + h_first[0], jw[1] + h_first[1], jw[2] + h_first[2]],
        lc: [0.0; 3],
        s: [[0.0; C]; 3],
    };
    // `dL(0)/dJ_c = E_c w0`, `dL(0)/dw0 = J` (no columns at all when only the cost is asked).
    for (i, (row, jrow)) in x.s.iter_mut().zip(j.iter()).enumerate() {
        for (c, dst) in row.iter_mut().enumerate().take(P0) {
            let v = if c < 6 {
                e_times(c, w0).get(i).copied()
            } else {
                jrow.get(c - 6).copied()
            };
            *dst = v.unwrap_or(0.0);
        }
    }
    // Layout: entries (m), initial rate (3), [torque (3)], [bias (3)].
    let tq = if torque { 3 } else { 0 };
    let q = if torque {
        [g(m + 3), g(m + 4), g(m + 5)]
    } else {
        [0.0f32; 3]
    };
    let sc = if scale { 3 } else { 0 };
    let kappa = if scale {
        [g(P - 3), g(P - 2), g(P - 1)]
    } else {
        [0.0f32; 3]
    };
    let biased = P == m + 6 + tq + sc + oc;
    let bias = if biased {
        [g(m + 3 + tq), g(m + 4 + tq), g(m + 5 + tq)]
    } else {
        [0.0f32; 3]
    };
    // Without a rotor momentum and a torque, (F1) keeps `|L|^2` and `L . J^-1 L`. The torque's
    // score test evaluates the extended model at zero torque: the same trajectory as the plain
    // model's, so the same restorations (without them its score saw the difference of the two
    // integrations and rejected a free body on 18 of 100 seeds of a fast 4 s tumble). A rotor
    // momentum, from the first node on, gives them up below.
    // (F7) is for flights with a rotor, which give the invariants up anyway.
    let mut invariants = (q == [0.0; 3] && oc == 0).then(|| Invariants::new(&k, &x));
    let mut forcing = Forcing {
        torque: q,
        offset: offset.u,
        on: [false; CELLS],
    };
    // (F7): `Sigma_d(t_0) = u` for an error on from the first block.
    if oc > 0 {
        for (c, on) in offset.at(0).iter().enumerate() {
            if *on {
                for (row, v) in x.s.iter_mut().zip(offset.u) {
                    if let Some(dst) = row.get_mut(P0 + c) {
                        *dst = v;
                    }
                }
            }
        }
    }
    // (F7): `J^-1 u`, what `dw/dd_c` loses where error `c` is on.
    let ku = if oc > 0 { mul(&k, offset.u) } else { [0.0; 3] };
    let mut sums = NormalSums::<P>::EMPTY;
    // Node b-1: block, rotor momentum at the mean time, its curvature, `|ybar|`.
    let mut prev: Option<(&Block<6>, [f32; 3], [f32; 3], f32)> = None;
    let mut hd = [0.0f32; 3];
    for (idx, b) in blocks.iter().enumerate().take(limit) {
        let (h, c) = rotor_node(blocks, idx);
        // A rotor that turns (a motor started after the release) does work on the body: the
        // energy is no longer the start's, even once it stops again.
        if h != [0.0; 3] || c != [0.0; 3] {
            invariants = None;
        }
        let w_here = norm(rate_of(b));
        if let Some((bp, hp, cp, w_prev)) = prev {
            let span = b.since(bp);
            if span > 0.0 {
                let seg = RotorSegment {
                    h0: shifted(hp, offset.between(idx)),
                    s: [
                        (h[0] - hp[0]) / span,
                        (h[1] - hp[1]) / span,
                        (h[2] - hp[2]) / span,
                    ],
                    c: [
                        0.5 * (c[0] + cp[0]),
                        0.5 * (c[1] + cp[1]),
                        0.5 * (c[2] + cp[2]),
                    ],
                    span,
                };
                hd = seg.rate_at_end();
                // The step count from the data and the fit's first guess ([`StepRule`]).
                let speed = rule.speed(w_prev.max(w_here), hp, h);
                let steps = substeps(span, speed);
                let dt = span / steps as f32;
                let mut tau = 0.0f32;
                if oc > 0 {
                    forcing.on = offset.between(idx);
                }
                for _ in 0..steps {
                    x = rk4(&k, &seg, &forcing, &x, tau, dt);
                    tau += dt;
                }
                // Every `RESTORE_EVERY` blocks, while no rotor momentum has been seen.
                if let (Some(inv), 0) = (&invariants, idx % RESTORE_EVERY) {
                    inv.restore(&k, &mut x);
                }
            }
        }
        let hdd = c;
        prev = Some((b, h, c, w_here));
        // The model's momentum at the node: the logged one and the offset of the run it is in.
        let on_here = if oc > 0 {
            offset.at(idx)
        } else {
            [false; CELLS]
        };
        let h_model = shifted(h, on_here);
        let w = mul(&k, sub(x.l, h_model));
        let u = rate_sens(&k, &x, w);
        // (B1): the block mean of w is w(tbar) + v/2 w''(tbar) + ... (`block_mean_correction`).
        let corr = block_mean_correction(&k, x.l, [h_model, hd, hdd], &b.time_moments());
        // The low part of `w`: the momentum is `l - lc` (compensated), so `w - J^-1 lc`.
        let w_lo = mul(&k, x.lc);
        let mut rows = [[0.0f32; P]; 3];
        for i in 0..3 {
            // (F5): the gyro reads (1 + kappa_i) times the block mean of w_i.
            let mean_w = w[i] + corr[i];
            // The block mean less `w` without rounding the mean first ([`Block::deviation`]:
            // a rounded mean of a rate of 25 rad/s is off by up to 1e-6 rad/s, on residuals of
            // 1e-3, and the cost moved by some 1e-4 of itself between evaluations on that
            // alone), with `w`'s low part.
            let dev = b.deviation(i, w[i]) + w_lo[i] - corr[i] - bias[i];
            let r = if scale { dev - kappa[i] * mean_w } else { dev };
            seen.residual(i, r);
            let mut row = [0.0f32; P];
            let ui = &u[i];
            let uc = |c: usize| ui.get(c).copied().unwrap_or(0.0);
            if m == 6 {
                // Entries, initial rate and torque: the columns as they are; the momentum's
                // errors go last.
                for (dst, src) in row.iter_mut().zip(ui.iter()).take(C - oc) {
                    *dst = *src;
                }
                if oc > 0 {
                    // (F7): `dw/dd_c = J^-1 (Sigma_d - u)` where error `c` is on.
                    for (c, on) in on_here.iter().enumerate() {
                        let v = uc(P0 + c) - if *on { ku[i] } else { 0.0 };
                        if let Some(dst) = row.get_mut(P - oc + c) {
                            *dst = v;
                        }
                    }
                }
            } else {
                // Trace held: Jzz moves against Jxx and Jyy.
                let cols = [
                    uc(0) - uc(2),
                    uc(1) - uc(2),
                    uc(3),
                    uc(4),
                    uc(5),
                    uc(6),
                    uc(7),
                    uc(8),
                    uc(9),
                    uc(10),
                    uc(11),
                ];
                for (dst, src) in row.iter_mut().zip(cols.iter().take(8 + tq)) {
                    *dst = *src;
                }
            }
            if biased {
                if let Some(dst) = row.get_mut(m + 3 + tq + i) {
                    *dst = 1.0;
                }
            }
            if scale {
                if let Some(dst) = row.get_mut(P - 3 + i) {
                    *dst = mean_w;
                }
            }
            if C == 0 {
                sums.add_cost(b.n, r);
            } else {
                sums.add(b.n, r, &row);
            }
            if let Some(dst) = rows.get_mut(i) {
                *dst = row;
            }
        }
        // `dL/dw0 = Phi J` ((F3) from `Sigma(t_0) = J`): the initial rates' columns.
        let col = |i: usize, c: usize| x.s.get(i).and_then(|r| r.get(c)).copied().unwrap_or(0.0);
        let s_w0 = core::array::from_fn(|i| core::array::from_fn(|c| col(i, 6 + c)));
        seen.node(&Node {
            index: idx,
            weight: b.n,
            rows: &rows,
            l: x.l,
            k: &k,
            s_w0,
        });
    }
    sums.finish()
}

/// What [`normal_visit`] shows besides its sums: each block's residuals, then its node.
trait Visitor<const P: usize> {
    /// The current block's residual `r` on axis `i`.
    fn residual(&mut self, _i: usize, _r: f32) {}
    /// The current block's node, once its three residuals are in.
    fn node(&mut self, _node: &Node<'_, P>) {}
}

/// The sums alone.
impl<const P: usize> Visitor<P> for () {}

/// Each node to a function.
struct OnNode<F>(F);

impl<const P: usize, F: FnMut(&Node<'_, P>)> Visitor<P> for OnNode<F> {
    fn node(&mut self, node: &Node<'_, P>) {
        (self.0)(node);
    }
}

/// [`residual_lag1`]'s sums: the previous residual per axis, `sum r_b r_(b-1)` and `sum r^2`.
struct Lag1 {
    prev: [Option<f32>; 3],
    num: f32,
    den: f32,
}

impl<const P: usize> Visitor<P> for Lag1 {
    fn residual(&mut self, i: usize, r: f32) {
        if let Some(slot) = self.prev.get_mut(i) {
            if let Some(p) = *slot {
                self.num += p * r;
            }
            *slot = Some(r);
        }
        self.den += r * r;
    }
}

/// A block's node as [`normal_visit`] leaves it, for [`input_cov`].
struct Node<'a, const P: usize> {
    /// The block's index.
    index: usize,
    /// Its sample count (the residuals' weight).
    weight: f32,
    /// `dw/dtheta` at the node, one row per axis.
    rows: &'a [[f32; P]; 3],
    /// The momentum `L`.
    l: [f32; 3],
    /// `J^-1`.
    k: &'a Mat3,
    /// `dL/dw(t_0)`: the transition `Phi(t, t_0)` of (F3) times `J` (absolute fits only).
    s_w0: Mat3,
}

/// The cost alone of all the blocks at `theta` (no sensitivities: a tenth of [`normal`]'s
/// work), for choosing between first guesses.
fn cost_only<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
) -> Option<f32> {
    normal_visit::<P, 0>(
        blocks,
        rule,
        blocks.len(),
        theta,
        trace,
        Layout::PLAIN,
        &mut (),
    )
    .map(|(cost, _, _)| cost)
}

/// The first `M` entries of `v` (zeros past its end).
fn leading<const M: usize>(v: &[f32]) -> [f32; M] {
    core::array::from_fn(|i| v.get(i).copied().unwrap_or(0.0))
}

/// The leading `M x M` block of the `A x A` matrix `c`.
fn leading_block<const A: usize, const M: usize>(c: &[[f32; A]; A]) -> Sym<M> {
    core::array::from_fn(|i| c.get(i).map_or([0.0; M], |row| leading(row)))
}

/// Fits one stretch from `th` (`P` parameters without the bias, `PB` with it, the first `M`
/// of interest; see [`normal`]): the plain model by [`levenberg`] on all the blocks at once,
/// and by [`staged_fit`] (growing prefixes) only if that does not fit to twice `noise_floor`,
/// the lower cost taken; then, when `test_bias`, the bias model if the likelihood-ratio test
/// asks for it.
///
/// Why all the blocks first: growing prefixes keep a start whose trajectory drifts away from
/// the data from being pulled into a wrong basin by the far blocks, but from a good start
/// (with only the first block's noisy rate as the initial rate) they throw information away:
/// on a short noisy toss the first 16 blocks alone determined the eight parameters of the fit
/// up to scale so poorly that the staged fit left the right basin on about 1 flight in 25.
/// On the simulated flywheel throw the absolute fit is as accurate as staged alone, at two
/// thirds of the cost.
///
/// With `cells` (the absolute fit of a flight whose rotor speed is read in steps: its steady
/// runs, [`steady_cells`]) the last [`CELLS`] of `th` are the rotor momentum's offsets of
/// (F7), fitted with the rest (the bias, when fitted, goes before them).
// Never inlined: the absolute fit has two instantiations (with and without the rotor
// telemetry's offsets) behind one branch, and inlined their frames added up.
#[inline(never)]
fn fit_model<
    const P: usize,
    const PB: usize,
    const M: usize,
    const PT: usize,
    const PTB: usize,
    const PTS: usize,
    const PTBS: usize,
>(
    blocks: &[Block<6>],
    th: [f32; P],
    trace: f32,
    noise_floor: f32,
    test_bias: bool,
    cells: &Cells,
    res: Resolution,
) -> Option<StretchResult<M>> {
    let total = blocks.len();
    let rule = StepRule::new(&tensor_of(&six(&th, trace, M)));
    let dof0 = (3 * total) as f32 - P as f32;
    let direct = levenberg(
        |p| normal(blocks, &rule, total, p, trace, cells),
        th,
        30,
        dof0,
        TOLERANCE,
        Start::Cold,
    );
    let fits = 4.0 * noise_floor * noise_floor * dof0;
    let plain = match direct {
        Some(d) if d.1 <= fits => Some(d),
        d => {
            let staged = staged_fit(
                |p, limit| normal(blocks, &rule, limit, p, trace, cells),
                th,
                total,
            );
            match (d, staged) {
                (Some(d), Some(st)) => Some(if st.1 < d.1 { st } else { d }),
                (d, st) => d.or(st),
            }
        }
    };
    let (th, cost0, f0) = plain?;
    let cov0 = scaled_inverse(&f0)?;
    // The bias goes after the initial rate (before the offsets of (F7), when there are any).
    let th1: [f32; PB] = core::array::from_fn(|i| {
        if i < M + 3 {
            th.get(i).copied().unwrap_or(0.0)
        } else if i < M + 6 {
            0.0
        } else {
            th.get(i - 3).copied().unwrap_or(0.0)
        }
    });
    let dof1 = (3 * total) as f32 - PB as f32;
    // One evaluation decides whether the bias model is worth its fit.
    let worth = test_bias
        && normal(blocks, &rule, total, &th1, trace, cells)
            .and_then(|(_, f, g)| score(&f, &g))
            .is_none_or(|sc| bias_worth_fitting(sc, cost0, dof0, noise_floor));
    let with_bias = if worth {
        levenberg(
            |p| normal(blocks, &rule, total, p, trace, cells),
            th1,
            30,
            dof1,
            TOLERANCE,
            Start::Warm,
        )
    } else {
        None
    };
    if let Some((t1, cost1, f1)) = with_bias {
        if bias_found(cost0, cost1, dof1, noise_floor) {
            if *cells != Cells::NONE && !cells.plausible(&t1) {
                return None;
            }
            if let Some(c1) = scaled_inverse(&f1) {
                let g = |i: usize| t1.get(i).copied().unwrap_or(0.0);
                let lag1 = if cost1 > 4.0 * noise_floor * noise_floor * dof1 {
                    residual_lag1(blocks, &rule, &t1, trace, cells)
                } else {
                    0.0
                };
                // The torque's parameters go between the initial rate and the bias.
                let th_t: [f32; PTB] = core::array::from_fn(|i| {
                    if i < M + 3 {
                        g(i)
                    } else if i < M + 6 {
                        0.0
                    } else {
                        g(i - 3)
                    }
                });
                let (torque, scale) =
                    tests_found::<PTB, PTBS>(blocks, &rule, &th_t, trace, cost1, dof1, noise_floor);
                let input = input_cov(blocks, &rule, &t1, cells, res, &f1);
                return Some(StretchResult {
                    p: leading(&t1),
                    cov: leading_block(&c1),
                    input: input.map(|(c, e)| (leading_block(&c), e)),
                    cost: cost1,
                    params: PB,
                    bias: Some([g(M + 3), g(M + 4), g(M + 5)]),
                    lag1,
                    torque,
                    scale,
                });
            }
        }
    }
    if *cells != Cells::NONE && !cells.plausible(&th) {
        return None;
    }
    let lag1 = if cost0 > fits {
        residual_lag1(blocks, &rule, &th, trace, cells)
    } else {
        0.0
    };
    let th_t: [f32; PT] = leading(&th);
    let (torque, scale) =
        tests_found::<PT, PTS>(blocks, &rule, &th_t, trace, cost0, dof0, noise_floor);
    let input = input_cov(blocks, &rule, &th, cells, res, &f0);
    Some(StretchResult {
        p: leading(&th),
        cov: leading_block(&cov0),
        input: input.map(|(c, e)| (leading_block(&c), e)),
        cost: cost0,
        params: P,
        bias: None,
        lag1,
        torque,
        scale,
    })
}

/// The score tests at a fitted model's optimum, from one evaluation: `theta` that model's
/// parameters with a zero torque inserted after the initial rate (`PT` of them; `PS = PT + 3`
/// with three zero `kappa` appended), `cost` and `dof` its own. Only up to scale (`trace` > 0,
/// the gyro-only path): with a rotor the model's error is the rotor's and the status says so
/// already. Returns
///
/// - a constant torque ((F4)): its score `g^T F^-1 g` (the scale factors dropped) against 21.11
///   (chi-square, 3 degrees of freedom, 0.01 %, see `output_error::score_rejects`), a rejection
///   confirmed by the likelihood ratio of the model refitted with the torque
///   ([`torque_confirmed`]; that fit runs only where the score rejected): the cost with it;
/// - the gyro's scale-factor errors ((F5)): scored beyond the model's own columns (the torque
///   dropped, see `output_error::score_beyond`) against 21.11.
///
/// The two tests were two evaluations (12 and 9 sensitivity columns) until 2026-11-26; the
/// columns are integrated independently, so one evaluation with the torque's and the scale
/// factors' columns gives both the same sums.
fn tests_found<const PT: usize, const PS: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; PT],
    trace: f32,
    cost: f32,
    dof: f32,
    noise_floor: f32,
) -> (Option<f32>, bool) {
    if !(trace > 0.0) {
        return (None, false);
    }
    let both: [f32; PS] = leading(theta);
    let Some((_, f, g)) = normal_extended::<PS, C_TORQUE>(blocks, rule, &both, trace, true) else {
        return (None, false);
    };
    // Layout: five entries, the initial rate, the torque, [the bias], the scale factors.
    let torque_cols = [8, 9, 10];
    let kappa = [PS - 3, PS - 2, PS - 1];
    let (ft, gt) = without(&f, &g, &kappa);
    let torque_rejects =
        score(&ft, &gt).is_some_and(|sc| score_rejects(sc, cost, dof, noise_floor));
    let (fs, gs) = without(&f, &g, &torque_cols);
    let scale =
        score_beyond(&fs, &gs, &kappa).is_some_and(|sc| score_rejects(sc, cost, dof, noise_floor));
    let torque = if torque_rejects {
        let extended =
            |th: &[f32; PT]| normal_extended::<PT, C_TORQUE>(blocks, rule, th, trace, false);
        torque_confirmed(
            refit_cost(extended, *theta, cost, dof),
            cost,
            dof,
            noise_floor,
        )
    } else {
        None
    };
    (torque, scale)
}

/// Lag-1 autocorrelation of the block residuals at `theta` over the three axes: the sum of
/// each block's residual times the previous block's on the same axis, over the sum of
/// squares; 0 when the residuals cannot be computed. Only the residuals are needed: without
/// the offsets of (F7) the trajectory is integrated without sensitivities (until 2026-11-26
/// with the nine columns, unused: the fit of a flight its model does not explain costs about 5 %
/// less), with them the columns go along (the layout needs them).
fn residual_lag1<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
) -> f32 {
    let mut lag = Lag1 {
        prev: [None; 3],
        num: 0.0,
        den: 0.0,
    };
    let ok = visit_fit::<P, 0>(blocks, rule, blocks.len(), theta, trace, cells, &mut lag).is_some();
    let Lag1 { num, den, .. } = lag;
    if ok && den > 0.0 && num.is_finite() {
        num / den
    } else {
        0.0
    }
}

/// The rotor momentum's errors along ramps and short steady runs ((F8)) in the covariance of
/// the fitted parameters, `sum_g v_g (F^-1 gamma_g) (F^-1 gamma_g)^T` (the parameters' units
/// squared, not scaled by the noise), with `F` the fit's normal matrix at its optimum (see the
/// module docs, (F8)), and the weighted cost the errors are expected to leave in the residual,
/// their direct and integrated parts less what the fit takes up, `tr(F^-1 K)` (module docs).
/// One pass over the trajectory forms each block's `gamma_b = a_b u - (Z - Y_b) c_b`
/// ([`each_gamma`]) from the suffix `Z - Y_b` of `Z = sum_b a_b Phi_b`, which the normal
/// matrix holds already. (The sums `S_pp`, `S_pc`, `S_cc` of the expanded square, with `Z`
/// applied at the end, are the same algebra, but in `f32` their terms cancel to less than
/// their rounding: they gave negative variances on a simulated throw.) `None` without a
/// resolution, a rotor or a trajectory.
fn input_cov<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    cells: &Cells,
    res: Resolution,
    f: &Sym<P>,
) -> Option<(Sym<P>, f32)> {
    let quantum = res.quantum;
    if !(quantum > 0.0) {
        return None;
    }
    let u = rotor_direction(blocks)?;
    let along = |b: usize| blocks.get(b).map(|blk| dot(rotor_of(blk), u));
    let mut sums = InputSums::<P> {
        fi: scaled_inverse(f)?,
        out: [[0.0; P]; P],
        group: None,
    };
    let mut expected = 0.0f32;
    // The covariance of the integrated momentum's error referred to t_0, `sum v_k c_k c_k^T`.
    let mut drift = [[0.0f32; 3]; 3];
    let ok = each_gamma(blocks, rule, theta, cells, f, u, &mut |nd, gain| {
        let Some((gamma, c, phi)) = gain else {
            // A steady run's error is a parameter of the fit.
            sums.flush();
            return;
        };
        let b = nd.index;
        let here = along(b).unwrap_or(0.0);
        // The quanta the speed crosses over the block, from the neighbours' means.
        let prev = along(b.saturating_sub(1)).unwrap_or(here);
        let next = along(b + 1).unwrap_or(here);
        let crossed = 0.5 * (next - prev).abs() / quantum;
        let var = quantum * quantum / 12.0 * ramp_share(crossed, nd.weight * res.readings);
        let ku = mul(nd.k, u);
        expected += nd.weight * var * dot(ku, ku);
        // The integrated part at this node: tr(M C M^T), M = J^-1 Phi_b.
        let m: Mat3 = core::array::from_fn(|i| {
            core::array::from_fn(|j| (0..3).map(|q| nd.k[i][q] * phi[q][j]).sum())
        });
        for row in &m {
            expected += nd.weight * dot(*row, mul(&drift, *row));
        }
        for i in 0..3 {
            for j in 0..3 {
                drift[i][j] += var * c[i] * c[j];
            }
        }
        sums.push(*gamma, var, here, quantum);
    });
    sums.flush();
    // What the fit itself takes up of the errors: tr(F^-1 K) = tr(F out).
    let absorbed: f32 = f.iter().zip(&sums.out).map(|(fr, or)| dot_n(fr, or)).sum();
    let expected = (expected - absorbed).max(0.0);
    (ok && sums.out.iter().flatten().all(|x| x.is_finite())).then_some((sums.out, expected))
}

/// A block's `gamma_b`, `c_b` and `Phi_b` of (F8).
type Gain<'a, const P: usize> = (&'a [f32; P], [f32; 3], &'a Mat3);

/// Each block's `gamma_b` of (F8) at `theta`, in order, with its node: how an error of one
/// unit in the block's momentum along `u` moves the fit's gradient (`None` for a block in a
/// steady run of (F7), whose error is a parameter). `f` is the normal matrix at `theta`. False
/// when the trajectory or a block's transition could not be formed.
fn each_gamma<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    cells: &Cells,
    f: &Sym<P>,
    u: [f32; 3],
    visit: &mut dyn FnMut(&Node<'_, P>, Option<Gain<'_, P>>),
) -> bool {
    let mut y = [[0.0f32; 3]; P];
    // Z = sum_b a_b Phi_b = (sum_b n_b R_b^T R_b,w0) J^-1: the normal matrix's initial-rate
    // columns (`R_b,w0 = J^-1 Phi_b J`, the rows' initial-rate block), times `J^-1`.
    let mut z = None;
    let mut failed = false;
    let mut node = |nd: &Node<'_, P>| {
        let b = nd.index;
        let z = z.get_or_insert_with(|| {
            let mut z = [[0.0f32; 3]; P];
            for (zp, fp) in z.iter_mut().zip(f) {
                for j in 0..3 {
                    let fm = |m: usize| fp.get(6 + m).copied().unwrap_or(0.0);
                    zp[j] = (0..3).map(|m| fm(m) * nd.k[m][j]).sum();
                }
            }
            z
        });
        let (a, phi) = gains(nd);
        add_product(&mut y, &a, &phi);
        if cells.at(b).iter().any(|on| *on) {
            visit(nd, None);
            return;
        }
        // c_b = Phi_b^-1 beta_b, beta_b = -(L x J^-1 u) Delta_b over the half spans on either
        // side of the node.
        let gap = |x: usize, y: usize| match (blocks.get(x), blocks.get(y)) {
            (Some(later), Some(earlier)) => later.since(earlier),
            _ => 0.0,
        };
        let half = 0.5 * (gap(b + 1, b) + if b > 0 { gap(b, b - 1) } else { 0.0 });
        let lku = cross(nd.l, mul(nd.k, u));
        let Some(c) = solve(&phi, lku.map(|x| -x * half)) else {
            failed = true;
            return;
        };
        let gamma: [f32; P] = core::array::from_fn(|p| {
            let suffix = [z[p][0] - y[p][0], z[p][1] - y[p][1], z[p][2] - y[p][2]];
            dot(a[p], u) - dot(suffix, c)
        });
        visit(nd, Some((&gamma, c, &phi)));
    };
    let node: &mut dyn FnMut(&Node<'_, P>) = &mut node;
    let mut seen = OnNode(node);
    let ok = visit_fit::<P, P0>(blocks, rule, blocks.len(), theta, 0.0, cells, &mut seen);
    ok.is_some() && !failed
}

/// A node's `a_b = n_b R_b^T J^-1` (P x 3) and `Phi_b = Phi(t_b, t_0) = Sigma_w0 J^-1`.
fn gains<const P: usize>(nd: &Node<'_, P>) -> ([[f32; 3]; P], Mat3) {
    let k = nd.k;
    let a = core::array::from_fn(|p| {
        core::array::from_fn(|j| {
            let t: f32 = (0..3).map(|i| nd.rows[i][p] * k[i][j]).sum();
            nd.weight * t
        })
    });
    let phi = core::array::from_fn(|i| {
        core::array::from_fn(|j| (0..3).map(|m| nd.s_w0[i][m] * k[m][j]).sum())
    });
    (a, phi)
}

/// `y += a phi` (P x 3 by 3 x 3).
fn add_product<const P: usize>(y: &mut [[f32; 3]; P], a: &[[f32; 3]; P], phi: &Mat3) {
    for (yp, ap) in y.iter_mut().zip(a) {
        for j in 0..3 {
            yp[j] += (0..3).map(|m| ap[m] * phi[m][j]).sum::<f32>();
        }
    }
}

/// The variance of a block mean's quantisation error over a quantum's, `q^2 / 12`, when the
/// speed crosses `d` quanta over the block's `n` readings:
///
/// ```text
/// g(d, n) = c(d) + min(d, n) / n^2,
/// c(d) = (1 - d)^2 + d^2 / 30  (d < 1),   1 / (30 d^2)  (d >= 1)
/// ```
///
/// The error of a reading is a sawtooth of the speed (zero mean, period one quantum). Its mean
/// over a span of `d` periods from a random phase has the variance `q^2 / 12 f^2 (1 - f)^2 /
/// d^2`, `f` the fractional part of `d` (the sawtooth's antiderivative at the two ends; worked
/// out exactly): `(1 - d)^2` below one quantum, `1 / (30 d^2)` on average over `f` above (the
/// `d^2 / 30` below one joins the two where `d`, taken from the neighbours' means, is
/// uncertain). The second term is the readings' own granularity: each of the `d` steps falls
/// between two of the `n` readings at a random point, `q^2 / (12 n^2)` each, up to the `1 / n`
/// of independent readings. Against rounded ramps simulated from random phases it is within
/// 0.7-1.4 of the variance except near one quantum per block, where it is up to 2.6 times
/// larger (`ramp_share_matches_rounded_ramps`).
fn ramp_share(d: f32, n: f32) -> f32 {
    let n = n.max(1.0);
    let c = if d < 1.0 {
        (1.0 - d) * (1.0 - d) + d * d / 30.0
    } else {
        1.0 / (30.0 * d * d)
    };
    c + d.min(n) / (n * n)
}

/// How the rotor momentum is read: its quantum (kg m^2/s; 0: exact) and the readings each
/// sample of the fit stands for (the inputs averaged into it; one reading per input assumed).
#[derive(Clone, Copy, Debug)]
struct Resolution {
    quantum: f32,
    readings: f32,
}

impl Resolution {
    const EXACT: Resolution = Resolution {
        quantum: 0.0,
        readings: 1.0,
    };
}

/// [`input_cov`]'s groups of blocks that share one reading error (variance `v`), summed as
/// `out += v (F^-1 gamma) (F^-1 gamma)^T` with `gamma` the group's sum of `gamma_b`.
struct InputSums<const P: usize> {
    fi: Sym<P>,
    out: Sym<P>,
    /// The open group: `gamma`, its variance and the momentum (along `u`) it started at.
    group: Option<([f32; P], f32, f32)>,
}

impl<const P: usize> InputSums<P> {
    /// Adds a block's `gamma_b` to the open group when its momentum is within one quantum of
    /// the group's first (one reading, one error), else starts a group with it.
    fn push(&mut self, gamma: [f32; P], var: f32, here: f32, quantum: f32) {
        if let Some((g, _, start)) = &mut self.group {
            if (here - *start).abs() < quantum {
                for (gi, x) in g.iter_mut().zip(gamma) {
                    *gi += x;
                }
                return;
            }
        }
        self.flush();
        self.group = Some((gamma, var, here));
    }

    /// Closes the open group into `out`.
    fn flush(&mut self) {
        let Some((g, v, _)) = self.group.take() else {
            return;
        };
        let d: [f32; P] = core::array::from_fn(|i| dot_n(&self.fi[i], &g));
        for i in 0..P {
            for j in 0..P {
                self.out[i][j] += v * d[i] * d[j];
            }
        }
    }
}

/// `a . b` over `P` entries.
fn dot_n<const P: usize>(a: &[f32; P], b: &[f32; P]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// How much a residual of lag-1 autocorrelation `rho` inflates the variance of what is fitted
/// to it, against white noise of the same variance: `(1 + rho) / (1 - rho)`, the variance of the
/// mean of a first-order autoregressive series over that of a white one (`rho` taken in
/// `[0, 0.98]`: at most 99). The blocks' residuals are independent for white gyro noise; a model
/// error is not white (on the thrown-FC logs it is low-frequency, `rho` about 0.9), and the
/// covariance scaled by the residual variance alone then claims several times the information
/// the flight holds.
fn ar1_inflation(rho: f32) -> f32 {
    let r = rho.clamp(0.0, 0.98);
    (1.0 + r) / (1.0 - r)
}

/// The absolute fit (six entries in kg m^2) from `init`: of all the blocks, and, when that
/// does not fit to twice `noise_floor`, also of the blocks from the rotor's spin-up
/// ([`spin_up`]), the one whose residual per degree of freedom is lower taken. The whole
/// flight's residual is the one reported either way: leaving out the part that fits worst
/// does not make the flight fit, so the status stays `ModelMismatch` and the covariance is
/// scaled to that residual.
///
/// Why: the rotor's momentum is what fixes the scale of `J`, and where it is small against its
/// peak (idle before the spin-up, or the start from rest at the release, when a sensorless
/// ESC's speed telemetry is least trustworthy) a model error of the same size weighs far more
/// against it. On the ten thrown-FC logs the fit of the whole free flight left a residual of
/// 0.1-0.2 rad/s (several hundred times the gyro's noise, low-frequency: a model error, not
/// vibration), and the part before the spin-up alone gave a scale 7-10 % above the rest's;
/// from the spin-up on the residual fell by a third and the five board-alone throws agreed
/// to 0.7-1.5 % instead of 0.5-2.5 %. On a flight the model explains to the noise the whole
/// fit is kept and nothing changes.
///
/// `resolution` (kg m^2/s) is the rotor momentum's quantum as the rotor speed is read (0: exact):
/// where the speed is steady its error is one constant per run, fitted as an offset of the
/// momentum ((F7), [`steady_cells`]), under a prior of a quantum's uniform variance, unless the
/// fitted offsets are larger than a quantum ([`Cells::plausible`]): then the momentum is taken
/// as read.
fn fit_stretch(
    blocks: &[Block<6>],
    init: &Mat3,
    noise_floor: f32,
    test_bias: bool,
    res: Resolution,
) -> Option<StretchResult<6>> {
    let resolution = res.quantum;
    let from = |blocks: &[Block<6>], init: &Mat3| {
        let w0 = rate_of(blocks.first()?);
        let th = [
            init[0][0], init[1][1], init[2][2], init[0][1], init[0][2], init[1][2], w0[0], w0[1],
            w0[2],
        ];
        let plain = || {
            fit_model::<P0, P1, 6, { P0 + 3 }, { P1 + 3 }, { P0 + 6 }, { P1 + 6 }>(
                blocks,
                th,
                0.0,
                noise_floor,
                test_bias,
                &Cells::NONE,
                res,
            )
        };
        let cells = (resolution > 0.0)
            .then(|| steady_cells(blocks, resolution))
            .flatten()
            .map(|c| Cells {
                prior: noise_floor * noise_floor * 12.0 / (resolution * resolution),
                ..c
            });
        let Some(cells) = cells else {
            return plain();
        };
        let with = fit_model::<
            { P0 + CELLS },
            { P1 + CELLS },
            6,
            { P0 + CELLS + 3 },
            { P1 + CELLS + 3 },
            { P0 + CELLS + 6 },
            { P1 + CELLS + 6 },
        >(
            blocks,
            leading(&th),
            0.0,
            noise_floor,
            test_bias,
            &cells,
            res,
        );
        // Offsets that are no quantisation's ([`Cells::plausible`]: `None`): the plain fit.
        with.or_else(plain)
    };
    let mut r = fit_stretch_from(blocks, init, noise_floor, &from)?;
    // (F8): the reading's errors, in the covariance's units (it is scaled by the residual's
    // variance per degree of freedom when pooled); the residual's variance that scales the
    // rest is taken without what those errors are expected to leave in it (counted once, not
    // twice), never below the gyro's noise floor.
    let dof = (3 * blocks.len()) as f32 - r.params as f32;
    let s2 = r.cost / dof;
    if let (Some((x, expected)), true) = (r.input.take(), s2 > 0.0) {
        // Without a known gyro noise there is no floor to hold it to: the residual's as it is.
        let floor = noise_floor * noise_floor;
        let adj = if floor > 0.0 {
            ((r.cost - expected) / dof).max(floor).min(s2)
        } else {
            s2
        };
        let scale = adj / s2;
        for (row, xr) in r.cov.iter_mut().zip(x) {
            for (c, xc) in row.iter_mut().zip(xr) {
                *c = *c * scale + xc / s2;
            }
        }
    }
    Some(r)
}

/// The rotor's steady stretches for (F7): the direction `u` of the largest block-mean rotor
/// momentum, and the [`CELLS`] longest runs of at least three consecutive blocks over which
/// the momentum along `u` stays within one `quantum` of the run's first block (`None` without
/// a rotor momentum or such a run). A reading that keeps one value keeps one error.
fn steady_cells(blocks: &[Block<6>], quantum: f32) -> Option<Cells> {
    let u = rotor_direction(blocks)?;
    let along = |b: &Block<6>| dot(rotor_of(b), u);
    let mut cells = Cells {
        u,
        runs: [(0, 0); CELLS],
        prior: 0.0,
        quantum,
    };
    let mut keep = |run: (usize, usize)| {
        let len = |r: &(usize, usize)| r.1.saturating_sub(r.0);
        if len(&run) < 3 {
            return;
        }
        // Replace the shortest kept run when this one is longer.
        let shortest = cells
            .runs
            .iter_mut()
            .fold(None::<&mut (usize, usize)>, |s, r| match s {
                Some(s) if len(s) <= len(r) => Some(s),
                _ => Some(r),
            });
        if let Some(s) = shortest {
            if len(&run) > len(s) {
                *s = run;
            }
        }
    };
    let mut start = 0;
    let mut first = blocks.first().map_or(0.0, along);
    for (b, block) in blocks.iter().enumerate() {
        let here = along(block);
        if !((here - first).abs() < quantum) {
            keep((start, b));
            start = b;
            first = here;
        }
    }
    keep((start, blocks.len()));
    cells.runs.iter().any(|r| r.1 > r.0).then_some(cells)
}

/// The direction of the largest block-mean rotor momentum (`None` without one).
fn rotor_direction(blocks: &[Block<6>]) -> Option<[f32; 3]> {
    let h =
        blocks.iter().map(rotor_of).fold(
            [0.0f32; 3],
            |a, h| if dot(h, h) > dot(a, a) { h } else { a },
        );
    let n = norm(h);
    (n > 0.0 && n.is_finite()).then(|| h.map(|x| x / n))
}

/// [`fit_stretch`]'s choice between the whole flight and the part from the spin-up, `from`
/// fitting a run of blocks from a first guess.
fn fit_stretch_from(
    blocks: &[Block<6>],
    init: &Mat3,
    noise_floor: f32,
    from: &dyn Fn(&[Block<6>], &Mat3) -> Option<StretchResult<6>>,
) -> Option<StretchResult<6>> {
    let whole = from(blocks, init)?;
    let per_dof = |r: &StretchResult<6>, n: usize| r.cost / ((3 * n) as f32 - r.params as f32);
    let whole_noise = per_dof(&whole, blocks.len());
    if whole_noise <= 4.0 * noise_floor * noise_floor {
        return Some(whole);
    }
    // The model does not hold: the covariance is inflated for the residual's correlation.
    let inflate = |mut r: StretchResult<6>| {
        let f = ar1_inflation(r.lag1);
        r.cov = r.cov.map(|row| row.map(|x| x * f));
        r
    };
    let Some(later) = spin_up(blocks).and_then(|s| blocks.get(s..)) else {
        return Some(inflate(whole));
    };
    let start = tensor_of(&whole.p);
    match from(later, &start) {
        Some(mut r) if per_dof(&r, later.len()) < whole_noise => {
            // The flight as a whole still does not fit: its residual is the one reported
            // (status `ModelMismatch`, the covariance scaled to it), as the cost over the
            // whole stretch's degrees of freedom, which the pooling divides by.
            r.cost = whole_noise * ((3 * blocks.len()) as f32 - r.params as f32);
            Some(inflate(r))
        }
        _ => Some(inflate(whole)),
    }
}

/// The first block at which the rotor momentum reaches half its peak magnitude over the
/// stretch, when that leaves out at least one block and keeps at least [`MIN_SPIN_UP_BLOCKS`]
/// (a third of the stretch or 32 blocks, the larger): `None` otherwise (no rotor, or a
/// momentum already near its peak at the start).
fn spin_up(blocks: &[Block<6>]) -> Option<usize> {
    let mag = |b: &Block<6>| {
        let h = rotor_of(b);
        h[0] * h[0] + h[1] * h[1] + h[2] * h[2]
    };
    let peak = blocks
        .iter()
        .map(mag)
        .fold(0.0f32, |a, m| if m > a { m } else { a });
    if !(peak > 0.0 && peak.is_finite()) {
        return None;
    }
    // Half the peak magnitude: a quarter of its square.
    let s = blocks.iter().position(|b| mag(b) >= 0.25 * peak)?;
    let keep = blocks.len().saturating_sub(s);
    let min_keep = MIN_SPIN_UP_BLOCKS.max(blocks.len() / 3);
    (s > 0 && keep >= min_keep).then_some(s)
}

/// Fewest blocks a fit from the rotor's spin-up may use ([`spin_up`]).
const MIN_SPIN_UP_BLOCKS: usize = 32;

/// The fit up to scale from the best of the first guesses `inits` (any scale each): the one
/// whose trajectory from the first block's rate fits all the blocks best (one evaluation of
/// the cost each; a poor start can end in a local minimum that fits nearly as well as the
/// truth on a short, noisy toss), the trace held at its trace, the five free entries `(Jxx,
/// Jyy, Jxy, Jxz, Jyz)` returned divided by it (trace 1), their covariance by its square.
fn fit_stretch_normalized(
    blocks: &[Block<6>],
    inits: &[Mat3],
    noise_floor: f32,
    test_bias: bool,
) -> Option<StretchResult<5>> {
    let w0 = rate_of(blocks.first()?);
    let start = |init: &Mat3| {
        let tr = init[0][0] + init[1][1] + init[2][2];
        let th = [
            init[0][0], init[1][1], init[0][1], init[0][2], init[1][2], w0[0], w0[1], w0[2],
        ];
        (tr > 0.0 && tr.is_finite()).then_some((th, tr))
    };
    let mut best: Option<([f32; P0 - 1], f32, f32)> = None;
    // One guess needs no choosing (its evaluation is the fit's first).
    let choose = inits.len() > 1;
    for init in inits {
        let Some((th, tr)) = start(init) else {
            continue;
        };
        let cost = if choose {
            cost_only(blocks, &StepRule::new(init), &th, tr)
        } else {
            Some(0.0)
        };
        if let Some(cost) = cost {
            if best.is_none_or(|b| cost < b.2) {
                best = Some((th, tr, cost));
            }
        }
    }
    let (th, tr, _) = best?;
    let mut r =
        fit_model::<{ P0 - 1 }, { P1 - 1 }, 5, { P0 + 2 }, { P1 + 2 }, { P0 + 5 }, { P1 + 5 }>(
            blocks,
            th,
            tr,
            noise_floor,
            test_bias,
            &Cells::NONE,
            Resolution::EXACT,
        )?;
    let k = 1.0 / tr;
    r.p = r.p.map(|x| x * k);
    r.cov = r.cov.map(|row| row.map(|x| x * k * k));
    Some(r)
}

impl<const N: usize> TensorFit<N> {
    /// An empty fit: samples at or beyond `full_scale` (rad/s) are skipped (their time kept);
    /// a time step that is not finite, not positive or longer than `max_dt` ends what the
    /// stretch takes; `noise_std` (rad/s per sample) is the least noise the bias test assumes.
    /// `N` must be at least 16.
    pub const fn new(full_scale: f32, max_dt: f32, noise_std: f32) -> Self {
        TensorFit {
            state: FitState::EMPTY,
            normalized: Pooled::EMPTY,
            full_scale,
            max_dt,
            noise_std,
            momentum_resolution: 0.0,
            inputs: 1,
        }
    }

    /// The rotor momentum's quantum and the readings per sample, for the fits.
    fn resolution(&self) -> Resolution {
        Resolution {
            quantum: self.momentum_resolution,
            readings: f32::from(self.inputs.max(1)),
        }
    }

    /// The same fit with the rotor momentum known only to `quantum` (kg m^2/s: the rotor
    /// inertia times the speed telemetry's step, e.g. 100 eRPM): the absolute fit then fits
    /// one offset of the momentum per steady run of the speed ((F7)) and counts the reading's
    /// errors elsewhere in the covariance ((F8)). 0 (the default), negative or not finite:
    /// the momentum is taken as exact.
    pub const fn with_momentum_resolution(mut self, quantum: f32) -> Self {
        self.momentum_resolution = if quantum > 0.0 && quantum < f32::INFINITY {
            quantum
        } else {
            0.0
        };
        self
    }

    /// Adds one sample of the open stretch: rate (rad/s), rotor momentum (kg m^2/s) and the
    /// time since the previous sample (s).
    pub fn step(&mut self, omega: [f32; 3], h: [f32; 3], dt: f32) {
        self.step_mean(omega, h, dt, 1);
    }

    /// [`TensorFit::step`] for a sample that is the mean of `inputs` equally spaced readings
    /// spanning `dt` (see [`crate::RatioFit::step_mean`]).
    pub fn step_mean(&mut self, omega: [f32; 3], h: [f32; 3], dt: f32, inputs: u8) {
        let usable = omega
            .iter()
            .all(|w| w.is_finite() && w.abs() < self.full_scale)
            && h.iter().all(|x| x.is_finite());
        let y = [omega[0], omega[1], omega[2], h[0], h[1], h[2]];
        self.inputs = self.inputs.max(inputs);
        self.state
            .buf
            .add(&y, usable, dt, self.max_dt, mean_spread(dt, inputs));
    }

    /// Ends the open stretch: fits it from the tensor `init` (kg m^2; a positive definite
    /// first guess, such as [`crate::TensorEstimator`]'s), pools it and starts a new stretch.
    pub fn close(&mut self, init: Option<[[f32; 3]; 3]>) -> StretchOutcome {
        let (noise, q) = (self.noise_std, self.resolution());
        self.state
            .close(|blocks| init.and_then(|j| fit_stretch(blocks, &j, noise, true, q)))
    }

    /// [`TensorFit::close`] for a gyro whose bias is known and was removed (measured on a
    /// still stretch before the throw, as the pipeline's free-flight gate does): no bias is
    /// looked for. Why not test for one anyway: the likelihood-ratio test measures the gain
    /// against the gyro's white noise, so when the model leaves a residual far above it (a
    /// real vehicle's unmodelled effects) the test always "finds" a bias, and the bias then
    /// soaks up model error. On the ten thrown-FC logs it found 0.1-0.38 rad/s on every throw,
    /// where the bench measured at most 0.015 rad/s, and moved `J` by up to 4 %.
    pub fn close_without_bias(&mut self, init: Option<[[f32; 3]; 3]>) -> StretchOutcome {
        let (noise, q) = (self.noise_std, self.resolution());
        self.state
            .close(|blocks| init.and_then(|j| fit_stretch(blocks, &j, noise, false, q)))
    }

    /// Ends the open stretch of a flight whose rotor momentum does not fix the scale of `J`
    /// (none, or constant along the rate): fits `J / trace J` from whichever of the first
    /// guesses `inits` (positive definite, any scale) fits the blocks best as it stands (one
    /// evaluation each; none: the stretch fails), the trace held (five free entries and the
    /// initial rate, and, when `test_bias`, the bias if its likelihood-ratio test asks for it),
    /// pools it apart from the absolute fits ([`TensorFit::estimate_normalized`]) and starts a
    /// new stretch.
    ///
    /// Why the bias test can be switched off: on a short noisy toss the bias and the products
    /// of inertia are nearly interchangeable, and the likelihood has far-apart minima that the
    /// test (calibrated for a local alternative) takes for a bias on about 1 in 50 flights,
    /// moving `J` by tens of its standard deviations. The pipeline tests it only when the
    /// principal-axis fit of the same blocks ([`crate::RatioFit`]) found a bias or did not fit
    /// to the noise.
    ///
    /// ```
    /// use identifier_core::{StretchOutcome, TensorFit};
    ///
    /// // A body of inertia (2, 3, 4)e-4 kg m^2 tumbling freely for 2 s at 1 kHz, no rotor.
    /// let j = [2e-4f64, 3e-4, 4e-4];
    /// let mut w = [3.0f64, -2.0, 4.0];
    /// let mut fit = TensorFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
    /// for _ in 0..2000 {
    ///     fit.step(w.map(|x| x as f32), [0.0; 3], 1e-3);
    ///     for _ in 0..100 {
    ///         // J w' = (J w) x w, midpoint steps of 10 us (an example, not a reference).
    ///         let f = |w: [f64; 3]| {
    ///             [
    ///                 (j[1] - j[2]) / j[0] * w[1] * w[2],
    ///                 (j[2] - j[0]) / j[1] * w[2] * w[0],
    ///                 (j[0] - j[1]) / j[2] * w[0] * w[1],
    ///             ]
    ///         };
    ///         let d = f(w);
    ///         let mid = [w[0] + 5e-6 * d[0], w[1] + 5e-6 * d[1], w[2] + 5e-6 * d[2]];
    ///         let d = f(mid);
    ///         for k in 0..3 {
    ///             w[k] += 1e-5 * d[k];
    ///         }
    ///     }
    /// }
    /// // First guesses at any scale: the better one is taken.
    /// let guesses = [[[1.0, 0.0, 0.0], [0.0, 1.6, 0.0], [0.0, 0.0, 2.1]]];
    /// assert_eq!(fit.close_normalized(&guesses, true), StretchOutcome::Fitted);
    /// let e = fit.estimate_normalized().unwrap();
    /// let tr = j[0] + j[1] + j[2];
    /// for k in 0..3 {
    ///     assert!((e.tensor[k][k] as f64 - j[k] / tr).abs() < 1e-3, "{:?}", e.tensor);
    /// }
    /// ```
    pub fn close_normalized(&mut self, inits: &[[[f32; 3]; 3]], test_bias: bool) -> StretchOutcome {
        let noise = self.noise_std;
        self.state.close_into(&mut self.normalized, |blocks| {
            fit_stretch_normalized(blocks, inits, noise, test_bias)
        })
    }

    /// Drops the open stretch without fitting it.
    pub fn discard(&mut self) {
        self.state.buf.clear();
    }

    /// What the last [`TensorFit::close`] did.
    pub fn last_outcome(&self) -> StretchOutcome {
        self.state.last
    }

    /// Samples in the open stretch (not yet fitted).
    pub fn open_samples(&self) -> u32 {
        self.state.buf.samples()
    }

    /// The estimate pooled over the closed stretches (information-weighted, `output_error`),
    /// `None` before one was fitted.
    pub fn estimate(&self) -> Option<TensorFitEstimate> {
        let (e, cov, noise) = self.state.pooled.mean()?;
        Some(TensorFitEstimate {
            tensor: tensor_of(&e),
            cov,
            noise,
            stretches: self.state.pooled.stretches,
            samples: self.state.pooled.samples,
            biased: self.state.biased,
            bias: self.state.bias,
            torque: self.state.torque,
            scale_rejected: self.state.scale,
            cost: self.state.pooled.cost(),
        })
    }

    /// The tensor up to scale pooled over the stretches closed by
    /// [`TensorFit::close_normalized`]: `tensor` is `J / trace J`, `cov` the covariance of its
    /// six entries (rank 5: `dJzz = -dJxx - dJyy`); `None` before one was fitted.
    pub fn estimate_normalized(&self) -> Option<TensorFitEstimate> {
        let (p, c5, noise) = self.normalized.mean()?;
        let e = [p[0], p[1], 1.0 - p[0] - p[1], p[2], p[3], p[4]];
        // Row k: entry k of the six as a combination of the five free ones.
        let rows: [[f32; 5]; 6] = [
            [1.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 1.0],
        ];
        let mut cov = [[0.0f32; 6]; 6];
        for (i, ri) in rows.iter().enumerate() {
            for (j, rj) in rows.iter().enumerate() {
                let mut acc = 0.0;
                for (a, ca) in ri.iter().zip(c5.iter()) {
                    for (b, cab) in rj.iter().zip(ca.iter()) {
                        acc += a * b * cab;
                    }
                }
                cov[i][j] = acc;
            }
        }
        Some(TensorFitEstimate {
            tensor: tensor_of(&e),
            cov,
            noise,
            stretches: self.normalized.stretches,
            samples: self.normalized.samples,
            biased: self.state.biased,
            bias: self.state.bias,
            torque: self.state.torque,
            scale_rejected: self.state.scale,
            cost: self.normalized.cost(),
        })
    }

    /// Forgets everything: the open stretch and the pooled estimate.
    pub fn reset(&mut self) {
        *self = TensorFit::new(self.full_scale, self.max_dt, self.noise_std)
            .with_momentum_resolution(self.momentum_resolution);
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// A body with products of inertia and a flywheel on -z spinning up, f64 RK4 reference;
    /// returns (rate, rotor momentum) per sample.
    /// Rates, rotor momenta and the true tensor.
    type Flight = (Vec<[f32; 3]>, Vec<[f32; 3]>, [[f64; 3]; 3]);

    fn throw(rate: f64, secs: f64) -> Flight {
        throw_with(
            rate,
            secs,
            [
                [2.1e-4, 1.2e-5, -0.8e-5],
                [1.2e-5, 2.9e-4, 0.6e-5],
                [-0.8e-5, 0.6e-5, 3.6e-4],
            ],
            [9.0, -6.0, 14.0],
            |t| -1.7e-6 * (1500.0 + 1500.0 * t),
        )
    }

    fn throw_with(
        rate: f64,
        secs: f64,
        j: [[f64; 3]; 3],
        w0: [f64; 3],
        hz: impl Fn(f64) -> f64,
    ) -> Flight {
        let inv = {
            // f64 adjugate for the reference.
            let m = j;
            let c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
            let c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
            let c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
            let det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
            [
                [
                    c00 / det,
                    (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det,
                    (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det,
                ],
                [
                    c01 / det,
                    (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det,
                    (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det,
                ],
                [
                    c02 / det,
                    (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det,
                    (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det,
                ],
            ]
        };
        let mv = |m: &[[f64; 3]; 3], v: [f64; 3]| -> [f64; 3] {
            core::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
        };
        let cr = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let jw = mv(&j, w0);
        let mut l = [jw[0], jw[1], jw[2] + hz(0.0)];
        let f = |t: f64, l: [f64; 3]| {
            let w = mv(&inv, [l[0], l[1], l[2] - hz(t)]);
            cr(l, w)
        };
        let sub = 40;
        let h = 1.0 / rate / sub as f64;
        let (mut ws, mut hs) = (Vec::new(), Vec::new());
        let mut t = 0.0;
        for _ in 0..(rate * secs) as usize {
            let w = mv(&inv, [l[0], l[1], l[2] - hz(t)]);
            ws.push(w.map(|x| x as f32));
            hs.push([0.0, 0.0, hz(t) as f32]);
            for _ in 0..sub {
                let k1 = f(t, l);
                let k2 = f(
                    t + h / 2.0,
                    core::array::from_fn(|i| l[i] + h / 2.0 * k1[i]),
                );
                let k3 = f(
                    t + h / 2.0,
                    core::array::from_fn(|i| l[i] + h / 2.0 * k2[i]),
                );
                let k4 = f(t + h, core::array::from_fn(|i| l[i] + h * k3[i]));
                for i in 0..3 {
                    l[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
                t += h;
            }
        }
        (ws, hs, j)
    }

    #[test]
    fn noise_free_flywheel_throw_gives_the_tensor_in_kg_m2() {
        for rate in [500.0, 2000.0, 4000.0] {
            let (ws, hs, j) = throw(rate, 0.8);
            let mut fit = fed(&ws, &hs, rate);
            // A first guess 10 % off, products zero.
            let init = [[2.3e-4, 0.0, 0.0], [0.0, 2.6e-4, 0.0], [0.0, 0.0, 3.9e-4]];
            let o = fit.close(Some(init));
            let e = fit.estimate().unwrap();
            std::println!("{rate} Hz: {o:?} noise {}", e.noise);
            assert_eq!(o, StretchOutcome::Fitted, "{rate} Hz");
            assert_near(&e.tensor, &j, 2e-4 * 3.6e-4, &std::format!("{rate} Hz"));
        }
    }

    /// Every entry of `got` within `tol` of `truth` (`what` names the case in the message).
    fn assert_near(got: &[[f32; 3]; 3], truth: &[[f64; 3]; 3], tol: f64, what: &str) {
        for r in 0..3 {
            for c in 0..3 {
                let err = (got[r][c] as f64 - truth[r][c]).abs();
                assert!(err < tol, "{what}: {got:?} vs {truth:?}");
            }
        }
    }

    /// A fresh fit fed the rates `ws` and rotor momenta `hs` sampled at `rate`.
    fn fed(ws: &[[f32; 3]], hs: &[[f32; 3]], rate: f64) -> TensorFit<256> {
        let mut fit = TensorFit::<256>::new(f32::INFINITY, 0.1, 1e-3);
        for (w, h) in ws.iter().zip(hs) {
            fit.step(*w, *h, (1.0 / rate) as f32);
        }
        fit
    }

    /// A flight controller's board (the thrown-FC's), light against its flywheel's momentum,
    /// kg m^2.
    const BOARD: [[f64; 3]; 3] = [
        [7.5e-5, -1.7e-6, 1.1e-6],
        [-1.7e-6, 2.2e-5, 6.8e-6],
        [1.1e-6, 6.8e-6, 8.8e-5],
    ];
    /// Its flywheel's inertia, kg m^2 (the thrown-FC's size).
    const JR: f64 = 1.7e-6;

    /// A raised-cosine ramp from 0 (x <= 0) to 1 (x >= 1): speed and acceleration continuous,
    /// as a motor's.
    fn ramp(x: f64) -> f64 {
        0.5 - 0.5 * (core::f64::consts::PI * x.clamp(0.0, 1.0)).cos()
    }

    /// (F7): a rotor speed read in steps of 1.75 rad/s is off by a constant wherever it is
    /// steady. A board's flywheel idling at 1500 rad/s (0.4 of a step above a reading), spun
    /// up to 2250 and back, read in steps, with white gyro noise of 1e-3 rad/s: taken as exact
    /// the momentum pulls the tensor 13 of its reported standard deviations off; with the
    /// resolution given the steady runs' offsets are fitted and the reading's error along the
    /// ramps is counted ((F8)): the largest error is 1.2 (3.2 with the offsets alone).
    #[test]
    fn steady_telemetry_offsets_are_fitted_with_the_resolution() {
        let rate = 2000.0;
        let speed = |t: f64| 1500.0 + 750.0 * (ramp((t - 0.25) / 0.15) - ramp((t - 0.5) / 0.15));
        let j = BOARD;
        let (ws, hs, truth) = throw_with(rate, 0.8, j, [9.0, -6.0, 14.0], |t| -JR * speed(t));
        let mut state = 0x2545_f491_u32;
        let mut noise = || {
            let mut s = 0.0f32;
            for _ in 0..12 {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                s += state as f32 / u32::MAX as f32;
            }
            1e-3 * (s - 6.0)
        };
        let ws: std::vec::Vec<[f32; 3]> = ws.iter().map(|w| w.map(|x| x + noise())).collect();
        let step = 1.745f64;
        // The speed as telemetry reads it: rounded to its step.
        let read: std::vec::Vec<[f32; 3]> = (0..hs.len())
            .map(|k| {
                let v = speed(k as f64 / rate);
                [0.0, 0.0, (-JR * (v / step).round() * step) as f32]
            })
            .collect();
        let init = [[7.9e-5, 0.0, 0.0], [0.0, 2.3e-5, 0.0], [0.0, 0.0, 9.2e-5]];
        // The largest error of an entry over its reported standard deviation.
        let worst = |fit: &mut TensorFit<256>| {
            // The gyro's bias known (a bias would soak up some of the offsets).
            assert_eq!(fit.close_without_bias(Some(init)), StretchOutcome::Fitted);
            let e = fit.estimate().unwrap();
            let t6 = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
            let mut w = 0.0f64;
            for (i, (r, c)) in t6.iter().enumerate() {
                let err = e.tensor[*r][*c] as f64 - truth[*r][*c];
                w = w.max(err.abs() / (e.cov[i][i] as f64).sqrt());
            }
            w
        };
        let exact = worst(&mut fed(&ws, &hs, rate));
        let mut plain = fed(&ws, &read, rate);
        let off = worst(&mut plain);
        let mut fitted = fed(&ws, &read, rate).with_momentum_resolution((JR * step) as f32);
        let with = worst(&mut fitted);
        std::println!(
            "largest error over its std: exact momentum {exact:.2}, offsets taken as exact \
             {off:.2}, fitted {with:.2}"
        );
        assert!(off > 5.0, "the offsets should matter: {off:.2}");
        // With the ramps' errors counted too ((F8)): 3.2 with the offsets alone.
        assert!(with < 2.5, "fitted: {with:.2} against {off:.2}");
        // Not finite or not positive: the momentum is taken as exact (the plain fit).
        for q in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let mut same = fed(&ws, &read, rate).with_momentum_resolution(q);
            same.close_without_bias(Some(init));
            assert_eq!(same.estimate(), plain.estimate());
        }
    }

    /// (F8)'s gain: an error `d` in the momentum read over some blocks moves the fitted
    /// parameters by `F^-1 sum_b gamma_b d` to first order. Checked against fitting again a
    /// noise-free flight whose reading was moved by half a quantum over ten blocks of the
    /// spin-up.
    #[test]
    fn a_reading_error_moves_the_fit_as_its_gain_says() {
        let rate = 2000.0;
        let speed = |t: f64| 300.0 + 900.0 * ramp((t - 0.2) / 0.3);
        let j = BOARD;
        let w0 = [9.0, -6.0, 14.0];
        let (ws, hs, _) = throw_with(rate, 0.8, j, w0, |t| -JR * speed(t));
        let blocks_of = |hs: &[[f32; 3]]| {
            let mut fit = fed(&ws, hs, rate);
            fit.state.buf.finish().to_vec()
        };
        let base = blocks_of(&hs);
        let start = |b: usize| base.iter().take(b).map(|blk| blk.n as usize).sum::<usize>();
        let th0: [f32; P0] = core::array::from_fn(|i| match i {
            0..=2 => j[i][i] as f32,
            3 => j[0][1] as f32,
            4 => j[0][2] as f32,
            5 => j[1][2] as f32,
            _ => w0[i - 6] as f32,
        });
        let rule = StepRule::new(&tensor_of(&six(&th0, 0.0, 6)));
        let dof = (3 * base.len() - P0) as f32;
        let fit_of = |blocks: &[Block<6>]| {
            let normal = |p: &[f32; P0]| normal(blocks, &rule, blocks.len(), p, 0.0, &Cells::NONE);
            levenberg(normal, th0, 30, dof, TOLERANCE, Start::Cold).unwrap()
        };
        let (th_a, _, f) = fit_of(&base);
        let u = rotor_direction(&base).unwrap();
        let d = 0.5 * (JR * 1.745) as f32;
        let (first, last) = (90, 100);
        let moved: Vec<[f32; 3]> = hs
            .iter()
            .enumerate()
            .map(|(k, h)| {
                if (start(first)..start(last)).contains(&k) {
                    core::array::from_fn(|i| h[i] + d * u[i])
                } else {
                    *h
                }
            })
            .collect();
        let (th_b, _, _) = fit_of(&blocks_of(&moved));
        let mut g = [0.0f32; P0];
        let ok = each_gamma(&base, &rule, &th_a, &Cells::NONE, &f, u, &mut |nd, gain| {
            if let (true, Some((gamma, _, _))) = ((first..last).contains(&nd.index), gain) {
                for (gi, x) in g.iter_mut().zip(gamma) {
                    *gi += x * d;
                }
            }
        });
        assert!(ok);
        let fi = scaled_inverse(&f).unwrap();
        let largest = (0..6)
            .map(|i| (th_b[i] - th_a[i]).abs())
            .fold(0.0, f32::max);
        assert!(largest > 1e-8, "the move should matter: {largest:.3e}");
        // Measured: within 2-5 % on the five entries it moves, 7e-11 on Jzz, which it hardly
        // moves (its sensitivity to a momentum along z is second order).
        for i in 0..6 {
            let moved = th_b[i] - th_a[i];
            let said = dot_n(&fi[i], &g);
            std::println!("entry {i}: refitted {moved:+.3e}, gain {said:+.3e}");
            assert!(
                (said - moved).abs() <= 0.1 * moved.abs() + 0.01 * largest,
                "entry {i}: refitted {moved:.3e}, gain {said:.3e}"
            );
        }
    }

    /// `ramp_share` against the block means of rounded ramps from random phases, each over
    /// a span drawn within 20 % of `d` quanta (away from one quantum per block, where it is
    /// the conservative side by design).
    #[test]
    fn ramp_share_matches_rounded_ramps() {
        let mut state = 0x9E37_79B9_u32;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f64 / u32::MAX as f64
        };
        for n in [4usize, 16] {
            for d0 in [0.1, 0.3, 0.5, 2.0, 3.0, 30.0, 100.0] {
                let (mut var, mut share) = (0.0f64, 0.0f64);
                let trials = 20_000;
                for _ in 0..trials {
                    let phase = uniform();
                    let d = d0 * (0.8 + 0.4 * uniform());
                    let mean = (0..n)
                        .map(|i| {
                            let x = phase + d * (i as f64 + 0.5) / n as f64;
                            x.round() - x
                        })
                        .sum::<f64>()
                        / n as f64;
                    var += mean * mean;
                    share += f64::from(ramp_share(d as f32, n as f32));
                }
                let ratio = 12.0 * var / share;
                assert!(
                    (0.6..1.6).contains(&ratio),
                    "n {n}, d {d0}: simulated over ramp_share {ratio:.2}"
                );
            }
        }
    }

    /// A first guess far off in scale (the step count comes from it, see `StepRule`): the
    /// fit still integrates finely enough for the tensor it ends at.
    #[test]
    fn a_first_guess_far_off_in_scale_still_gives_the_tensor() {
        let rate = 2000.0;
        let (ws, hs, j) = throw(rate, 0.8);
        for k in [0.25f32, 4.0] {
            let mut fit = fed(&ws, &hs, rate);
            let init = [
                [2.3e-4 * k, 0.0, 0.0],
                [0.0, 2.6e-4 * k, 0.0],
                [0.0, 0.0, 3.9e-4 * k],
            ];
            let o = fit.close(Some(init));
            let e = fit.estimate().unwrap();
            std::println!("x{k}: {o:?} noise {} tensor {:?}", e.noise, e.tensor);
            assert_eq!(o, StretchOutcome::Fitted, "x{k}");
            assert!(e.noise < 1e-3, "x{k}: residual {} rad/s", e.noise);
            assert_near(&e.tensor, &j, 2e-4 * 3.6e-4, &std::format!("x{k}"));
        }
    }

    /// A rotor at rest at the release, spun up and stopped again: the momentum is held on its
    /// invariants only while no rotor momentum has been seen (the motor does work on the body,
    /// so the start's energy is wrong once it has turned, even after it stops).
    #[test]
    fn a_rotor_started_and_stopped_in_flight_keeps_the_tensor() {
        let rate = 1000.0;
        let profile = |t: f64| {
            // Rest for 0.3 s, a smooth pulse to 2000 rad/s, rest again from 0.9 s.
            if (0.3..0.9).contains(&t) {
                let s = (t - 0.3) / 0.6 * core::f64::consts::PI;
                -1.7e-6 * 2000.0 * s.sin() * s.sin()
            } else {
                0.0
            }
        };
        let j = [
            [2.1e-4, 1.2e-5, -0.8e-5],
            [1.2e-5, 2.9e-4, 0.6e-5],
            [-0.8e-5, 0.6e-5, 3.6e-4],
        ];
        let (ws, hs, j) = throw_with(rate, 1.6, j, [9.0, -6.0, 14.0], profile);
        let mut fit = fed(&ws, &hs, rate);
        let init = [[2.3e-4, 0.0, 0.0], [0.0, 2.6e-4, 0.0], [0.0, 0.0, 3.9e-4]];
        let o = fit.close(Some(init));
        let e = fit.estimate().unwrap();
        std::println!("{o:?} noise {} tensor {:?}", e.noise, e.tensor);
        assert_eq!(o, StretchOutcome::Fitted);
        // Noise-free: the trajectory explains the rates (restored onto the start's energy
        // after the rotor stopped, the residual was 2.1 rad/s).
        assert!(e.noise < 1e-3, "residual {} rad/s", e.noise);
        assert_near(&e.tensor, &j, 2e-4 * 3.6e-4, "rotor started and stopped");
    }

    #[test]
    fn without_rotor_momentum_the_tensor_comes_up_to_scale() {
        let j = [
            [2.1e-4, 1.2e-5, -0.8e-5],
            [1.2e-5, 2.9e-4, 0.6e-5],
            [-0.8e-5, 0.6e-5, 3.6e-4],
        ];
        let tr = j[0][0] + j[1][1] + j[2][2];
        for rate in [100.0, 1000.0, 8000.0] {
            let (ws, hs, _) = throw_with(rate, 2.0, j, [3.0, -2.0, 4.0], |_| 0.0);
            let mut fit = fed(&ws, &hs, rate);
            // A first guess at another scale, 10 % off, products zero.
            let init = [[1.0, 0.0, 0.0], [0.0, 1.5, 0.0], [0.0, 0.0, 1.6]];
            let o = fit.close_normalized(&[init], true);
            assert_eq!(o, StretchOutcome::Fitted, "{rate} Hz");
            assert!(
                fit.estimate().is_none(),
                "no absolute tensor without rotor momentum"
            );
            let e = fit.estimate_normalized().unwrap();
            let t = e.tensor[0][0] + e.tensor[1][1] + e.tensor[2][2];
            assert!((t - 1.0).abs() < 1e-6, "trace {t}");
            let jn = j.map(|row| row.map(|x| x / tr));
            assert_near(&e.tensor, &jn, 1e-5, &std::format!("{rate} Hz"));
            // The covariance keeps the trace: Jzz moves against Jxx and Jyy.
            let var_tr: f32 = (0..3)
                .flat_map(|a| (0..3).map(move |b| (a, b)))
                .map(|(a, b)| e.cov[a][b])
                .sum();
            assert!(
                var_tr.abs() < 1e-6 * e.cov[0][0].abs().max(1e-30),
                "{var_tr}"
            );
        }
    }
}
