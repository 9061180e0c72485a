//! A refined on-board identifier: (1) integrated, every sample used, no derivatives, no
//! sign-change restarts, and the integral's own noise accounted for.
//!
//! # Why
//!
//! The paper's identifier with `C = -lambda E` low-passes the instantaneous ratio
//! `(w_i^2)' / (2 w1 w2 w3)` with the weight `|w1 w2 w3|` (see (13)-(14)). Even with a gain
//! that decays like `1 / (information so far)` its estimate would telescope to differences of
//! `w_i^2` between sign changes of `w1 w2 w3`: the information enters through a few noisy end
//! points, and on noisy data the plain identifier stays far above the Cramer-Rao bound
//! (`BENCHMARKS.md`).
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
//! says about `a_i` once the integral's noise is accounted for (it ignores that the integral's
//! noise on one axis comes from the other axes' measurement noise). Both variances scale with
//! `sigma^2`, so the filter runs in units of `sigma^2` and its gains do not depend on the
//! noise level; only the prior on `a` does ([`RefinedSettings::prior_std`] over
//! [`RefinedSettings::noise_std`]).
//!
//! The filter is kept in information form and its measurement update is done once per block
//! of [`RefinedSettings::block`] samples: per sample only four running sums per axis are
//! added (`sum G`, `sum G^2`, `sum w`, `sum w G`), and per block one 2x2 solve per axis turns
//! them into the new `(c_i, a_i)`. Within a block the intercept's wander is lumped at the
//! block's start, a negligible approximation for blocks much shorter than the time over which
//! the integral's noise grows to the gyro's noise. [`Refined::step`] reports the estimate of
//! the last completed block; [`Refined::estimate`] includes the samples of the open block.
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
//! fifty floating-point operations, plus one 2x2 solve per axis per block.

use crate::convergence::{Convergence, ConvergenceMonitor};
use crate::invariant::{sign, triple_product};
use crate::status::{
    physically_possible, precise, Counters, Estimate, Exposure, SampleStatus, Status, Verdict,
    MIN_SAMPLES,
};

