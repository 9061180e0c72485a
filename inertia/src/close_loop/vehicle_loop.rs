//! Closing the loop with the inertia tensor as the base model for a vehicle file's rotors
//! (`inertia close-loop --vehicle`): a spacecraft with reaction wheels, logged slowly (1-10 Hz)
//! for minutes to orbits, where the environment's torques and the gyro's drift are what the
//! model leaves out.
//!
//! The base model is Euler's equation with the vehicle's known momentum
//! `h(t) = sum_i j_i w_i g_i` ([`crate::vehicle::Vehicle::momentum`], the same as `identify`),
//! `L = J w + h`, `L' + w x L = tau`. Over a block `[s, s + T]` it integrates to (TB) of
//! [`super::tensor`]:
//!
//! ```text
//! L(s + T) - L(s) + integral_s^{s+T} (w x L - tau) dt = 0                             (TB)
//! ```
//!
//! On a slow log the two end samples of (TB) carry the gyro noise of the whole equation, and
//! that noise is also in the regressors of `J` (errors in variables: the tensor comes out
//! biased, low, by about the noise's variance over the rate change's). Here (TB) is averaged
//! over the start time `s` across one block, which is the same as weighting Euler's equation by
//! a hat over two neighbouring blocks `B1 = [t_a, t_m]`, `B2 = [t_m, t_e]`:
//!
//! ```text
//! mean_B2 L - mean_B1 L + integral phi (w x L - tau) dt = 0,                          (TBA)
//! phi = (t - t_a) / T1 on B1, (t_e - t) / T2 on B2
//! ```
//!
//! (integration by parts; trapezoid sums over the samples). The end samples' noise is averaged
//! over each block, so its variance, and the bias with it, falls with the samples per block.
//! One equation (three rows) per pair of neighbouring blocks inside one of the free flights
//! `identify` feeds its pipeline (the whole log when it has no accelerometer); neighbouring
//! equations share a block.
//!
//! **Block length, from the data.** For block lengths of 2, 3, 4, 6, 8, ... samples (while
//! at least [`MIN_EQUATIONS`] equations remain) the model is fitted and scored by the tensor's
//! expected error: its standard deviation (least squares, from the residual, which grows with
//! the block when a torque is left out) and its errors-in-variables bias to first order,
//! `-(A^T A)^-1 sum_eq (v_1 + v_2) tr(E_k J)` with `v` the variance of a block mean of the gyro
//! noise and `E_k` the unit tensor of entry `k`. The smallest root sum of squares wins. The
//! tensor alone is scored first and the effects are selected at its length; when effects were
//! chosen, the model with them is scored again and, if its length differs, the selection runs
//! again from the tensor alone at that length (a torque left out makes the tensor alone prefer
//! short blocks; with it in the model longer blocks carry more of the rotor's momentum change).
//! Every length tried is in the report (`block_choice`). On `leo-free-1hz` at 5 s blocks the
//! tensor alone errs by 1.03 % against a predicted bias of 1.03 % and a std of 0.18 %; at the
//! 96 s chosen the predicted bias is 0.0006 % (`inertia/tests/close_loop_space.rs`,
//! `short_blocks_bias_the_tensor_as_the_block_choice_predicts`).
//!
//! **Candidate effects**, each an exact extension of (TBA), fitted with `J` by Gauss-Newton (the
//! bilinear terms relinearised until the step is below a millionth of its standard deviation):
//!
//! * `gravity_gradient` (`gamma`): `tau = gamma 3 mu / r^5 (r_B x J r_B)`, `r_B = R(q)^T r`,
//!   `mu` = [`MU_EARTH_M3_S2`]; the known torque (linear in `J`, it changes `J`'s regressors)
//!   times a free scale `gamma`, so that the F test can weigh it. `gamma` near 1 where the
//!   effect is present. Needs the attitude (`qw..qz`) and position (`rx..rz`) columns.
//! * `magnetic_dipole` (`m`, A m^2): `tau = m x B`, `B` the magnetometer (`bx..bz`, T, body).
//! * `body_torque` (`tau`, N m): a constant body-frame torque.
//! * `gyro_bias` (`b`, rad/s, and `bdot`, rad/s^2): the gyro reads `w + b + bdot (t - t_ref)`,
//!   a constant plus a linear drift, `t_ref` the middle of the flights used. On `mems-walk-10hz`
//!   (a bounded random walk of the bias over 300 s, and a quantiser that truncates toward zero)
//!   it leaves the tensor within its standard deviation of the truth, the residual at 2.6 times
//!   the white noise's share: the walk's curvature and the truncation's offset of half a step
//!   against the rate's sign are left.
//!
//! **Selection** ([`super::selection`]). Each round adds the candidate with the smallest p-value
//! of its F test when it is below `alpha / (candidates left)` (Bonferroni, family-wise `alpha`
//! per round), then drops any chosen effect whose partial F test (given all the others) is no
//! longer significant at `alpha / (effects chosen)`; it stops when no candidate is significant.
//! Ranking by p-value, not F, lets a three- or six-parameter effect win over a one-parameter one
//! of the same strength. The F test takes the rows as independent with equal variance: neighbouring equations share
//! a block (a lag-one correlation of -0.5 in the noise, which makes the test conservative for a
//! smooth effect) and an effect left out colours the residual the other way (the report gives
//! the lag-one autocorrelation). With thousands of rows a small effect becomes significant: a
//! wrong candidate can be chosen in place of the missing true one (on `leo-gg-1hz` a constant
//! body torque has p = 5e-34 before the gyro bias and the gravity gradient are in the model, and
//! p = 0.90 after; the backward step is there to drop such an effect once the true ones are in).

use serde::Serialize;

use super::model::cross;
use super::selection::{
    self, j6, mat_vec, unit_mat_vec, Candidates, Fit, LoopError, Named, Rank, Rules, Selection,
    Steps, V3,
};
use super::stats;
use crate::identify::{identify, IdentifyOptions, RotorHold};
use crate::vehicle::Vehicle;
use crate::Recording;

