//! What the two tensor close-loops share: [`super::tensor`] (a thrown body with a flywheel,
//! Euler's equation integrated over blocks, (TB)) and [`super::vehicle_loop`] (a vehicle file's
//! rotors, (TB) averaged over its start time across one block, (TBA)). Both fit the six entries
//! of `J` and the candidate effects' parameters by least squares on three rows per block or
//! equation (`Fit`), choose the effects by F tests round by round (`select`), and report
//! the rounds and the model before and after in the same tables. What is theirs (the rows, each
//! effect's columns, and how a model is fitted) they give through `Candidates`.
//!
//! **Selection.** Each round fits every candidate not yet chosen with the model so far, tests
//! it by the F test of the larger model against the nested one, and adds the best of those
//! significant at `alpha / (candidates left)` (Bonferroni, family-wise `alpha` per round): the
//! largest F (`Rank::LargestF`, (TB)) or the smallest p-value (`Rank::SmallestP`, (TBA),
//! which lets a three- or six-parameter effect win over a one-parameter one of the same
//! strength). With a backward step (`Steps::ForwardBackward`) it then drops the least
//! significant chosen effect while one's partial F test (the others kept) is no longer
//! significant at `alpha / (effects chosen)`. It stops when no candidate is significant or none
//! is left. The F test takes the rows as independent with equal variance; each module says
//! where that is approximate.

use serde::Serialize;

use super::stats;
use crate::Recording;

pub(super) type V3 = [f64; 3];

/// `J w` for `J` given by its six entries (xx, yy, zz, xy, xz, yz).
pub(super) fn mat_vec(j: &[f64; 6], w: V3) -> V3 {
    let [xx, yy, zz, xy, xz, yz] = *j;
    [
        xx * w[0] + xy * w[1] + xz * w[2],
        xy * w[0] + yy * w[1] + yz * w[2],
        xz * w[0] + yz * w[1] + zz * w[2],
    ]
}

/// `E_k w` for the k-th entry of `J` (xx, yy, zz, xy, xz, yz).
pub(super) fn unit_mat_vec(k: usize, w: V3) -> V3 {
    let mut j = [0.0; 6];
    j[k] = 1.0;
    mat_vec(&j, w)
}

/// `J`'s six entries, the first of a fit's parameters.
pub(super) fn j6(theta: &[f64]) -> [f64; 6] {
    [theta[0], theta[1], theta[2], theta[3], theta[4], theta[5]]
}

/// `J` as a matrix from its six entries.
pub(super) fn matrix(j: &[f64; 6]) -> [[f64; 3]; 3] {
    [[j[0], j[3], j[4]], [j[3], j[1], j[5]], [j[4], j[5], j[2]]]
}

/// Why a tensor close-loop ([`super::analyse_tensor`], [`super::analyse_vehicle`]) gave no
/// result.
#[derive(Clone, Debug, PartialEq)]
pub enum LoopError {
    /// The input cannot be used: no free flight, no rotor channel, no pole count for an eRPM
    /// channel, the vehicle file's columns not read, a zero or non-finite position (the command
    /// exits 3).
    Input(String),
    /// The free flights cannot determine the tensor and its effects (exit 4).
    Data(String),
}

impl core::fmt::Display for LoopError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LoopError::Input(m) | LoopError::Data(m) => f.write_str(m),
        }
    }
}

/// The fewest blocks or equations a selection starts from: `count` of `what` below it is a
/// [`LoopError::Data`].
pub(super) fn enough(count: usize, what: &str) -> Result<(), LoopError> {
    if count < 10 {
        return Err(LoopError::Data(format!(
            "{count} {what}: too few for the tensor and its effects"
        )));
    }
    Ok(())
}

/// The gyro's white noise, rad/s: the noise the log shows, as white noise before its filters
/// ((G2)); each report's `residual_over_noise` is over its share through the equation.
pub(super) fn gyro_noise(rec: &Recording) -> f64 {
    f64::from(crate::recording::white_noise(
        crate::recording::estimate_noise(&rec.gyro),
        rec.gyro_filters.as_ref(),
        crate::recording::median_dt(&rec.t),
    ))
}