/// Tuning of [`Refined`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefinedSettings {
    /// Gyro white noise per sample, rad/s (datasheet noise density times the square root of
    /// the bandwidth). It scales the prior and the unmodelled torque of
    /// [`Refined::set_torque_noise`]; the filter's gains for (1) do not depend on it. Must be
    /// finite and `> 0`.
    pub noise_std: f32,
    /// Prior standard deviation of each `a_i` around [`RefinedSettings::initial_estimate`]
    /// (`|a_i| < 1` for any real body, so `1` is a wide prior). Must be finite and `> 0`.
    pub prior_std: f32,
    /// Samples per measurement update (1 to 1024). Larger blocks cost fewer instructions per
    /// sample; the estimate reported by [`Refined::step`] then lags by up to this many samples.
    /// Keep a block short against the motion (32 samples at 1 kHz, 8 at 100 Hz in the
    /// benchmark's fast toss), because the integral's noise is lumped once per block.
    pub block: u16,
    /// Use the fourth-order end correction of the integral (worth it when the rates change
    /// appreciably between samples, as at 100 Hz in a fast tumble; negligible at 1 kHz on a
    /// slow body, where it would only add about 40 instructions per step on the Cortex-M4F).
    pub end_correction: bool,
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
    /// Defaults: `noise_std = 2e-3 rad/s`, `prior_std = 1`, blocks of 32 samples, end
    /// correction off (turn it on below about 200 Hz), no full-scale limit, `max_dt = 0.1 s`, `eps = 1e-3`, `h = 1 s`, zero
    /// initial estimate.
    pub const fn new() -> Self {
        RefinedSettings {
            noise_std: 2e-3,
            prior_std: 1.0,
            block: 32,
            end_correction: false,
            full_scale: f32::INFINITY,
            max_dt: 0.1,
            eps: 1e-3,
            h: 1.0,
            initial_estimate: [0.0; 3],
        }
    }

    /// Settings for a gyro sampled at `rate_hz` with white noise `noise_std` rad/s per sample,
    /// from these two numbers alone and with no edge at any particular rate:
    ///
    /// * `block = clamp(round(0.032 s * rate_hz), 8, 1024)` samples: about 32 ms of data per
    ///   measurement update (32 samples at 1 kHz, 256 at 8 kHz), short against the motion,
    ///   at least 8 samples so that the 2x2 solves stay a small part of the cost;
    /// * `end_correction = true` at every rate: the integral `G_i` is then fourth order
    ///   (`h^2/12 (f'(t_prev) - f'(t))`, Euler-Maclaurin), so the noise-free bias stays below
    ///   `1e-5` from 100 Hz to 8 kHz (host test `for_rate_noise_free_bias`) instead of jumping
    ///   at a switching rate; it costs about 40 instructions per step on the Cortex-M4F;
    /// * `max_dt = max(0.1 s, 10 / rate_hz)`: a gap is at least ten sample periods;
    /// * everything else as [`RefinedSettings::new`].
    ///
    /// A `rate_hz` or `noise_std` that is not finite and positive gives settings that fail
    /// [`RefinedSettings::is_valid`] (so [`Refined::new`] refuses them).
    pub fn for_rate(rate_hz: f32, noise_std: f32) -> RefinedSettings {
        let samples = 0.032 * rate_hz + 0.5;
        let block = if rate_hz.is_finite() && rate_hz > 0.0 && samples.is_finite() {
            // In [8, 1024] after the clamp, so the conversion is exact.
            samples.clamp(8.0, 1024.0) as u16
        } else {
            0
        };
        let max_dt = 10.0 / rate_hz;
        RefinedSettings {
            noise_std,
            block,
            end_correction: true,
            max_dt: if max_dt > 0.1 { max_dt } else { 0.1 },
            ..RefinedSettings::new()
        }
    }

    /// True when every field is usable.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        let info = self.noise_std / self.prior_std;
        pos(self.noise_std)
            && pos(self.prior_std)
            && pos(info * info)
            && self.block >= 1
            && self.block <= 1024
            && !self.full_scale.is_nan()
            && self.full_scale > 0.0
            && pos(self.max_dt)
            && pos(self.eps)
            && pos(self.h)
            && self.initial_estimate.iter().all(|a| a.is_finite())
    }
}

impl Default for RefinedSettings {
    fn default() -> Self {
        Self::new()
    }
}

/// One axis: the estimate `(c_i, a_i)`, its information matrix (units `sigma^-2`), the
/// running integral `G_i` and the sums of the open block.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Axis {
    c: f32,
    a: f32,
    lcc: f32,
    lca: f32,
    laa: f32,
    g: f32,
    sg: f32,
    sgg: f32,
    sw: f32,
    swg: f32,
    /// `sum e^2` of the open block, `e = w - c - a G` at the block's start values.
    see: f32,
}

/// The result of a block update of one axis.
struct Solved {
    c: f32,
    a: f32,
    lcc: f32,
    lca: f32,
    laa: f32,
}

impl Axis {
    const fn new(a: f32, prior_info: f32) -> Self {
        Axis {
            c: 0.0,
            a,
            lcc: 1.0,
            lca: 0.0,
            laa: prior_info,
            g: 0.0,
            sg: 0.0,
            sgg: 0.0,
            sw: 0.0,
            swg: 0.0,
            see: 0.0,
        }
    }

    /// Adds one sample: `dg` the integral's increment, `w` the measured rate of this axis.
    #[inline(always)]
    fn add(&mut self, dg: f32, w: f32) {
        self.g += dg;
        let g = self.g;
        self.sg += g;
        self.sgg += g * g;
        self.sw += w;
        self.swg += w * g;
        let e = w - self.c - self.a * g;
        self.see += e * e;
    }

