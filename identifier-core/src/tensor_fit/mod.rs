//! Output-error maximum likelihood of the whole inertia tensor in kg m^2, with a known rotor
//! momentum: the trajectory of Euler's equation fitted to block means of the gyro.
//!
//! # Why
//!
//! [`crate::TensorEstimator`] solves Euler's equation integrated per stretch by least squares:
//! one pass, no iteration, cheap per sample, but the measured rates enter its regressors, so
//! their noise is in both sides of the equations and the estimate is not efficient (above the
//! Cramer-Rao bound per entry; `tensor-bench` measures both on the simulated flywheel throw).
//! The output-error fit is the efficient estimator for white gyro noise; like
//! [`crate::RatioFit`] it only sums blocks per sample and fits once per free flight.
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
//! of (F1) ((F6), every eight blocks, evaluated to twice the `f32` precision): otherwise the
//! `f32` drift of the motion's phase on a long fast tumble leaves the fit up to scale above its
//! bound.
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
//! products of inertia partly absorb: on a principal body with the gyro a few tenths of a
//! percent off on two axes, products appear and the tensor can say `Converged` many standard
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
//! the tensor little (its variance stays near the exact momentum's, where taking them as errors
//! of uniform variance makes it tens of times larger); `tensor-bench` measures the errors
//! against the white-noise bound on simulated board throws at the logged resolution. The
//! errors along the ramps, where the reading changes from block to block, are left (they also
//! act on later blocks through the integrated momentum, which neither the residual's level nor
//! the offsets count: the reported standard deviation is too small there). The fit is kept
//! only when every offset came out within one quantum (a quantisation's error is at most half
//! of one): where the model error is tens of times the gyro's noise (the thrown-FC logs), free
//! offsets come out at several quanta, soaking up that error, and the fit without them is
//! taken.
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
//! the light board they are several times the gyro's noise per block, and counted in the
//! residual's level too they would double the products' standard deviation. The reported
//! standard deviation against the errors is measured by `tensor-bench` on simulated light
//! board throws and by the test `calibrate_sim` on assembly throws through `inertia identify`;
//! on the thrown-FC logs it is set by their model error.
//!
//! The fit starts from an estimate of `J` the caller gives (the pipeline gives
//! [`crate::TensorEstimator`]'s) and the first block's rate, on all the blocks at once, and on
//! growing prefixes of them only when that does not fit to twice the noise.
//!
//! # When the model does not fit
//!
//! A real vehicle's flight leaves a residual far above the gyro's noise, and a slow one
//! (drift, steps where a rotor spins up): the covariance scaled by the residual's level alone
//! claims several times the information the flight holds. Each parameter's variance is then
//! inflated by what the residual's correlation does to it, the sandwich of the block scores
//! summed over batches of the residual's correlation length, never less than a first-order
//! autoregressive residual's `(1 + rho) / (1 - rho)`:
//!
//! ```text
//! k_i = max((1 + rho) / (1 - rho), (F^-1 V F^-1)_ii / (s^2 (F^-1)_ii)),
//! V = K/(K-1) sum_k G_k G_k^T,   G_k = sum_(b in batch k) n_b R_b^T r_b              (F10)
//! ```
//!
//! and the covariance becomes `D C D`, `D = diag(sqrt(k_i))`. It applies where the residual
//! is above twice the noise, and also below that level where the block residuals' lag-1
//! autocorrelation is positive beyond four standard deviations of a white residual's,
//!
//! ```text
//! rho > 4 / sqrt(3 n)      (n blocks, three axes)                                   (F10')
//! ```
//!
//! where the residual is at least the noise's level (a residual below it, such as a noise-free
//! log's rounding, fits to the noise whatever its colour).
//!
//! A gyro whose bias walks or that truncates its readings, or a small unmodelled torque, leaves
//! a residual near the noise's level but coloured, and the white covariance then claims
//! information the flight does not hold (the spacecraft benchmark's MEMS gyro and residual
//! dipole, `scripts/bench-spacecraft.sh`); a white residual leaves the covariance as it is.
//!
//! A single trajectory also carries the model error along the whole flight: the error of a
//! small unmodelled torque grows with time and `J` bends to follow it. When the single
//! trajectory's residual is above twice the noise (less the rotor reading's known errors of
//! (F8)), the flight is fitted again by multiple shooting: consecutive segments of the
//! residual's correlation length, each from its own initial rate, one `J` shared, the initial
//! rates eliminated from the normal equations ((F11), `shooting`), its covariance the sandwich
//! over the segments. It is kept when its likelihood-ratio test against the single trajectory
//! passes (`shooting_found`), with a covariance never below the single trajectory's (the
//! segments' sandwich sees the residual within one flight, not what moves a whole flight's
//! answer). Where the single trajectory's own error is large that floor errs on the large
//! side. Holding the segments' covariance at the floor of (F14), below, instead is not enough:
//! a product of inertia of the proof body then claims more than its five throws' scatter
//! allows (the test `thrown_fc_free_flights_found_hand_and_catch_excluded` of
//! `inertia/tests/identify.rs`). `scripts/bench-objects.sh` measures both fits on thrown
//! objects of known inertia.
//!
//! Neither the sandwich nor the segments see an error that the whole flight shares, and on a
//! thrown body the slow residual can move every throw alike. Where the flight does not fit to
//! the noise (its residual beyond twice the noise's, or coloured), the slow error is described
//! as a walk of the output ((F12), its size by (F13)) over the blocks the single trajectory was
//! fitted to, and the reported variance of each entry is never below that model's generalised
//! least squares, which no linear unbiased estimate from the same blocks beats under it:
//!
//! ```text
//! var_i >= s_w^2 (F_w^-1)_ii                                                          (F14)
//! ```
//!
//! (`F_w` the whitened normal matrix of the bias model refitted with the walk, `s_w^2` its
//! whitened cost per degree of freedom). The estimate is unchanged; `scripts/bench-objects.sh`
//! measures the calibration of the reported standard deviation with and against it.
//!
//! # A gyro bias that walks
//!
//! A satellite's MEMS gyro drifts over its long, slow flight: its bias is a random walk, not
//! a constant, and a residual near the noise's level hides a slow error that a constant bias
//! leaves in the estimate and a white covariance does not count. Where the bias model is
//! checked (a long flight whose gyro bias nothing measures, [`BiasModel::Checked`]), the walk
//! is looked for: per axis, the walk `d` of step variance `lambda sigma^2` per sample is read
//! in each block mean beside the white noise, and the fit becomes the generalised least squares
//! of that error, the residuals and every sensitivity column whitened by the walk's Kalman
//! filter over the blocks (`walk`):
//!
//! ```text
//! cost = sum_b sum_axes nu_b^2 / V_b,   F = sum nu_(R,b) nu_(R,b)^T / V_b               (F12)
//! ```
//!
//! (`nu` the filter's innovations of the residual and of the rows `R_b`, `V_b` their variance
//! in units of `sigma^2`; `V_b = 1 / n_b` and the plain fit without a walk). `lambda` is the
//! maximum of the restricted likelihood of the fit ((F13) of `walk`) over candidates four times
//! apart about the walk that equals one block's white variance over the whole stretch, refined
//! by a parabola, at the constant bias's parameters, then once more at the parameters the walk
//! gives. It is taken when its likelihood ratio against no walk exceeds 10.83 (chi-square, one
//! degree of freedom, 0.1 %; see `walk::WALK_LR` for the balance of the two errors). A stretch whose walk states a variance of some entry more than
//! 1.44 times the white fit's counts as coloured ((F10')): the tensor is at most
//! `ModelMismatch`, usable with its stated standard deviation (a small walk taken on a white
//! gyro leaves the status as it was). Its residual
//! level ([`TensorFitEstimate::residual`]) is the residual not whitened, the walk's error in it,
//! which the choices between models (the gravity gradient folded in or not, readings centred
//! or as read) compare: the walk would take up a torque the model lacks as well. `scripts/bench-spacecraft.sh` measures the errors against the bound of the MEMS
//! gyro's own model and the calibration of the reported standard deviation.
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
//! Cost: a few hundred instructions per sample, and millions per fit (tens of milliseconds at
//! 168 MHz on the Cortex-M4F; more with the rotor telemetry's offsets of (F7), four more
//! parameters, or when the fit from the rotor's spin-up follows). `bench-mcu` measures each
//! case in the release and flight builds. A fit is too long for one gyro period, which is why
//! the pipeline runs it in [`crate::Pipeline::fit_ended_flight`], outside its per-sample step.
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
use crate::output_error::StretchOutcome;
use crate::output_error::{
    bias_found, bias_worth_fitting, higher_orders, levenberg, refit_cost, scaled_inverse, score,
    score_beyond, score_rejects, substeps, torque_confirmed, whole_or_staged, without, Alternative,
    Block, FitState, Normal, NormalSums, Pooled, Readings, Start, StretchResult, TOLERANCE,
};
use crate::symmetric::{eigen_symmetric3, sqrt, Sym};

