//! The identifier itself: one step of (3), (7), (12) per gyro sample.
//!
//! # Discretisation
//!
//! For `Phi` of (9) the controls (7) reduce to `alpha' = |w1 w2 w3| C Delta` with
//! `Delta = alpha - Phi`, which is exactly the estimate (12). Differentiating (12) along the
//! motion gives, on an interval where `s = sgn(w1 w2 w3)` is constant,
//!
//! ```text
//! Delta' = |w1 w2 w3| C Delta - 1/2 s C (w1^2, w2^2, w3^2)'
//! ```
//!
//! and the step integrates this form, not alpha:
//!
//! * the drive term uses the *measured difference* of the squares between samples, which is
//!   exact: no derivative is approximated, so no discretisation bias enters through it;
//! * the `|w1 w2 w3| C Delta` term is integrated by the implicit trapezoidal rule with the
//!   Euler-Maclaurin end correction, `integral f = h/2 (f0 + f1) + h^2/12 (f0' - f1')`, with
//!   `f' = |p|' C Delta` and `|p|' = s (a1 (w2 w3)^2 + a2 (w3 w1)^2 + a3 (w1 w2)^2)` from (1)
//!   at the current estimate (along (1) `Delta' = 0` at `Delta = a`): fourth order on the
//!   quantity that sets the estimate's fixed point, `integral |p| dt`, and stable for any gain
//!   and step (`I - k C` is invertible for Hurwitz `C` and `k >= 0`; the correction only
//!   changes the two weights `k`). The correction comes from the model at the estimate, not
//!   from the data, so it is used only while it is small against the step and leaves both
//!   weights non-negative; otherwise (junk samples, long steps, an estimate thrown far off) the
//!   step is the plain trapezoid. Unguarded, it grows with the estimate and feeds back: a few
//!   junk samples threw `Delta` to `1e9` and beyond, and clean data never brought it back.
//!
//! A forward-Euler update of alpha leaves a bias near `1e-3` at 1 kHz; this scheme's noise-free
//! error is below `3e-5` from 100 Hz to 1 kHz on every body tested (`1e-5` at 100 Hz; host test
//! `settings_for_rate`); above 1 kHz the `f32` rounding of many small increments dominates
//! (`8e-5` at 4 kHz, `1.8e-4` at 8 kHz). Storing `Delta` rather than alpha also keeps the
//! small increments of the estimate from being rounded away against the large `Phi` in `f32`.
//! alpha itself is recovered as `Delta + Phi` by [`Identifier::alpha`].
//!
//! # Sign changes and identifiability
//!
//! On a step across a sign change of `w1 w2 w3`, the crossing instant is found on the cubic
//! Hermite interpolant of omega (end slopes from (1) at the current estimate; a linear
//! interpolation leaves a second-order error in the split of the drive term, `2.6e-3` of bias
//! at 100 Hz; under the same kind of guard, the linear one is kept where the cubic's slopes
//! disagree with the chord) and the drive term is split there, each part with its own sign.
//! This is the paper's correction: alpha is shifted by the jump of `Phi` taken with the
//! opposite sign, which in `Delta` coordinates means `Delta` does not jump. Where (2) fails the
//! estimate is held and the integration restarts at the next identifiable sample with alpha
//! re-initialised to `Delta + Phi`: the same correction applied across a whole unidentifiable
//! stretch.

use crate::convergence::{Convergence, ConvergenceMonitor};
use crate::invariant::{phi, phi_of_squares, sign, squares, triple_product};
use crate::linalg::{mul_vec, solve};
use crate::settings::{Settings, SettingsError, SignChangeCorrection};
use crate::status::{
    ln_approx, Counters, Estimate, Exposure, SampleStatus, Status, Verdict, MIN_SAMPLES,
};

/// The last sample the integration runs from.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Anchor {
    omega: [f32; 3],
    p: f32,
}

