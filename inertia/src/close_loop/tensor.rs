//! Closing the loop with the inertia tensor as the base model: for logs with a known rotor
//! momentum (a flywheel, spinning propellers), where the torque-free principal-axis model of
//! [`super::analysis`] cannot hold.
//!
//! Euler's equation with the rotor momentum `h(t)`, integrated over a block `[t0, t1]` of the
//! free flight so that no derivative of the gyro is needed:
//!
//! ```text
//! J (w(t1) - w(t0)) + integral w x (J w) dt  =  -(h(t1) - h(t0)) - integral w x h dt
//!                                                + integral tau dt                    (TB)
//! ```
//!
//! is linear in the six entries of `J` (kg m^2): products of inertia and the rotor momentum are
//! exact terms here, not linearised effects. The candidate effects add columns to (TB):
//!
//! * `body_torque` (`tau`, N m): `integral tau dt = tau (t1 - t0)`;
//! * `damping` (`d_i`, N m s): `tau_i = -d_i w_i`, column `-integral w_i dt e_i`;
//! * `gyro_bias` (`b`, rad/s): the gyro reads `w + b`; (TB) at `w - b`, linearised at the
//!   current `J`: `-b x integral (J w + h) dt - integral w x (J b) dt`;
//! * `rotor_lag` (`delta`, s): the logged rotor speed lags the rotor, `h(t + delta)` is the
//!   true momentum. Not linearised (a first-order column `delta h'` finds about half the lag
//!   put into a simulated log): `delta` is searched over +-10 ms (0.25 ms grid, parabolic
//!   refinement), `J` and the other effects refitted at each, its standard deviation from the
//!   curvature of the residual sum of squares;
//! * `rotor_axis` (`eps_1, eps_2`, rad): the rotor turns about `u + eps_1 p + eps_2 q` (`p, q`
//!   perpendicular to the given axis `u`): two more momentum terms like `h`'s;
//! * `gyro_scale` (`s_k`): the gyro reads `(1 + s_k) w_k`, linearised at the current `J`;
//! * `rotor_drag` (`c`, 1/(kg m^2)): the air's drag on the spinning rotor, `tau = -c |h| h`
//!   (quadratic in the rotor speed, along its axis; `c j_r^2` is the rotor's drag coefficient
//!   in N m s^2). The motor's torque on the rotor is internal to the body and already in `h`;
//!   the air's is not: it takes angular momentum out of the whole body, most at the
//!   spin-up's peak. Column `integral |h| h dt`;
//! * `aero_drag` (`c_k`, kg m^2): the air's drag on the tumbling body, quadratic in its rate,
//!   `tau_k = -c_k |w| w_k` (per body axis: the body is not round). Column `integral |w| w_k dt`
//!   on axis `k`. It takes angular momentum out of the body in proportion to the square of the
//!   rate, so left out it biases the scale of `J` more on a fast, large body.
//!
//! Each round adds the candidate whose F statistic is largest when it is significant at
//! `alpha / (candidates left)` (Bonferroni, family-wise `alpha` per round) and stops when none
//! is ([`super::selection`], forward only). The F test takes the blocks' residuals as
//! independent with equal variance; neighbouring blocks share an end sample and a real rotor's
//! vibration colours the residual, so the p-values are approximate (the report says how white
//! the residual is).
//!
//! The free flights are those `inertia identify` feeds its on-board pipeline (gate, guards,
//! gyro bias from the bench), or the given segments; the rotor speed the same as there.

use serde::Serialize;

use super::model::cross;
use super::selection::{
    self, mat_vec, unit_mat_vec, Candidates, Fit, LoopError, Named, Rank, Rules, Steps, V3,
};
use crate::identify::{identify, slow_telemetry, unhold, IdentifyOptions, Rotor, RotorHold};
use crate::Recording;

/// The effects (TB) can take, in a fixed order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TensorEffect {
    /// Constant body-frame torque, N m.
    BodyTorque,
    /// Viscous damping per axis, N m s.
    Damping,
    /// Constant gyro bias, rad/s.
    GyroBias,
    /// Delay of the logged rotor speed, s.
    RotorLag,
    /// Tilt of the rotor axis, rad.
    RotorAxis,
    /// Gyro scale factor per axis.
    GyroScale,
    /// Aerodynamic drag on the rotor, `tau = -c |h| h`, 1/(kg m^2).
    RotorDrag,
    /// Aerodynamic drag on the body, `tau_k = -c_k |w| w_k`, kg m^2.
    AeroDrag,
}