/// A least-squares fit of the rows: `theta` is `J`'s six entries (xx, yy, zz, xy, xz, yz), then
/// each effect's parameters in the order the effects were added.
#[derive(Clone, Debug)]
pub(super) struct Fit {
    pub(super) theta: Vec<f64>,
    /// Covariance of `theta` (`xtx_inv` times the residual variance).
    pub(super) cov: Vec<Vec<f64>>,
    pub(super) xtx_inv: Vec<Vec<f64>>,
    /// Residual sum of squares.
    pub(super) rss: f64,
    /// Rows.
    pub(super) n: usize,
    /// Residual per block or equation (its three rows).
    pub(super) residuals: Vec<V3>,
}

impl Fit {
    /// Standard deviation of `theta[k]`.
    pub(super) fn sd(&self, k: usize) -> f64 {
        self.cov[k][k].max(0.0).sqrt()
    }

    /// `J`'s six entries.
    pub(super) fn j(&self) -> [f64; 6] {
        j6(&self.theta)
    }

    /// `J`, kg m^2.
    pub(super) fn tensor(&self) -> [[f64; 3]; 3] {
        matrix(&self.j())
    }

    /// The standard deviations of `J`'s entries as a matrix, kg m^2.
    pub(super) fn tensor_std(&self) -> [[f64; 3]; 3] {
        matrix(&core::array::from_fn(|k| self.sd(k)))
    }

    /// `J`'s principal moments, ascending, kg m^2.
    pub(super) fn principal_moments(&self) -> [f64; 3] {
        crate::calibrate::eigen(&self.tensor()).0
    }

    /// RMS residual per row.
    pub(super) fn residual_rms(&self) -> f64 {
        (self.rss / self.n.max(1) as f64).sqrt()
    }

    /// [`Fit::residual_rms`] over the share `floor` the gyro's noise alone would leave (NaN
    /// without one).
    pub(super) fn residual_over(&self, floor: f64) -> f64 {
        if floor > 0.0 {
            self.residual_rms() / floor
        } else {
            f64::NAN
        }
    }

    /// Mean over the axes of the lag-one autocorrelation of the residuals (0 for white).
    pub(super) fn residual_lag1(&self) -> f64 {
        let mut acc = 0.0;
        for k in 0..3 {
            let x: Vec<f64> = self.residuals.iter().map(|e| e[k]).collect();
            let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
            let var: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
            let cov: f64 = x.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
            acc += if var > 0.0 { cov / var } else { 0.0 };
        }
        acc / 3.0
    }
}

/// An effect as the reports name it.
pub(super) trait Named: Copy + PartialEq {
    /// Its name in the markdown tables.
    fn label(self) -> String;
}

/// A model family the selection works on: how it fits a model with a set of effects, and what
/// a candidate's record shows.
pub(super) trait Candidates {
    /// The candidate effects.
    type Effect: Named;
    /// A model's fit: its least squares and whatever is fitted outside it.
    type Fit;

    /// The model with `effects` (in the order added) fitted from `from` (the model so far,
    /// whose `J` linearises the bilinear columns); `None` when the rows cannot determine it.
    fn fit(&self, effects: &[Self::Effect], from: &Self::Fit) -> Option<Self::Fit>;

    /// The least squares of a fit.
    fn ls(fit: &Self::Fit) -> &Fit;

    /// How many parameters a fit has (the F test's degrees of freedom): the least squares' and
    /// any searched outside it.
    fn n_params(fit: &Self::Fit) -> usize {
        Self::ls(fit).theta.len()
    }

    /// The parameters of `e`, the effect added last in `fit`, and their standard deviations
    /// where the report gives them.
    fn params(&self, fit: &Self::Fit, e: Self::Effect) -> (Vec<f64>, Option<Vec<f64>>);
}

/// Which significant candidate a round adds.
#[derive(Clone, Copy, Debug)]
pub(super) enum Rank {
    /// The one with the largest F.
    LargestF,
    /// The one with the smallest p-value.
    SmallestP,
}

/// Whether a round may also drop effects.
#[derive(Clone, Copy, Debug)]
pub(super) enum Steps {
    /// Each round adds one effect at most; nothing is dropped.
    Forward,
    /// After an addition, drop the effects no longer significant; at most `max_rounds` rounds
    /// (an effect dropped may come back).
    ForwardBackward {
        /// The most rounds.
        max_rounds: usize,
    },
}