/// Earth's gravitational parameter, m^3/s^2.
pub const MU_EARTH_M3_S2: f64 = 3.986004418e14;

/// The fewest equations a block length may leave (three rows each).
pub const MIN_EQUATIONS: usize = 40;

/// Gauss-Newton iterations at most.
const MAX_ITERATIONS: usize = 30;

/// The effects (TBA) can take, in a fixed order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VehicleEffect {
    /// Constant body-frame torque, N m.
    BodyTorque,
    /// Gyro bias with a linear drift, rad/s and rad/s^2.
    GyroBias,
    /// The gravity-gradient torque, scaled by `gamma`.
    GravityGradient,
    /// A residual magnetic dipole, A m^2.
    MagneticDipole,
}

impl VehicleEffect {
    /// Every candidate.
    pub const ALL: [VehicleEffect; 4] = [
        VehicleEffect::BodyTorque,
        VehicleEffect::GyroBias,
        VehicleEffect::GravityGradient,
        VehicleEffect::MagneticDipole,
    ];

    /// Its name in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            VehicleEffect::BodyTorque => "body_torque",
            VehicleEffect::GyroBias => "gyro_bias",
            VehicleEffect::GravityGradient => "gravity_gradient",
            VehicleEffect::MagneticDipole => "magnetic_dipole",
        }
    }

    /// Parameters it adds.
    pub fn n_params(self) -> usize {
        match self {
            VehicleEffect::BodyTorque | VehicleEffect::MagneticDipole => 3,
            VehicleEffect::GyroBias => 6,
            VehicleEffect::GravityGradient => 1,
        }
    }

    /// Names of its parameters.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            VehicleEffect::BodyTorque => &["tau_x", "tau_y", "tau_z"],
            VehicleEffect::GyroBias => &["b_x", "b_y", "b_z", "bdot_x", "bdot_y", "bdot_z"],
            VehicleEffect::GravityGradient => &["gamma"],
            VehicleEffect::MagneticDipole => &["m_x", "m_y", "m_z"],
        }
    }
}

impl Named for VehicleEffect {
    fn label(self) -> String {
        self.name().to_string()
    }
}

/// Options of [`analyse_vehicle`].
#[derive(Clone, Debug)]
pub struct VehicleOptions {
    /// The vehicle file (its columns must have been read into [`Recording::wheels`]).
    pub vehicle: Vehicle,
    /// Family-wise significance level of each selection round.
    pub alpha: f64,
    /// Hand-chosen free flights `(start_s, end_s)`; `None`: `identify`'s.
    pub segments: Option<Vec<(f64, f64)>>,
    /// Block length, s; `None`: chosen from the data (see the module documentation).
    pub block_s: Option<f64>,
}

/// One block length tried.
#[derive(Clone, Debug, Serialize)]
pub struct BlockChoice {
    /// The model scored (the tensor alone, then the effects chosen).
    pub model: Vec<VehicleEffect>,
    /// Block length, s (samples times the median step).
    pub block_s: f64,
    /// Samples per block (intervals).
    pub block_samples: usize,
    /// Equations (three rows each).
    pub equations: usize,
    /// The base model's tensor standard deviation over its norm (Frobenius).
    pub tensor_std_rel: f64,
    /// Its first-order errors-in-variables bias over its norm (Frobenius).
    pub eiv_bias_rel: f64,
    /// The root sum of squares of the two: the smallest is chosen.
    pub score: f64,
}

/// One model's fit.
#[derive(Clone, Debug, Serialize)]
pub struct VehicleFitReport {
    /// Effects in the model, in the order they were added.
    pub effects: Vec<VehicleEffect>,
    /// The tensor, kg m^2, in the gyro axes.
    pub tensor_kg_m2: [[f64; 3]; 3],
    /// Its standard deviations (least squares, residual variance), kg m^2.
    pub tensor_std_kg_m2: [[f64; 3]; 3],
    /// Principal moments, ascending, kg m^2.
    pub principal_moments: [f64; 3],
    /// RMS residual of (TBA) per row, kg m^2/s.
    pub residual_rms: f64,
    /// The same over the share the gyro's white noise alone would leave (its block means
    /// through `J`).
    pub residual_over_noise: f64,
    /// Lag-one autocorrelation of the residual (0 for white; about -0.5 for the noise of
    /// neighbouring equations sharing a block).
    pub residual_lag1: f64,
    /// The tensor's first-order errors-in-variables bias over its norm (Frobenius), as the
    /// block choice predicts it for this model.
    pub eiv_bias_rel: f64,
}

/// An effect of the final model.
#[derive(Clone, Debug, Serialize)]
pub struct SelectedEffect {
    /// The effect.
    pub effect: VehicleEffect,
    /// Parameter names ([`VehicleEffect::param_names`]).
    pub names: Vec<&'static str>,
    /// Values.
    pub values: Vec<f64>,
    /// Standard deviations.
    pub std: Vec<f64>,
    /// What `size` measures: `torque_rms` (over the samples used), `torque` (constant),
    /// `bias_rms`.
    pub size_what: &'static str,
    /// The effect's fitted size.
    pub size: f64,
    /// Its unit.
    pub size_unit: &'static str,
    /// Its partial F statistic in the final model (dropping it, the others kept).
    pub f: f64,
    /// The p-value of that F.
    pub p: f64,
}

/// One candidate tried in a round (its parameters in the order of
/// [`VehicleEffect::param_names`], with their standard deviations).
pub type VehicleCandidate = selection::Candidate<VehicleEffect>;

/// One selection round (with the effects the backward step dropped).
pub type VehicleRound = selection::Round<VehicleEffect>;

/// A candidate the log cannot test.
#[derive(Clone, Debug, Serialize)]
pub struct Unavailable {
    /// The effect.
    pub effect: VehicleEffect,
    /// Why.
    pub reason: String,
}