impl TensorEffect {
    /// Every candidate.
    pub const ALL: [TensorEffect; 8] = [
        TensorEffect::BodyTorque,
        TensorEffect::Damping,
        TensorEffect::GyroBias,
        TensorEffect::RotorLag,
        TensorEffect::RotorAxis,
        TensorEffect::GyroScale,
        TensorEffect::RotorDrag,
        TensorEffect::AeroDrag,
    ];

    /// Parameters it adds.
    pub fn n_params(self) -> usize {
        match self {
            TensorEffect::RotorLag | TensorEffect::RotorDrag => 1,
            TensorEffect::RotorAxis => 2,
            _ => 3,
        }
    }

    /// Names of its parameters.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            TensorEffect::BodyTorque => &["tau_x", "tau_y", "tau_z"],
            TensorEffect::Damping => &["d_x", "d_y", "d_z"],
            TensorEffect::GyroBias => &["b_x", "b_y", "b_z"],
            TensorEffect::RotorLag => &["delta_s"],
            TensorEffect::RotorAxis => &["eps_1", "eps_2"],
            TensorEffect::GyroScale => &["s_x", "s_y", "s_z"],
            TensorEffect::RotorDrag => &["c_drag"],
            TensorEffect::AeroDrag => &["c_x", "c_y", "c_z"],
        }
    }
}

/// Options of [`analyse_tensor`].
#[derive(Clone, Debug)]
pub struct TensorOptions {
    /// The rotor (inertia, axis, poles).
    pub rotor: Rotor,
    /// Family-wise significance level of each selection round.
    pub alpha: f64,
    /// Block length, s (10 ms: the gyro noise in `w(t1) - w(t0)` is small against the
    /// integral, and a rotor's vibration at a few hundred hertz averages out within a block).
    pub block_s: f64,
    /// Hand-chosen free flights `(start_s, end_s)`; `None`: the gate's.
    pub segments: Option<Vec<(f64, f64)>>,
    /// The rotor speed as logged, interpolated, or decided from the log ([`RotorHold`]).
    pub rotor_hold: RotorHold,
}

/// One model's fit.
#[derive(Clone, Debug, Serialize)]
pub struct TensorFitReport {
    /// Effects in the model, in the order they were added.
    pub effects: Vec<TensorEffect>,
    /// The tensor, kg m^2, in the log's gyro axes.
    pub tensor_kg_m2: [[f64; 3]; 3],
    /// Its standard deviations (least squares, residual variance), kg m^2.
    pub tensor_std_kg_m2: [[f64; 3]; 3],
    /// Principal moments, ascending, kg m^2.
    pub principal_moments: [f64; 3],
    /// Each effect's parameters with their standard deviations.
    pub effect_params: Vec<EffectParams>,
    /// RMS residual of (TB) per block, kg m^2/s.
    pub residual_rms: f64,
    /// The same over the noise the gyro alone would leave (`noise |J| sqrt(2)` per block).
    pub residual_over_noise: f64,
    /// Lag-one autocorrelation of the residual (0 for white).
    pub residual_lag1: f64,
}

/// An effect's fitted parameters.
#[derive(Clone, Debug, Serialize)]
pub struct EffectParams {
    /// The effect.
    pub effect: TensorEffect,
    /// Parameter names.
    pub names: Vec<&'static str>,
    /// Values.
    pub values: Vec<f64>,
    /// Standard deviations.
    pub std: Vec<f64>,
}

/// One candidate tried in a round (its parameters in the order of
/// [`TensorEffect::param_names`]; no standard deviations).
pub type TensorCandidate = selection::Candidate<TensorEffect>;

/// One selection round (no backward step: nothing is dropped).
pub type TensorRound = selection::Round<TensorEffect>;