/// How [`select`] chooses.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rules {
    /// Family-wise significance level of each round.
    pub(super) alpha: f64,
    pub(super) rank: Rank,
    pub(super) steps: Steps,
}

/// One candidate tried in a round.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate<E> {
    /// The effect.
    pub effect: E,
    /// F statistic of adding it.
    pub f: f64,
    /// Its p-value.
    pub p: f64,
    /// RMS residual with it, kg m^2/s.
    pub residual_rms: f64,
    /// Its parameters fitted with the model so far, in the order of the effect's parameter
    /// names.
    pub params: Vec<f64>,
    /// Their standard deviations, where the analysis reports them (the vehicle close-loop's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std: Option<Vec<f64>>,
    /// The tensor fitted with it, kg m^2 (what `J` would be were it added).
    pub tensor_kg_m2: [[f64; 3]; 3],
}

/// One selection round.
#[derive(Clone, Debug, Serialize)]
pub struct Round<E> {
    /// Every candidate tried.
    pub candidates: Vec<Candidate<E>>,
    /// The one added, if any was significant.
    pub chosen: Option<E>,
    /// The level each candidate was tested at.
    pub level: f64,
    /// Effects dropped after the addition (their partial F test no longer significant); absent
    /// where the selection has no backward step (the tensor close-loop's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub removed: Option<Vec<E>>,
}

/// What [`select`] ends with.
pub(super) struct Selection<E, F> {
    /// The effects chosen, in the order added.
    pub(super) chosen: Vec<E>,
    /// The final model's fit.
    pub(super) fit: F,
    pub(super) rounds: Vec<Round<E>>,
}

/// Upper tail of the F distribution with `(d1, d2)` degrees of freedom (Paulson's normal
/// approximation, as the torque-free close-loop uses).
fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    stats::normal_sf(stats::f_to_z(f, d1, d2))
}

/// The F test of the larger fit `f1` against the nested `f0`: F and its p-value.
fn f_test<M: Candidates>(f0: &M::Fit, f1: &M::Fit) -> (f64, f64) {
    let (p0, p1) = (M::n_params(f0), M::n_params(f1));
    let (rss0, ls1) = (M::ls(f0).rss, M::ls(f1));
    let q = (p1 - p0) as f64;
    let dof = ls1.n as f64 - p1 as f64;
    let f = ((rss0 - ls1.rss) / q) / (ls1.rss / dof);
    (f, f_sf(f, q, dof))
}

/// The partial F test of the `k`-th of the effects `chosen` in `fit`: F, p-value and the fit
/// of the model without it (the others kept); `None` when that model cannot be fitted.
pub(super) fn drop_test<M: Candidates>(
    model: &M,
    chosen: &[M::Effect],
    fit: &M::Fit,
    k: usize,
) -> Option<(f64, f64, M::Fit)> {
    let without: Vec<M::Effect> = chosen
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, x)| *x)
        .collect();
    let f0 = model.fit(&without, fit)?;
    let (f, p) = f_test::<M>(&f0, fit);
    Some((f, p, f0))
}

/// Forward selection from `base` (the tensor alone) over `candidates` by `rules` (see the
/// module documentation).
pub(super) fn select<M: Candidates>(
    model: &M,
    base: M::Fit,
    candidates: &[M::Effect],
    rules: &Rules,
) -> Selection<M::Effect, M::Fit> {
    let mut chosen: Vec<M::Effect> = Vec::new();
    let mut cur = base;
    let mut rounds = Vec::new();
    let backward = matches!(rules.steps, Steps::ForwardBackward { .. });
    loop {
        let left: Vec<M::Effect> = candidates
            .iter()
            .copied()
            .filter(|e| !chosen.contains(e))
            .collect();
        if left.is_empty() {
            break;
        }
        let level = rules.alpha / left.len() as f64;
        let mut tried = Vec::new();
        let mut best: Option<(f64, f64, M::Effect, M::Fit)> = None;
        for e in left {
            let with: Vec<M::Effect> = chosen.iter().copied().chain([e]).collect();
            let Some(f1) = model.fit(&with, &cur) else {
                continue;
            };
            let (f, p) = f_test::<M>(&cur, &f1);
            let (params, std) = model.params(&f1, e);
            let ls = M::ls(&f1);
            tried.push(Candidate {
                effect: e,
                f,
                p,
                residual_rms: (ls.rss / ls.n as f64).sqrt(),
                params,
                std,
                tensor_kg_m2: ls.tensor(),
            });
            let better = best.as_ref().is_none_or(|b| match rules.rank {
                Rank::LargestF => f > b.0,
                Rank::SmallestP => p < b.1,
            });
            if p < level && better {
                best = Some((f, p, e, f1));
            }
        }
        let Some((_, _, e, f1)) = best else {
            rounds.push(Round {
                candidates: tried,
                chosen: None,
                level,
                removed: backward.then(Vec::new),
            });
            break;
        };
        chosen.push(e);
        cur = f1;
        let removed =
            backward.then(|| drop_insignificant(model, &mut chosen, &mut cur, rules.alpha));
        rounds.push(Round {
            candidates: tried,
            chosen: Some(e),
            level,
            removed,
        });
        if let Steps::ForwardBackward { max_rounds } = rules.steps {
            if rounds.len() >= max_rounds {
                break;
            }
        }
    }
    Selection {
        chosen,
        fit: cur,
        rounds,
    }
}