/// The identifier's whole state: a fixed-size value, no heap, no buffers
/// (`core::mem::size_of::<Identifier>()`: 216 bytes on x86_64, settings and the
/// [`Exposure`] of [`Identifier::trust`] included).
///
/// ```
/// use identifier_core::{Identifier, SampleStatus, Settings};
///
/// // The paper's identifier with C = -3 E; a NaN sample is refused and changes nothing.
/// let mut id = Identifier::new(Settings::with_lambda(3.0)).unwrap();
/// id.step([1.0, 1.0, 1.0], 1e-3);
/// let before = id.estimate();
/// assert_eq!(id.step([f32::NAN, 1.0, 1.0], 1e-3).status, SampleStatus::NonFinite);
/// assert_eq!(id.estimate(), before);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identifier {
    settings: Settings,
    /// `Delta = alpha - Phi`, i.e. the estimate (12).
    delta: [f32; 3],
    anchor: Option<Anchor>,
    /// Time since the anchor that belongs to samples which were rejected.
    pending_dt: f32,
    /// `sgn(w1 w2 w3)` at the last integrated sample (0 before the first).
    branch: f32,
    monitor: ConvergenceMonitor,
    counters: Counters,
    /// What the data offered (for [`Identifier::trust`]).
    exposure: Exposure,
    /// Excitation `E` needed before the estimate has forgotten its initial value
    /// (see [`Identifier::trust`]).
    excitation_needed: f32,
}

impl Identifier {
    /// A new identifier; refuses settings that fail [`Settings::validate`].
    pub fn new(settings: Settings) -> Result<Self, SettingsError> {
        settings.validate()?;
        Ok(Self::fresh(settings))
    }

    /// The state before the first sample, for settings already validated.
    fn fresh(settings: Settings) -> Self {
        Identifier {
            settings,
            delta: settings.initial_estimate,
            anchor: None,
            pending_dt: 0.0,
            branch: 0.0,
            monitor: ConvergenceMonitor::new(),
            counters: Counters::default(),
            exposure: Exposure::new(),
            excitation_needed: excitation_needed(&settings),
        }
    }

    /// Forgets everything learnt and starts again from the settings' initial estimate.
    pub fn reset(&mut self) {
        *self = Self::fresh(self.settings);
    }

    /// Forgets the last sample (a new toss, a new log) but keeps the estimate and counters, so
    /// that identification carries on from what earlier data taught.
    pub fn restart(&mut self) {
        self.anchor = None;
        self.pending_dt = 0.0;
    }

    /// One identifier step for the gyro sample `omega` (rad/s, sensor axes) taken `dt` seconds
    /// after the previous call.
    ///
    /// Runs (3) with the controls (7), applies the sign-change correction and returns the
    /// estimate (12) (with `C = -lambda E`, (14)). Never panics; for every input the returned
    /// [`SampleStatus`] says what happened and the state stays finite.
    pub fn step(&mut self, omega: [f32; 3], dt: f32) -> Estimate {
        let status = self.advance(omega, dt);
        self.counters.record(status);
        Estimate {
            a: self.delta,
            status,
            convergence: self.monitor.verdict(self.settings.h),
            trust: self.trust(),
        }
    }