/// What [`analyse_tensor`] found.
#[derive(Clone, Debug, Serialize)]
pub struct TensorAnalysis {
    /// Always `"tensor"`.
    pub base_model: &'static str,
    /// The log.
    pub source: String,
    /// Free-flight stretches used, `(start_s, end_s)`.
    pub stretches: Vec<(f64, f64)>,
    /// Blocks (three equations each).
    pub blocks: usize,
    /// Block length, s.
    pub block_s: f64,
    /// Gyro noise used for `residual_over_noise`, rad/s.
    pub noise_std: f64,
    /// The on-board estimate of the same free flights (`inertia identify`'s pooled tensor) and
    /// its status, for reference.
    pub on_board_tensor_kg_m2: Option<[[f32; 3]; 3]>,
    /// Its status.
    pub on_board_status: String,
    /// The base model (the tensor alone).
    pub before: TensorFitReport,
    /// The selection rounds.
    pub rounds: Vec<TensorRound>,
    /// The final model.
    pub after: TensorFitReport,
    /// Relative change of the tensor from before to after (Frobenius norm).
    pub tensor_change: f64,
    /// Residual per block before and after, per axis: `(t_mid, before, after)`.
    #[serde(skip)]
    pub residuals: Vec<(f64, [f64; 3], [f64; 3])>,
}

impl Named for TensorEffect {
    fn label(self) -> String {
        format!("{self:?}")
    }
}

/// The samples of one block: time, rate (bias removed), momentum, and the momenta the rotor
/// would have about its axis's two perpendiculars.
struct Block {
    t: Vec<f64>,
    w: Vec<V3>,
    h: Vec<V3>,
    hp: Vec<V3>,
    hq: Vec<V3>,
}

impl Block {
    fn trap(&self, f: impl Fn(usize) -> V3) -> V3 {
        let mut s = [0.0; 3];
        for i in 1..self.t.len() {
            let dt = self.t[i] - self.t[i - 1];
            let (a, b) = (f(i - 1), f(i));
            for k in 0..3 {
                s[k] += 0.5 * dt * (a[k] + b[k]);
            }
        }
        s
    }

    fn delta(&self, v: &[V3]) -> V3 {
        let (a, b) = (v[0], v[v.len() - 1]);
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
    }

    /// Momentum terms of (TB) for a momentum series `g`: `g(t1) - g(t0) + integral w x g`.
    fn momentum(&self, g: &[V3]) -> V3 {
        let d = self.delta(g);
        let i = self.trap(|k| cross(self.w[k], g[k]));
        [d[0] + i[0], d[1] + i[1], d[2] + i[2]]
    }

    /// The columns of the `J` entries and the right-hand side, and each effect's columns
    /// (the nonlinear ones linearised at `j`).
    fn rows(&self, j: &[f64; 6], effects: &[TensorEffect]) -> (Vec<V3>, V3) {
        let dw = self.delta(&self.w);
        let mut cols: Vec<V3> = (0..6)
            .map(|k| {
                let e = unit_mat_vec(k, dw);
                let i = self.trap(|s| cross(self.w[s], unit_mat_vec(k, self.w[s])));
                [e[0] + i[0], e[1] + i[1], e[2] + i[2]]
            })
            .collect();
        let m = self.momentum(&self.h);
        let y = [-m[0], -m[1], -m[2]];
        let span = self.t[self.t.len() - 1] - self.t[0];
        for e in effects {
            match e {
                TensorEffect::BodyTorque => {
                    for k in 0..3 {
                        let mut c = [0.0; 3];
                        c[k] = -span;
                        cols.push(c);
                    }
                }
                TensorEffect::Damping => {
                    let iw = self.trap(|s| self.w[s]);
                    for k in 0..3 {
                        let mut c = [0.0; 3];
                        c[k] = iw[k];
                        cols.push(c);
                    }
                }
                TensorEffect::GyroBias => {
                    let l = self.trap(|s| {
                        let jw = mat_vec(j, self.w[s]);
                        let h = self.h[s];
                        [jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]]
                    });
                    for k in 0..3 {
                        let mut b = [0.0; 3];
                        b[k] = 1.0;
                        let jb = mat_vec(j, b);
                        let a = cross(b, l);
                        let c = self.trap(|s| cross(self.w[s], jb));
                        cols.push([-a[0] - c[0], -a[1] - c[1], -a[2] - c[2]]);
                    }
                }
                // Searched, not a column (the blocks are built at the lag).
                TensorEffect::RotorLag => {}
                TensorEffect::RotorAxis => {
                    cols.push(self.momentum(&self.hp));
                    cols.push(self.momentum(&self.hq));
                }
                TensorEffect::RotorDrag => {
                    // (TB)'s right-hand side gains integral tau dt = -c integral |h| h dt.
                    cols.push(self.trap(|s| {
                        let h = self.h[s];
                        let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                        [n * h[0], n * h[1], n * h[2]]
                    }));
                }
                TensorEffect::AeroDrag => {
                    let i = self.trap(|s| {
                        let w = self.w[s];
                        let n = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
                        [n * w[0], n * w[1], n * w[2]]
                    });
                    for k in 0..3 {
                        let mut c = [0.0; 3];
                        c[k] = i[k];
                        cols.push(c);
                    }
                }
                TensorEffect::GyroScale => {
                    for k in 0..3 {
                        // d/ds_k of (TB) at w_k -> (1 - s_k) w_k (the reading is (1 + s_k) w).
                        let ws: Vec<V3> = self
                            .w
                            .iter()
                            .map(|w| {
                                let mut v = [0.0; 3];
                                v[k] = -w[k];
                                v
                            })
                            .collect();
                        let jd = mat_vec(j, self.delta(&ws));
                        let a = self.trap(|s| {
                            let l = mat_vec(j, self.w[s]);
                            let h = self.h[s];
                            cross(ws[s], [l[0] + h[0], l[1] + h[1], l[2] + h[2]])
                        });
                        let b = self.trap(|s| cross(self.w[s], mat_vec(j, ws[s])));
                        cols.push([
                            jd[0] + a[0] + b[0],
                            jd[1] + a[1] + b[1],
                            jd[2] + a[2] + b[2],
                        ]);
                    }
                }
            }
        }
        (cols, y)
    }
}