/// What [`analyse_vehicle`] found.
#[derive(Clone, Debug, Serialize)]
pub struct VehicleAnalysis {
    /// Always `"tensor"`.
    pub base_model: &'static str,
    /// The equation fitted.
    pub equation: &'static str,
    /// The log.
    pub source: String,
    /// The vehicle file.
    pub vehicle: String,
    /// Its rotors.
    pub rotors: usize,
    /// Free-flight stretches used, `(start_s, end_s)`.
    pub stretches: Vec<(f64, f64)>,
    /// Block length, s.
    pub block_s: f64,
    /// Samples per block (intervals).
    pub block_samples: usize,
    /// Equations (three rows each).
    pub equations: usize,
    /// The block lengths tried (empty when the length was given).
    pub block_choice: Vec<BlockChoice>,
    /// Gyro white noise, rad/s (for `residual_over_noise` and the block choice).
    pub noise_std: f64,
    /// The reference time of the gyro bias's drift, s.
    pub t_ref_s: f64,
    /// The candidates tested.
    pub candidates: Vec<VehicleEffect>,
    /// The candidates the log cannot test, and why.
    pub unavailable: Vec<Unavailable>,
    /// `inertia identify`'s pooled tensor on the same log, for reference.
    pub on_board_tensor_kg_m2: Option<[[f32; 3]; 3]>,
    /// Its status.
    pub on_board_status: String,
    /// Each gyro axis's LSB, rad/s, where `identify` took the readings as truncated toward zero
    /// and moved them to their counts' centres ((Q1) of [`crate::grid`]): the fits here take
    /// them so too. Absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_centred_lsb_rad_s: Option<[f32; 3]>,
    /// The base model (the tensor alone).
    pub before: VehicleFitReport,
    /// The selection rounds.
    pub rounds: Vec<VehicleRound>,
    /// The effects of the final model, in the order they were added.
    pub effects: Vec<SelectedEffect>,
    /// The final model.
    pub after: VehicleFitReport,
    /// Relative change of the tensor from before to after (Frobenius norm).
    pub tensor_change: f64,
    /// Residual per equation before and after: `(t_mid, before, after)`.
    #[serde(skip)]
    pub residuals: Vec<(f64, V3, V3)>,
}

/// The samples the fits take, in `f64`.
struct Series {
    t: Vec<f64>,
    /// Gyro, `identify`'s bias removed, rad/s.
    g: Vec<V3>,
    /// The vehicle's momentum, kg m^2/s.
    h: Vec<V3>,
    /// Position in the body frame, m, and `3 mu / r^5`.
    gg: Option<Vec<(V3, f64)>>,
    /// Magnetometer, body frame, T.
    mag: Option<Vec<V3>>,
    /// The drift's reference time, s.
    t_ref: f64,
}

/// `R(q)^T v` for `q = (w, x, y, z)`, `v_N = R(q) v_B` (normalised in `f64` first; zero for an
/// unusable `q`).
fn to_body(q: [f32; 4], v: V3) -> V3 {
    use crate::identify::gravity::{mul_t, rotation};
    rotation(q).map_or([0.0; 3], |r| mul_t(&r, v))
}

/// A block: samples `s..=e`, its span and the sum of its squared trapezoid weights over its
/// span squared (the variance of a block mean of unit white noise).
#[derive(Clone, Copy, Debug)]
struct Block {
    s: usize,
    e: usize,
    span: f64,
    mean_var: f64,
}

/// The blocks of a length and the equations (pairs of neighbouring blocks in one run).
struct Layout {
    per_block: usize,
    blocks: Vec<Block>,
    pairs: Vec<(usize, usize)>,
}

impl Layout {
    /// The blocks' mean span, s.
    fn mean_span(&self) -> f64 {
        self.blocks.iter().map(|b| b.span).sum::<f64>() / self.blocks.len().max(1) as f64
    }
}

fn layout(t: &[f64], runs: &[(usize, usize)], per_block: usize) -> Layout {
    let mut blocks = Vec::new();
    let mut pairs = Vec::new();
    for &(a, b) in runs {
        let mut s = a;
        let mut first = true;
        while s + per_block < b {
            let e = s + per_block;
            let span = t[e] - t[s];
            let mut sq = 0.0;
            for i in s..=e {
                let c = trapezoid_weight(t, s, e, i);
                sq += c * c;
            }
            if span > 0.0 {
                if !first {
                    pairs.push((blocks.len() - 1, blocks.len()));
                }
                blocks.push(Block {
                    s,
                    e,
                    span,
                    mean_var: sq / (span * span),
                });
                first = false;
            } else {
                first = true;
            }
            s = e;
        }
    }
    Layout {
        per_block,
        blocks,
        pairs,
    }
}

fn trapezoid_weight(t: &[f64], s: usize, e: usize, i: usize) -> f64 {
    let mut c = 0.0;
    if i > s {
        c += 0.5 * (t[i] - t[i - 1]);
    }
    if i < e {
        c += 0.5 * (t[i + 1] - t[i]);
    }
    c
}

/// The model's parameters: `J` (xx, yy, zz, xy, xz, yz) then each effect's, in `effects`'
/// order.
struct Model<'a> {
    effects: &'a [VehicleEffect],
    n: usize,
}

impl<'a> Model<'a> {
    fn new(effects: &'a [VehicleEffect]) -> Self {
        let n = 6 + effects.iter().map(|e| e.n_params()).sum::<usize>();
        Model { effects, n }
    }

