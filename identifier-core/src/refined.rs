//! A refined on-board identifier: (1) integrated, every sample used, no derivatives, no
//! sign-change restarts, and the integral's own noise accounted for.
//!
//! # Why
//!
//! The paper's identifier with `C = -lambda E` low-passes the instantaneous ratio
//! `(w_i^2)' / (2 w1 w2 w3)` with the weight `|w1 w2 w3|` (see (13)-(14)). With a gain that
//! decays like `1 / (information so far)` its estimate telescopes to differences of `w_i^2`
//! between sign changes of `w1 w2 w3`: the information enters through a few noisy end points,
//! and on noisy data the plain identifier stays far above the Cramer-Rao bound.
//!
//! # What this module does instead
//!
//! Equation (1) integrated from the start `t0` of a stretch of data to every later sample `t`
//! is exact and contains no derivative:
//!
//! ```text
//! w_i(t) = c_i + a_i G_i(t),    G_i(t) = integral_t0^t w_j w_k dt,   c_i = w_i(t0)   (1, integrated)
//! ```
//!
//! with `(i, j, k)` cyclic. Every sample is one linear equation in `(c_i, a_i)`: the noise of
//! `w_i(t)` enters once, and `c_i` is estimated, so the noisy first sample carries no special
//! weight. `G_i` is built from measured rates, so it carries the gyro noise integrated: a random
//! walk with increments of variance `sigma^2 h^2 (w_j^2 + w_k^2)` per step. Written into the
//! equation, that walk is a slowly wandering intercept `c_i(t)` with process-noise variance
//! `a_i^2 sigma^2 h^2 (w_j^2 + w_k^2)` per step, next to the white measurement noise
//! `sigma^2`. A two-state Kalman filter per axis on `(c_i, a_i)` with exactly these variances
//! is the best linear estimator for that model: it weighs each sample by what it still
//! says about `a_i` once the integral's noise is accounted for. Both variances scale with
//! `sigma^2`, so the filter runs in units of `sigma^2` and its gains do not depend on the
//! noise level; only the prior on `a` does ([`RefinedSettings::prior_std`] over
//! [`RefinedSettings::noise_std`]).
//!
//! Compared with the paper's identifier this is the invariant relation (4) of
//! (1, integrated), `a_i = (w_i(t) - c_i) / G_i(t)`, with a time-varying gain that follows the
//! information gathered, the direction the paper's `Delta` update takes to its limit.
//!
//! `G_i` is integrated by the trapezoid with the end correction
//! `h^2/12 (f'(t_prev) - f'(t))` (Euler-Maclaurin), `f' = (w_j w_k)'` taken from (1) itself
//! with the current estimate: fourth order, so that 100 Hz data of a fast tumble carry no
//! discretisation bias worth the name.
//!
//! The identifiability condition (2) is not needed: a stretch where `w1 w2 w3` is small simply
//! adds little information instead of being cut out, and sign changes of `w1 w2 w3` need no
//! correction because no branch of (9) is involved. A gap or [`Refined::restart`] starts a new
//! integral (new `c_i`, `G_i = 0`) and keeps `a_i` with its variance, so tosses combine by their
//! information. The state is a fixed-size value; one [`Refined::step`] per sample costs about
//! ninety floating-point operations and three divisions.

use crate::convergence::{Convergence, ConvergenceMonitor};
use crate::invariant::{sign, triple_product};
use crate::status::{Counters, Estimate, SampleStatus};

/// Tuning of [`Refined`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefinedSettings {
    /// Gyro white noise per sample, rad/s (datasheet noise density times the square root of
    /// the bandwidth). Only scales the prior: the filter's gains are independent of it. Must
    /// be finite and `> 0`.
    pub noise_std: f32,
    /// Prior standard deviation of each `a_i` around [`RefinedSettings::initial_estimate`]
    /// (`|a_i| < 1` for any real body, so `1` is a wide prior). Must be finite and `> 0`.
    pub prior_std: f32,
    /// Gyro full scale in rad/s, as in [`crate::Settings::full_scale`].
    pub full_scale: f32,
    /// Longest time step still integrated, as in [`crate::Settings::max_dt`]; a longer one
    /// starts a new integral from the new sample, keeping the estimate.
    pub max_dt: f32,
    /// `eps` of the paper's accuracy criterion (section 4), as in [`crate::Settings::eps`].
    pub eps: f32,
    /// `h` of the criterion, seconds, as in [`crate::Settings::h`].
    pub h: f32,
    /// Estimate of `a` before any information.
    pub initial_estimate: [f32; 3],
}