    /// How far the estimate can be trusted ([`Status`], by [`Status::assess`]). The paper's
    /// identifier has no standard deviation of its own, so this is a **weaker** verdict than
    /// [`crate::Refined::trust`]'s, derived from:
    ///
    /// * enough: at least `MIN_SAMPLES` accepted samples (identifiable or not: a stretch
    ///   where (2) fails is judged by the excitation below);
    /// * excited: the excitation `E = integral |w1 w2 w3| dt` over integrated intervals
    ///   satisfies `lambda E >= ln(1 / eps)`, `lambda = -trace(C) / 3` (for `C = -lambda E`
    ///   exactly the decay rate of (13)): by (10) the mismatch decays as `exp(-lambda E)`, so
    ///   only then has an initial error of up to 1 (any `|a_i| < 1` from a zero start) shrunk
    ///   below `eps`;
    /// * settled: the paper's criterion (section 4) holds ([`Identifier::convergence`]);
    /// * possible: judged only once settled (before, the estimate is in transit): every
    ///   `|a_i| < 1 + eps` and `|a1 + a2 + a3 + a1 a2 a3| <= 6 eps` (each `a_i` within `eps`
    ///   moves the consistency value by at most `2 eps`, `|1 + a_j a_k| <= 2`).
    ///
    /// Weaker because the criterion measures stillness, not error: on noisy data the estimate
    /// (12) carries the noise of the current sample and a bias the criterion cannot see; use
    /// [`crate::Refined`] for a trust backed by a standard deviation.
    pub fn trust(&self) -> Status {
        let s = &self.settings;
        let settled = self.monitor.verdict(s.h) == Convergence::Converged;
        let a = self.delta;
        let possible = !settled
            || (a.iter().all(|x| x.abs() < 1.0 + s.eps)
                && crate::inertia::consistency(a).abs() <= 6.0 * s.eps);
        let verdict = Verdict {
            enough: self.exposure.accepted >= MIN_SAMPLES,
            excited: self.exposure.excitation >= self.excitation_needed,
            possible,
            settled,
        };
        Status::assess(&self.exposure, verdict)
    }

    /// What the data offered so far (counts, peak rate, excitation `E`).
    pub fn exposure(&self) -> &Exposure {
        &self.exposure
    }

    /// The current estimate `(a1, a2, a3)` of (12).
    pub fn estimate(&self) -> [f32; 3] {
        self.delta
    }

    /// The auxiliary state alpha of (3) at the last accepted sample: `alpha = Delta + Phi` by
    /// (5) with `eta = 0`. Before the first sample `Phi` is taken as zero.
    pub fn alpha(&self) -> [f32; 3] {
        let f = match self.anchor {
            Some(a) => phi(&self.settings.gain, sign(a.p), a.omega),
            None => [0.0; 3],
        };
        [
            self.delta[0] + f[0],
            self.delta[1] + f[1],
            self.delta[2] + f[2],
        ]
    }

    /// The paper's criterion at this moment.
    pub fn convergence(&self) -> Convergence {
        self.monitor.verdict(self.settings.h)
    }

    /// The criterion's internals: how long the estimate has stayed within `2 eps`.
    pub fn monitor(&self) -> &ConvergenceMonitor {
        &self.monitor
    }