    /// `sum (w - c' - a' G)^2` over the open block at the updated `(c', a')`, from the sums at
    /// the block's start values (no cancellation of the large `sum w^2`).
    fn block_rss(&self, m: f32, s: &Solved) -> f32 {
        let se = self.sw - m * self.c - self.a * self.sg;
        let seg = self.swg - self.c * self.sg - self.a * self.sgg;
        let (dc, da) = (s.c - self.c, s.a - self.a);
        let r = self.see - 2.0 * dc * se - 2.0 * da * seg
            + m * dc * dc
            + 2.0 * dc * da * self.sg
            + da * da * self.sgg;
        if r > 0.0 && r.is_finite() {
            r
        } else {
            0.0
        }
    }

    /// The information-form update with the `m` samples of the open block: the intercept's
    /// wander first (Sherman-Morrison; `sq` is the variance per `sigma^2` of the integral's
    /// noise over the block, times `a^2` here), then the block's information and the sums of
    /// the residuals `e = w - c - a G` at the block's start values.
    fn solve(&self, m: f32, sq: f32, extra: f32) -> Option<Solved> {
        let q = self.a * self.a * sq + extra;
        let se = self.sw - m * self.c - self.a * self.sg;
        let seg = self.swg - self.c * self.sg - self.a * self.sgg;
        let r = 1.0 / (1.0 + q * self.lcc);
        let lcc = self.lcc * r + m;
        let lca = self.lca * r + self.sg;
        let laa = (self.laa - q * self.lca * self.lca * r) + self.sgg;
        let det = lcc * laa - lca * lca;
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        let id = 1.0 / det;
        let c = self.c + (laa * se - lca * seg) * id;
        let a = self.a + (lcc * seg - lca * se) * id;
        let all = [c, a, lcc, lca, laa];
        all.iter().all(|x| x.is_finite()).then_some(Solved {
            c,
            a,
            lcc,
            lca,
            laa,
        })
    }

    fn clear_block(&mut self) {
        self.sg = 0.0;
        self.sgg = 0.0;
        self.sw = 0.0;
        self.swg = 0.0;
        self.see = 0.0;
    }

    fn commit(&mut self, s: Solved) {
        self.c = s.c;
        self.a = s.a;
        self.lcc = s.lcc;
        self.lca = s.lca;
        self.laa = s.laa;
        self.clear_block();
    }

    /// Starts a new integral at the measured `w`: the old intercept is marginalised out of the
    /// information (Schur complement), the new one is known to one `sigma`.
    fn anchor(&mut self, w: f32) {
        if self.lcc > 0.0 {
            let laa = self.laa - self.lca * self.lca / self.lcc;
            if laa.is_finite() && laa > 0.0 {
                self.laa = laa;
            }
        }
        self.c = w;
        self.g = 0.0;
        self.lcc = 1.0;
        self.lca = 0.0;
        self.clear_block();
    }

    /// Variance of `a` per `sigma^2`: `(L^-1)_aa` (infinite when `L` is not positive definite).
    fn var_per_sigma2(&self) -> f32 {
        let det = self.lcc * self.laa - self.lca * self.lca;
        let v = self.lcc / det;
        if det > 0.0 && v.is_finite() {
            v
        } else {
            f32::INFINITY
        }
    }

    /// Standard deviation of `a` per `sigma`: `sqrt((L^-1)_aa)`.
    fn std_per_sigma(&self) -> f32 {
        let det = self.lcc * self.laa - self.lca * self.lca;
        if det > 0.0 {
            sqrt_approx(self.lcc / det)
        } else {
            f32::INFINITY
        }
    }
}

