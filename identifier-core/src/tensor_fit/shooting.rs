//! Multiple shooting ((F11) of the module docs): one tensor shared by consecutive segments of
//! a flight, each segment integrated from its own initial rate.
//!
//! The single trajectory of (F1) carries any unmodelled torque along the whole flight: a
//! small one accumulates into a rate error that grows with time, and the fit bends `J` to
//! follow it. Restarting the trajectory at every segment (its initial rate a parameter of its
//! own) keeps what a model error can accumulate to one segment's length, while `J`, shared,
//! still sees every segment's dynamics. With `S` segments the parameters are the six entries
//! and `3 S` initial rates:
//!
//! ```text
//! F_s = [[A_s, B_s], [B_s^T, C_s]]    (segment s: entries, its initial rate)
//! A = sum_s (A_s - B_s C_s^-1 B_s^T),   g = sum_s g_s,
//! g_s = g_J,s - B_s C_s^-1 g_w,s                                                   (F11)
//! ```
//!
//! the Gauss-Newton equations of the entries with every initial rate eliminated (the Schur
//! complement); each evaluation first takes Gauss-Newton steps of every segment's initial
//! rate with the entries held (while they lower the segment's cost), so the Levenberg-
//! Marquardt loop of `output_error` runs on the six entries alone (variable projection). Each
//! segment is an ordinary stretch for [`normal`] (its own first block, the rotor momentum from
//! its own blocks).
//!
//! The covariance is the sandwich over the segments ((F10) with the segments as its batches):
//! the reduced scores `g_s` of neighbouring segments share no trajectory, so `V = S/(S-1) sum_s
//! g_s g_s^T` estimates the score's covariance from the residual actually seen, its level and
//! its correlation within a segment alike; never less than the first-order autoregressive
//! inflation of the segments' own residual. The caller ([`fit_stretch`]) holds it at least at
//! the single trajectory's covariance: the sandwich sees the residual within one flight, not
//! what moves a whole flight's answer.

use super::*;
use core::cell::Cell;

/// Most segments of one flight.
const MAX_SEGMENTS: usize = 32;

/// Fewest blocks in a segment: its initial rate is three parameters.
const MIN_SEGMENT_BLOCKS: usize = 4;

/// Fewest segments a flight is cut into (the sandwich's batches).
const MIN_SEGMENTS: usize = 8;

/// Most Gauss-Newton steps of a segment's initial rate per evaluation of the entries.
const INNER_STEPS: usize = 4;

/// A segment's initial rate is taken as converged once a step lowers its cost by at most
/// this share of it.
const INNER_GAIN: f32 = 1e-4;

/// Block ranges of the segments.
#[derive(Clone, Copy)]
struct Segments {
    bounds: [(usize, usize); MAX_SEGMENTS],
    count: usize,
}

impl Segments {
    /// `n` blocks cut into segments of `len` blocks (the last takes the remainder), at least
    /// [`MIN_SEGMENT_BLOCKS`] long and at most [`MAX_SEGMENTS`] of them; `None` when fewer
    /// than [`MIN_SEGMENTS`] result.
    fn cut(n: usize, len: usize) -> Option<Segments> {
        let len = len
            .max(MIN_SEGMENT_BLOCKS)
            .max(n.div_ceil(MAX_SEGMENTS))
            .min(n / MIN_SEGMENTS);
        if len < MIN_SEGMENT_BLOCKS {
            return None;
        }
        let count = (n / len).min(MAX_SEGMENTS);
        let mut bounds = [(0, 0); MAX_SEGMENTS];
        for (s, b) in bounds.iter_mut().enumerate().take(count) {
            let hi = if s + 1 == count { n } else { (s + 1) * len };
            *b = (s * len, hi);
        }
        (count >= MIN_SEGMENTS).then_some(Segments { bounds, count })
    }

    fn ranges(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.bounds.iter().copied().take(self.count)
    }
}

/// Segment length in blocks for block residuals of lag-1 autocorrelation `rho` at a single
/// trajectory's optimum: the residual's [`correlation_length`], over which a model error is
/// one slow excursion.
fn segment_len(rho: f32) -> usize {
    // In [1, 99]: the cast of its ceiling is exact.
    (correlation_length(rho) + 0.999) as usize
}

