//! The loop: identify, residual, trace, add, report.
//!
//! # The residual and why this one
//!
//! The residual is the *integral equation error* of the model over blocks of five samples
//! (see [`model::Block`], equation (B)):
//!
//! ```text
//! r = w(t4) - w(t0) - sum_m q_m phi(w(t_m)) theta        (rad/s, one 3-vector per block)
//! ```
//!
//! * It needs no derivative of the gyro signal: a smoothing differentiator at 100 Hz either
//!   amplifies the noise (about `sigma / h`) or, with a window long enough to quell it, biases
//!   the derivative during the fast flips of an intermediate-axis toss; its residual is
//!   coloured by the filter, which breaks the F-test and any whiteness test.
//! * Unlike the output error (free-run prediction from the first sample), it does not grow
//!   exponentially with the sensitivity of the unstable intermediate-axis motion, so a small
//!   parameter or model error gives a small, local, residual.
//! * It is linear in every parameter of the model and its extensions, so the effect search is
//!   nested least squares with exact F-tests.
//! * Blocks share no sample, so for white gyro noise the residual is independent from block
//!   to block (variance about `2 sigma^2` per axis plus the small noise of the regressors), and
//!   the Ljung-Box whiteness test applies to what is left.
//! * The degree-4 quadrature leaves an integration error of order `h^6 f^(4)`, negligible at
//!   100 Hz for rates up to ~40 rad/s.
//!
//! The free-run prediction error is reported as well, as the user-facing error.
//!
//! # Trace
//!
//! Forward selection over [`Effect::RESIDUAL`]: each candidate's three columns are added to
//! the current model and the reduction of the residual sum of squares is tested with the
//! F-test (Paulson's normal deviate `z`, Bonferroni over the candidates of the round at
//! family-wise level `alpha`) and must also improve BIC. The most significant candidate is
//! added and the search repeats; when no residual candidate is significant, the consistency
//! value `c = a1 + a2 + a3 + a1 a2 a3` is tested against its standard deviation from the fit's
//! covariance (`z = c / sigma_c`) for a gyro scale factor. "None" when nothing passes.
#![allow(clippy::needless_range_loop)]

use super::input::{self, Log, Spike};
use super::model::{self, Block, Effect};
use super::stats::{self, LsFit};
use identifier_core::extended::{ExtendedIdentifier, ExtendedSettings, ExtraEffect};
use identifier_core::{Identifier, Settings};
use serde::Serialize;
use std::collections::BTreeMap;

/// Tuning of the analysis.
#[derive(Clone, Debug)]
pub struct Options {
    /// Family-wise significance level per selection round.
    pub alpha: f64,
    /// Most residual effects added (the on-board extended identifier holds two).
    pub max_effects: usize,
    /// Gain of the core identifier, `C = -lambda E`.
    pub lambda: f32,
    /// True `a` where known (simulator, pendulum), for the parameter error.
    pub truth: Option<[f64; 3]>,
    /// Segments with fewer samples are skipped.
    pub min_samples: usize,
    /// Largest standard deviation of the torque-free least-squares `a` accepted: above it the
    /// motion does not determine `a` (a still log, a spin about one axis) and the analysis
    /// stops with an error.
    pub max_std_a: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            alpha: 1e-3,
            max_effects: 2,
            lambda: 3.0,
            truth: None,
            min_samples: 15,
            max_std_a: MAX_STD_A,
        }
    }
}

/// Default [`Options::max_std_a`]. Physical ratios lie in `[-1, 1]`; a standard deviation of
/// 0.25 leaves nothing to report about them.
pub const MAX_STD_A: f64 = 0.25;

/// One candidate's test in one round.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// The effect.
    pub effect: Effect,
    /// F statistic (for `scale_factor`: `z^2` of the consistency value).
    pub f: f64,
    /// Its critical value at the round's per-candidate level.
    pub f_crit: f64,
    /// Normal deviate of the statistic (Paulson for F; `|c| / sigma_c` for scale).
    pub z: f64,
    /// Critical normal deviate.
    pub z_crit: f64,
    /// BIC gain (0 for scale factor, which adds no column).
    pub delta_bic: f64,
    /// Passed both the test and BIC.
    pub significant: bool,
}