impl RefinedSettings {
    /// Defaults: `noise_std = 2e-3 rad/s`, `prior_std = 1`, no full-scale limit,
    /// `max_dt = 0.1 s`, `eps = 1e-3`, `h = 1 s`, zero initial estimate.
    pub const fn new() -> Self {
        RefinedSettings {
            noise_std: 2e-3,
            prior_std: 1.0,
            full_scale: f32::INFINITY,
            max_dt: 0.1,
            eps: 1e-3,
            h: 1.0,
            initial_estimate: [0.0; 3],
        }
    }

    /// True when every field is usable.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.noise_std)
            && pos(self.prior_std)
            && (self.prior_std / self.noise_std).is_finite()
            && (self.prior_std / self.noise_std) * (self.prior_std / self.noise_std) < 1e30
            && !self.full_scale.is_nan()
            && self.full_scale > 0.0
            && pos(self.max_dt)
            && pos(self.eps)
            && pos(self.h)
            && self.initial_estimate.iter().all(|a| a.is_finite())
    }

    /// Prior variance of `a_i` in units of `noise_std^2`.
    fn prior_var(&self) -> f32 {
        let r = self.prior_std / self.noise_std;
        r * r
    }
}

impl Default for RefinedSettings {
    fn default() -> Self {
        Self::new()
    }
}

/// One axis of the filter: `(c_i, a_i)` and their covariance in units of `sigma^2`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Axis {
    c: f32,
    a: f32,
    g: f32,
    pcc: f32,
    pca: f32,
    paa: f32,
}

impl Axis {
    /// Starts a new integral at the measured `w` (intercept known to one `sigma`).
    fn anchor(&mut self, w: f32) {
        self.c = w;
        self.g = 0.0;
        self.pcc = 1.0;
        self.pca = 0.0;
    }

    /// One Kalman step: the intercept wanders by `q`, then the sample `w` = `c + a G` + noise.
    /// Returns the updated axis, or `None` if anything became non-finite.
    fn update(&self, dg: f32, q: f32, w: f32) -> Option<Axis> {
        let g = self.g + dg;
        let pcc = self.pcc + q;
        let (pca, paa) = (self.pca, self.paa);
        // P H^T with H = [1, G]; innovation variance s = H P H^T + 1.
        let hp0 = pcc + g * pca;
        let hp1 = pca + g * paa;
        let s = hp0 + g * hp1 + 1.0;
        if !(s.is_finite() && s >= 1.0) {
            return None;
        }
        let inv = 1.0 / s;
        let (k0, k1) = (hp0 * inv, hp1 * inv);
        let e = w - self.c - self.a * g;
        let mut next = Axis {
            c: self.c + k0 * e,
            a: self.a + k1 * e,
            g,
            pcc: pcc - k0 * hp0,
            pca: pca - k0 * hp1,
            paa: paa - k1 * hp1,
        };
        // Keep the covariance a covariance in f32: positive diagonal, |correlation| < 1.
        next.pcc = next.pcc.max(1e-12);
        next.paa = next.paa.max(1e-20);
        let lim = 0.999_999 * next.pcc * next.paa;
        if next.pca * next.pca > lim {
            next.pca = sign(next.pca) * sqrt_approx(lim);
        }
        let ok = [next.c, next.a, next.g, next.pcc, next.pca, next.paa]
            .iter()
            .all(|x| x.is_finite());
        ok.then_some(next)
    }
}

/// `sqrt(x)` for `x >= 0` (0 for anything else) without `std` or `libm`: an exponent-halving
/// first guess refined by Newton's method; used for the reported standard deviation and the
/// rare clamp of the covariance, where a few ulps do not matter.
fn sqrt_approx(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) {
        return 0.0;
    }
    let mut y = f32::from_bits((x.to_bits() >> 1).wrapping_add(0x1fbd_1df5));
    for _ in 0..4 {
        y = 0.5 * (y + x / y);
    }
    if y.is_finite() {
        y
    } else {
        0.0
    }
}