/// What [`reduced`] leaves per segment for the covariance: its reduced score `g_s` of (F11)
/// and its cost.
struct SegmentSums {
    scores: [[f32; 6]; MAX_SEGMENTS],
    costs: [f32; MAX_SEGMENTS],
}

/// Entry `(i, j)` of `m`, 0 outside it.
fn at<const N: usize>(m: &Sym<N>, i: usize, j: usize) -> f32 {
    m.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0)
}

/// The six entries `j6` and an initial rate `w` as one segment's parameters.
fn with_rate(j6: &[f32; 6], w: [f32; 3]) -> [f32; P0] {
    let mut th = [0.0f32; P0];
    for (d, x) in th.iter_mut().zip(j6.iter().chain(w.iter())) {
        *d = *x;
    }
    th
}

/// A segment's initial rate (or its gradient) from its parameters.
fn rate_of_theta(th: &[f32; P0]) -> [f32; 3] {
    core::array::from_fn(|i| th.get(6 + i).copied().unwrap_or(0.0))
}

/// The entries' reduced normal equations (F11) at `j6`, the segments' initial rates taken
/// from and returned to `rates` (one Gauss-Newton step each, see the module docs), and each
/// segment's reduced score and cost into `sums` when given.
fn reduced(
    blocks: &[Block<6>],
    rule: &StepRule,
    segs: &Segments,
    j6: &[f32; 6],
    rates: &Cell<[[f32; 3]; MAX_SEGMENTS]>,
    mut sums: Option<&mut SegmentSums>,
) -> Option<Normal<6>> {
    let mut w0 = rates.get();
    let mut cost = 0.0f32;
    let mut a = [[0.0f32; 6]; 6];
    let mut g = [0.0f32; 6];
    for (s, (lo, hi)) in segs.ranges().enumerate() {
        let seg = blocks.get(lo..hi)?;
        let start = w0.get(s).copied().unwrap_or([0.0; 3]);
        let th = with_rate(j6, start);
        let first = normal::<P0>(seg, rule, seg.len(), &th, 0.0, &Cells::NONE)?;
        let rate_block = |f: &Sym<P0>| -> Sym<3> {
            core::array::from_fn(|i| core::array::from_fn(|k| at(f, 6 + i, 6 + k)))
        };
        // Gauss-Newton steps of the initial rate, the entries held, while they lower the
        // segment's cost by more than [`INNER_GAIN`] of it (at most [`INNER_STEPS`]).
        let mut best = (th, first);
        for _ in 0..INNER_STEPS {
            let (t, (c, f, gr)) = best;
            let Some(ci) = scaled_inverse(&rate_block(&f)) else {
                break;
            };
            let gw = rate_of_theta(&gr);
            let w = rate_of_theta(&t);
            let moved = with_rate(
                j6,
                core::array::from_fn(|i| w[i] + (0..3).map(|k| at(&ci, i, k) * gw[k]).sum::<f32>()),
            );
            match normal::<P0>(seg, rule, seg.len(), &moved, 0.0, &Cells::NONE) {
                Some(n2) if n2.0 < c => {
                    let gain = c - n2.0;
                    best = (moved, n2);
                    if gain <= INNER_GAIN * c {
                        break;
                    }
                }
                _ => break,
            }
        }
        let (th, (c, f, gs)) = best;
        if let Some(slot) = w0.get_mut(s) {
            *slot = rate_of_theta(&th);
        }
        // (F11): the initial rate eliminated.
        let ci = scaled_inverse(&rate_block(&f))?;
        // `B C^-1`, 6 x 3.
        let bc: [[f32; 3]; 6] = core::array::from_fn(|i| {
            core::array::from_fn(|k| (0..3).map(|l| at(&f, i, 6 + l) * at(&ci, l, k)).sum())
        });
        let gw = rate_of_theta(&gs);
        let score: [f32; 6] = core::array::from_fn(|i| {
            let bci = bc.get(i).copied().unwrap_or([0.0; 3]);
            let bcg: f32 = bci.iter().zip(gw).map(|(b, x)| b * x).sum();
            gs.get(i).copied().unwrap_or(0.0) - bcg
        });
        for (i, (row, gi)) in a.iter_mut().zip(g.iter_mut()).enumerate() {
            let bci = bc.get(i).copied().unwrap_or([0.0; 3]);
            for (jx, x) in row.iter_mut().enumerate() {
                let bcb: f32 = (0..3).map(|k| bci[k] * at(&f, jx, 6 + k)).sum();
                *x += at(&f, i, jx) - bcb;
            }
            *gi += score.get(i).copied().unwrap_or(0.0);
        }
        if let Some(out) = sums.as_deref_mut() {
            if let (Some(g), Some(cs)) = (out.scores.get_mut(s), out.costs.get_mut(s)) {
                *g = score;
                *cs = c;
            }
        }
        cost += c;
    }
    rates.set(w0);
    Some((cost, a, g))
}