/// One round of the forward selection.
#[derive(Clone, Debug, Serialize)]
pub struct Round {
    /// Every candidate tested.
    pub candidates: Vec<Candidate>,
    /// The effect added, if any.
    pub chosen: Option<Effect>,
}

/// Ljung-Box test pooled over segments and axes.
#[derive(Clone, Debug, Serialize)]
pub struct Whiteness {
    /// Pooled Q.
    pub q: f64,
    /// Degrees of freedom.
    pub df: f64,
    /// Wilson-Hilferty normal deviate (large positive: not white).
    pub z: f64,
    /// White at the 1 % level (`z < 2.326`).
    pub white: bool,
}

/// Per-segment results.
#[derive(Clone, Debug, Serialize)]
pub struct SegmentReport {
    /// Label from the segments file.
    pub label: String,
    /// Window, seconds.
    pub start: f64,
    /// Window end, seconds.
    pub end: f64,
    /// Samples in the window.
    pub samples: usize,
    /// Blocks of (B).
    pub blocks: usize,
    /// Core identifier's estimate at the end of the segment (state carried over).
    pub core_a: [f64; 3],
    /// Extended identifier's estimate at the end of the segment (state carried over).
    pub extended_a: [f64; 3],
    /// Least-squares `a` from this segment alone, torque-free model.
    pub ls_a_before: Option<[f64; 3]>,
    /// Least-squares `a` from this segment alone, with the effects at their global values.
    pub ls_a_after: Option<[f64; 3]>,
    /// Free-run prediction RMS, rad/s, before (core `a`, torque-free).
    pub free_run_before: f64,
    /// Free-run prediction RMS, rad/s, after (extended identifier, extended model).
    pub free_run_after: f64,
    /// Free-run prediction RMS with the batch least-squares fit, torque-free model.
    pub free_run_ls_before: f64,
    /// Free-run prediction RMS with the batch least-squares fit, extended model.
    pub free_run_ls_after: f64,
}

/// Fitted estimates of one estimator.
#[derive(Clone, Debug, Serialize)]
pub struct Fitted {
    /// `a`.
    pub a: [f64; 3],
    /// Effect parameters by name.
    pub effect_params: BTreeMap<String, Vec<f64>>,
    /// Residual RMS of (B), rad/s.
    pub residual_rms: f64,
    /// Its systematic part, rad/s.
    pub residual_systematic: f64,
    /// Consistency value of `a`.
    pub consistency: f64,
    /// `max_i |a_i - truth_i|` when a truth is known.
    pub a_error: Option<f64>,
}