/// The backward step: drops the least significant of `chosen` while one's partial F test is not
/// significant at `alpha / (effects chosen)`, refitting `cur` without it; returns those dropped.
fn drop_insignificant<M: Candidates>(
    model: &M,
    chosen: &mut Vec<M::Effect>,
    cur: &mut M::Fit,
    alpha: f64,
) -> Vec<M::Effect> {
    let mut removed = Vec::new();
    while chosen.len() > 1 {
        let level = alpha / chosen.len() as f64;
        let mut worst: Option<(f64, usize, M::Fit)> = None;
        for k in 0..chosen.len() {
            let Some((_, p, f0)) = drop_test(model, chosen, cur, k) else {
                continue;
            };
            if p >= level && worst.as_ref().is_none_or(|w| p > w.0) {
                worst = Some((p, k, f0));
            }
        }
        let Some((_, k, f0)) = worst else {
            break;
        };
        removed.push(chosen.remove(k));
        *cur = f0;
    }
    removed
}

/// The markdown table of the model before and after (`rows`: name, residual RMS, its ratio to
/// the gyro noise's share, lag-one autocorrelation, principal moments), the ratio with
/// `ratio_digits` decimals and the moments with `moment_digits`.
pub(super) fn fits_table(
    rows: [(&str, f64, f64, f64, [f64; 3]); 2],
    ratio_digits: usize,
    moment_digits: usize,
) -> String {
    let mut s = String::from(
        "| model | residual RMS (kg m^2/s) | / gyro noise's share | lag-1 autocorrelation | principal moments (kg m^2) |\n|---|---|---|---|---|\n",
    );
    for (name, rms, ratio, lag1, m) in rows {
        s += &format!(
            "| {name} | {rms:.3e} | {ratio:.r$} | {lag1:.2} | {:.d$e}, {:.d$e}, {:.d$e} |\n",
            m[0],
            m[1],
            m[2],
            r = ratio_digits,
            d = moment_digits
        );
    }
    s
}

/// The markdown table of the rounds: every candidate's F, p and residual, the one chosen and
/// those dropped.
pub(super) fn rounds_table<E: Named>(rounds: &[Round<E>]) -> String {
    let mut s = String::from(
        "\n| round | candidate | F | p | residual RMS | chosen |\n|---|---|---|---|---|---|\n",
    );
    for (i, r) in rounds.iter().enumerate() {
        for c in &r.candidates {
            s += &format!(
                "| {} | {} | {:.1} | {:.1e} | {:.3e} | {} |\n",
                i + 1,
                c.effect.label(),
                c.f,
                c.p,
                c.residual_rms,
                if r.chosen == Some(c.effect) {
                    "yes"
                } else {
                    ""
                }
            );
        }
        for e in r.removed.iter().flatten() {
            s += &format!("| {} | {} | | | | dropped |\n", i + 1, e.label());
        }
    }
    s
}

/// `name = value +- std, ...` of an effect's parameters, the values with `digits` decimals.
pub(super) fn param_list(names: &[&str], values: &[f64], std: &[f64], digits: usize) -> String {
    let v: Vec<String> = names
        .iter()
        .zip(values.iter().zip(std.iter()))
        .map(|(n, (v, sd))| format!("{n} = {v:.digits$e} +- {sd:.1e}"))
        .collect();
    v.join(", ")
}