mod model;
mod normal;
mod reading;
mod shooting;
#[cfg(test)]
mod tests;
mod walk;

use model::*;
use normal::*;
use reading::*;

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
    /// Gyro noise per sample seen in the fits' residuals, rad/s: the white noise's, with a
    /// walking bias ((F12)) that of the residuals whitened by the walk's filter.
    pub noise: f32,
    /// The residual's level per sample, rad/s: with a walking bias ((F12)) that of the fitted
    /// parameters' residuals not whitened (`sqrt(sum_b n_b |r_b|^2 / dof)`, the walk's error
    /// included), which the fit to the noise is judged by and fits of other models are
    /// compared by; `noise` itself where no walk was found.
    pub residual: f32,
    /// The gyro bias's walk found on the pooled stretches ((F12), (F13)): the largest step std
    /// per sample, rad/s; 0 where none was found.
    pub bias_walk: f32,
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
    /// True when a pooled stretch's residual, near the noise's level, was coloured ((F10'):
    /// its lag-1 autocorrelation beyond what a white residual gives): the fit does not fit to
    /// the noise, whatever the residual's level says.
    pub coloured: bool,
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
    /// How each gyro reading spreads over time ([`TensorFit::with_reading_window`],
    /// [`TensorFit::with_reading_smoothing`]).
    readings: Readings,
    /// The gyro readings' own time variance of the latest sample ((B0), (B0'): the window's
    /// and the filters'), which the blocks' `v` holds and the rotor's readings lack.
    own_spread: f32,
    /// Multiple shooting ((F11)) where the single trajectory leaves a model error.
    shooting: bool,
}

/// The block buffer used by the pipeline: 256 blocks of rate and rotor momentum (16.7 KB in
/// all).
pub type FlightTensorFit = TensorFit<256>;

/// Whether a stretch's fit has a constant gyro bias `b` in (F2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BiasModel {
    /// None: the bias was measured and removed.
    Without,
    /// The bias model when its likelihood-ratio test finds one.
    Tested,
    /// [`BiasModel::Tested`], and also where the bias model moves an entry of interest by
    /// more than [`HAUSMAN_Z`] standard deviations of the difference (Hausman's test, per
    /// entry: `|p_b - p| > z sqrt(var_b - var)`), for a gyro whose bias nothing measures on a
    /// long, slow flight. The likelihood-ratio test alone is a pre-test: where the bias and
    /// the products of inertia are nearly interchangeable the plain model fits to the noise
    /// with products off by many of its standard deviations (a satellite's gyro bias of 1e-4
    /// rad/s against tumble rates of 0.05 rad/s), while the bias model's covariance counts the
    /// confusion. Fitting the bias always costs the bias-free flight precision (three
    /// parameters per window).
    Checked,
}