/// Everything the command writes.
#[derive(Clone, Debug, Serialize)]
pub struct Analysis {
    /// Input file.
    pub input: String,
    /// Effects in the order added (empty: none).
    pub effects: Vec<Effect>,
    /// Core identifier's `a` (torque-free model) after all segments.
    pub a_before: [f64; 3],
    /// Extended identifier's `a` (with the effects) after all segments.
    pub a_after: [f64; 3],
    /// Extended identifier's effect parameters by effect name.
    pub effect_params: BTreeMap<String, Vec<f64>>,
    /// Residual RMS of (B) for `a_before` and the torque-free model, rad/s.
    pub residual_rms_before: f64,
    /// Residual RMS of (B) for the extended identifier's estimate and model, rad/s.
    pub residual_rms_after: f64,
    /// Systematic part of the residual before (see [`systematic_rms`]).
    pub residual_systematic_before: f64,
    /// Systematic part after.
    pub residual_systematic_after: f64,
    /// Mean over segments of the free-run prediction RMS before, rad/s.
    pub free_run_rms_before: f64,
    /// Mean over segments of the free-run prediction RMS after, rad/s.
    pub free_run_rms_after: f64,
    /// The same for the batch least-squares fits (model change alone), before.
    pub free_run_ls_before: f64,
    /// The same for the batch least-squares fits, after.
    pub free_run_ls_after: f64,
    /// Standard deviation across segments of the per-segment least-squares `a`, before.
    pub spread_before: Option<[f64; 3]>,
    /// The same with the effects at their global values.
    pub spread_after: Option<[f64; 3]>,
    /// Consistency value of `a_before`.
    pub consistency_before: f64,
    /// Consistency value of `a_after`.
    pub consistency_after: f64,
    /// `max_i |a_before_i - truth_i|`.
    pub a_error_before: Option<f64>,
    /// `max_i |a_after_i - truth_i|`.
    pub a_error_after: Option<f64>,
    /// The truth used.
    pub truth: Option<[f64; 3]>,
    /// Batch least squares, torque-free model (the best the model can do).
    pub ls_before: Fitted,
    /// Batch least squares with the effects.
    pub ls_after: Fitted,
    /// The on-board extended estimator run with no effect (separates estimator from model).
    pub rls_no_effect: Fitted,
    /// Whiteness of the least-squares residual before.
    pub whiteness_before: Option<Whiteness>,
    /// Whiteness after.
    pub whiteness_after: Option<Whiteness>,
    /// Gyro noise per sample estimated from the final residual, rad/s.
    pub noise_std_estimate: f64,
    /// The selection rounds.
    pub rounds: Vec<Round>,
    /// Per segment.
    pub segments: Vec<SegmentReport>,
    /// Blocks of (B) used.
    pub blocks: usize,
    /// Samples per block of (B).
    pub samples_per_block: usize,
    /// Labels of segments skipped for having fewer than `min_samples` samples.
    pub skipped_segments: Vec<String>,
    /// Isolated spikes replaced by the plausibility gate before the fit
    /// ([`input::gate_spikes`]).
    #[serde(skip)]
    pub spikes: Vec<Spike>,
    /// Standard deviation of the torque-free least-squares `a` (the excitation check).
    #[serde(skip)]
    pub std_a: [f64; 3],
    /// Residual series for plots: (segment, block mid-time, torque-free at the least-squares
    /// `a`, extended model at the extended identifier's estimate).
    #[serde(skip)]
    pub residual_series: Vec<(usize, f64, [f64; 3], [f64; 3])>,
}

/// Least squares of (B) with Gauss-Newton on the linearisation point of bilinear columns.
pub fn fit(
    blocks: &[Block],
    omega: &[[f64; 3]],
    effects: &[Effect],
    a0: [f64; 3],
) -> Option<(LsFit, [f64; 3])> {
    let bilinear = effects.iter().any(|e| {
        matches!(
            e,
            Effect::GyroBias | Effect::ProductsOfInertia | Effect::RotorMomentum
        )
    });
    let mut a_lin = a0;
    let mut out = None;
    for _ in 0..if bilinear { 6 } else { 1 } {
        let (x, y) = model::block_rows(blocks, omega, effects, a_lin);
        let f = stats::lstsq(&x, &y)?;
        let a_new = [f.theta[0], f.theta[1], f.theta[2]];
        out = Some((f, a_lin));
        a_lin = a_new;
    }
    out
}

fn rms3(r: &[[f64; 3]]) -> f64 {
    let s: f64 = r.iter().flat_map(|v| v.iter()).map(|v| v * v).sum();
    (s / (3 * r.len()).max(1) as f64).sqrt()
}