/// The multiple-shooting fit (F11) of `blocks` from the tensor `init`, in segments of the
/// residual's correlation length at a single trajectory's optimum (`rho`, [`segment_len`]),
/// with the sandwich covariance over the segments; `None` when the flight is too short for
/// [`MIN_SEGMENTS`] segments or the fit fails.
pub(super) fn fit_segments(
    blocks: &[Block<6>],
    init: &Mat3,
    rho: f32,
    gyro_spread: f32,
) -> Option<StretchResult<6>> {
    let n = blocks.len();
    let segs = &Segments::cut(n, segment_len(rho))?;
    let rule = StepRule::new(init).with_gyro_spread(gyro_spread);
    let mut start = [[0.0f32; 3]; MAX_SEGMENTS];
    for (slot, (lo, _)) in start.iter_mut().zip(segs.ranges()) {
        *slot = rate_of(blocks.get(lo)?);
    }
    let rates = Cell::new(start);
    let params = 6 + 3 * segs.count;
    let dof = (3 * n) as f32 - params as f32;
    let j6 = [
        init[0][0], init[1][1], init[2][2], init[0][1], init[0][2], init[1][2],
    ];
    let (j6, _, _) = levenberg(
        |p| reduced(blocks, &rule, segs, p, &rates, None),
        j6,
        30,
        dof,
        TOLERANCE,
        Start::Cold,
    )?;
    let mut sums = SegmentSums {
        scores: [[0.0; 6]; MAX_SEGMENTS],
        costs: [0.0; MAX_SEGMENTS],
    };
    let (cost, a, _) = reduced(blocks, &rule, segs, &j6, &rates, Some(&mut sums))?;
    let ainv = scaled_inverse(&a)?;
    // The residual's lag-1 autocorrelation within the segments (their rates at the optimum),
    // each segment's weighted by its cost.
    let w0 = rates.get();
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for (s, ((lo, hi), c)) in segs.ranges().zip(sums.costs).enumerate() {
        let seg = blocks.get(lo..hi)?;
        let r = w0.get(s).copied().unwrap_or([0.0; 3]);
        let rho = residual_lag1(seg, &rule, &with_rate(&j6, r), 0.0, &Cells::NONE);
        num += rho * c;
        den += c;
    }
    let ar1 = correlation_length(if den > 0.0 { num / den } else { 0.0 });
    // (F10) over the segments: `A^-1 V A^-1` against the white `s^2 A^-1`.
    let k = segs.count as f32;
    let s2 = if dof > 0.0 { cost / dof } else { 0.0 };
    let inflation: [f32; 6] = core::array::from_fn(|i| {
        let mut seen = 0.0f32;
        for sc in sums.scores.iter().take(segs.count) {
            let x: f32 = sc
                .iter()
                .enumerate()
                .map(|(c, v)| at(&ainv, i, c) * v)
                .sum();
            seen += x * x;
        }
        inflation_of(seen * k / (k - 1.0), s2 * at(&ainv, i, i), ar1)
    });
    Some(StretchResult {
        p: j6,
        cov: inflated(&ainv, &inflation),
        input: None,
        cost,
        params,
        bias: None,
        lag1: 0.0,
        coloured: false,
        torque: None,
        scale: false,
        alt: None,
        walk: None,
    })
}