/// The effects' names joined, or `none`.
pub(super) fn names_or_none(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

/// The report's last line: how far the tensor moved, in percent with `digits` decimals.
pub(super) fn moved_line(change: f64, digits: usize) -> String {
    format!(
        "\nThe tensor moved by {:.digits$} % (Frobenius) from before to after.\n",
        100.0 * change
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Copy, Debug, PartialEq)]
    enum E {
        A,
        B,
    }

    impl Named for E {
        fn label(self) -> String {
            format!("{self:?}")
        }
    }

    /// Fits given by a table: the RSS of each set of effects over 300 rows, `A` with `pa`
    /// parameters and `B` with `pb`.
    struct Table {
        rss: [f64; 4],
        pa: usize,
        pb: usize,
    }

    impl Table {
        /// `rss` is indexed by (A in the model) + 2 (B in the model).
        fn at(&self, effects: &[E]) -> Fit {
            let (a, b) = (effects.contains(&E::A), effects.contains(&E::B));
            let k = 6 + usize::from(a) * self.pa + usize::from(b) * self.pb;
            Fit {
                theta: vec![0.0; k],
                cov: vec![vec![0.0; k]; k],
                xtx_inv: vec![vec![0.0; k]; k],
                rss: self.rss[usize::from(a) + 2 * usize::from(b)],
                n: 300,
                residuals: Vec::new(),
            }
        }
    }

    impl Candidates for Table {
        type Effect = E;
        type Fit = Fit;

        fn fit(&self, effects: &[E], _: &Fit) -> Option<Fit> {
            Some(self.at(effects))
        }

        fn ls(fit: &Fit) -> &Fit {
            fit
        }

        fn params(&self, _: &Fit, _: E) -> (Vec<f64>, Option<Vec<f64>>) {
            (Vec::new(), None)
        }
    }

    fn run(t: &Table, alpha: f64, rank: Rank, steps: Steps) -> Selection<E, Fit> {
        select(t, t.at(&[]), &[E::A, E::B], &Rules { alpha, rank, steps })
    }

    #[test]
    fn the_largest_f_and_the_smallest_p_can_choose_differently() {
        // A: one parameter, F about 30; B: six parameters, F about 20 but the smaller p-value.
        let t = Table {
            rss: [100.0, 90.71, 70.59, 70.0],
            pa: 1,
            pb: 6,
        };
        let by_f = run(&t, 1e-3, Rank::LargestF, Steps::Forward);
        let by_p = run(&t, 1e-3, Rank::SmallestP, Steps::Forward);
        let round1 = &by_f.rounds[0].candidates;
        assert!(
            round1[0].f > round1[1].f && round1[1].p < round1[0].p,
            "{round1:?}"
        );
        assert_eq!(by_f.rounds[0].chosen, Some(E::A));
        assert_eq!(by_p.rounds[0].chosen, Some(E::B));
        assert!(by_f.rounds.iter().all(|r| r.removed.is_none()));
    }

    #[test]
    fn the_backward_step_drops_an_effect_the_next_one_explains() {
        // B alone has the larger F (one parameter against A's six); with A in the model it adds
        // nothing.
        let t = Table {
            rss: [100.0, 58.0, 60.0, 57.95],
            pa: 6,
            pb: 1,
        };
        let back = run(
            &t,
            0.5,
            Rank::LargestF,
            Steps::ForwardBackward { max_rounds: 8 },
        );
        assert_eq!(back.rounds[0].chosen, Some(E::B));
        assert_eq!(back.rounds[1].chosen, Some(E::A));
        assert_eq!(back.rounds[1].removed, Some(vec![E::B]));
        assert_eq!(back.chosen, [E::A]);
        // The last round tries B again and stops: nothing significant, nothing dropped.
        let last = back.rounds.last().unwrap();
        assert_eq!(
            (last.chosen, last.removed.as_deref()),
            (None, Some(&[][..]))
        );
        let fwd = run(&t, 0.5, Rank::LargestF, Steps::Forward);
        assert_eq!(fwd.chosen, [E::B, E::A]);
    }
}