/// Systematic part of a block residual: per segment and axis, a centred moving average over
/// `W = 5` blocks; for a white residual of variance `s^2` its mean square is `s^2 / W`, so the
/// systematic power is `(ms(MA r) - ms(r) / W) / (1 - 1/W)` (floored at 0).
pub fn systematic_rms(blocks: &[Block], r: &[[f64; 3]]) -> f64 {
    const W: usize = 5;
    let mut ms_ma = 0.0;
    let mut n = 0usize;
    let segs: Vec<usize> = {
        let mut s: Vec<usize> = blocks.iter().map(|b| b.segment).collect();
        s.dedup();
        s
    };
    for s in segs {
        let idx: Vec<usize> = (0..blocks.len())
            .filter(|&i| blocks[i].segment == s)
            .collect();
        for (p, _) in idx.iter().enumerate() {
            let lo = p.saturating_sub(W / 2);
            let hi = (p + W / 2 + 1).min(idx.len());
            if hi - lo < W {
                continue;
            }
            for i in 0..3 {
                let m: f64 = idx[lo..hi].iter().map(|&k| r[k][i]).sum::<f64>() / W as f64;
                ms_ma += m * m;
                n += 1;
            }
        }
    }
    if n == 0 {
        return f64::NAN;
    }
    let ms = rms3(r).powi(2);
    let sys = (ms_ma / n as f64 - ms / W as f64) / (1.0 - 1.0 / W as f64);
    sys.max(0.0).sqrt()
}

fn whiteness(blocks: &[Block], r: &[[f64; 3]]) -> Option<Whiteness> {
    let nseg = blocks.iter().map(|b| b.segment).max()? + 1;
    let (mut q, mut df) = (0.0, 0.0);
    for s in 0..nseg {
        for i in 0..3 {
            let x: Vec<f64> = blocks
                .iter()
                .zip(r)
                .filter(|(b, _)| b.segment == s)
                .map(|(_, v)| v[i])
                .collect();
            let lags = (x.len() / 4).min(5);
            if let Some(qs) = stats::ljung_box(&x, lags) {
                q += qs;
                df += lags as f64;
            }
        }
    }
    if df == 0.0 {
        return None;
    }
    let z = stats::chi2_to_z(q, df);
    Some(Whiteness {
        q,
        df,
        z,
        white: z < 2.326,
    })
}

fn consistency(a: [f64; 3]) -> f64 {
    a[0] + a[1] + a[2] + a[0] * a[1] * a[2]
}

/// `c / sigma_c` for the fitted `a` with covariance from the fit.
fn consistency_z(f: &LsFit) -> f64 {
    let a = [f.theta[0], f.theta[1], f.theta[2]];
    let g = [1.0 + a[1] * a[2], 1.0 + a[0] * a[2], 1.0 + a[0] * a[1]];
    let cov = f.cov();
    let mut v = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            v += g[i] * cov[i][j] * g[j];
        }
    }
    consistency(a) / v.max(1e-300).sqrt()
}

/// Scale `s` with `c(s a) = 0` (`s^2 = -(a1+a2+a3)/(a1 a2 a3)`), if in `[0.5, 2]`.
pub fn consistency_scale(a: [f64; 3]) -> Option<f64> {
    let s2 = -(a[0] + a[1] + a[2]) / (a[0] * a[1] * a[2]);
    (s2.is_finite() && (0.25..=4.0).contains(&s2)).then(|| s2.sqrt())
}

fn params_by_effect(effects: &[Effect], theta: &[f64], scale: f64) -> BTreeMap<String, Vec<f64>> {
    let mut m = BTreeMap::new();
    let mut k = 3;
    for e in effects {
        if *e == Effect::ScaleFactor {
            m.insert(e.name().to_string(), vec![scale]);
        } else {
            m.insert(e.name().to_string(), theta[k..k + 3].to_vec());
            k += 3;
        }
    }
    m
}

fn to_extra(e: Effect) -> Option<ExtraEffect> {
    match e {
        Effect::GyroBias => Some(ExtraEffect::GyroBias),
        Effect::BodyTorque => Some(ExtraEffect::BodyTorque),
        Effect::Damping => Some(ExtraEffect::Damping),
        Effect::ProductsOfInertia => Some(ExtraEffect::ProductsOfInertia),
        Effect::RotorMomentum => Some(ExtraEffect::RotorMomentum),
        Effect::ScaleFactor => None,
    }
}