/// `sqrt(x)` for `x >= 0` (0 for anything else) without `std` or `libm`: an exponent-halving
/// first guess refined by Newton's method; only used for the reported standard deviation.
pub(crate) fn sqrt_approx(x: f32) -> f32 {
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
///
/// ```
/// use identifier_core::{Refined, RefinedSettings, Status};
///
/// // A gyro lying still carries no information: no ratios, and the status says why.
/// let mut r = Refined::new(RefinedSettings::for_rate(1000.0, 1e-3)).unwrap();
/// for k in 0..5000 {
///     let n = if k % 2 == 0 { 1e-3 } else { -1e-3 };
///     r.step([n, -n, n], 1e-3);
/// }
/// assert_eq!(r.trust(), Status::NoExcitation);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refined {
    settings: RefinedSettings,
    last: Option<Last>,
    pending_dt: f32,
    axes: [Axis; 3],
    /// Samples and seconds in the open block.
    m: u16,
    block_time: f32,
    monitor: ConvergenceMonitor,
    counters: Counters,
    /// See [`Refined::set_torque_noise`].
    torque_noise: f32,
    /// What the data offered (for [`Refined::trust`]).
    exposure: Exposure,
    /// The estimator's side of the trust, as of the last completed block.
    verdict: Verdict,
    /// Sum of the squared residuals of completed blocks and their count (three per sample):
    /// [`Refined::noise_estimate`].
    rss: f32,
    rss_n: u32,
}

impl Refined {
    /// A new refined identifier, or `None` when the settings are not usable
    /// ([`RefinedSettings::is_valid`]).
    pub fn new(settings: RefinedSettings) -> Option<Self> {
        if !settings.is_valid() {
            return None;
        }
        let r = settings.noise_std / settings.prior_std;
        let info = r * r;
        let [a0, a1, a2] = settings.initial_estimate;
        Some(Refined {
            settings,
            last: None,
            pending_dt: 0.0,
            axes: [
                Axis::new(a0, info),
                Axis::new(a1, info),
                Axis::new(a2, info),
            ],
            m: 0,
            block_time: 0.0,
            monitor: ConvergenceMonitor::new(),
            counters: Counters::default(),
            torque_noise: 0.0,
            rss: 0.0,
            rss_n: 0,
            exposure: Exposure::new(),
            verdict: Verdict::NONE,
        })
    }

    /// Allows for an unmodelled torque (air drag, a wobbling mount) as a white angular
    /// acceleration of spectral density `torque_noise`, rad/s per sqrt(s); `0` (the default)
    /// is the torque-free model (1). It lets the intercept `c_i` wander further, so that (1)
    /// is trusted only over the time such a torque takes to matter; this needs
    /// [`RefinedSettings::noise_std`] to be the actual gyro noise. Returns false and changes
    /// nothing unless `torque_noise` is finite and `>= 0`. Kept by [`Refined::reset`].
    pub fn set_torque_noise(&mut self, torque_noise: f32) -> bool {
        let ok = torque_noise.is_finite()
            && torque_noise >= 0.0
            && (torque_noise / self.settings.noise_std).is_finite();
        if ok {
            self.torque_noise = torque_noise;
        }
        ok
    }

    /// The unmodelled-torque density in force (see [`Refined::set_torque_noise`]).
    pub fn torque_noise(&self) -> f32 {
        self.torque_noise
    }

    /// Forgets everything learnt.
    pub fn reset(&mut self) {
        if let Some(mut fresh) = Refined::new(self.settings) {
            fresh.torque_noise = self.torque_noise;
            *self = fresh;
        }
    }

    /// Ends the current stretch of data (a new toss, a new log): the open block is folded in,
    /// the next sample starts a new integral; the estimate and its information are kept, so
    /// tosses combine.
    pub fn restart(&mut self) {
        self.flush();
        self.last = None;
        self.pending_dt = 0.0;
    }

    /// The current estimate of `a = (a1, a2, a3)` of (1), including the samples of the open
    /// block (one 2x2 solve per axis; nothing is changed).
    pub fn estimate(&self) -> [f32; 3] {
        let m = f32::from(self.m);
        let q = self.block_noise();
        let extra = self.torque_wander();
        let [x, y, z] = &self.axes;
        let [qx, qy, qz] = q;
        let one = |ax: &Axis, q: f32| {
            if self.m == 0 {
                ax.a
            } else {
                ax.solve(m, q, extra).map_or(ax.a, |s| s.a)
            }
        };
        [one(x, qx), one(y, qy), one(z, qz)]
    }