    fn offset(&self, e: VehicleEffect) -> Option<usize> {
        let mut at = 6;
        for x in self.effects {
            if *x == e {
                return Some(at);
            }
            at += x.n_params();
        }
        None
    }
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn unit(k: usize) -> V3 {
    let mut e = [0.0; 3];
    e[k] = 1.0;
    e
}

/// The gyro bias at sample `i` under `theta`.
fn bias_at(series: &Series, model: &Model, theta: &[f64], i: usize) -> V3 {
    match model.offset(VehicleEffect::GyroBias) {
        Some(o) => {
            let dt = series.t[i] - series.t_ref;
            [0, 1, 2].map(|k| theta[o + k] + theta[o + 3 + k] * dt)
        }
        None => [0.0; 3],
    }
}

/// The external torque of the effects at sample `i` under `theta`, N m.
fn torque_at(series: &Series, model: &Model, theta: &[f64], i: usize) -> V3 {
    let j = j6(theta);
    let mut tau = [0.0; 3];
    for e in model.effects {
        let o = model.offset(*e).unwrap_or(6);
        match e {
            VehicleEffect::BodyTorque => tau = add(tau, [theta[o], theta[o + 1], theta[o + 2]]),
            VehicleEffect::GravityGradient => {
                if let Some(gg) = &series.gg {
                    let (r, k) = gg[i];
                    tau = add(tau, scale(cross(r, mat_vec(&j, r)), k * theta[o]));
                }
            }
            VehicleEffect::MagneticDipole => {
                if let Some(b) = &series.mag {
                    tau = add(tau, cross([theta[o], theta[o + 1], theta[o + 2]], b[i]));
                }
            }
            VehicleEffect::GyroBias => {}
        }
    }
    tau
}

/// Fills `out` (length `model.n + 1`) with, per parameter, the derivative of `(L, w x L - tau)`
/// at sample `i`, and at index `model.n` their values.
fn sample_columns(series: &Series, model: &Model, theta: &[f64], i: usize, out: &mut [(V3, V3)]) {
    let j = j6(theta);
    let b = bias_at(series, model, theta, i);
    let g = series.g[i];
    let w = [g[0] - b[0], g[1] - b[1], g[2] - b[2]];
    let l = add(mat_vec(&j, w), series.h[i]);
    let tau = torque_at(series, model, theta, i);
    let f = cross(w, l);
    out[model.n] = (l, [f[0] - tau[0], f[1] - tau[1], f[2] - tau[2]]);
    let gamma = model
        .offset(VehicleEffect::GravityGradient)
        .map_or(0.0, |o| theta[o]);
    for (k, col) in out.iter_mut().enumerate().take(6) {
        let ekw = unit_mat_vec(k, w);
        let mut dg = cross(w, ekw);
        if gamma != 0.0 {
            if let Some(gg) = &series.gg {
                let (r, kappa) = gg[i];
                let t = cross(r, unit_mat_vec(k, r));
                dg = add(dg, scale(t, -gamma * kappa));
            }
        }
        *col = (ekw, dg);
    }
    for e in model.effects {
        let o = model.offset(*e).unwrap_or(6);
        match e {
            VehicleEffect::BodyTorque => {
                for a in 0..3 {
                    out[o + a] = ([0.0; 3], scale(unit(a), -1.0));
                }
            }
            VehicleEffect::GravityGradient => {
                let t = match &series.gg {
                    Some(gg) => {
                        let (r, kappa) = gg[i];
                        scale(cross(r, mat_vec(&j, r)), kappa)
                    }
                    None => [0.0; 3],
                };
                out[o] = ([0.0; 3], scale(t, -1.0));
            }
            VehicleEffect::MagneticDipole => {
                let bf = series.mag.as_ref().map_or([0.0; 3], |m| m[i]);
                for a in 0..3 {
                    out[o + a] = ([0.0; 3], scale(cross(unit(a), bf), -1.0));
                }
            }
            VehicleEffect::GyroBias => {
                let dt = series.t[i] - series.t_ref;
                for a in 0..3 {
                    let je = mat_vec(&j, unit(a));
                    let dl = scale(je, -1.0);
                    let dg = scale(add(cross(unit(a), l), cross(w, je)), -1.0);
                    out[o + a] = (dl, dg);
                    out[o + 3 + a] = (scale(dl, dt), scale(dg, dt));
                }
            }
        }
    }
}

/// The rows of (TBA) (three per equation) and their residuals at `theta`.
fn linearise(
    series: &Series,
    lay: &Layout,
    model: &Model,
    theta: &[f64],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let m = model.n + 1;
    let mut buf = vec![([0.0; 3], [0.0; 3]); m];
    // Per block and column: integral of dL, rising- and falling-weighted integrals of dg.
    let mut sums: Vec<Vec<[V3; 3]>> = Vec::with_capacity(lay.blocks.len());
    for blk in &lay.blocks {
        let mut s = vec![[[0.0; 3]; 3]; m];
        for i in blk.s..=blk.e {
            let c = trapezoid_weight(&series.t, blk.s, blk.e, i);
            let rise = c * (series.t[i] - series.t[blk.s]) / blk.span;
            let fall = c * (series.t[blk.e] - series.t[i]) / blk.span;
            sample_columns(series, model, theta, i, &mut buf);
            for (acc, (dl, dg)) in s.iter_mut().zip(buf.iter()) {
                for k in 0..3 {
                    acc[0][k] += c * dl[k];
                    acc[1][k] += rise * dg[k];
                    acc[2][k] += fall * dg[k];
                }
            }
        }
        sums.push(s);
    }
    let mut rows = Vec::with_capacity(3 * lay.pairs.len());
    let mut res = Vec::with_capacity(3 * lay.pairs.len());
    for &(b1, b2) in &lay.pairs {
        let (t1, t2) = (lay.blocks[b1].span, lay.blocks[b2].span);
        let (s1, s2) = (&sums[b1], &sums[b2]);
        for k in 0..3 {
            let v = |p: usize| s2[p][0][k] / t2 - s1[p][0][k] / t1 + s1[p][1][k] + s2[p][2][k];
            rows.push((0..model.n).map(v).collect());
            res.push(v(model.n));
        }
    }
    (rows, res)
}

/// Gauss-Newton from `j0` (the effects' parameters from zero) until every step is below a
/// millionth of its standard deviation; `None` when the normal equations are singular or the
/// iteration does not settle.
fn fit(series: &Series, lay: &Layout, effects: &[VehicleEffect], j0: &[f64; 6]) -> Option<Fit> {
    let model = Model::new(effects);
    let mut theta = vec![0.0; model.n];
    // `gamma`'s column is the torque of the current `J`: start from the tensor alone.
    if effects.contains(&VehicleEffect::GravityGradient) && j0.iter().all(|x| *x == 0.0) {
        theta[..6].copy_from_slice(&fit(series, lay, &[], j0)?.j());
    } else {
        theta[..6].copy_from_slice(j0);
    }
    for _ in 0..MAX_ITERATIONS {
        let (rows, res) = linearise(series, lay, &model, &theta);
        let neg: Vec<f64> = res.iter().map(|r| -r).collect();
        let ls = stats::lstsq(&rows, &neg)?;
        let cov = ls.cov();
        let mut done = true;
        for (k, d) in ls.theta.iter().enumerate() {
            if !d.is_finite() {
                return None;
            }
            theta[k] += d;
            let sd = cov[k][k].max(0.0).sqrt();
            if d.abs() > 1e-6 * sd.max(1e-300) {
                done = false;
            }
        }
        if done {
            let (_, res) = linearise(series, lay, &model, &theta);
            let rss: f64 = res.iter().map(|r| r * r).sum();
            let n = res.len();
            let s2 = rss / n.saturating_sub(model.n).max(1) as f64;
            let cov = ls
                .xtx_inv
                .iter()
                .map(|r| r.iter().map(|v| v * s2).collect())
                .collect();
            return Some(Fit {
                theta,
                cov,
                xtx_inv: ls.xtx_inv,
                rss,
                n,
                residuals: res.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
            });
        }
    }
    None
}

/// The Frobenius norm of a tensor given by its six entries (off-diagonal ones counted twice).
fn frobenius6(v: &[f64]) -> f64 {
    (0..6)
        .map(|k| v[k] * v[k] * if k < 3 { 1.0 } else { 2.0 })
        .sum::<f64>()
        .sqrt()
}

/// The tensor's first-order errors-in-variables bias over its norm: the gyro noise `sigma`
/// in the block means of (TBA) is in `J`'s regressors and in the residual alike.
fn eiv_bias_rel(fit: &Fit, lay: &Layout, sigma: f64) -> f64 {
    let j = fit.j();
    // tr(E_k J): the diagonal entries, twice the off-diagonal ones.
    let tr = [j[0], j[1], j[2], 2.0 * j[3], 2.0 * j[4], 2.0 * j[5]];
    let v: f64 = lay
        .pairs
        .iter()
        .map(|&(a, b)| lay.blocks[a].mean_var + lay.blocks[b].mean_var)
        .sum::<f64>()
        * sigma
        * sigma;
    let bias: Vec<f64> = (0..6)
        .map(|r| -(0..6).map(|c| fit.xtx_inv[r][c] * v * tr[c]).sum::<f64>())
        .collect();
    frobenius6(&bias) / frobenius6(&j)
}

fn tensor_std_rel(fit: &Fit) -> f64 {
    let var: f64 = (0..6)
        .map(|k| fit.cov[k][k].max(0.0) * if k < 3 { 1.0 } else { 2.0 })
        .sum();
    var.sqrt() / frobenius6(&fit.j())
}

/// The block lengths tried, 2, 3, 4, 6, 8, 12, ... samples.
fn block_grid(max: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut x = 2.0f64;
    while (x.round() as usize) <= max {
        let l = x.round() as usize;
        if out.last() != Some(&l) {
            out.push(l);
        }
        x *= if out.len() % 2 == 1 { 1.5 } else { 4.0 / 3.0 };
    }
    out
}

/// Runs the vehicle close-loop on `rec` (read with the vehicle file's columns).
pub fn analyse_vehicle(
    rec: &Recording,
    opts: &VehicleOptions,
) -> Result<VehicleAnalysis, LoopError> {
    use LoopError::Input;
    let v = &opts.vehicle;
    if rec.wheels.len() != v.rotors.len() {
        return Err(Input(format!(
            "the log was read with {} of the vehicle file's {} rotor columns",
            rec.wheels.len(),
            v.rotors.len()
        )));
    }
    let id = identify(
        rec,
        &IdentifyOptions {
            rotor: None,
            vehicle: Some(v.clone()),
            segments: opts.segments.clone(),
            noise_std: None,
            rotor_hold: RotorHold::Auto,
            trace: false,
        },
    )
    .map_err(|e| Input(e.to_string()))?;
    let n = rec.len();
    let bias = id.gyro_bias.map(f64::from);
    let mut speeds = vec![0.0f32; v.rotors.len()];
    let h: Vec<V3> = (0..n)
        .map(|i| {
            for (s, col) in speeds.iter_mut().zip(&rec.wheels) {
                *s = col[i];
            }
            v.momentum(&speeds).map(f64::from)
        })
        .collect();
    // The readings as `identify` fitted them: moved to their counts' centres where it found
    // them truncated toward zero.
    let centred = id
        .gyro_grid
        .as_ref()
        .filter(|g| g.centred)
        .map(|g| g.lsb_rad_s);
    let moved = centred.map(|lsb| {
        let mut gyro = rec.gyro.clone();
        crate::grid::centre_readings(&mut gyro, lsb);
        gyro
    });
    let g: Vec<V3> = moved
        .as_deref()
        .unwrap_or(&rec.gyro)
        .iter()
        .map(|w| [0, 1, 2].map(|k| f64::from(w[k]) - bias[k]))
        .collect();
    let mut unavailable = Vec::new();
    let gg = match (&rec.attitude, &rec.position) {
        (Some(q), Some(r)) => Some(
            q.iter()
                .zip(r)
                .map(|(q, r)| {
                    let rb = to_body(*q, *r);
                    let rn = (rb[0] * rb[0] + rb[1] * rb[1] + rb[2] * rb[2]).sqrt();
                    (rb, 3.0 * MU_EARTH_M3_S2 / rn.powi(5))
                })
                .collect::<Vec<_>>(),
        ),
        _ => {
            unavailable.push(Unavailable {
                effect: VehicleEffect::GravityGradient,
                reason: "needs the attitude (qw,qx,qy,qz) and position (rx,ry,rz) columns".into(),
            });
            None
        }
    };
    if gg.as_ref().is_some_and(|g| {
        g.iter()
            .any(|(r, k)| !(k.is_finite() && r.iter().all(|c| c.is_finite())))
    }) {
        return Err(Input(
            "the position or attitude columns hold a zero or non-finite position".into(),
        ));
    }
    let mag = match &rec.magnetic {
        Some(b) => Some(b.iter().map(|b| b.map(f64::from)).collect::<Vec<V3>>()),
        None => {
            unavailable.push(Unavailable {
                effect: VehicleEffect::MagneticDipole,
                reason: "needs the magnetometer columns (bx,by,bz)".into(),
            });
            None
        }
    };
    let runs: Vec<(usize, usize)> = id
        .fed_runs
        .iter()
        .flatten()
        .map(|r| (r.start, r.end.min(n)))
        .filter(|(a, b)| b > a)
        .collect();
    let (Some(first), Some(last)) = (runs.first(), runs.last()) else {
        return Err(Input("no free flight to fit".into()));
    };
    let t_ref = 0.5 * (rec.t[first.0] + rec.t[last.1 - 1]);
    let stretches: Vec<(f64, f64)> = runs
        .iter()
        .map(|&(a, b)| (rec.t[a], rec.t[b - 1]))
        .collect();
    let series = Series {
        t: rec.t.clone(),
        g,
        h,
        gg,
        mag,
        t_ref,
    };
    let noise = selection::gyro_noise(rec);
    let dt_med = crate::recording::median_dt(&rec.t);
    let used: usize = runs.iter().map(|(a, b)| b - a).sum();
    let candidates: Vec<VehicleEffect> = VehicleEffect::ALL
        .into_iter()
        .filter(|e| !unavailable.iter().any(|u| u.effect == *e))
        .collect();
    // The block length: given, or the one whose fit has the smallest expected error, first
    // for the tensor alone, then (when effects were chosen and the length changes) for the
    // model chosen, the selection run again at that length.
    let (lay, choice, (base, sel)) = match opts.block_s {
        Some(s) => {
            let lay = layout(&rec.t, &runs, ((s / dt_med).round() as usize).max(2));
            let sel = select(&series, &lay, &candidates, opts.alpha)?;
            (lay, Vec::new(), sel)
        }
        None => {
            let (lay, mut choice) = choose_block(&series, &runs, used, &[], noise)?;
            let (base, sel) = select(&series, &lay, &candidates, opts.alpha)?;
            if sel.chosen.is_empty() {
                (lay, choice, (base, sel))
            } else {
                let (lay2, choice2) = choose_block(&series, &runs, used, &sel.chosen, noise)?;
                choice.extend(choice2);
                if lay2.per_block == lay.per_block {
                    (lay, choice, (base, sel))
                } else {
                    let sel2 = select(&series, &lay2, &candidates, opts.alpha)?;
                    (lay2, choice, sel2)
                }
            }
        }
    };
    let Selection {
        chosen,
        fit: cur,
        rounds,
    } = sel;
    let jb = base.j();
    let base_residuals = base.residuals.clone();
    let after = report(&series, &cur, &lay, &chosen, noise);
    let before = report(&series, &base, &lay, &[], noise);
    let model = Model::new(&chosen);
    let eqs = Equations {
        series: &series,
        lay: &lay,
    };
    let mut effects = Vec::new();
    for (k, e) in chosen.iter().enumerate() {
        let o = model.offset(*e).unwrap_or(6);
        let (fs, pv) = selection::drop_test(&eqs, &chosen, &cur, k)
            .map_or((f64::NAN, f64::NAN), |(f, p, _)| (f, p));
        let (what, size, unit) = effect_size(&series, &lay, &model, &cur.theta, *e);
        effects.push(SelectedEffect {
            effect: *e,
            names: e.param_names().to_vec(),
            values: cur.theta[o..o + e.n_params()].to_vec(),
            std: (o..o + e.n_params()).map(|i| cur.sd(i)).collect(),
            size_what: what,
            size,
            size_unit: unit,
            f: fs,
            p: pv,
        });
    }
    let jc = cur.j();
    let d: Vec<f64> = (0..6).map(|k| jc[k] - jb[k]).collect();
    let tensor_change = frobenius6(&d) / frobenius6(&jb);
    let residuals = lay
        .pairs
        .iter()
        .zip(base_residuals.iter().zip(cur.residuals.iter()))
        .map(|(&(a, _), (e0, e1))| (rec.t[lay.blocks[a].e], *e0, *e1))
        .collect();
    Ok(VehicleAnalysis {
        base_model: "tensor",
        equation: "(TBA): (TB) averaged over its start time across one block",
        source: rec.source.clone(),
        vehicle: v.path.display().to_string(),
        rotors: v.rotors.len(),
        stretches,
        block_s: lay.mean_span(),
        block_samples: lay.per_block,
        equations: lay.pairs.len(),
        block_choice: choice,
        noise_std: noise,
        t_ref_s: t_ref,
        candidates,
        unavailable,
        on_board_tensor_kg_m2: id.pooled.tensor_kg_m2,
        on_board_status: id.pooled.status.clone(),
        gyro_centred_lsb_rad_s: centred,
        before,
        rounds,
        effects,
        after,
        tensor_change,
        residuals,
    })
}

/// The block length (see the module documentation) for the model with `effects`: the layout
/// chosen and every length tried.
fn choose_block(
    series: &Series,
    runs: &[(usize, usize)],
    used: usize,
    effects: &[VehicleEffect],
    noise: f64,
) -> Result<(Layout, Vec<BlockChoice>), LoopError> {
    let mut choice = Vec::new();
    let mut best: Option<(f64, Layout)> = None;
    for l in block_grid(used / 2) {
        let lay = layout(&series.t, runs, l);
        if lay.pairs.len() < MIN_EQUATIONS {
            break;
        }
        let Some(f) = fit(series, &lay, effects, &[0.0; 6]) else {
            continue;
        };
        let (sd, eiv) = (tensor_std_rel(&f), eiv_bias_rel(&f, &lay, noise));
        let score = sd.hypot(eiv);
        choice.push(BlockChoice {
            model: effects.to_vec(),
            block_s: lay.mean_span(),
            block_samples: l,
            equations: lay.pairs.len(),
            tensor_std_rel: sd,
            eiv_bias_rel: eiv,
            score,
        });
        if score.is_finite() && best.as_ref().is_none_or(|b| score < b.0) {
            best = Some((score, lay));
        }
    }
    let lay = best.map(|b| b.1).ok_or_else(|| {
        LoopError::Data(format!(
            "{used} samples of free flight: too few for {MIN_EQUATIONS} equations of the tensor \
             and its effects"
        ))
    })?;
    Ok((lay, choice))
}

/// (TBA) over the equations of one block length, for [`selection::select`].
struct Equations<'a> {
    series: &'a Series,
    lay: &'a Layout,
}