/// The per-entry Hausman statistic beyond which [`BiasModel::Checked`] takes the bias model
/// (a 0.01 % two-sided normal point).
const HAUSMAN_Z: f32 = 3.9;

/// Fits one stretch from `th` (`P` parameters without the bias, `PB` with it, the first `M`
/// of interest; see [`normal`]): the plain model on all the blocks at once, and on growing
/// prefixes only if that does not fit to twice `noise_floor` ([`whole_or_staged`]); then,
/// the bias model as `bias` says ([`BiasModel`]). On the
/// simulated flywheel throw the absolute fit of all the blocks is as accurate as the staged
/// one alone, at two thirds of the cost.
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
    bias: BiasModel,
    cells: &Cells,
    res: Resolution,
) -> Option<StretchResult<M>> {
    let total = blocks.len();
    let rule = StepRule::new(&tensor_of(&six(&th, trace, M))).with_gyro_spread(res.gyro_spread);
    let dof0 = (3 * total) as f32 - P as f32;
    let (th, cost0, f0) = whole_or_staged(
        |p, limit| normal(blocks, &rule, limit, p, trace, cells),
        th,
        total,
        noise_floor,
    )?;
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
    let worth = match bias {
        BiasModel::Without => false,
        // Checked: the bias model is always fitted, for its comparison with the plain one.
        BiasModel::Checked => true,
        BiasModel::Tested => normal(blocks, &rule, total, &th1, trace, cells)
            .and_then(|(_, f, g)| score(&f, &g))
            .is_none_or(|sc| bias_worth_fitting(sc, cost0, dof0, noise_floor)),
    };
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
    let mut alt = None;
    if let Some(mut fit1) = with_bias {
        let (t1, cost1, f1) = (&fit1.0, fit1.1, &fit1.2);
        let moved = || {
            let s2 = (cost1 / dof1).max(noise_floor * noise_floor);
            let c1 = scaled_inverse(f1);
            (0..M).any(|i| {
                let d = t1.get(i).copied().unwrap_or(0.0) - th.get(i).copied().unwrap_or(0.0);
                let diag = |c: &Sym<PB>| c.get(i).and_then(|r| r.get(i)).copied();
                let vb = c1.as_ref().and_then(diag).unwrap_or(0.0);
                let vp = cov0.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
                let v = s2 * (vb - vp).max(1e-6 * vb);
                v > 0.0 && d * d > HAUSMAN_Z * HAUSMAN_Z * v
            })
        };
        let found = bias_found(cost0, cost1, dof1, noise_floor);
        if !found && bias == BiasModel::Checked {
            alt = scaled_inverse(f1).map(|c1| Alternative {
                p: leading(t1),
                cov: leading_block(&c1),
                cost: cost1,
                params: PB,
            });
        }
        if found || (bias == BiasModel::Checked && moved()) {
            if *cells != Cells::NONE && !cells.plausible(t1) {
                return None;
            }
            // A long flight whose gyro bias nothing measures: the bias may walk ((F12),
            // (F13)). The fit is changed in place: a copy of its normal matrix would stay in
            // this frame, which the flight's fits share the stack with.
            let mut rule = rule;
            let raw = if bias == BiasModel::Checked {
                walked(blocks, &mut rule, &mut fit1, trace, cells, dof1)
            } else {
                None
            };
            let (t1, cost1, f1) = (&fit1.0, fit1.1, &fit1.2);
            if let Some(c1) = scaled_inverse(f1) {
                let g = |i: usize| t1.get(i).copied().unwrap_or(0.0);
                let (inflation, lag1, col) = residual_inflation(
                    blocks,
                    &rule,
                    t1,
                    trace,
                    cells,
                    &c1,
                    (cost1, dof1),
                    noise_floor,
                );
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
                let input = input_cov(blocks, &rule, t1, cells, res, f1);
                return Some(StretchResult {
                    p: leading(t1),
                    cov: inflated(&leading_block(&c1), &inflation),
                    input: input.map(|(c, e)| (leading_block(&c), e)),
                    cost: cost1,
                    params: PB,
                    bias: Some([g(M + 3), g(M + 4), g(M + 5)]),
                    lag1,
                    // A walking bias ((F12)) that widens the tensor's variance is a model of
                    // the gyro's error, not of the noise: what it takes up the white noise
                    // does not hold, and the tensor says so as a coloured residual's does
                    // ((F10')).
                    coloured: col || raw.is_some_and(|(_, matters)| matters),
                    torque,
                    scale,
                    alt: None,
                    walk: raw.map(|(r, _)| (rule.walk * cost1 / dof1, r)),
                });
            }
        }
    }
    if *cells != Cells::NONE && !cells.plausible(&th) {
        return None;
    }
    let (inflation, lag1, col) = residual_inflation(
        blocks,
        &rule,
        &th,
        trace,
        cells,
        &cov0,
        (cost0, dof0),
        noise_floor,
    );
    let th_t: [f32; PT] = leading(&th);
    let (torque, scale) =
        tests_found::<PT, PTS>(blocks, &rule, &th_t, trace, cost0, dof0, noise_floor);
    let input = input_cov(blocks, &rule, &th, cells, res, &f0);
    Some(StretchResult {
        p: leading(&th),
        cov: inflated(&leading_block(&cov0), &inflation),
        input: input.map(|(c, e)| (leading_block(&c), e)),
        cost: cost0,
        params: P,
        bias: None,
        lag1,
        coloured: col,
        torque,
        scale,
        alt,
        walk: None,
    })
}