    /// Variance per `sigma^2` of each integral's noise accumulated over the open block,
    /// `sum h^2 (w_j^2 + w_k^2)`, taken as `T^2 / m (w_j^2 + w_k^2)` at the last sample.
    fn block_noise(&self) -> [f32; 3] {
        let Some(last) = self.last else {
            return [0.0; 3];
        };
        let w = last.omega;
        let m = f32::from(self.m).max(1.0);
        let k = self.block_time * self.block_time / m;
        let q = [w[0] * w[0], w[1] * w[1], w[2] * w[2]];
        [k * (q[1] + q[2]), k * (q[2] + q[0]), k * (q[0] + q[1])]
    }

    /// The intercept's extra wander over the open block from the unmodelled torque, per
    /// `sigma^2`.
    fn torque_wander(&self) -> f32 {
        let r = self.torque_noise / self.settings.noise_std;
        r * r * self.block_time
    }

    /// The estimate as of the last completed block (what [`Refined::step`] reports).
    pub fn block_estimate(&self) -> [f32; 3] {
        self.axes.map(|x| x.a)
    }

    /// The filter's standard deviation of each `a_i` (last completed block) in units of the
    /// gyro noise `sigma` per sample: multiply by the actual `sigma` for the expected error
    /// under white noise.
    pub fn std_per_sigma(&self) -> [f32; 3] {
        self.axes.map(|x| x.std_per_sigma())
    }

    /// The standard deviation of each `a_i` (last completed block), rad/s-free:
    /// [`Refined::std_per_sigma`] times [`RefinedSettings::noise_std`]. It is honest only when
    /// `noise_std` is the actual gyro noise, and it does not include discretisation bias
    /// (below `1e-5` with [`RefinedSettings::for_rate`]).
    pub fn std_a(&self) -> [f32; 3] {
        let sigma = self.sigma();
        self.std_per_sigma().map(|x| x * sigma)
    }

    /// The gyro noise seen in the data: `sqrt(sum e^2 / (n - 6))` over the residuals
    /// `e = w_i - c_i - a_i G_i` of every completed block at its updated estimate (three axes,
    /// two parameters each), once at least 30 residuals are in; `None` before. It includes
    /// whatever the model leaves out, which is why the reported uncertainty uses it.
    pub fn noise_estimate(&self) -> Option<f32> {
        if self.rss_n < 30 {
            return None;
        }
        let v = self.rss / (self.rss_n - 6) as f32;
        (v > 0.0 && v.is_finite()).then(|| sqrt_approx(v))
    }

    /// The `sigma` behind [`Refined::std_a`] and the trust: [`Refined::noise_estimate`] once
    /// 200 samples' residuals are in; before, the larger of it and
    /// [`RefinedSettings::noise_std`] (a few residuals of a fit that has just absorbed them
    /// understate the noise, and an early `Converged` must not come from that).
    fn sigma(&self) -> f32 {
        let configured = self.settings.noise_std;
        match self.noise_estimate() {
            Some(s) if self.rss_n >= 600 => s,
            Some(s) if s > configured => s,
            _ => configured,
        }
    }

    /// How far the estimate of the last completed block can be trusted ([`Status`], by
    /// [`Status::assess`]), with `var_i = (L^-1)_aa sigma^2` the filter's variance of `a_i`
    /// (`sigma` = [`RefinedSettings::noise_std`]):
    ///
    /// * enough: at least `MIN_SAMPLES` samples in completed blocks;
    /// * excited: the data carried information, i.e. every `var_i <= (prior_std / 2)^2` (the
    ///   data at least halved the prior's standard deviation on every axis) **and** the
    ///   rates moved: [`Exposure::moved`] (two axes swung by more than
    ///   `SWING_SIGMAS` `sigma`; a still gyro, with or without bias, does
    ///   not);
    /// * possible: `physically_possible``(a, var)`;
    /// * settled: every standard deviation below [`RefinedSettings::eps`]:
    ///   `var_i < eps^2`.
    ///
    /// Evaluated at each completed block (no square root, three divisions); between blocks
    /// only the data-side counts change.
    pub fn trust(&self) -> Status {
        let mut v = self.verdict;
        v.excited = v.excited && self.exposure.moved(self.settings.noise_std);
        Status::assess(&self.exposure, v)
    }