/// Runs the on-board extended identifier over the segments (restart between segments, state
/// carried); returns the final estimator and the estimate `theta` at each segment end.
pub fn run_extended(
    log: &Log,
    ranges: &[(usize, usize)],
    effects: &[Effect],
    noise_std: f64,
) -> Result<(ExtendedIdentifier, Vec<[f64; 3]>), String> {
    let residual: Vec<ExtraEffect> = effects.iter().filter_map(|e| to_extra(*e)).collect();
    let mut s = ExtendedSettings::new([residual.first().copied(), residual.get(1).copied()]);
    s.scale_correction = effects.contains(&Effect::ScaleFactor);
    s.noise_std = (noise_std as f32).max(1e-4);
    // Effect parameters are small next to a: a tighter prior keeps the early, poorly
    // excited updates from wandering.
    s.prior_effect = 1.0;
    s.max_dt = max_dt(&log.t);
    let mut id = ExtendedIdentifier::new(s)
        .ok_or_else(|| format!("extended identifier refused its settings {s:?}"))?;
    // Blocks as long as the residual's (B): two Simpson pairs per run of four intervals.
    let pairs = (2 * model::runs_per_block(&log.t, &log.omega, ranges)).min(1000) as u16;
    id.set_block_pairs(pairs);
    let mut ends = Vec::new();
    for &(i0, i1) in ranges {
        id.restart();
        for k in i0..i1 {
            let dt = if k > i0 {
                log.t[k] - log.t[k - 1]
            } else {
                0.01
            };
            id.step(log.omega[k].map(|v| v as f32), dt as f32);
        }
        ends.push(
            id.estimate(identifier_core::ExtendedStatus::Buffered)
                .a
                .map(f64::from),
        );
    }
    Ok((id, ends))
}

/// A step longer than 2.5 median steps is a gap.
fn max_dt(t: &[f64]) -> f32 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(f64::total_cmp);
    (2.5 * d.get(d.len() / 2).copied().unwrap_or(0.01)) as f32
}

fn run_core(
    log: &Log,
    ranges: &[(usize, usize)],
    lambda: f32,
) -> Result<(Identifier, Vec<[f64; 3]>), String> {
    let mut s = Settings::with_lambda(lambda);
    s.max_dt = max_dt(&log.t);
    let mut id = Identifier::new(s).map_err(|e| format!("core identifier settings: {e}"))?;
    let mut ends = Vec::new();
    for &(i0, i1) in ranges {
        id.restart();
        for k in i0..i1 {
            let dt = if k > i0 {
                log.t[k] - log.t[k - 1]
            } else {
                0.01
            };
            id.step(log.omega[k].map(|v| v as f32), dt as f32);
        }
        ends.push(id.estimate().map(f64::from));
    }
    Ok((id, ends))
}