/// (F13): the gyro bias's walk of largest restricted likelihood at `theta` (its step variance
/// per sample over the white noise's; each candidate's parameters at the Gauss-Newton optimum
/// from `theta`, [`walk::restricted_deviance`]) and its likelihood ratio against no walk;
/// `None` when a deviance cannot be computed.
fn walk_restricted<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
    dof: f32,
) -> Option<(f32, f32)> {
    let deviance = |lambda: f32| {
        let whitened = rule.with_walk(lambda);
        let (cost, f, g) = normal(blocks, &whitened, blocks.len(), theta, trace, cells)?;
        walk::restricted_deviance(blocks, lambda, (cost, &f, &g), dof)
    };
    let none = deviance(0.0)?;
    let lambdas = walk::candidates(blocks);
    let mut devs = [f32::INFINITY; walk::CANDIDATES];
    for (d, l) in devs.iter_mut().zip(lambdas) {
        *d = deviance(l).unwrap_or(f32::INFINITY);
    }
    let (lambda, best) = walk::refined(&lambdas, &devs);
    let ratio = none - best;
    (ratio.is_finite() && lambda > 0.0).then_some((lambda, ratio))
}

/// The bias model's `fit` (parameters, cost, normal matrix) refitted with the walk its
/// residuals show ((F12), (F13)), with the rule that whitens by it; the fit and `rule` as they
/// are when no walk is found. The walk of largest restricted likelihood at the constant bias's
/// parameters ([`walk_restricted`]) is fitted, found again at the parameters that fit gives,
/// and taken when its likelihood ratio there passes [`walk::WALK_LR`] (fitted again if it
/// moved by more than a quarter). `fit` and `rule` are replaced by the walk's, and the taken
/// fit's cost without the whitening returned (`sum_b n_b |r_b|^2`, [`StretchResult::walk`]);
/// `None`, both left as they are, when no walk is taken.
///
/// Never inlined, and the fit updated in place: its frames (the candidates' normal equations,
/// the refits') then live only while it runs, not in every caller's (the sample loop's fits
/// run on the same stack).
#[inline(never)]
fn walked<const P: usize>(
    blocks: &[Block<6>],
    rule: &mut StepRule,
    fit: &mut ([f32; P], f32, Sym<P>),
    trace: f32,
    cells: &Cells,
    dof: f32,
) -> Option<(f32, bool)> {
    let plain = *rule;
    let refit = |theta: &[f32; P], lambda: f32| {
        let whitened = plain.with_walk(lambda);
        levenberg(
            |p| normal(blocks, &whitened, blocks.len(), p, trace, cells),
            *theta,
            30,
            dof,
            TOLERANCE,
            Start::Warm,
        )
    };
    let (first, _) = walk_restricted(blocks, &plain, &fit.0, trace, cells, dof)?;
    let once = refit(&fit.0, first)?;
    let (lambda, ratio) = walk_restricted(blocks, &plain, &once.0, trace, cells, dof)?;
    if !(ratio > walk::WALK_LR) {
        return None;
    }
    let settled = lambda < 1.25 * first && lambda > 0.8 * first;
    let (taken, walk) = match settled {
        true => (once, first),
        false => match refit(&once.0, lambda) {
            Some(again) => (again, lambda),
            None => (once, first),
        },
    };
    let raw = visit_fit::<P, 0>(
        blocks,
        &plain,
        blocks.len(),
        &taken.0,
        trace,
        cells,
        &mut (),
    )
    .map_or(f32::INFINITY, |(c, _, _)| c);
    let matters = walk_matters(fit, &taken, dof);
    *fit = taken;
    *rule = plain.with_walk(walk);
    Some((raw, matters))
}

/// Whether the walk's fit `walked` states a variance of one of the six entries more than
/// [`WALK_MATTERS`] times the white fit's `white` (each its cost per degree of freedom times
/// its inverse normal matrix): where it does not, the white noise's model told the flight's
/// information on `J` nearly as well, and a small walk taken in vain on a white gyro
/// ([`walk::WALK_LR`]) leaves the tensor's status as it was.
fn walk_matters<const P: usize>(
    white: &([f32; P], f32, Sym<P>),
    walked: &([f32; P], f32, Sym<P>),
    dof: f32,
) -> bool {
    let (Some(cw), Some(cv)) = (scaled_inverse(&white.2), scaled_inverse(&walked.2)) else {
        return true;
    };
    (0..6).any(|i| {
        let d = |c: &Sym<P>| c.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
        let (vw, vv) = (white.1 / dof * d(&cw), walked.1 / dof * d(&cv));
        !(vv <= WALK_MATTERS * vw)
    })
}

/// The variance ratio, walk over white on some entry, beyond which a walk is the gyro's error
/// model and not a detail of its noise ([`walk_matters`]): a standard deviation a fifth larger.
const WALK_MATTERS: f32 = 1.44;

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
/// Both tests come from one evaluation with the torque's and the scale factors' columns: the
/// columns are integrated independently, so it gives the same sums as one evaluation per test
/// at less cost.
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
/// the offsets of (F7) the trajectory is integrated without sensitivities (the columns would go
/// unused and cost time in the fit of a flight its model does not explain), with them the
/// columns go along (the layout needs them).
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

/// How far the block residuals' lag-1 autocorrelation may rise above zero, in standard
/// deviations of its estimate from white residuals (`1 / sqrt(3 n)` over `n` blocks of three
/// axes), before the residual counts as coloured ([`coloured`], (F10')): a white residual
/// passes it but once in about thirty thousand fits.
const WHITE_LAG1_Z: f32 = 4.0;

/// Whether block residuals of lag-1 autocorrelation `rho` over `n` blocks are coloured ((F10')):
/// `rho` positive and beyond [`WHITE_LAG1_Z`] standard deviations of white residuals' (a
/// walking gyro bias, a truncating gyro, an unmodelled slow torque), even where their level is
/// near the noise's; the fit's covariance is then inflated by (F10).
fn coloured(rho: f32, n: usize) -> bool {
    let m = 3usize.saturating_mul(n) as f32;
    m > 0.0 && rho * rho * m > WHITE_LAG1_Z * WHITE_LAG1_Z && rho > 0.0
}