/// The last accepted sample.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Last {
    omega: [f32; 3],
    p: f32,
}

/// The refined identifier: per axis a Kalman filter on the integrated (1) with the integral's
/// noise as a wandering intercept. Fixed size, no heap, no buffers.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refined {
    settings: RefinedSettings,
    last: Option<Last>,
    pending_dt: f32,
    axes: [Axis; 3],
    monitor: ConvergenceMonitor,
    counters: Counters,
}

impl Refined {
    /// A new refined identifier, or `None` when the settings are not usable
    /// ([`RefinedSettings::is_valid`]).
    pub fn new(settings: RefinedSettings) -> Option<Self> {
        if !settings.is_valid() {
            return None;
        }
        let p = settings.prior_var();
        let [a0, a1, a2] = settings.initial_estimate;
        let axis = |a: f32| Axis {
            c: 0.0,
            a,
            g: 0.0,
            pcc: 1.0,
            pca: 0.0,
            paa: p,
        };
        Some(Refined {
            settings,
            last: None,
            pending_dt: 0.0,
            axes: [axis(a0), axis(a1), axis(a2)],
            monitor: ConvergenceMonitor::new(),
            counters: Counters::default(),
        })
    }

    /// Forgets everything learnt.
    pub fn reset(&mut self) {
        if let Some(fresh) = Refined::new(self.settings) {
            *self = fresh;
        }
    }

    /// Ends the current stretch of data (a new toss, a new log): the next sample starts a new
    /// integral; the estimate and its information are kept, so tosses combine.
    pub fn restart(&mut self) {
        self.last = None;
        self.pending_dt = 0.0;
    }

    /// The current estimate of `a = (a1, a2, a3)` of (1).
    pub fn estimate(&self) -> [f32; 3] {
        self.axes.map(|x| x.a)
    }

    /// The filter's standard deviation of each `a_i` in units of the gyro noise `sigma` per
    /// sample: multiply by the actual `sigma` for the expected error (an approximation of the
    /// Cramer-Rao bound of this model when the noise is white).
    pub fn std_per_sigma(&self) -> [f32; 3] {
        self.axes.map(|x| sqrt_approx(x.paa))
    }

    /// Counts of sample outcomes since creation or [`Refined::reset`].
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// The settings in force.
    pub fn settings(&self) -> &RefinedSettings {
        &self.settings
    }

    /// One step for the gyro sample `omega` (rad/s) taken `dt` seconds after the previous one.
    ///
    /// Adds the sample to the per-axis filters of (1, integrated) and returns the estimate.
    /// Bad inputs get the same [`SampleStatus`] as [`crate::Identifier::step`];
    /// `Updated` / `SignChange` mean the sample entered the filters (`SignChange` when
    /// `w1 w2 w3` changed sign since the previous sample; no correction is needed here).
    /// Never panics; the state stays finite.
    pub fn step(&mut self, omega: [f32; 3], dt: f32) -> Estimate {
        let status = self.advance(omega, dt);
        self.count(status);
        Estimate {
            a: self.estimate(),
            status,
            convergence: self.monitor.verdict(self.settings.h),
        }
    }

    fn advance(&mut self, omega: [f32; 3], dt: f32) -> SampleStatus {
        if !(dt.is_finite() && dt > 0.0) {
            self.restart();
            return SampleStatus::InvalidTimeStep;
        }
        if !omega.iter().all(|w| w.is_finite()) {
            self.pending_dt += dt;
            return SampleStatus::NonFinite;
        }
        if omega.iter().any(|w| w.abs() >= self.settings.full_scale) {
            self.pending_dt += dt;
            return SampleStatus::Saturated;
        }
        let h = self.pending_dt + dt;
        self.pending_dt = 0.0;
        let p = triple_product(omega);
        if !p.is_finite() {
            self.restart();
            return SampleStatus::NumericalFault;
        }
        let now = Last { omega, p };
        let Some(prev) = self.last.replace(now) else {
            self.anchor(omega);
            return SampleStatus::Anchored;
        };
        if h.is_nan() || h > self.settings.max_dt {
            self.anchor(omega);
            return SampleStatus::Gap;
        }
        if !self.accumulate(prev.omega, omega, h) {
            // Held: the estimate keeps its value and a new integral starts here.
            self.anchor(omega);
            return SampleStatus::NumericalFault;
        }
        if sign(prev.p) * sign(p) < 0.0 {
            SampleStatus::SignChange
        } else {
            SampleStatus::Updated
        }
    }