fn spread(v: &[[f64; 3]]) -> Option<[f64; 3]> {
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    Some(std::array::from_fn(|i| {
        let m = v.iter().map(|x| x[i]).sum::<f64>() / n;
        (v.iter().map(|x| (x[i] - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    }))
}

fn err_vs(truth: Option<[f64; 3]>, a: [f64; 3]) -> Option<f64> {
    truth.map(|t| (0..3).map(|i| (a[i] - t[i]).abs()).fold(0.0, f64::max))
}

/// Per-segment least squares of `a` with the effect columns fixed at `theta_fx`.
fn segment_a(
    blocks: &[Block],
    omega: &[[f64; 3]],
    seg: usize,
    effects: &[Effect],
    a_lin: [f64; 3],
    theta: &[f64],
) -> Option<[f64; 3]> {
    let bs: Vec<Block> = blocks
        .iter()
        .filter(|b| b.segment == seg)
        .cloned()
        .collect();
    if bs.len() < 3 {
        return None;
    }
    let (x, y) = model::block_rows(&bs, omega, effects, a_lin);
    let rows: Vec<Vec<f64>> = x.iter().map(|r| r[..3].to_vec()).collect();
    let yy: Vec<f64> = x
        .iter()
        .zip(&y)
        .map(|(r, yi)| {
            yi - r[3..]
                .iter()
                .zip(&theta[3..])
                .map(|(a, b)| a * b)
                .sum::<f64>()
        })
        .collect();
    let f = stats::lstsq(&rows, &yy)?;
    Some([f.theta[0], f.theta[1], f.theta[2]])
}

/// The whole loop on one log. `Err` when no segment has enough data for a fit, or when the
/// motion does not determine `a` (standard deviation above [`Options::max_std_a`]). Isolated
/// spikes are replaced first ([`input::gate_spikes`]; listed in [`Analysis::spikes`]).
pub fn analyse(log: &Log, opts: &Options) -> Result<Analysis, String> {
    let mut gated = log.clone();
    let spikes = input::gate_spikes(&mut gated);
    let log = &gated;
    let all_ranges = log.segment_ranges();
    let keep: Vec<usize> = (0..all_ranges.len())
        .filter(|&s| all_ranges[s].1 - all_ranges[s].0 >= opts.min_samples)
        .collect();
    let ranges: Vec<(usize, usize)> = keep.iter().map(|&s| all_ranges[s]).collect();
    let runs = model::runs_per_block(&log.t, &log.omega, &ranges);
    let blocks = model::blocks(&log.t, &ranges, runs);
    if 3 * blocks.len() < 30 {
        return Err(format!(
            "only {} usable blocks of {} samples in the free-flight segments",
            blocks.len(),
            4 * runs + 1
        ));
    }
    let omega = &log.omega;
    let step = f64::from(max_dt(&log.t)) / 2.5;
    if !(1e-6..=10.0).contains(&step) {
        return Err(format!(
            "median sample interval {step:e} s is outside 1e-6..10 s: not a gyro log in seconds"
        ));
    }

    // 1. Identify with the on-board core.
    let (core, core_ends) = run_core(log, &ranges, opts.lambda)?;
    let a_before = core.estimate().map(f64::from);

    // 2-3. Residual and trace.
    let (base, _) = fit(&blocks, omega, &[], [0.0; 3]).ok_or("torque-free fit is singular")?;
    let a_ls0 = [base.theta[0], base.theta[1], base.theta[2]];
    let cov0 = base.cov();
    let std_a: [f64; 3] = std::array::from_fn(|i| cov0[i][i].max(0.0).sqrt());
    if !std_a.iter().all(|s| *s <= opts.max_std_a) {
        return Err(format!(
            "the motion does not determine the inertia ratios: standard deviation of the \
             least-squares a = ({:.3}, {:.3}, {:.3}), above {} (a = ({:.3}, {:.3}, {:.3}) would \
             be noise). A still log or a spin about one axis cannot identify a: the body must \
             tumble, turning about at least two axes at once, in each free flight",
            std_a[0], std_a[1], std_a[2], opts.max_std_a, a_ls0[0], a_ls0[1], a_ls0[2]
        ));
    }
    let mut effects: Vec<Effect> = Vec::new();
    let mut current = base.clone();
    let mut current_lin = a_ls0;
    let mut rounds = Vec::new();
    let n = 3 * blocks.len();
    loop {
        let residual_count = effects
            .iter()
            .filter(|e| **e != Effect::ScaleFactor)
            .count();
        if effects.contains(&Effect::ScaleFactor) {
            break;
        }
        let cands: Vec<Effect> = if residual_count < opts.max_effects {
            Effect::RESIDUAL
                .iter()
                .copied()
                .filter(|e| !effects.contains(e))
                .collect()
        } else {
            Vec::new()
        };
        let m = (cands.len() + 1) as f64;
        let alpha_each = opts.alpha / m;
        let z_crit = stats::normal_isf(alpha_each);
        let mut tested = Vec::new();
        let mut fits = Vec::new();
        let a_now = [current.theta[0], current.theta[1], current.theta[2]];
        for e in &cands {
            let mut fx = effects.clone();
            fx.push(*e);
            let Some((f1, lin)) = fit(&blocks, omega, &fx, a_now) else {
                continue;
            };
            let p = 3.0;
            let d2 = (n - f1.theta.len()) as f64;
            let fstat = ((current.rss - f1.rss) / p) / (f1.rss / d2);
            let z = stats::f_to_z(fstat, p, d2);
            let dbic = stats::delta_bic(current.rss, f1.rss, n, 3);
            tested.push(Candidate {
                effect: *e,
                f: fstat,
                f_crit: stats::f_isf(alpha_each, p, d2),
                z,
                z_crit,
                delta_bic: dbic,
                significant: z > z_crit && dbic > 0.0,
            });
            fits.push((f1, lin));
        }
        let best = tested
            .iter()
            .enumerate()
            .filter(|(_, c)| c.significant)
            .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
            .map(|(i, _)| i);
        // The consistency test for a scale factor, with the current model.
        let zc = consistency_z(&current);
        let z_crit2 = stats::normal_isf(alpha_each / 2.0);
        let scale_ok = consistency_scale(a_now).is_some();
        tested.push(Candidate {
            effect: Effect::ScaleFactor,
            f: zc * zc,
            f_crit: z_crit2 * z_crit2,
            z: zc.abs(),
            z_crit: z_crit2,
            delta_bic: 0.0,
            significant: zc.abs() > z_crit2 && scale_ok,
        });
        let chosen = if let Some(i) = best {
            let (f1, lin) = fits.swap_remove(i);
            current = f1;
            current_lin = lin;
            Some(tested[i].effect)
        } else if tested.last().is_some_and(|c| c.significant) {
            Some(Effect::ScaleFactor)
        } else {
            None
        };
        rounds.push(Round {
            candidates: tested,
            chosen,
        });
        match chosen {
            Some(e) => effects.push(e),
            None => break,
        }
    }

    let noise_std = (current.sigma2() / 2.0).sqrt();
    let scale_ls = if effects.contains(&Effect::ScaleFactor) {
        consistency_scale([current.theta[0], current.theta[1], current.theta[2]]).unwrap_or(1.0)
    } else {
        1.0
    };

    // 4. The on-board extended identifier with the chosen effects, and with none.
    let (ext, ext_ends) = run_extended(log, &ranges, &effects, noise_std)?;
    let ext_theta: Vec<f64> = ext.theta().iter().map(|v| f64::from(*v)).collect();
    let ext_est = ext.estimate(identifier_core::ExtendedStatus::Buffered);
    let a_after = ext_est.a.map(f64::from);
    let n_p = model::n_params(&effects);
    let ext_theta = ext_theta[..n_p].to_vec();
    let ext_lin = [ext_theta[0], ext_theta[1], ext_theta[2]];
    let (rls0, _) = run_extended(log, &ranges, &[], noise_std)?;
    let rls0_theta: Vec<f64> = rls0.theta()[..3].iter().map(|v| f64::from(*v)).collect();

    // 5. Report.
    let r_before = model::block_residuals(&blocks, omega, &[], a_before, &a_before);
    let r_after = model::block_residuals(&blocks, omega, &effects, ext_lin, &ext_theta);
    let r_ls0 = model::block_residuals(&blocks, omega, &[], a_ls0, &base.theta);
    let r_ls1 = model::block_residuals(&blocks, omega, &effects, current_lin, &current.theta);
    let r_rls0 = model::block_residuals(&blocks, omega, &[], [0.0; 3], &rls0_theta);
    let a_ls1 = [
        current.theta[0] * scale_ls,
        current.theta[1] * scale_ls,
        current.theta[2] * scale_ls,
    ];
    let fitted = |a: [f64; 3], params, r: &[[f64; 3]]| Fitted {
        a,
        effect_params: params,
        residual_rms: rms3(r),
        residual_systematic: systematic_rms(&blocks, r),
        consistency: consistency(a),
        a_error: err_vs(opts.truth, a),
    };
    let ls_before = fitted(a_ls0, BTreeMap::new(), &r_ls0);
    let ls_after = fitted(
        a_ls1,
        params_by_effect(&effects, &current.theta, scale_ls),
        &r_ls1,
    );
    let rls_no_effect = fitted(
        [rls0_theta[0], rls0_theta[1], rls0_theta[2]],
        BTreeMap::new(),
        &r_rls0,
    );

    let mut segments = Vec::new();
    let (mut seg_before, mut seg_after) = (Vec::new(), Vec::new());
    for (si, &s) in keep.iter().enumerate() {
        let seg = &log.segments[s];
        let range = ranges[si];
        let nb = blocks.iter().filter(|b| b.segment == si).count();
        let lb = segment_a(&blocks, omega, si, &[], a_ls0, &base.theta);
        let la = segment_a(&blocks, omega, si, &effects, current_lin, &current.theta)
            .map(|a| a.map(|v| v * scale_ls));
        seg_before.extend(lb);
        seg_after.extend(la);
        segments.push(SegmentReport {
            label: seg.label.clone(),
            start: seg.start,
            end: seg.end,
            samples: range.1 - range.0,
            blocks: nb,
            core_a: core_ends[si],
            extended_a: ext_ends[si],
            ls_a_before: lb,
            ls_a_after: la,
            free_run_before: model::free_run_rms(&log.t, omega, range, &[], a_before, &a_before),
            free_run_after: model::free_run_rms(
                &log.t, omega, range, &effects, ext_lin, &ext_theta,
            ),
            free_run_ls_before: model::free_run_rms(&log.t, omega, range, &[], a_ls0, &base.theta),
            free_run_ls_after: model::free_run_rms(
                &log.t,
                omega,
                range,
                &effects,
                current_lin,
                &current.theta,
            ),
        });
    }
    let mean = |f: fn(&SegmentReport) -> f64| {
        segments.iter().map(f).sum::<f64>() / segments.len().max(1) as f64
    };
    let residual_series = blocks
        .iter()
        .zip(r_ls0.iter().zip(&r_after))
        .map(|(b, (x, y))| (b.segment, b.t_mid, *x, *y))
        .collect();

    Ok(Analysis {
        input: log.source.display().to_string(),
        effects: effects.clone(),
        a_before,
        a_after,
        effect_params: params_by_effect(&effects, &ext_theta, f64::from(ext_est.scale)),
        residual_rms_before: rms3(&r_before),
        residual_rms_after: rms3(&r_after),
        residual_systematic_before: systematic_rms(&blocks, &r_before),
        residual_systematic_after: systematic_rms(&blocks, &r_after),
        free_run_rms_before: mean(|s| s.free_run_before),
        free_run_rms_after: mean(|s| s.free_run_after),
        free_run_ls_before: mean(|s| s.free_run_ls_before),
        free_run_ls_after: mean(|s| s.free_run_ls_after),
        spread_before: spread(&seg_before),
        spread_after: spread(&seg_after),
        consistency_before: consistency(a_before),
        consistency_after: consistency(a_after),
        a_error_before: err_vs(opts.truth, a_before),
        a_error_after: err_vs(opts.truth, a_after),
        truth: opts.truth,
        ls_before,
        ls_after,
        rls_no_effect,
        whiteness_before: whiteness(&blocks, &r_ls0),
        whiteness_after: whiteness(&blocks, &r_ls1),
        noise_std_estimate: noise_std,
        rounds,
        segments,
        blocks: blocks.len(),
        samples_per_block: 4 * runs + 1,
        skipped_segments: (0..all_ranges.len())
            .filter(|s| !keep.contains(s))
            .map(|s| log.segments[s].label.clone())
            .collect(),
        spikes,
        std_a,
        residual_series,
    })
}