    /// Counts of sample outcomes since creation or [`Identifier::reset`].
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// The settings in force.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    fn advance(&mut self, omega: [f32; 3], dt: f32) -> SampleStatus {
        // Without a trustworthy dt the interval to the anchor is unknown: restart from the next
        // sample rather than integrate over a guessed time.
        if !(dt.is_finite() && dt > 0.0) {
            self.restart();
            return SampleStatus::InvalidTimeStep;
        }
        // A refused sample keeps its time, so the next good sample integrates over the whole
        // interval since the anchor (or is declared a gap if that is too long).
        if !omega.iter().all(|w| w.is_finite()) {
            self.pending_dt += dt;
            return SampleStatus::NonFinite;
        }
        if omega.iter().any(|w| w.abs() >= self.settings.full_scale) {
            self.pending_dt += dt;
            self.exposure.saturate();
            return SampleStatus::Saturated;
        }
        self.exposure.accept(omega);
        let elapsed = self.pending_dt + dt;
        self.pending_dt = 0.0;
        let p = triple_product(omega);
        if !p.is_finite() {
            self.anchor = None;
            return SampleStatus::NumericalFault;
        }
        let new = Anchor { omega, p };
        let Some(prev) = self.anchor.replace(new) else {
            return SampleStatus::Anchored;
        };
        // `elapsed` is a sum of finite positive steps: never NaN, at worst +inf (a gap).
        if elapsed > self.settings.max_dt {
            return SampleStatus::Gap;
        }
        let w_min = self.settings.w_min;
        let identifiable = |p: f32| p != 0.0 && p.abs() >= w_min;
        if !(identifiable(prev.p) && identifiable(p)) {
            return SampleStatus::Unidentifiable;
        }
        let status = self.integrate(prev, new, elapsed);
        if status.integrated() {
            self.exposure.excite(prev.p, p, elapsed);
        }
        status
    }

    /// Implicit trapezoidal step of `Delta' = |p| C Delta - 1/2 s C q'` from `prev` to `new`.
    fn integrate(&mut self, prev: Anchor, new: Anchor, h: f32) -> SampleStatus {
        let c = self.settings.gain.rows();
        let (s0, s1) = (sign(prev.p), sign(new.p));
        let (q0, q1) = (squares(prev.omega), squares(new.omega));
        let (k0, k1) = (prev.p.abs(), new.p.abs());

        // Weights of the trapezoid for the integral of |p| C Delta, and the signed increment
        // of the squares, s dq, for the drive term.
        let (w0, w1, sdq, q_cross) = if s0 == s1 {
            let sdq = [
                s1 * (q1[0] - q0[0]),
                s1 * (q1[1] - q0[1]),
                s1 * (q1[2] - q0[2]),
            ];
            let (w0, w1) = end_corrected(h, prev, new, self.delta);
            (w0, w1, sdq, q1)
        } else {
            // p is close to linear between the samples: it crosses zero at the fraction
            // theta of the step. |p| is then two triangles, and the squares are split at the
            // interpolated omega, each part taken with its own sign: the sign-change
            // correction, so the estimate does not jump.
            let (theta, mid) = crossing(prev, new, h, self.delta);
            let qm = squares(mid);
            let sdq = [
                s0 * (qm[0] - q0[0]) + s1 * (q1[0] - qm[0]),
                s0 * (qm[1] - q0[1]) + s1 * (q1[1] - qm[1]),
                s0 * (qm[2] - q0[2]) + s1 * (q1[2] - qm[2]),
            ];
            let w0 = 0.5 * h * theta * k0;
            let w1 = 0.5 * h * (1.0 - theta) * k1;
            (w0, w1, sdq, qm)
        };

        // The branch of (9) changed since the last integrated sample: during this step, or
        // during the unidentifiable stretch before it.
        let crossed = self.branch != 0.0 && s1 != self.branch;
        let mut d = self.delta;
        if self.settings.sign_change == SignChangeCorrection::Disabled {
            // The uncorrected scheme keeps alpha continuous, so the estimate (12) takes the
            // jump of Phi with the opposite sign at each change of branch.
            if self.branch != 0.0 && s0 != self.branch {
                let jump = phi_of_squares(self.settings.gain.rows(), s0 - self.branch, q0);
                sub_assign(&mut d, jump);
            }
            if s0 != s1 {
                let jump = phi_of_squares(self.settings.gain.rows(), s1 - s0, q_cross);
                sub_assign(&mut d, jump);
            }
        }

        let cd = mul_vec(c, d);
        let cdq = mul_vec(c, sdq);
        let r = [
            d[0] + w0 * cd[0] - 0.5 * cdq[0],
            d[1] + w0 * cd[1] - 0.5 * cdq[1],
            d[2] + w0 * cd[2] - 0.5 * cdq[2],
        ];
        let m = [
            [1.0 - w1 * c[0][0], -w1 * c[0][1], -w1 * c[0][2]],
            [-w1 * c[1][0], 1.0 - w1 * c[1][1], -w1 * c[1][2]],
            [-w1 * c[2][0], -w1 * c[2][1], 1.0 - w1 * c[2][2]],
        ];
        let Some(next) = solve(&m, r) else {
            return SampleStatus::NumericalFault;
        };
        self.delta = next;
        self.branch = s1;
        let s = &self.settings;
        self.monitor.observe(next, h, s.eps, s.h);
        if crossed {
            SampleStatus::SignChange
        } else {
            SampleStatus::Updated
        }
    }
}