/// Least squares of the stacked rows; `None` when singular.
fn solve(blocks: &[Block], j: &[f64; 6], effects: &[TensorEffect]) -> Option<Fit> {
    let mut rows = Vec::new();
    let mut ys = Vec::new();
    for b in blocks {
        let (cols, y) = b.rows(j, effects);
        for r in 0..3 {
            rows.push(cols.iter().map(|c| c[r]).collect::<Vec<f64>>());
            ys.push(y[r]);
        }
    }
    let fit = super::stats::lstsq(&rows, &ys)?;
    let x = fit.theta.clone();
    let residuals: Vec<V3> = ys
        .chunks(3)
        .zip(rows.chunks(3))
        .map(|(y, r)| {
            let mut e = [0.0; 3];
            for k in 0..3 {
                let pred: f64 = r[k].iter().zip(x.iter()).map(|(a, b)| a * b).sum();
                e[k] = y[k] - pred;
            }
            e
        })
        .collect();
    Some(Fit {
        cov: fit.cov(),
        xtx_inv: fit.xtx_inv,
        rss: fit.rss,
        n: ys.len(),
        theta: x,
        residuals,
    })
}

/// Fits the model with `effects`, relinearising the nonlinear effects at the new `J` (three
/// passes).
fn fit_model(blocks: &[Block], j0: &[f64; 6], effects: &[TensorEffect]) -> Option<Fit> {
    let nonlinear = effects
        .iter()
        .any(|e| matches!(e, TensorEffect::GyroBias | TensorEffect::GyroScale));
    let mut j = *j0;
    let mut out = None;
    for _ in 0..if nonlinear { 3 } else { 1 } {
        let ls = solve(blocks, &j, effects)?;
        j = ls.j();
        out = Some(ls);
    }
    out
}

/// A fit of (TB): the least squares, and the rotor lag with its standard deviation when it is
/// in the model (searched, not a column).
struct TbFit {
    ls: Fit,
    lag: Option<(f64, f64)>,
}

/// (TB) over the free flights' blocks, for [`selection::select`].
struct Throws<'a> {
    /// The blocks with the logged rotor speed read `delta` seconds later.
    make_blocks: &'a dyn Fn(f64) -> Vec<Block>,
    /// The blocks as logged (no lag).
    blocks: &'a [Block],
}