/// The correlation length, in blocks, of block residuals of lag-1 autocorrelation `rho`:
/// `(1 + rho) / (1 - rho)`, `rho` taken in `[0, 0.98]` (so in `[1, 99]`). It is also the
/// variance of the mean of a first-order autoregressive series over a white one's: the least
/// the residual's correlation inflates a variance by ((F10)).
fn correlation_length(rho: f32) -> f32 {
    let r = rho.clamp(0.0, 0.98);
    (1.0 + r) / (1.0 - r)
}

/// (F10)'s `k_i` from the variance `seen` (the sandwich's) and `white` (the white residual's):
/// their ratio, never below `floor`.
fn inflation_of(seen: f32, white: f32, floor: f32) -> f32 {
    if white > 0.0 && seen.is_finite() && seen > floor * white {
        seen / white
    } else {
        floor
    }
}

/// Blocks per batch of [`score_inflation`] for block residuals of lag-1 autocorrelation `rho`
/// over `n` blocks: twice the residual's [`correlation_length`], so that neighbouring batches'
/// sums are nearly independent, but no more than `n / 8` (eight batches at least).
fn batch_len(rho: f32, n: usize) -> usize {
    let len = 2.0 * correlation_length(rho);
    let cap = (n / MIN_BATCHES).max(1);
    // `len` is in [2, 198]: the cast is exact for its ceiling.
    let l = (len + 0.999) as usize;
    l.max(1).min(cap)
}

/// `k C`: the covariance `c` scaled.
fn scaled<const M: usize>(c: &Sym<M>, k: f32) -> Sym<M> {
    let mut out = *c;
    for row in out.iter_mut() {
        for x in row.iter_mut() {
            *x *= k;
        }
    }
    out
}

/// `D C D` with `D = diag(sqrt(k))`: the covariance `c` inflated per parameter ((F10)).
fn inflated<const M: usize>(c: &Sym<M>, k: &[f32; M]) -> Sym<M> {
    let d = k.map(sqrt);
    let mut out = *c;
    for (row, di) in out.iter_mut().zip(d) {
        for (x, dj) in row.iter_mut().zip(d) {
            *x *= di * dj;
        }
    }
    out
}

/// The fit's inflation where its residual calls for it, with the residual's lag-1
/// autocorrelation and whether it is coloured near the noise's level: (F10) where the residual
/// (`cost` over `dof`) is above twice `noise_floor`, or at least at its level and coloured
/// ((F10'), [`coloured`]); else none (`[1; M]`, 0, false). The lag-1 is computed once, for the
/// colour test and the batches alike.
#[allow(clippy::too_many_arguments)]
fn residual_inflation<const P: usize, const M: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
    finv: &Sym<P>,
    (cost, dof): (f32, f32),
    noise_floor: f32,
) -> ([f32; M], f32, bool) {
    // Below the noise's level the residual fits to the noise whatever its colour (a
    // noise-free log's rounding); written so that a NaN cost inflates nothing.
    if !(cost > noise_floor * noise_floor * dof) {
        return ([1.0; M], 0.0, false);
    }
    let rho = residual_lag1(blocks, rule, theta, trace, cells);
    let above = cost > 4.0 * noise_floor * noise_floor * dof;
    let col = !above && coloured(rho, blocks.len());
    if above || col {
        let k = score_inflation(blocks, rule, theta, trace, cells, finv, cost, dof, rho);
        (k, rho, col)
    } else {
        ([1.0; M], 0.0, false)
    }
}

/// Fewest batches [`score_inflation`] takes.
const MIN_BATCHES: usize = 8;