    /// What the data offered so far (counts, peak rate, excitation `E`).
    pub fn exposure(&self) -> &Exposure {
        &self.exposure
    }

    /// The estimator's side of the trust for the committed estimate.
    fn judge(&self) -> Verdict {
        let s = &self.settings;
        let sigma = self.sigma();
        let s2 = sigma * sigma;
        let var = self.axes.map(|x| x.var_per_sigma2() * s2);
        // Both sides are judged conservatively: precision with the larger noise, physical
        // possibility with the smaller one (the configured noise when the residuals are
        // noisier: deg/s data read as rad/s has 57x the noise, and that noise must not make an
        // impossible consistency value look possible).
        let low = if sigma < s.noise_std {
            sigma
        } else {
            s.noise_std
        };
        let var_low = self.axes.map(|x| x.var_per_sigma2() * low * low);
        let a = self.block_estimate();
        let half_prior = 0.5 * s.prior_std;
        let folded = self.counters.integrated.saturating_sub(u32::from(self.m));
        Verdict {
            enough: folded >= MIN_SAMPLES,
            excited: var.iter().all(|v| *v <= half_prior * half_prior),
            possible: physically_possible(a, var_low),
            settled: precise(var, s.eps),
        }
    }

    /// Counts of sample outcomes since creation or [`Refined::reset`].
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// The settings in force.
    pub fn settings(&self) -> &RefinedSettings {
        &self.settings
    }

    /// The paper's criterion (section 4) on the estimate, checked at each completed block.
    pub fn convergence(&self) -> Convergence {
        self.monitor.verdict(self.settings.h)
    }

    /// One step for the gyro sample `omega` (rad/s) taken `dt` seconds after the previous one.
    ///
    /// Adds the sample to the per-axis filters of (1, integrated) and returns the estimate of
    /// the last completed block. Bad inputs get the same [`SampleStatus`] as
    /// [`crate::Identifier::step`]; `Updated` / `SignChange` mean the sample entered the
    /// filters (`SignChange` when `w1 w2 w3` changed sign since the previous sample; no
    /// correction is needed here). Never panics; the state stays finite.
    pub fn step(&mut self, omega: [f32; 3], dt: f32) -> Estimate {
        let status = self.advance(omega, dt);
        self.counters.record(status);
        Estimate {
            a: self.block_estimate(),
            status,
            convergence: self.monitor.verdict(self.settings.h),
            trust: self.trust(),
        }
    }

    fn advance(&mut self, omega: [f32; 3], dt: f32) -> SampleStatus {
        if !(dt.is_finite() && dt > 0.0) {
            self.restart();
            return SampleStatus::InvalidTimeStep;
        }
        let [w1, w2, w3] = omega;
        if !(w1.is_finite() && w2.is_finite() && w3.is_finite()) {
            self.pending_dt += dt;
            return SampleStatus::NonFinite;
        }
        let fs = self.settings.full_scale;
        if w1.abs() >= fs || w2.abs() >= fs || w3.abs() >= fs {
            self.pending_dt += dt;
            self.exposure.saturate();
            return SampleStatus::Saturated;
        }
        self.exposure.accept(omega);
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
        self.accumulate(prev.omega, omega, h);
        self.exposure.excite(prev.p, p, h);
        if self.m >= self.settings.block && !self.flush() {
            // Held: the block is dropped and a new integral starts here.
            self.discard(omega);
            return SampleStatus::NumericalFault;
        }
        if sign(prev.p) * sign(p) < 0.0 {
            SampleStatus::SignChange
        } else {
            SampleStatus::Updated
        }
    }