impl Candidates for Throws<'_> {
    type Effect = TensorEffect;
    type Fit = TbFit;

    /// The linear effects fitted at the lag of `from` when the lag is in the model; the lag,
    /// when it is added, searched with them ([`search_lag`]).
    fn fit(&self, effects: &[TensorEffect], from: &TbFit) -> Option<TbFit> {
        let linear: Vec<TensorEffect> = effects
            .iter()
            .copied()
            .filter(|x| *x != TensorEffect::RotorLag)
            .collect();
        let j = from.ls.j();
        if !effects.contains(&TensorEffect::RotorLag) {
            let ls = fit_model(self.blocks, &j, &linear)?;
            return Some(TbFit { ls, lag: None });
        }
        match from.lag {
            Some(lag) => {
                let ls = fit_model(&(self.make_blocks)(lag.0), &j, &linear)?;
                Some(TbFit { ls, lag: Some(lag) })
            }
            None => {
                let (ls, d, sd) = search_lag(self.make_blocks, &j, &linear)?;
                Some(TbFit {
                    ls,
                    lag: Some((d, sd)),
                })
            }
        }
    }

    fn ls(fit: &TbFit) -> &Fit {
        &fit.ls
    }

    fn n_params(fit: &TbFit) -> usize {
        fit.ls.theta.len() + usize::from(fit.lag.is_some())
    }

    fn params(&self, fit: &TbFit, e: TensorEffect) -> (Vec<f64>, Option<Vec<f64>>) {
        let values = if e == TensorEffect::RotorLag {
            fit.lag.map(|l| vec![l.0]).unwrap_or_default()
        } else {
            fit.ls.theta[fit.ls.theta.len() - e.n_params()..].to_vec()
        };
        (values, None)
    }
}

fn report(fit: &TbFit, effects: &[TensorEffect], noise: f64) -> TensorFitReport {
    let ls = &fit.ls;
    let t = ls.tensor();
    let mut effect_params = Vec::new();
    let mut at = 6;
    for e in effects {
        if *e == TensorEffect::RotorLag {
            let (d, sd_d) = fit.lag.unwrap_or((f64::NAN, f64::NAN));
            effect_params.push(EffectParams {
                effect: *e,
                names: e.param_names().to_vec(),
                values: vec![d],
                std: vec![sd_d],
            });
            continue;
        }
        let n = e.n_params();
        effect_params.push(EffectParams {
            effect: *e,
            names: e.param_names().to_vec(),
            values: ls.theta[at..at + n].to_vec(),
            std: (at..at + n).map(|k| ls.sd(k)).collect(),
        });
        at += n;
    }
    // The gyro noise alone leaves `noise |J| sqrt(2)` per block (its two end samples).
    let jn = t.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    let floor = noise * jn * std::f64::consts::SQRT_2;
    TensorFitReport {
        effects: effects.to_vec(),
        tensor_kg_m2: t,
        tensor_std_kg_m2: ls.tensor_std(),
        principal_moments: ls.principal_moments(),
        effect_params,
        residual_rms: ls.residual_rms(),
        residual_over_noise: ls.residual_over(floor),
        residual_lag1: ls.residual_lag1(),
    }
}