/// Each parameter's variance inflation from the residual actually seen ((F10)): the sandwich
/// `F^-1 V F^-1` with `V` the batch-means estimate of the score's covariance (the blocks'
/// scores `n_b R_b^T r_b` summed over batches of [`batch_len`] blocks, `V = K/(K-1) sum_k G_k
/// G_k^T` over the `K` batches), against the white residual's `s^2 F^-1`, `s^2 = cost / dof`:
///
/// ```text
/// k_i = max(1, (F^-1 V F^-1)_ii / (s^2 (F^-1)_ii))                                 (F10)
/// ```
///
/// and the covariance becomes `D C D`, `D = diag(sqrt(k_i))`. Why: a model error is not white
/// (on a real thrown vehicle it is slow: drift, and steps where a rotor spins up), so the
/// covariance scaled by the residual's level alone claims several times the information the
/// flight holds; and how much a slow residual weighs differs per parameter, as its
/// sensitivities do (the initial rates see the start of the flight, the entries of `J` its
/// whole length). For white noise `E V = s^2 F` and `k_i` is 1 up to the batches' scatter,
/// which the floor keeps from lowering the white covariance. `theta` and `finv` (`F^-1` at
/// unit noise) are the fit's optimum, `rho` its residual's lag-1 autocorrelation
/// ([`residual_lag1`]); returns the leading `M`.
#[allow(clippy::too_many_arguments)]
fn score_inflation<const P: usize, const M: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
    finv: &Sym<P>,
    cost: f32,
    dof: f32,
    rho: f32,
) -> [f32; M] {
    let n = blocks.len();
    let mut sums = BatchScores {
        finv,
        len: batch_len(rho, n),
        open: 0,
        r: [0.0; 3],
        g: [0.0; P],
        acc: [0.0; P],
        batches: 0,
    };
    let ok = visit_fit::<P, P0>(blocks, rule, n, theta, trace, cells, &mut sums).is_some();
    sums.flush();
    let k = sums.batches as f32;
    let s2 = if dof > 0.0 { cost / dof } else { 0.0 };
    let ar1 = correlation_length(rho);
    core::array::from_fn(|i| {
        let white = s2 * finv.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
        let seen = if ok && k > 1.0 {
            sums.acc.get(i).copied().unwrap_or(0.0) * k / (k - 1.0)
        } else {
            0.0
        };
        inflation_of(seen, white, ar1)
    })
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
/// against it. On the thrown-FC logs the fit of the whole free flight leaves a residual
/// hundreds of times the gyro's noise and low-frequency (a model error, not vibration), and
/// the part before the spin-up alone gives a higher scale than the rest; from the spin-up on
/// the residual is lower and the board-alone throws agree more closely (the test
/// `calibrate_on_thrown_fc`). On a flight the model explains to the noise the whole fit is kept
/// and nothing changes.
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
    bias: BiasModel,
    res: Resolution,
    shooting: bool,
) -> Option<StretchResult<6>> {
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
                bias,
                &Cells::NONE,
                res,
            )
        };
        let Some(cells) = cells_for(blocks, res, noise_floor) else {
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
        >(blocks, leading(&th), 0.0, noise_floor, bias, &cells, res);
        // Offsets that are no quantisation's ([`Cells::plausible`]: `None`): the plain fit.
        with.or_else(plain)
    };
    let (mut r, (whole_tensor, whole_lag1), used) =
        fit_stretch_from(blocks, init, noise_floor, &from)?;
    // (F8): the reading's errors, in the covariance's units (it is scaled by the residual's
    // variance per degree of freedom when pooled); the residual's variance that scales the
    // rest is taken without what those errors are expected to leave in it (counted once, not
    // twice), never below the gyro's noise floor.
    let dof = (3 * blocks.len()) as f32 - r.params as f32;
    let s2 = r.cost / dof;
    // The residual's variance the model leaves unexplained (the reading's errors taken out).
    let mut unexplained = s2;
    if let (Some((x, expected)), true) = (r.input.take(), s2 > 0.0) {
        // Without a known gyro noise there is no floor to hold it to: the residual's as it is.
        let floor = noise_floor * noise_floor;
        let adj = if floor > 0.0 {
            ((r.cost - expected) / dof).max(floor).min(s2)
        } else {
            s2
        };
        unexplained = adj;
        let scale = adj / s2;
        for (row, xr) in r.cov.iter_mut().zip(x) {
            for (c, xc) in row.iter_mut().zip(xr) {
                *c = *c * scale + xc / s2;
            }
        }
    }
    // (F14): where the flight does not fit to the noise, the variance no estimator can beat
    // under the residual's own error model (white noise and a walk of the output, (F12)), a
    // floor on the reported one. Not on a checked bias's stretch: its fit has the walk already.
    // Over the blocks the single trajectory was fitted to (from the spin-up, where it was).
    let beyond_noise = unexplained > 4.0 * noise_floor * noise_floor;
    if (beyond_noise || r.coloured) && bias != BiasModel::Checked {
        let floor = blocks
            .get(used..)
            .and_then(|b| walk_floor(b, &r.p, res, noise_floor));
        floored(&mut r, floor, blocks.len());
    }
    // A model error the single trajectory does not explain (nor the reading's known errors):
    // multiple shooting ((F11)) over the same blocks, from its tensor, in segments of its
    // residual's correlation length.
    if shooting && beyond_noise {
        // From the single trajectory's tensor (of the whole flight or from the spin-up), over
        // every block: restarting the trajectory is what keeps a model error of the idle
        // phase from accumulating.
        let fit = || shooting::fit_segments(blocks, &whole_tensor, whole_lag1, res.gyro_spread);
        if let Some(mut ms) = fit().filter(|m| shooting_found(&r, m, blocks.len())) {
            // Never more precise than the single trajectory's covariance says, inflated for
            // its residual ((F10)): the segments' sandwich sees the residual within one
            // flight, not what moves the whole flight's answer (see the module docs).
            let n = blocks.len();
            let (vs, vm) = (per_dof(&r, n), per_dof(&ms, n));
            let mut k = [1.0f32; 6];
            for (i, ki) in k.iter_mut().enumerate() {
                let diag = |c: &Sym<6>| c.get(i).and_then(|row| row.get(i)).copied();
                if let (Some(a), Some(b)) = (diag(&r.cov), diag(&ms.cov)) {
                    let (a, b) = (vs * a, vm * b);
                    if b > 0.0 && a > b {
                        *ki = a / b;
                    }
                }
            }
            ms.cov = inflated(&ms.cov, &k);
            return Some(ms);
        }
    }
    Some(r)
}

/// (F14): the variances of the six entries under the walk's generalised least squares
/// ((F12), (F13)), in (kg m^2)^2: the bias model refitted from the entries `p`, the first
/// block's rate and no bias, then with the walk its residuals show; `None` when no walk is taken or a fit
/// fails. The walk model describes a slow error of the output whatever its cause (a torque the
/// model lacks, a drifting gyro): under it, no linear unbiased estimate of `J` from these
/// blocks has a smaller variance than the walk's generalised least squares, so it is a floor
/// on the variance reported for any of them.
///
/// Never inlined: called after the stretch's fits have returned, its frames (the walk's search
/// and refits) do not add to theirs on the stack the flight's fits share.
#[inline(never)]
fn walk_floor(
    blocks: &[Block<6>],
    p: &[f32; 6],
    res: Resolution,
    noise_floor: f32,
) -> Option<[f32; 6]> {
    let w0 = rate_of(blocks.first()?);
    // The bias model's layout (a free constant beside the walk, as the checked bias's fit:
    // the same functions, no more code on board), from no bias.
    let th: [f32; P1] = [
        p[0], p[1], p[2], p[3], p[4], p[5], w0[0], w0[1], w0[2], 0.0, 0.0, 0.0,
    ];
    // The rotor telemetry's offsets of (F7) where the stretch's fit had them: the same model.
    match cells_for(blocks, res, noise_floor) {
        Some(c) => walk_floor_of::<{ P1 + CELLS }>(blocks, leading(&th), p, res, &c),
        None => walk_floor_of::<P1>(blocks, th, p, res, &Cells::NONE),
    }
}