impl Candidates for Equations<'_> {
    type Effect = VehicleEffect;
    type Fit = Fit;

    /// Gauss-Newton from the tensor of `from` ([`fit`]).
    fn fit(&self, effects: &[VehicleEffect], from: &Fit) -> Option<Fit> {
        fit(self.series, self.lay, effects, &from.j())
    }

    fn ls(fit: &Fit) -> &Fit {
        fit
    }

    fn params(&self, fit: &Fit, e: VehicleEffect) -> (Vec<f64>, Option<Vec<f64>>) {
        let at = fit.theta.len() - e.n_params();
        let std = (at..fit.theta.len()).map(|k| fit.sd(k)).collect();
        (fit.theta[at..].to_vec(), Some(std))
    }
}

/// The tensor alone and the selection from it at one block length: forward by p-value with
/// backward elimination (see the module documentation).
fn select(
    series: &Series,
    lay: &Layout,
    candidates: &[VehicleEffect],
    alpha: f64,
) -> Result<(Fit, Selection<VehicleEffect, Fit>), LoopError> {
    selection::enough(lay.pairs.len(), "equations")?;
    let base = fit(series, lay, &[], &[0.0; 6])
        .ok_or_else(|| LoopError::Data("the tensor is not determined".into()))?;
    let rules = Rules {
        alpha,
        rank: Rank::SmallestP,
        // An effect dropped may come back; the rounds are bounded all the same.
        steps: Steps::ForwardBackward {
            max_rounds: 4 * VehicleEffect::ALL.len(),
        },
    };
    let sel = selection::select(&Equations { series, lay }, base.clone(), candidates, &rules);
    Ok((base, sel))
}