/// Runs the tensor close-loop on `rec`.
pub fn analyse_tensor(rec: &Recording, opts: &TensorOptions) -> Result<TensorAnalysis, LoopError> {
    use LoopError::{Data, Input};
    let id = identify(
        rec,
        &IdentifyOptions {
            rotor: Some(opts.rotor),
            vehicle: None,
            segments: opts.segments.clone(),
            noise_std: None,
            rotor_hold: opts.rotor_hold,
            trace: false,
        },
    )
    .map_err(|e| Input(e.to_string()))?;
    let ch = rec
        .rotor
        .as_ref()
        .ok_or_else(|| Input("the log has no rotor-speed channel".into()))?;
    let speed = ch.rad_per_sec(opts.rotor.poles).ok_or_else(|| {
        Input("the log gives rotor speed as eRPM: --rotor-poles is needed".into())
    })?;
    let speed = if opts.rotor_hold.interpolates(slow_telemetry(&rec.t, &speed)) {
        unhold(&rec.t, &speed)
    } else {
        speed
    };
    let u = opts.rotor.axis.map(f64::from);
    let (p, q) = perpendiculars(u);
    let jr = f64::from(opts.rotor.inertia);
    let bias = id.gyro_bias.map(f64::from);
    let n = rec.len();
    let dt_med = {
        let mut d: Vec<f64> = rec.t.windows(2).map(|w| w[1] - w[0]).collect();
        d.sort_by(|a, b| a.total_cmp(b));
        d.get(d.len() / 2).copied().unwrap_or(1e-3)
    };
    let per_block = ((opts.block_s / dt_med).round() as usize).max(2);
    // The rotor speed at any time (linear between samples, held beyond the ends).
    let speed_at = |t: f64| -> f64 {
        let k = rec.t.partition_point(|x| *x <= t);
        if k == 0 {
            return f64::from(speed[0]);
        }
        if k >= n {
            return f64::from(speed[n - 1]);
        }
        let (t0, t1) = (rec.t[k - 1], rec.t[k]);
        let (s0, s1) = (f64::from(speed[k - 1]), f64::from(speed[k]));
        if t1 > t0 {
            s0 + (s1 - s0) * (t - t0) / (t1 - t0)
        } else {
            s1
        }
    };
    let mut stretches = Vec::new();
    let mut spans = Vec::new();
    for run in id.fed_runs.iter().flatten() {
        let (a, b) = (run.start, run.end.min(n));
        if b <= a + 1 {
            continue;
        }
        stretches.push((rec.t[a], rec.t[b - 1]));
        let mut s = a;
        while s + per_block < b {
            spans.push(s..s + per_block + 1);
            s += per_block;
        }
    }
    // The blocks with the logged rotor speed read `delta` seconds later (`h(t + delta)`).
    let make_blocks = |delta: f64| -> Vec<Block> {
        spans
            .iter()
            .map(|span| {
                let t: Vec<f64> = span.clone().map(|i| rec.t[i]).collect();
                let w: Vec<V3> = span
                    .clone()
                    .map(|i| [0, 1, 2].map(|k| f64::from(rec.gyro[i][k]) - bias[k]))
                    .collect();
                let sp: Vec<f64> = t.iter().map(|x| speed_at(x + delta)).collect();
                let along =
                    |v: V3| -> Vec<V3> { sp.iter().map(|s| v.map(|c| c * jr * s)).collect() };
                Block {
                    h: along(u),
                    hp: along(p),
                    hq: along(q),
                    t,
                    w,
                }
            })
            .collect()
    };
    let blocks = make_blocks(0.0);
    selection::enough(blocks.len(), "blocks of free flight")?;
    let noise = selection::gyro_noise(rec);
    let base = TbFit {
        ls: fit_model(&blocks, &[0.0; 6], &[])
            .ok_or_else(|| Data("the tensor is not determined".into()))?,
        lag: None,
    };
    let before = report(&base, &[], noise);
    let throws = Throws {
        make_blocks: &make_blocks,
        blocks: &blocks,
    };
    let rules = Rules {
        alpha: opts.alpha,
        rank: Rank::LargestF,
        steps: Steps::Forward,
    };
    let jb = base.ls.j();
    let base_residuals = base.ls.residuals.clone();
    let sel = selection::select(&throws, base, &TensorEffect::ALL, &rules);
    let after = report(&sel.fit, &sel.chosen, noise);
    let jc = sel.fit.ls.j();
    let change = {
        let d: f64 = (0..6)
            .map(|k| (jc[k] - jb[k]).powi(2) * if k < 3 { 1.0 } else { 2.0 })
            .sum();
        let b: f64 = (0..6)
            .map(|k| jb[k].powi(2) * if k < 3 { 1.0 } else { 2.0 })
            .sum();
        (d / b).sqrt()
    };
    let mut residuals = Vec::new();
    // The blocks' times do not depend on the rotor lag.
    for ((blk, e0), e1) in blocks
        .iter()
        .zip(base_residuals.iter())
        .zip(sel.fit.ls.residuals.iter())
    {
        let tm = 0.5 * (blk.t[0] + blk.t[blk.t.len() - 1]);
        residuals.push((tm, *e0, *e1));
    }
    Ok(TensorAnalysis {
        base_model: "tensor",
        source: rec.source.clone(),
        stretches,
        blocks: blocks.len(),
        block_s: per_block as f64 * dt_med,
        noise_std: noise,
        on_board_tensor_kg_m2: id.pooled.tensor_kg_m2,
        on_board_status: id.pooled.status.clone(),
        before,
        rounds: sel.rounds,
        after,
        tensor_change: change,
        residuals,
    })
}