/// `ln(1 / eps) / lambda`, `lambda = -trace(C) / 3`: the excitation `E` after which (10)
/// has shrunk an initial error of 1 below `eps` (see [`Identifier::trust`]).
fn excitation_needed(settings: &Settings) -> f32 {
    let c = settings.gain.rows();
    let lambda = -(c[0][0] + c[1][1] + c[2][2]) / 3.0;
    let need = ln_approx(1.0 / settings.eps) / lambda;
    if need.is_finite() && need > 0.0 {
        need
    } else {
        0.0
    }
}

/// How large a model-based higher-order term may be against the second-order quantity it
/// refines before the step falls back to the second-order scheme (see [`end_corrected`] and
/// [`crossing`]). On clean data the end correction reaches about `1/6` of the step's integral
/// (next to a sign change, where `|p|` rises almost linearly from near zero: `h^2/12 |p|'`
/// against `h/2 |p1|`; at most `0.164` over the nine bodies of the host test
/// `settings_for_rate`, 100 Hz to 8 kHz) and the cubic's slope terms `~ (h |w|)^2 / 2` of `|w|`
/// (`1.5e-2` at 100 Hz). Junk samples (rates unrelated to the previous sample, long steps) or
/// an estimate thrown far off make them of order one or far larger.
const RESOLVED: f32 = 0.5;

/// The weights `(w0, w1)` of the integral of `|p| C Delta` over a step of length `h` on which
/// `p` keeps its sign: `integral ~ w0 C Delta(t0) + w1 C Delta(t1)`.
///
/// The trapezoid `h/2 |p|` at each end plus the Euler-Maclaurin end correction
/// `h^2/12 (f'(t0) - f'(t1))` for `f = |p| C Delta`: along (1) `Delta' = 0` at `Delta = a`, so
/// `f' = |p|' C Delta` with `|p|' = s p'` from (1) at the current estimate `a` (`p_rate`).
///
/// Stability guard: the correction is taken from the model at the *estimate*, not from the
/// data, so it is only a refinement while it is small against the step. Unchecked, a junk
/// sample (rates unrelated to the previous one, a long step) or an estimate already thrown far
/// off makes it of order one or larger: a weight turns negative (`I - w1 C` near singular,
/// `I + w0 C` amplifying), and since it grows with the estimate it feeds back: `|Delta|` of
/// `1e9` and more after a few junk samples, and on clean data afterwards the corrections
/// `~ h^2/12 |Delta| |w|^4`, far larger than the trapezoid weights, turn the damping of the
/// step into a slow growth, so it never recovers. So the corrected
/// weights are used only if both are non-negative and each correction is at most [`RESOLVED`]
/// times the trapezoid integral `h/2 (|p0| + |p1|)`; otherwise the plain trapezoid, bounded by
/// the data alone and stable for any step (as before the correction). Clean data never meet
/// the guard (see [`RESOLVED`]), so the noise-free figures are those of the corrected scheme.
fn end_corrected(h: f32, prev: Anchor, new: Anchor, a: [f32; 3]) -> (f32, f32) {
    let (t0, t1) = (0.5 * h * prev.p.abs(), 0.5 * h * new.p.abs());
    let e = h * h * (1.0 / 12.0);
    let c0 = e * sign(prev.p) * p_rate(prev.omega, a);
    let c1 = e * sign(new.p) * p_rate(new.omega, a);
    let (w0, w1) = (t0 + c0, t1 - c1);
    let bound = RESOLVED * (t0 + t1);
    // Written so that a NaN (an overflowing `p_rate` without a full scale) falls back too.
    if c0.abs() <= bound && c1.abs() <= bound && w0 >= 0.0 && w1 >= 0.0 {
        (w0, w1)
    } else {
        (t0, t1)
    }
}