/// [`walk_floor`] with `P` parameters from `th` (the bias model, with the offsets of (F7) over
/// `cells` when `P` holds them).
fn walk_floor_of<const P: usize>(
    blocks: &[Block<6>],
    th: [f32; P],
    p: &[f32; 6],
    res: Resolution,
    cells: &Cells,
) -> Option<[f32; 6]> {
    let mut rule = StepRule::new(&tensor_of(p)).with_gyro_spread(res.gyro_spread);
    let total = blocks.len();
    let dof = (3 * total) as f32 - P as f32;
    let plain = |q: &[f32; P]| normal(blocks, &rule, total, q, 0.0, cells);
    let mut fit = levenberg(plain, th, 30, dof, TOLERANCE, Start::Warm)?;
    walked(blocks, &mut rule, &mut fit, 0.0, cells, dof)?;
    let c = scaled_inverse(&fit.2)?;
    let s2 = fit.1 / dof;
    Some(core::array::from_fn(|i| {
        s2 * c.get(i).and_then(|row| row.get(i)).copied().unwrap_or(0.0)
    }))
}

/// (F14): `r`'s covariance widened, entry by entry, to the walk's variances `floor` where it
/// states less (its own scale being `r`'s cost per degree of freedom over `n` blocks).
fn floored(r: &mut StretchResult<6>, floor: Option<[f32; 6]>, n: usize) {
    let Some(v) = floor else {
        return;
    };
    let s2 = per_dof(r, n);
    let mut k = [1.0f32; 6];
    for (i, ki) in k.iter_mut().enumerate() {
        let stated = r
            .cov
            .get(i)
            .and_then(|row| row.get(i))
            .copied()
            .unwrap_or(0.0)
            * s2;
        let want = v.get(i).copied().unwrap_or(0.0);
        if stated > 0.0 && want > stated && want.is_finite() {
            *ki = want / stated;
        }
    }
    r.cov = inflated(&r.cov, &k);
}

/// The likelihood-ratio test of the multiple-shooting fit `ms` against the single trajectory
/// `single` of the same `n` blocks (both costs over the whole stretch's degrees of freedom):
/// true when the fall of the cost over `ms`'s residual variance exceeds the chi-square bound
/// of its `3 (S - 1)` more parameters, taken as `df + 4 sqrt(2 df)` (beyond the 0.01 % point
/// for any `df` it can have). A single trajectory whose residual is the reading's known errors
/// (a rotor speed read in steps, (F7), (F8)) keeps its efficiency and their accounting.
fn shooting_found(single: &StretchResult<6>, ms: &StretchResult<6>, n: usize) -> bool {
    let s2 = per_dof(ms, n);
    let df = ms.params.saturating_sub(single.params) as f32;
    let bound = df + 4.0 * sqrt(2.0 * df);
    s2 > 0.0 && df > 0.0 && (single.cost - ms.cost) > bound * s2
}

/// [`fit_stretch`]'s choice between the whole flight and the part from the spin-up, `from`
/// fitting a run of blocks from a first guess; with the whole flight's tensor and the lag-1
/// autocorrelation of its residual.
fn fit_stretch_from(
    blocks: &[Block<6>],
    init: &Mat3,
    noise_floor: f32,
    from: &dyn Fn(&[Block<6>], &Mat3) -> Option<StretchResult<6>>,
) -> Option<(StretchResult<6>, (Mat3, f32), usize)> {
    let whole = from(blocks, init)?;
    let start = tensor_of(&whole.p);
    let of_whole = (start, whole.lag1);
    let whole_noise = per_dof(&whole, blocks.len());
    if whole_noise <= 4.0 * noise_floor * noise_floor {
        return Some((whole, of_whole, 0));
    }
    let Some((first, later)) = spin_up(blocks).and_then(|s| Some((s, blocks.get(s..)?))) else {
        return Some((whole, of_whole, 0));
    };
    match from(later, &start) {
        Some(mut r) if per_dof(&r, later.len()) < whole_noise => {
            // The flight as a whole still does not fit: its residual is the one reported
            // (status `ModelMismatch`, the covariance scaled to it), as the cost over the
            // whole stretch's degrees of freedom, which the pooling divides by.
            r.cost = whole_noise * ((3 * blocks.len()) as f32 - r.params as f32);
            Some((r, of_whole, first))
        }
        _ => Some((whole, of_whole, 0)),
    }
}