/// The rotor lag that minimises the residual with the linear `effects`: a 0.25 ms grid over
/// +-10 ms, then a parabola through the best point and its neighbours. Returns the fit, the lag
/// and its standard deviation (`sqrt(2 s^2 / RSS'')`).
fn search_lag(
    make_blocks: &dyn Fn(f64) -> Vec<Block>,
    j0: &[f64; 6],
    effects: &[TensorEffect],
) -> Option<(Fit, f64, f64)> {
    const STEP: f64 = 2.5e-4;
    let rss = |d: f64| fit_model(&make_blocks(d), j0, effects).map(|ls| ls.rss);
    let grid: Vec<(f64, f64)> = (-40..=40)
        .filter_map(|k| {
            let d = k as f64 * STEP;
            rss(d).map(|r| (d, r))
        })
        .collect();
    let (i, &(d0, r0)) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    let (dm, dp) = (grid.get(i.wrapping_sub(1)), grid.get(i + 1));
    let (d, curv) = match (dm, dp) {
        (Some(&(_, rm)), Some(&(_, rp))) => {
            let c = (rp - 2.0 * r0 + rm) / (STEP * STEP);
            if c > 0.0 {
                (d0 - 0.5 * (rp - rm) / STEP / c, c)
            } else {
                (d0, f64::NAN)
            }
        }
        _ => (d0, f64::NAN),
    };
    let ls = fit_model(&make_blocks(d), j0, effects)?;
    let s2 = ls.rss / (ls.n as f64 - ls.theta.len() as f64 - 1.0).max(1.0);
    let sd = (2.0 * s2 / curv).sqrt();
    Some((ls, d, sd))
}

/// Two unit vectors perpendicular to `u` and to each other.
fn perpendiculars(u: V3) -> (V3, V3) {
    let a = if u[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let p = cross(u, a);
    let np = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let p = p.map(|x| x / np);
    (p, cross(u, p))
}

/// One line for the terminal.
pub fn summary_line(an: &TensorAnalysis) -> String {
    let names: Vec<String> = an.after.effects.iter().map(|e| e.label()).collect();
    format!(
        "tensor base model, {} blocks of {:.1} ms: residual {:.3e} -> {:.3e} kg m^2/s ({:.1}x -> {:.1}x the gyro noise's share); effects added: {}; tensor moved {:.2} %",
        an.blocks,
        an.block_s * 1e3,
        an.before.residual_rms,
        an.after.residual_rms,
        an.before.residual_over_noise,
        an.after.residual_over_noise,
        selection::names_or_none(&names),
        100.0 * an.tensor_change
    )
}

/// A markdown table of the rounds and the model before and after.
pub fn markdown(an: &TensorAnalysis, title: &str) -> String {
    let mut s = format!("# Close-loop (tensor base model): {title}\n\n");
    s += &format!(
        "{} blocks of {:.1} ms from {} free-flight stretch(es); gyro noise {:.2e} rad/s; on-board estimate status {}.\n\n",
        an.blocks,
        an.block_s * 1e3,
        an.stretches.len(),
        an.noise_std,
        an.on_board_status
    );
    let row = |name, r: &TensorFitReport| {
        let (rms, lag1, m) = (r.residual_rms, r.residual_lag1, r.principal_moments);
        (name, rms, r.residual_over_noise, lag1, m)
    };
    s += &selection::fits_table(
        [row("before (tensor)", &an.before), row("after", &an.after)],
        1,
        4,
    );
    s += &selection::rounds_table(&an.rounds);
    for e in &an.after.effect_params {
        let v = selection::param_list(&e.names, &e.values, &e.std, 3);
        s += &format!("\n{}: {v}\n", e.effect.label());
    }
    s += &selection::moved_line(an.tensor_change, 2);
    s
}

/// `residuals.svg`: the blocks' residual per axis before and after.
pub fn plots(an: &TensorAnalysis, dir: &std::path::Path, title: &str) -> anyhow::Result<()> {
    super::plot::write_residuals(dir, title, "(TB)", &an.residuals)
}