/// The zero crossing of `p = w1 w2 w3` between `prev` and `new` (opposite signs), as the
/// fraction `theta` of the step and the angular velocity there. Between the samples omega is
/// the cubic Hermite interpolant with end slopes from (1) at the estimate `a` (third order,
/// so the drive split at the crossing carries no second-order error); its root is bracketed
/// by false position from the linear guess `|p0| / (|p0| + |p1|)`, three iterations.
///
/// Stability guard: the cubic is the chord `w0 + t (w1 - w0)` plus the differences of the end
/// slopes `m` from the chord weighted by at most `4/27`. The slopes come from the model at the
/// estimate, so on junk samples or with an estimate thrown far off they are unrelated to the
/// data and grow with the estimate: the interpolated omega, hence the drive split at the
/// crossing, would kick `Delta` by an amount that grows with `Delta` itself. The cubic is
/// used only if every `|m - (w1 - w0)|` is at most [`RESOLVED`] times the largest `|w|` of the
/// two samples (on a resolved step it is `~ (h |w|)^2 / 2` of it); otherwise the linear
/// interpolation, which keeps omega between the two samples.
fn crossing(prev: Anchor, new: Anchor, h: f32, a: [f32; 3]) -> (f32, [f32; 3]) {
    let (w0, w1) = (prev.omega, new.omega);
    let linear = |t: f32| -> [f32; 3] {
        [
            w0[0] + t * (w1[0] - w0[0]),
            w0[1] + t * (w1[1] - w0[1]),
            w0[2] + t * (w1[2] - w0[2]),
        ]
    };
    let theta_linear = prev.p.abs() / (prev.p.abs() + new.p.abs());
    let slope = |w: [f32; 3]| {
        [
            h * a[0] * w[1] * w[2],
            h * a[1] * w[2] * w[0],
            h * a[2] * w[0] * w[1],
        ]
    };
    let (m0, m1) = (slope(w0), slope(w1));
    let scale = w0
        .iter()
        .chain(w1.iter())
        .fold(0.0f32, |acc, x| acc.max(x.abs()));
    let bound = RESOLVED * scale;
    // Written so that a NaN falls back too.
    let agrees = |m: [f32; 3]| {
        m.iter()
            .zip(w0.iter().zip(w1.iter()))
            .all(|(m, (x0, x1))| (m - (x1 - x0)).abs() <= bound)
    };
    if !(agrees(m0) && agrees(m1)) {
        return (theta_linear, linear(theta_linear));
    }
    let at = |t: f32| -> [f32; 3] {
        let t2 = t * t;
        let t3 = t2 * t;
        let h00 = 2.0 * t3 - 3.0 * t2 + 1.0;
        let h10 = t3 - 2.0 * t2 + t;
        let h01 = 3.0 * t2 - 2.0 * t3;
        let h11 = t3 - t2;
        [
            h00 * w0[0] + h10 * m0[0] + h01 * w1[0] + h11 * m1[0],
            h00 * w0[1] + h10 * m0[1] + h01 * w1[1] + h11 * m1[1],
            h00 * w0[2] + h10 * m0[2] + h01 * w1[2] + h11 * m1[2],
        ]
    };
    let (mut lo, mut p_lo, mut hi, mut p_hi) = (0.0f32, prev.p, 1.0f32, new.p);
    let mut theta = lo + (hi - lo) * p_lo / (p_lo - p_hi);
    for _ in 0..3 {
        let pm = triple_product(at(theta));
        if !(pm.is_finite() && pm != 0.0) {
            break;
        }
        if sign(pm) == sign(p_lo) {
            (lo, p_lo) = (theta, pm);
        } else {
            (hi, p_hi) = (theta, pm);
        }
        theta = lo + (hi - lo) * p_lo / (p_lo - p_hi);
    }
    if !(theta.is_finite() && (0.0..=1.0).contains(&theta)) {
        // Not reachable with finite samples of opposite sign; the linear guess is safe.
        return (theta_linear, linear(theta_linear));
    }
    (theta, at(theta))
}

/// `p' = (w1 w2 w3)' = a1 (w2 w3)^2 + a2 (w3 w1)^2 + a3 (w1 w2)^2` along (1) with the
/// estimate `a`.
fn p_rate(w: [f32; 3], a: [f32; 3]) -> f32 {
    let f = [w[1] * w[2], w[2] * w[0], w[0] * w[1]];
    a[0] * f[0] * f[0] + a[1] * f[1] * f[1] + a[2] * f[2] * f[2]
}