    /// Folds the open block into the estimate; false (and nothing changed) if the update
    /// would not be finite.
    fn flush(&mut self) -> bool {
        if self.m == 0 {
            return true;
        }
        let m = f32::from(self.m);
        let [qx, qy, qz] = self.block_noise();
        let e = self.torque_wander();
        let [x, y, z] = &self.axes;
        let (Some(sx), Some(sy), Some(sz)) =
            (x.solve(m, qx, e), y.solve(m, qy, e), z.solve(m, qz, e))
        else {
            return false;
        };
        let rss = x.block_rss(m, &sx) + y.block_rss(m, &sy) + z.block_rss(m, &sz);
        self.rss += rss;
        self.rss_n = self.rss_n.saturating_add(3 * u32::from(self.m));
        let [x, y, z] = &mut self.axes;
        x.commit(sx);
        y.commit(sy);
        z.commit(sz);
        let a = self.block_estimate();
        let s = &self.settings;
        self.monitor.observe(a, self.block_time, s.eps, s.h);
        self.m = 0;
        self.block_time = 0.0;
        self.verdict = self.judge();
        true
    }

    fn discard(&mut self, omega: [f32; 3]) {
        for ax in self.axes.iter_mut() {
            ax.clear_block();
        }
        self.m = 0;
        self.block_time = 0.0;
        self.anchor(omega);
    }

    /// Folds the open block in (or drops it if it cannot be) and starts a new integral at
    /// `omega`.
    fn anchor(&mut self, omega: [f32; 3]) {
        if !self.flush() {
            for ax in self.axes.iter_mut() {
                ax.clear_block();
            }
            self.m = 0;
            self.block_time = 0.0;
        }
        let [x, y, z] = &mut self.axes;
        x.anchor(omega[0]);
        y.anchor(omega[1]);
        z.anchor(omega[2]);
    }

    /// Adds the sample `v` taken `h` after `u` to the open block.
    fn accumulate(&mut self, u: [f32; 3], v: [f32; 3], h: f32) {
        // f = (w2 w3, w3 w1, w1 w2); the integral's increment by the trapezoid, with the end
        // correction h^2/12 (f'(u) - f'(v)), f' = (w1 (a2 w3^2 + a3 w2^2), ...) by (1).
        let [x, y, z] = &self.axes;
        let a = self.settings.end_correction.then_some([x.a, y.a, z.a]);
        let dg = integral_step(u, v, h, a);
        let [x, y, z] = &mut self.axes;
        x.add(dg[0], v[0]);
        y.add(dg[1], v[1]);
        z.add(dg[2], v[2]);
        self.m = self.m.saturating_add(1);
        self.block_time += h;
    }
}