/// What an effect's size is, its value and unit, over the samples of the blocks.
fn effect_size(
    series: &Series,
    lay: &Layout,
    model: &Model,
    theta: &[f64],
    e: VehicleEffect,
) -> (&'static str, f64, &'static str) {
    let o = model.offset(e).unwrap_or(6);
    // Every sample of the blocks once (neighbouring blocks share their end sample).
    let mut samples = Vec::new();
    for b in &lay.blocks {
        let from = if samples.last() == Some(&b.s) {
            b.s + 1
        } else {
            b.s
        };
        samples.extend(from..=b.e);
    }
    let rms = |f: &dyn Fn(usize) -> V3| {
        let (mut s, mut c) = (0.0, 0usize);
        for &i in &samples {
            let v = f(i);
            s += v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
            c += 1;
        }
        (s / c.max(1) as f64).sqrt()
    };
    let j = j6(theta);
    match e {
        VehicleEffect::BodyTorque => {
            let t = [theta[o], theta[o + 1], theta[o + 2]];
            (
                "torque",
                (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt(),
                "N m",
            )
        }
        VehicleEffect::GyroBias => (
            "bias_rms",
            rms(&|i| {
                let dt = series.t[i] - series.t_ref;
                [0, 1, 2].map(|k| theta[o + k] + theta[o + 3 + k] * dt)
            }),
            "rad/s",
        ),
        VehicleEffect::GravityGradient => (
            "torque_rms",
            rms(&|i| match &series.gg {
                Some(gg) => {
                    let (r, k) = gg[i];
                    scale(cross(r, mat_vec(&j, r)), k * theta[o])
                }
                None => [0.0; 3],
            }),
            "N m",
        ),
        VehicleEffect::MagneticDipole => (
            "torque_rms",
            rms(&|i| match &series.mag {
                Some(b) => cross([theta[o], theta[o + 1], theta[o + 2]], b[i]),
                None => [0.0; 3],
            }),
            "N m",
        ),
    }
}

/// The RMS per row of the residual the gyro's white noise `sigma` alone leaves in (TBA) under
/// `theta`: each sample's noise through the block means (`J`) and through the weighted
/// integral (`-[L]x + [w]x J`), summed over the equation's samples.
fn noise_floor(series: &Series, lay: &Layout, model: &Model, theta: &[f64], sigma: f64) -> f64 {
    let j = j6(theta);
    let mut total = 0.0;
    for &(b1, b2) in &lay.pairs {
        let (x, y) = (lay.blocks[b1], lay.blocks[b2]);
        for i in x.s..=y.e {
            let (mut alpha, mut beta) = (0.0, 0.0);
            if i <= x.e {
                let c = trapezoid_weight(&series.t, x.s, x.e, i);
                alpha -= c / x.span;
                beta += c * (series.t[i] - series.t[x.s]) / x.span;
            }
            if i >= y.s {
                let c = trapezoid_weight(&series.t, y.s, y.e, i);
                alpha += c / y.span;
                beta += c * (series.t[y.e] - series.t[i]) / y.span;
            }
            let b = bias_at(series, model, theta, i);
            let w = [0, 1, 2].map(|k| series.g[i][k] - b[k]);
            let l = add(mat_vec(&j, w), series.h[i]);
            // Column `a` of the sample's matrix: its response to noise along axis `a`.
            for a in 0..3 {
                let ja = mat_vec(&j, unit(a));
                let k = add(cross(unit(a), l), cross(w, ja));
                let col = add(scale(ja, alpha), scale(k, beta));
                total += col[0] * col[0] + col[1] * col[1] + col[2] * col[2];
            }
        }
    }
    sigma * (total / (3 * lay.pairs.len()).max(1) as f64).sqrt()
}

fn report(
    series: &Series,
    fit: &Fit,
    lay: &Layout,
    effects: &[VehicleEffect],
    noise: f64,
) -> VehicleFitReport {
    let floor = noise_floor(series, lay, &Model::new(effects), &fit.theta, noise);
    VehicleFitReport {
        effects: effects.to_vec(),
        tensor_kg_m2: fit.tensor(),
        tensor_std_kg_m2: fit.tensor_std(),
        principal_moments: fit.principal_moments(),
        residual_rms: fit.residual_rms(),
        residual_over_noise: fit.residual_over(floor),
        residual_lag1: fit.residual_lag1(),
        eiv_bias_rel: eiv_bias_rel(fit, lay, noise),
    }
}

/// One line for the terminal.
pub fn summary_line(an: &VehicleAnalysis) -> String {
    let names: Vec<String> = an
        .effects
        .iter()
        .map(|e| {
            format!(
                "{} ({} {:.3e} {})",
                e.effect.name(),
                e.size_what,
                e.size,
                e.size_unit
            )
        })
        .collect();
    format!(
        "tensor base model with the vehicle's momentum, {} equations of two {:.1} s blocks: residual {:.3e} -> {:.3e} kg m^2/s ({:.2}x -> {:.2}x the gyro noise's share); effects: {}; tensor moved {:.3} %",
        an.equations,
        an.block_s,
        an.before.residual_rms,
        an.after.residual_rms,
        an.before.residual_over_noise,
        an.after.residual_over_noise,
        selection::names_or_none(&names),
        100.0 * an.tensor_change
    )
}

/// A markdown report: the block choice, the rounds, the model before and after.
pub fn markdown(an: &VehicleAnalysis, title: &str) -> String {
    let mut s = format!("# Close-loop (tensor base model, vehicle file): {title}\n\n");
    s += &format!(
        "{} rotors ({}); {} equations of (TBA) over blocks of {} samples ({:.1} s) from {} \
         stretch(es); gyro noise {:.2e} rad/s; on-board estimate status {}.\n\n",
        an.rotors,
        an.vehicle,
        an.equations,
        an.block_samples,
        an.block_s,
        an.stretches.len(),
        an.noise_std,
        an.on_board_status
    );
    if !an.block_choice.is_empty() {
        s += "| block (s) | equations | tensor std (%) | errors-in-variables bias (%) | score (%) |\n|---|---|---|---|---|\n";
        for c in &an.block_choice {
            s += &format!(
                "| {:.1} | {} | {:.4} | {:.4} | {:.4}{} |\n",
                c.block_s,
                c.equations,
                100.0 * c.tensor_std_rel,
                100.0 * c.eiv_bias_rel,
                100.0 * c.score,
                if c.block_samples == an.block_samples {
                    " (chosen)"
                } else {
                    ""
                }
            );
        }
        s += "\n";
    }
    for u in &an.unavailable {
        s += &format!("Not a candidate: {} ({}).\n\n", u.effect.name(), u.reason);
    }
    let row = |name, r: &VehicleFitReport| {
        let (rms, lag1, m) = (r.residual_rms, r.residual_lag1, r.principal_moments);
        (name, rms, r.residual_over_noise, lag1, m)
    };
    s += &selection::fits_table(
        [row("before (tensor)", &an.before), row("after", &an.after)],
        2,
        5,
    );
    s += &selection::rounds_table(&an.rounds);
    for e in &an.effects {
        s += &format!(
            "\n{}: {}; {} {:.3e} {} (partial F {:.1}, p {:.1e})\n",
            e.effect.name(),
            selection::param_list(&e.names, &e.values, &e.std, 4),
            e.size_what,
            e.size,
            e.size_unit,
            e.f,
            e.p
        );
    }
    s += &selection::moved_line(an.tensor_change, 3);
    s
}

/// `residuals.svg`: the equations' residual per axis before and after.
pub fn plots(an: &VehicleAnalysis, dir: &std::path::Path, title: &str) -> anyhow::Result<()> {
    super::plot::write_residuals(dir, title, "(TBA)", &an.residuals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn body_frame_is_the_transpose_of_the_attitude() {
        // A quarter turn about z: body x points along inertial y, so inertial y is body x.
        let h = core::f32::consts::FRAC_1_SQRT_2;
        let b = to_body([h, 0.0, 0.0, h], [0.0, 1.0, 0.0]);
        assert!(
            (b[0] - 1.0).abs() < 1e-7 && b[1].abs() < 1e-7 && b[2].abs() < 1e-7,
            "{b:?}"
        );
    }

    #[test]
    fn block_grid_grows_by_half_and_a_third() {
        assert_eq!(block_grid(50), [2, 3, 4, 6, 8, 12, 16, 24, 32, 48]);
    }
}