fn sub_assign(d: &mut [f32; 3], x: [f32; 3]) {
    for (di, xi) in d.iter_mut().zip(x.iter()) {
        *di -= xi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_motion::{motion, A};

    fn max_err(a: [f32; 3]) -> f32 {
        (0..3).map(|i| (a[i] - A[i]).abs()).fold(0.0, f32::max)
    }

    /// Junk sample pairs: rates up to 35 rad/s unrelated to each other, one component
    /// sometimes tiny, steps from 0.2 ms to `max_dt`.
    fn junk_pairs() -> impl Iterator<Item = (Anchor, Anchor, f32)> {
        let mut x = 0x2545_f491_u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as f32 / u32::MAX as f32
        };
        (0..20_000).map(move |_| {
            let mut w = [[0.0f32; 3]; 2];
            for s in &mut w {
                for c in s.iter_mut() {
                    *c = 70.0 * next() - 35.0;
                    if next() < 0.1 {
                        *c *= 1e-4;
                    }
                }
            }
            let h = 2e-4 + 0.1 * next() * next();
            let anchor = |w: [f32; 3]| Anchor {
                omega: w,
                p: triple_product(w),
            };
            (anchor(w[0]), anchor(w[1]), h)
        })
    }

    #[test]
    fn guarded_terms_are_bounded_by_the_data_for_any_estimate() {
        for a in [A, [1e9, -1e9, 1e9], [-3e4, 2e4, 5e4], [0.0; 3]] {
            for (prev, new, h) in junk_pairs() {
                if sign(prev.p) == sign(new.p) {
                    let (t0, t1) = (0.5 * h * prev.p.abs(), 0.5 * h * new.p.abs());
                    let (w0, w1) = end_corrected(h, prev, new, a);
                    // RESOLVED = 0.5: no end gets more than half the step's trapezoid integral.
                    let most = 0.5 * (t0 + t1);
                    assert!(
                        (0.0..=t0 + most).contains(&w0),
                        "{prev:?} {new:?} {h} {a:?}"
                    );
                    assert!(
                        (0.0..=t1 + most).contains(&w1),
                        "{prev:?} {new:?} {h} {a:?}"
                    );
                } else if prev.p != 0.0 && new.p != 0.0 {
                    let (theta, mid) = crossing(prev, new, h, a);
                    let scale = prev
                        .omega
                        .iter()
                        .chain(new.omega.iter())
                        .fold(0.0f32, |m, x| m.max(x.abs()));
                    assert!((0.0..=1.0).contains(&theta));
                    // The chord plus two slope terms of at most RESOLVED |w| = |w| / 2 each,
                    // weighted by at most 4/27.
                    let most = scale * (1.0 + 4.0 / 27.0) * 1.000_1;
                    assert!(mid.iter().all(|m| m.abs() <= most), "{mid:?} {scale} {a:?}");
                }
            }
        }
    }

    /// From an estimate thrown far off (as junk samples can), clean data bring it back at the
    /// rate of (10): the end correction and the cubic crossing, taken from the model at that
    /// estimate, must not keep it there. Without the guards every one of these stayed near its
    /// start (errors `5e7` to `1e10` after the 30 s).
    #[test]
    fn forgets_an_estimate_thrown_far_off() {
        for far in [
            [1e8, -1e8, 1e8],
            [1e8, 1e8, 1e8],
            [-1e8, -1e8, -1e8],
            [3e7, -2e7, 1e7],
            [1e9, 0.0, 0.0],
        ] {
            let mut id = Identifier::new(Settings {
                initial_estimate: far,
                ..Settings::with_lambda(3.0)
            })
            .unwrap();
            for w in motion(30_000, 1e-3) {
                id.step(w, 1e-3);
            }
            assert!(
                max_err(id.estimate()) < 1e-4,
                "{far:?}: {:?}",
                id.estimate()
            );
        }
    }
}