    fn anchor(&mut self, omega: [f32; 3]) {
        for (ax, &w) in self.axes.iter_mut().zip(omega.iter()) {
            ax.anchor(w);
        }
    }

    /// Adds the sample `w1` taken `h` after `w0`; false (nothing changed) if the update would
    /// not be finite.
    fn accumulate(&mut self, w0: [f32; 3], w1: [f32; 3], h: f32) -> bool {
        let b = self.estimate();
        // f = (w2 w3, w3 w1, w1 w2) and, from (1), f' = (w1 (a2 w3^2 + a3 w2^2), ...).
        let q0 = [w0[0] * w0[0], w0[1] * w0[1], w0[2] * w0[2]];
        let q1 = [w1[0] * w1[0], w1[1] * w1[1], w1[2] * w1[2]];
        let f = |w: [f32; 3]| [w[1] * w[2], w[2] * w[0], w[0] * w[1]];
        let fd = |w: [f32; 3], q: [f32; 3]| {
            [
                w[0] * (b[1] * q[2] + b[2] * q[1]),
                w[1] * (b[2] * q[0] + b[0] * q[2]),
                w[2] * (b[0] * q[1] + b[1] * q[0]),
            ]
        };
        let (f0, f1, d0, d1) = (f(w0), f(w1), fd(w0, q0), fd(w1, q1));
        let (half, corr) = (0.5 * h, h * h * (1.0 / 12.0));
        // Variance of the integral's increment per sigma^2: h^2 (w_j^2 + w_k^2), averaged
        // over the two ends of the step.
        let s0 = [q0[1] + q0[2], q0[2] + q0[0], q0[0] + q0[1]];
        let s1 = [q1[1] + q1[2], q1[2] + q1[0], q1[0] + q1[1]];
        let mut next = self.axes;
        for (i, ax) in next.iter_mut().enumerate() {
            let (Some(&x0), Some(&x1), Some(&y0), Some(&y1), Some(&v0), Some(&v1), Some(&w)) = (
                f0.get(i),
                f1.get(i),
                d0.get(i),
                d1.get(i),
                s0.get(i),
                s1.get(i),
                w1.get(i),
            ) else {
                return false;
            };
            let dg = half * (x0 + x1) + corr * (y0 - y1);
            let q = ax.a * ax.a * half * h * (v0 + v1);
            match ax.update(dg, q, w) {
                Some(n) => *ax = n,
                None => return false,
            }
        }
        self.axes = next;
        let est = self.estimate();
        let s = &self.settings;
        self.monitor.observe(est, h, s.eps, s.h);
        true
    }

    /// The paper's criterion (section 4) on the combined estimate.
    pub fn convergence(&self) -> Convergence {
        self.monitor.verdict(self.settings.h)
    }

    fn count(&mut self, status: SampleStatus) {
        let c = &mut self.counters;
        c.samples = c.samples.saturating_add(1);
        let slot = match status {
            SampleStatus::Updated => &mut c.integrated,
            SampleStatus::SignChange => {
                c.sign_changes = c.sign_changes.saturating_add(1);
                &mut c.integrated
            }
            SampleStatus::Unidentifiable => &mut c.unidentifiable,
            SampleStatus::Gap => &mut c.gaps,
            SampleStatus::NonFinite | SampleStatus::Saturated | SampleStatus::InvalidTimeStep => {
                &mut c.rejected
            }
            SampleStatus::NumericalFault => &mut c.numerical_faults,
            SampleStatus::Anchored => return,
        };
        *slot = slot.saturating_add(1);
    }
}