/// The increment of `G = integral (w2 w3, w3 w1, w1 w2) dt` from the sample `u` to the sample
/// `v` taken `h` later: the trapezoid, plus, with `a`, the end correction
/// `h^2/12 (f'(u) - f'(v))`, `f' = (w1 (a2 w3^2 + a3 w2^2), ...)` by (1) (fourth order).
pub(crate) fn integral_step(u: [f32; 3], v: [f32; 3], h: f32, a: Option<[f32; 3]>) -> [f32; 3] {
    let half = 0.5 * h;
    let mut dg = [
        half * (u[1] * u[2] + v[1] * v[2]),
        half * (u[2] * u[0] + v[2] * v[0]),
        half * (u[0] * u[1] + v[0] * v[1]),
    ];
    if let Some(b) = a {
        let qv = [v[0] * v[0], v[1] * v[1], v[2] * v[2]];
        let qu = [u[0] * u[0], u[1] * u[1], u[2] * u[2]];
        let k = h * h * (1.0 / 12.0);
        dg[0] += k * (u[0] * (b[1] * qu[2] + b[2] * qu[1]) - v[0] * (b[1] * qv[2] + b[2] * qv[1]));
        dg[1] += k * (u[1] * (b[2] * qu[0] + b[0] * qu[2]) - v[1] * (b[2] * qv[0] + b[0] * qv[2]));
        dg[2] += k * (u[2] * (b[0] * qu[1] + b[1] * qu[0]) - v[2] * (b[0] * qv[1] + b[1] * qv[0]));
    }
    dg
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_motion::{motion, A};

    #[test]
    fn converges_on_noise_free_motion() {
        let mut id = Refined::new(RefinedSettings::new()).unwrap();
        for w in motion(10_000, 1e-3) {
            id.step(w, 1e-3);
        }
        let est = id.estimate();
        for i in 0..3 {
            assert!((est[i] - A[i]).abs() < 1e-4, "{est:?}");
        }
        assert_eq!(id.convergence(), Convergence::Converged);
        assert_eq!(id.counters().integrated, 9_999);
    }

    #[test]
    fn bad_inputs_have_the_core_statuses_and_hold_the_estimate() {
        let mut id = Refined::new(RefinedSettings {
            full_scale: 30.0,
            ..RefinedSettings::new()
        })
        .unwrap();
        let mut samples = motion(3_000, 1e-3);
        for w in samples.by_ref().take(2_000) {
            id.step(w, 1e-3);
        }
        let held = id.estimate();
        let w = [1.0, 1.0, 1.0];
        assert_eq!(
            id.step([f32::NAN, 1.0, 1.0], 1e-3).status,
            SampleStatus::NonFinite
        );
        assert_eq!(
            id.step([f32::INFINITY, 1.0, 1.0], 1e-3).status,
            SampleStatus::NonFinite
        );
        assert_eq!(
            id.step([40.0, 1.0, 1.0], 1e-3).status,
            SampleStatus::Saturated
        );
        assert_eq!(id.step(w, 0.0).status, SampleStatus::InvalidTimeStep);
        assert_eq!(id.step(w, f32::NAN).status, SampleStatus::InvalidTimeStep);
        assert_eq!(id.step(w, -1.0).status, SampleStatus::InvalidTimeStep);
        assert_eq!(id.step(w, 1e-3).status, SampleStatus::Anchored);
        assert_eq!(id.step(w, 5.0).status, SampleStatus::Gap);
        let mut wide = Refined::new(RefinedSettings::new()).unwrap();
        assert_eq!(
            wide.step([1e30, 1e30, 1e-3], 1e-3).status,
            SampleStatus::NumericalFault
        );
        assert!(wide.estimate().iter().all(|a| a.is_finite()));
        let after = id.estimate();
        for i in 0..3 {
            assert!((after[i] - held[i]).abs() < 1e-3, "{after:?} vs {held:?}");
            assert!(after[i].is_finite());
        }
        // And it carries on learning afterwards.
        for w in samples {
            id.step(w, 1e-3);
        }
        assert!(id.estimate().iter().all(|a| a.is_finite()));
    }

    #[test]
    fn refuses_unusable_settings() {
        let ok = RefinedSettings::new();
        let mut id = Refined::new(ok).unwrap();
        assert!(!id.set_torque_noise(-1.0));
        assert!(!id.set_torque_noise(f32::NAN));
        assert!(id.set_torque_noise(0.03));
        id.reset();
        assert_eq!(id.torque_noise(), 0.03);
        for bad in [
            RefinedSettings {
                noise_std: 0.0,
                ..ok
            },
            RefinedSettings {
                prior_std: f32::NAN,
                ..ok
            },
            RefinedSettings { block: 0, ..ok },
            RefinedSettings { block: 2000, ..ok },
            RefinedSettings { max_dt: -1.0, ..ok },
            RefinedSettings {
                full_scale: 0.0,
                ..ok
            },
            RefinedSettings {
                initial_estimate: [0.0, f32::INFINITY, 0.0],
                ..ok
            },
        ] {
            assert!(Refined::new(bad).is_none(), "{bad:?}");
        }
    }
}