/// A stretch's residual variance per degree of freedom over its `n` blocks.
fn per_dof<const M: usize>(r: &StretchResult<M>, n: usize) -> f32 {
    r.cost / ((3 * n) as f32 - r.params as f32)
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
            if test_bias {
                BiasModel::Tested
            } else {
                BiasModel::Without
            },
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
            readings: Readings::INSTANTS,
            own_spread: 0.0,
            shooting: true,
        }
    }

    /// The same fit for a gyro whose every reading is the mean of the rate over a window
    /// (PX4's `sensor_combined`: the rate integrated over the sample interval), `window` the
    /// window's time variance over the interval squared (`1/12` for the whole interval, 0 by
    /// default); see [`crate::RatioFit::with_reading_window`] and (B0). Values outside
    /// `[0, 1)` count as 0.
    pub const fn with_reading_window(mut self, window: f32) -> Self {
        self.readings = self.readings.with_window(window);
        self
    }

    /// The same fit for a gyro whose readings have passed through a low-pass filter,
    /// `smoothing` the filter's time variance in s^2; see
    /// [`crate::RatioFit::with_reading_smoothing`] and (B0'). Values outside `[0, 1e-4]` count
    /// as 0.
    pub const fn with_reading_smoothing(mut self, smoothing: f32) -> Self {
        self.readings = self.readings.with_smoothing(smoothing);
        self
    }

    /// The same fit with the multiple-shooting refit ((F11)) on (the default) or off: off,
    /// a flight the single trajectory does not explain keeps the single trajectory's tensor
    /// (its covariance inflated by (F10)), at a quarter to half of the end-of-flight cost.
    pub const fn with_multiple_shooting(mut self, on: bool) -> Self {
        self.shooting = on;
        self
    }

    /// The same fit with the readings' spread of another fit.
    const fn with_readings(mut self, readings: Readings) -> Self {
        self.readings = readings;
        self
    }

    /// The rotor momentum's quantum and the readings per sample, for the fits.
    fn resolution(&self) -> Resolution {
        Resolution {
            quantum: self.momentum_resolution,
            readings: f32::from(self.inputs.max(1)),
            gyro_spread: self.own_spread,
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
        let [centres, own] = self.readings.spread(dt, inputs);
        self.own_spread = own;
        let spread = centres + own;
        self.state.buf.add(&y, usable, dt, self.max_dt, spread);
    }

    /// Ends the open stretch: fits it from the tensor `init` (kg m^2; a positive definite
    /// first guess, such as [`crate::TensorEstimator`]'s), pools it and starts a new stretch.
    pub fn close(&mut self, init: Option<[[f32; 3]; 3]>) -> StretchOutcome {
        let (noise, q, ms) = (self.noise_std, self.resolution(), self.shooting);
        self.state.close(|blocks| {
            init.and_then(|j| fit_stretch(blocks, &j, noise, BiasModel::Tested, q, ms))
        })
    }

    /// [`TensorFit::close`] with the bias model also taken where it moves the tensor beyond
    /// 3.9 standard deviations of the difference (Hausman's test per entry, on the window and
    /// on the pool of all windows): for a gyro whose bias
    /// nothing measured on a long, slow flight (a satellite's tumble), where the plain model
    /// can fit to the noise with the bias taken for products of inertia.
    pub fn close_with_bias(&mut self, init: Option<[[f32; 3]; 3]>) -> StretchOutcome {
        let (noise, q, ms) = (self.noise_std, self.resolution(), self.shooting);
        self.state.close(|blocks| {
            init.and_then(|j| fit_stretch(blocks, &j, noise, BiasModel::Checked, q, ms))
        })
    }

    /// [`TensorFit::close`] for a gyro whose bias is known and was removed (measured on a
    /// still stretch before the throw, as the pipeline's free-flight gate does): no bias is
    /// looked for. Why not test for one anyway: the likelihood-ratio test measures the gain
    /// against the gyro's white noise, so when the model leaves a residual far above it (a
    /// real vehicle's unmodelled effects) the test always "finds" a bias, and the bias then
    /// soaks up model error: on the thrown-FC logs it finds a bias on every throw, far above
    /// the one measured on the bench, and moves `J` by percents.
    pub fn close_without_bias(&mut self, init: Option<[[f32; 3]; 3]>) -> StretchOutcome {
        let (noise, q, ms) = (self.noise_std, self.resolution(), self.shooting);
        self.state.close(|blocks| {
            init.and_then(|j| fit_stretch(blocks, &j, noise, BiasModel::Without, q, ms))
        })
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
        let (mut e, mut cov, mut noise, mut spread) = self.state.pooled.mean()?;
        let mut biased = self.state.biased;
        // The checked bias ([`BiasModel::Checked`]) over all the pooled stretches: where the
        // bias model's pooled tensor differs from the one pooled as fitted by more than
        // [`HAUSMAN_Z`] standard deviations of the difference on any entry, a bias common to
        // the stretches moves it (each stretch's own comparison sees a sixth of it on six
        // windows), and the bias model's pool is the estimate.
        if let Some((ea, ca, na, sa)) = self.state.alternative() {
            let moved = (0..6).any(|i| {
                let diag = |c: &Sym<6>| c.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
                let d = ea.get(i).copied().unwrap_or(0.0) - e.get(i).copied().unwrap_or(0.0);
                let v = (diag(&ca) - diag(&cov)).max(1e-6 * diag(&ca));
                v > 0.0 && d * d > HAUSMAN_Z * HAUSMAN_Z * v
            });
            if moved {
                (e, cov, noise, spread) = (ea, ca, na, sa);
                biased = true;
            }
        }
        // The stretches' spread about the pooled mean, where it is beyond their stated
        // covariances ((P2) of `output_error`), widens the reported one; the tests above
        // compare the pools as fitted.
        let cov = scaled(&cov, spread);
        // The residual as the parameters leave it, the walk's error in it.
        let dof = self.state.pooled.dof();
        let residual = if self.state.walked && dof > 0.0 {
            sqrt(self.state.raw_cost / dof)
        } else {
            noise
        };
        Some(TensorFitEstimate {
            tensor: tensor_of(&e),
            cov,
            noise,
            residual,
            bias_walk: sqrt(self.state.walk_step_var),
            stretches: self.state.pooled.stretches,
            samples: self.state.pooled.samples,
            biased,
            bias: self.state.bias,
            torque: self.state.torque,
            scale_rejected: self.state.scale,
            cost: self.state.pooled.cost(),
            coloured: self.state.coloured,
        })
    }

    /// The tensor up to scale pooled over the stretches closed by
    /// [`TensorFit::close_normalized`]: `tensor` is `J / trace J`, `cov` the covariance of its
    /// six entries (rank 5: `dJzz = -dJxx - dJyy`); `None` before one was fitted.
    pub fn estimate_normalized(&self) -> Option<TensorFitEstimate> {
        let (p, c5, noise, spread) = self.normalized.mean()?;
        let c5 = scaled(&c5, spread);
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
            // The fits up to scale test no walk.
            residual: noise,
            bias_walk: 0.0,
            stretches: self.normalized.stretches,
            samples: self.normalized.samples,
            biased: self.state.biased,
            bias: self.state.bias,
            torque: self.state.torque,
            scale_rejected: self.state.scale,
            cost: self.normalized.cost(),
            coloured: self.state.coloured,
        })
    }

    /// Forgets everything: the open stretch and the pooled estimate.
    pub fn reset(&mut self) {
        *self = TensorFit::new(self.full_scale, self.max_dt, self.noise_std)
            .with_momentum_resolution(self.momentum_resolution)
            .with_readings(self.readings)
            .with_multiple_shooting(self.shooting);
    }
}
