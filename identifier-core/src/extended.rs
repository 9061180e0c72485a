//! Extended identifier: `a = (a1, a2, a3)` together with the parameters of up to two effects
//! the torque-free model (1) lacks, one [`ExtendedIdentifier::step`] per gyro sample.
//!
//! # Model
//!
//! The extended model is linear in `theta = (a1, a2, a3, p_1, p_2)` (`p_e` three parameters of
//! effect `e`):
//!
//! ```text
//! w' = sum_p theta_p phi_p(w)                                                          (E)
//! phi_a1 = (w2 w3, 0, 0),  phi_a2 = (0, w3 w1, 0),  phi_a3 = (0, 0, w1 w2)            (1)
//! BodyTorque        tau_i/A_i   column e_i
//! Damping           d_i/A_i     column -w_i e_i                  (torque -d_i w_i)
//! GyroBias          b_j         column -J_f(w) e_j               (reading w + b, f(w - b) linearised)
//! ProductsOfInertia eps_j       column e_j x f(w) - J_f(w)(e_j x w)   (sensor frame turned by I + [eps]x)
//! RotorMomentum     h_j/A1      column r (.) (e_j x w), r = (1, A1/A2, A1/A3)   (I w' = (I w + h) x w)
//! ```
//!
//! with `f` the right-hand side of (1) and `J_f` its Jacobian, both at the current estimate of
//! `a` (a pseudo-linear regression: the bilinear columns use the latest `a`), and
//! the ratios from `a` as in [`inverse_ratios`].
//!
//! # Why not the invariant-relation construction
//!
//! Shcherbak's construction (3)-(12) needs `Phi` with `dPhi/dw` times the right-hand side
//! cancelling the unknown terms; with additive terms such as `tau_i` or `-d_i w_i` each new
//! unknown needs its own nonvanishing excitation function and the gain design of (9)-(10) no
//! longer closes in general. The sound on-board estimator used instead is recursive least
//! squares on the *integrated* form of (E), so that no derivative of the noisy gyro signal is
//! needed: over a block of `K` Simpson pairs of sample intervals (pair `k`:
//! nodes `w_k0, w_k1, w_k2`, intervals `h1`, `h2`, Simpson's rule on uneven nodes)
//!
//! ```text
//! w(t_end) - w(t_start) = sum_k [q0 Phi(w_k0) + q1 Phi(w_k1) + q2 Phi(w_k2)] theta      (I)
//! q0 = (h1+h2)(2 h1 - h2)/(6 h1),  q1 = (h1+h2)^3/(6 h1 h2),  q2 = (h1+h2)(2 h2 - h1)/(6 h2)
//! ```
//!
//! The regressor is summed pair by pair in a fixed-size accumulator, and at the end of the
//! block each of the three rows of (I) is one scalar RLS update with forgetting factor 1
//! (`k = P x / (R + x^T P x)`, `theta += k (y - x^T theta)`, `P -= k x^T P`), `R = 2 sigma^2`
//! the variance of the difference of two gyro readings. Blocks share only their end samples.
//! [`ExtendedIdentifier::restart`] starts a new segment and keeps `theta` and `P`, so the
//! estimate carries over from toss to toss of the same body.
//!
//! A common gyro scale factor `s` (reading `s w`) only turns `a` into `a / s`; it is invisible
//! in (I) and is corrected, when enabled, through the rigid-body consistency
//! `c(a) = a1 + a2 + a3 + a1 a2 a3 = 0`: `s^2 = -(a1 + a2 + a3)/(a1 a2 a3)`, `a = s a_fit`.
//!
//! No heap, no `unsafe`, no panicking path, `f32` only, and only `+ - * /` (the one square
//! root is a fixed count of Newton steps), so host and MCU run the same arithmetic.

use crate::status::{physically_possible, precise, Exposure, Status, Verdict, MIN_SAMPLES};

/// Effects the extended identifier can estimate alongside `a` (see the module table (E)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ExtraEffect {
    /// Constant gyro bias `b` (rad/s), column `-J_f(w) e_j`.
    GyroBias,
    /// Constant body-frame torque over inertia `tau_i / A_i` (rad/s^2), column `e_i`.
    BodyTorque,
    /// Viscous damping `d_i / A_i` (1/s), column `-w_i e_i`.
    Damping,
    /// Small angles `eps` (rad) from principal to sensor axes, column
    /// `e_j x f(w) - J_f(w)(e_j x w)`.
    ProductsOfInertia,
    /// Internal rotor momentum `h / A1` (rad/s), column `r (.) (e_j x w)`.
    RotorMomentum,
}

/// Most effects estimated at once.
pub const MAX_EFFECTS: usize = 2;
/// Length of `theta`: `a` plus three parameters per effect.
pub const MAX_PARAMS: usize = 3 + 3 * MAX_EFFECTS;

type Vecp = [f32; MAX_PARAMS];
type Matp = [[f32; MAX_PARAMS]; MAX_PARAMS];
/// Regressor columns, one 3-vector per parameter.
type Cols = [[f32; 3]; MAX_PARAMS];

/// Tuning of an [`ExtendedIdentifier`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExtendedSettings {
    /// The effects estimated with `a`, in the order of their parameters in `theta`.
    pub effects: [Option<ExtraEffect>; MAX_EFFECTS],
    /// Correct a common gyro scale factor through the consistency `c(a) = 0`.
    pub scale_correction: bool,
    /// `a` before the first sample.
    pub initial_estimate: [f32; 3],
    /// Prior standard deviation of each `a_i` (the initial `P` is `diag(prior^2)`).
    pub prior_a: f32,
    /// Prior standard deviation of each effect parameter.
    pub prior_effect: f32,
    /// Gyro white-noise standard deviation per sample, rad/s (`R = 2 sigma^2` in (I)).
    pub noise_std: f32,
    /// Readings with any `|w_i| >= full_scale` are rejected (`f32::INFINITY` for none).
    pub full_scale: f32,
    /// Longest sample interval still integrated; a longer one restarts the block.
    pub max_dt: f32,
    /// Standard deviation of every `a_i` (from `P`) below which the estimate is
    /// [`Status::Converged`] (see [`ExtendedIdentifier::trust`]). Must be finite and `> 0`.
    pub tolerance: f32,
}

impl ExtendedSettings {
    /// No effect, no scale correction, priors `10` on `a` and `10` on effect parameters,
    /// `noise_std = 0.01 rad/s`, no full scale, `max_dt = 0.05 s`, `tolerance = 1e-3`.
    pub const fn new(effects: [Option<ExtraEffect>; MAX_EFFECTS]) -> Self {
        ExtendedSettings {
            effects,
            scale_correction: false,
            initial_estimate: [0.0; 3],
            prior_a: 10.0,
            prior_effect: 10.0,
            noise_std: 0.01,
            full_scale: f32::INFINITY,
            max_dt: 0.05,
            tolerance: 1e-3,
        }
    }

    /// True when every field is usable: priors and noise finite and positive with finite,
    /// positive squares (so `P(0)` and `R` are usable), finite positive `max_dt`, positive
    /// `full_scale`, finite initial estimate, and no effect listed twice.
    pub fn is_valid(&self) -> bool {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let [e0, e1] = self.effects;
        // The squares must be usable too: they are the initial P and R = 2 sigma^2.
        let sq = |v: f32| pos(v) && pos(v * v) && pos(2.0 * v * v);
        sq(self.prior_a)
            && sq(self.prior_effect)
            && sq(self.noise_std)
            && pos(self.max_dt)
            && sq(self.tolerance)
            && !self.full_scale.is_nan()
            && self.full_scale > 0.0
            && self.initial_estimate.iter().all(|v| v.is_finite())
            && !(e0.is_some() && e0 == e1)
    }
}

/// What [`ExtendedIdentifier::step`] did with one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ExtendedStatus {
    /// The sample closed a block: the three rows of (I) updated `theta`.
    Updated,
    /// The sample is the middle node of the current block.
    Buffered,
    /// The first usable sample, or the first after a restart or gap: it opens a block.
    Anchored,
    /// The interval since the previous sample exceeded `max_dt`: the block restarts here.
    Gap,
    /// A component was NaN or infinite: ignored, its `dt` carried over.
    NonFinite,
    /// A component reached `full_scale`: ignored, its `dt` carried over.
    Saturated,
    /// `dt` was zero, negative or not finite: ignored, the next sample opens a new block.
    InvalidTimeStep,
    /// The update would have produced a non-finite value: discarded, the block restarts.
    NumericalFault,
}

/// The result of one step.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExtendedEstimate {
    /// `(a1, a2, a3)`, times the scale factor when scale correction is on.
    pub a: [f32; 3],
    /// The parameters of `settings.effects[0]` and `[1]` (zeros for an empty slot).
    pub effect_params: [[f32; 3]; MAX_EFFECTS],
    /// The common gyro scale factor `s` from `c(a) = 0` (1 when off or undefined).
    pub scale: f32,
    /// What happened to this sample.
    pub status: ExtendedStatus,
    /// How far `a` can be trusted (see [`ExtendedIdentifier::trust`]).
    pub trust: Status,
}

impl ExtendedEstimate {
    /// Inertia ratios implied by `a` ([`crate::InertiaRatios::from_a`]), `None` while the data
    /// has carried no information ([`Status::has_information`] false).
    pub fn ratios(&self) -> Option<crate::InertiaRatios> {
        if !self.trust.has_information() {
            return None;
        }
        crate::InertiaRatios::from_a(self.a)
    }
}

/// Recursive least squares on (I) for `theta = (a, effect parameters)`: a fixed-size value,
/// no heap.
///
/// ```
/// use identifier_core::{ExtendedIdentifier, ExtendedSettings, ExtraEffect};
///
/// // The ratios and a constant gyro bias; a NaN sample is refused and changes nothing.
/// let s = ExtendedSettings::new([Some(ExtraEffect::GyroBias), None]);
/// let mut x = ExtendedIdentifier::new(s).unwrap();
/// x.step([1.0, 0.5, -0.2], 1e-3);
/// let before = x.theta();
/// x.step([f32::NAN, 0.0, 0.0], 1e-3);
/// assert_eq!(x.theta(), before);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExtendedIdentifier {
    settings: ExtendedSettings,
    theta: Vecp,
    p: Matp,
    /// Block start sample.
    w0: Option<[f32; 3]>,
    /// Middle sample and the interval `h1` before it.
    w1: Option<([f32; 3], f32)>,
    /// First sample of the current block.
    w_start: Option<[f32; 3]>,
    /// The block's regressor so far: sum over its Simpson pairs of weights times columns.
    acc: Cols,
    /// Simpson pairs in the current block.
    pairs: u16,
    /// Simpson pairs per block ([`ExtendedIdentifier::set_block_pairs`]).
    block_pairs: u16,
    /// See [`ExtendedIdentifier::set_bilinear_gate`].
    bilinear_gate: f32,
    pending_dt: f32,
    updates: u32,
    /// What the data offered (for [`ExtendedIdentifier::trust`]).
    exposure: Exposure,
    /// Samples in the blocks that updated `theta`.
    folded: u32,
    /// Samples in the open block.
    open: u32,
    /// The estimator's side of the trust, as of the last update.
    verdict: Verdict,
    /// Sum of the normalised innovations of the rows of (I) so far, and their number.
    nis_sum: f32,
    nis_rows: u32,
}

impl ExtendedIdentifier {
    /// A new identifier; `None` when `settings` fail [`ExtendedSettings::is_valid`].
    pub fn new(settings: ExtendedSettings) -> Option<Self> {
        if !settings.is_valid() {
            return None;
        }
        let mut theta = [0.0; MAX_PARAMS];
        for (t, a) in theta.iter_mut().zip(settings.initial_estimate.iter()) {
            *t = *a;
        }
        let n = n_params(&settings.effects);
        let mut p = [[0.0; MAX_PARAMS]; MAX_PARAMS];
        for (i, row) in p.iter_mut().enumerate().take(n) {
            let s = if i < 3 {
                settings.prior_a
            } else {
                settings.prior_effect
            };
            if let Some(v) = row.get_mut(i) {
                *v = s * s;
            }
        }
        Some(ExtendedIdentifier {
            settings,
            theta,
            p,
            w0: None,
            w1: None,
            w_start: None,
            acc: [[0.0; 3]; MAX_PARAMS],
            pairs: 0,
            block_pairs: 1,
            bilinear_gate: 0.02,
            pending_dt: 0.0,
            updates: 0,
            exposure: Exposure::new(),
            folded: 0,
            open: 0,
            verdict: Verdict::NONE,
            nis_sum: 0.0,
            nis_rows: 0,
        })
    }

    /// Starts a new segment (a new toss of the same body): forgets the open block, keeps
    /// `theta` and `P`.
    pub fn restart(&mut self) {
        self.w0 = None;
        self.w1 = None;
        self.w_start = None;
        self.acc = [[0.0; 3]; MAX_PARAMS];
        self.pairs = 0;
        self.pending_dt = 0.0;
        self.open = 0;
    }

    /// The settings in force.
    pub fn settings(&self) -> &ExtendedSettings {
        &self.settings
    }

    /// Sets the Simpson pairs (two sample intervals each) per block of (I), default 1: the
    /// block's regressor is summed over its pairs and one RLS update is made per block. Longer
    /// blocks carry more signal against the noise of their two end samples at high sample
    /// rates. Refused (returns false, nothing changed) for 0; takes effect from the next block.
    pub fn set_block_pairs(&mut self, pairs: u16) -> bool {
        if pairs == 0 {
            return false;
        }
        self.block_pairs = pairs;
        true
    }

    /// Sets the gate on the bilinear columns, default 0.02. The columns of `GyroBias`,
    /// `ProductsOfInertia` and `RotorMomentum` are evaluated at the current `a`; while `a` is
    /// still poorly known they would feed wrong regressors into `P` for good (forgetting
    /// factor 1), so they are held at zero until the standard deviation of every `a_i` in `P`
    /// is below the gate (`P_ii < gate^2`). Refused (false) unless `gate` and `gate^2` are
    /// finite and positive.
    pub fn set_bilinear_gate(&mut self, gate: f32) -> bool {
        let g2 = gate * gate;
        if !(gate.is_finite() && gate > 0.0 && g2.is_finite() && g2 > 0.0) {
            return false;
        }
        self.bilinear_gate = gate;
        true
    }

    /// True once every `a_i` has a standard deviation in `P` below the gate of
    /// [`ExtendedIdentifier::set_bilinear_gate`]: the bilinear columns are in use.
    pub fn a_settled(&self) -> bool {
        let g = self.bilinear_gate;
        self.p
            .iter()
            .take(3)
            .enumerate()
            .all(|(i, row)| row.get(i).is_some_and(|v| *v < g * g))
    }

    /// Blocks integrated so far.
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// `theta = (a1, a2, a3, p_1, p_2)` as fitted, without scale correction.
    pub fn theta(&self) -> [f32; MAX_PARAMS] {
        self.theta
    }

    /// Diagonal of `P`: with `noise_std` the true gyro noise, the variances of `theta`.
    pub fn variances(&self) -> [f32; MAX_PARAMS] {
        let mut v = [0.0; MAX_PARAMS];
        for (i, (vi, row)) in v.iter_mut().zip(self.p.iter()).enumerate() {
            *vi = row.get(i).copied().unwrap_or(0.0);
        }
        v
    }

    /// What the data offered so far (counts, peak rate, excitation `E`).
    pub fn exposure(&self) -> &Exposure {
        &self.exposure
    }

    /// How far the estimate can be trusted ([`Status`], by [`Status::assess`]), with
    /// `var_i = P_ii s^2 k` the variance of the reported `a_i` (`s` the scale factor of the
    /// scale correction, 1 without; `k` = [`ExtendedIdentifier::noise_inflation`]), judged at
    /// each update of `theta`:
    ///
    /// * enough: at least `MIN_SAMPLES` samples in blocks that updated `theta`;
    /// * excited: every `var_i <= (prior_a / 2)^2` (the data at least halved the prior's
    ///   standard deviation) and [`Exposure::moved`] with [`ExtendedSettings::noise_std`];
    /// * possible: `physically_possible``(a, var)` on the reported `a`;
    /// * settled: every standard deviation below [`ExtendedSettings::tolerance`].
    ///
    /// `P` is a covariance only when `noise_std` is the actual gyro noise and the effects
    /// listed are the ones present.
    pub fn trust(&self) -> Status {
        let mut v = self.verdict;
        v.excited = v.excited && self.exposure.moved(self.settings.noise_std);
        Status::assess(&self.exposure, v)
    }

    /// `max(1, mean normalised innovation)` of the rows of (I) so far: how much larger the
    /// residuals are than `P` and `R` predict (1 with the right model and `noise_std`; 57^2
    /// for data in deg/s; above 1 with unmodelled effects). [`ExtendedIdentifier::trust`]
    /// multiplies the variances by it, so a wrong `noise_std` or a missing effect cannot make
    /// the estimate look more precise than its residuals allow.
    pub fn noise_inflation(&self) -> f32 {
        if self.nis_rows == 0 {
            return 1.0;
        }
        let m = self.nis_sum / self.nis_rows as f32;
        if m > 1.0 && m.is_finite() {
            m
        } else {
            1.0
        }
    }

    /// The estimator's side of the trust for the current `theta`.
    fn judge(&self) -> Verdict {
        let e = self.estimate_without_trust(ExtendedStatus::Updated);
        let v = self.variances();
        let s2 = e.scale * e.scale * self.noise_inflation();
        let var = [v[0] * s2, v[1] * s2, v[2] * s2];
        let half = 0.5 * self.settings.prior_a;
        Verdict {
            enough: self.folded >= MIN_SAMPLES,
            excited: var.iter().all(|x| *x <= half * half),
            possible: physically_possible(e.a, var),
            settled: precise(var, self.settings.tolerance),
        }
    }

    /// The current estimate (see [`ExtendedEstimate`]) with `status`.
    pub fn estimate(&self, status: ExtendedStatus) -> ExtendedEstimate {
        let mut e = self.estimate_without_trust(status);
        e.trust = self.trust();
        e
    }

    fn estimate_without_trust(&self, status: ExtendedStatus) -> ExtendedEstimate {
        let [a1, a2, a3, p0, p1, p2, p3, p4, p5] = self.theta;
        let a = [a1, a2, a3];
        let scale = if self.settings.scale_correction {
            consistency_scale(a).unwrap_or(1.0)
        } else {
            1.0
        };
        // theta is finite, but near f32::MAX the scaled a is not: then report it unscaled.
        let scaled = [a1 * scale, a2 * scale, a3 * scale];
        let (a, scale) = if scaled.iter().all(|v| v.is_finite()) {
            (scaled, scale)
        } else {
            (a, 1.0)
        };
        ExtendedEstimate {
            a,
            effect_params: [[p0, p1, p2], [p3, p4, p5]],
            scale,
            status,
            trust: Status::NoInformation,
        }
    }

    /// One step for the gyro sample `omega` (rad/s, sensor axes) taken `dt` seconds after the
    /// previous call: stores it as a block node and, when it closes a block, applies the three
    /// rows of (I). Never panics.
    pub fn step(&mut self, omega: [f32; 3], dt: f32) -> ExtendedEstimate {
        let status = self.advance(omega, dt);
        self.estimate(status)
    }

    fn advance(&mut self, omega: [f32; 3], dt: f32) -> ExtendedStatus {
        if !(dt.is_finite() && dt > 0.0) {
            self.restart();
            return ExtendedStatus::InvalidTimeStep;
        }
        if !omega.iter().all(|w| w.is_finite()) {
            self.pending_dt += dt;
            return ExtendedStatus::NonFinite;
        }
        if omega.iter().any(|w| w.abs() >= self.settings.full_scale) {
            self.pending_dt += dt;
            self.exposure.saturate();
            return ExtendedStatus::Saturated;
        }
        self.exposure.accept(omega);
        let h = self.pending_dt + dt;
        self.pending_dt = 0.0;
        let Some(w0) = self.w0 else {
            self.open_block(omega);
            return ExtendedStatus::Anchored;
        };
        if h > self.settings.max_dt {
            self.open_block(omega);
            return ExtendedStatus::Gap;
        }
        let Some((w1, h1)) = self.w1 else {
            self.w1 = Some((omega, h));
            self.open = self.open.saturating_add(1);
            return ExtendedStatus::Buffered;
        };
        self.open = self.open.saturating_add(1);
        let p = |w: [f32; 3]| w[0] * w[1] * w[2];
        self.exposure.excite(p(w0), p(w1), h1);
        self.exposure.excite(p(w1), p(omega), h);
        // A Simpson pair closes here: add its share of the block integral.
        self.w0 = Some(omega);
        self.w1 = None;
        self.accumulate(w0, w1, omega, h1, h);
        self.pairs = self.pairs.saturating_add(1);
        if self.pairs < self.block_pairs {
            return ExtendedStatus::Buffered;
        }
        // The block closes here; the next one starts from this sample.
        let start = self.w_start.unwrap_or(w0);
        let ok = self.update(start, omega);
        let block_samples = self.open;
        self.open_block(omega);
        if ok {
            self.updates = self.updates.saturating_add(1);
            self.folded = self.folded.saturating_add(block_samples);
            self.verdict = self.judge();
            ExtendedStatus::Updated
        } else {
            ExtendedStatus::NumericalFault
        }
    }

    /// Starts a new block (and pair) at `omega`.
    fn open_block(&mut self, omega: [f32; 3]) {
        self.open = 0;
        self.w_start = Some(omega);
        self.w0 = Some(omega);
        self.w1 = None;
        self.acc = [[0.0; 3]; MAX_PARAMS];
        self.pairs = 0;
    }

    /// Adds the Simpson weights of (I) on nodes `w0, w1, w2` (intervals `h1`, `h2`) times the
    /// columns to the block's regressor.
    fn accumulate(&mut self, w0: [f32; 3], w1: [f32; 3], w2: [f32; 3], h1: f32, h2: f32) {
        let s = h1 + h2;
        let q = [
            s * (2.0 * h1 - h2) / (6.0 * h1),
            s * s * s / (6.0 * h1 * h2),
            s * (2.0 * h2 - h1) / (6.0 * h2),
        ];
        let a = [
            self.theta.first().copied().unwrap_or(0.0),
            self.theta.get(1).copied().unwrap_or(0.0),
            self.theta.get(2).copied().unwrap_or(0.0),
        ];
        let settled = self.a_settled();
        for (w, qm) in [w0, w1, w2].iter().zip(q.iter()) {
            let c = if settled {
                columns(&self.settings.effects, a, *w)
            } else {
                columns_linear_only(&self.settings.effects, a, *w)
            };
            for (xp, cp) in self.acc.iter_mut().zip(c.iter()) {
                for (xi, ci) in xp.iter_mut().zip(cp.iter()) {
                    *xi += qm * ci;
                }
            }
        }
    }

    /// The three rows of (I) for the block from `start` to `end` with the accumulated
    /// regressor.
    fn update(&mut self, start: [f32; 3], end: [f32; 3]) -> bool {
        let x = self.acc;
        let r = 2.0 * self.settings.noise_std * self.settings.noise_std;
        let (mut theta, mut p) = (self.theta, self.p);
        let mut nis = 0.0;
        for axis in 0..3 {
            let row: Vecp = core::array::from_fn(|k| {
                x.get(k).and_then(|c| c.get(axis)).copied().unwrap_or(0.0)
            });
            let y = end.get(axis).copied().unwrap_or(0.0) - start.get(axis).copied().unwrap_or(0.0);
            nis += rls_row(&mut theta, &mut p, &row, y, r);
        }
        let finite =
            theta.iter().all(|v| v.is_finite()) && p.iter().flatten().all(|v| v.is_finite());
        if finite {
            self.theta = theta;
            self.p = p;
            let sum = self.nis_sum + nis;
            if sum.is_finite() {
                self.nis_sum = sum;
                self.nis_rows = self.nis_rows.saturating_add(3);
            }
        }
        finite
    }
}

/// The columns of (E) with the bilinear ones held at zero (see
/// [`ExtendedIdentifier::set_bilinear_gate`]).
fn columns_linear_only(
    effects: &[Option<ExtraEffect>; MAX_EFFECTS],
    a: [f32; 3],
    w: [f32; 3],
) -> [[f32; 3]; MAX_PARAMS] {
    let mut c = columns(effects, a, w);
    let mut slots = c.iter_mut().skip(3);
    for e in effects.iter().flatten() {
        let bilinear = matches!(
            e,
            ExtraEffect::GyroBias | ExtraEffect::ProductsOfInertia | ExtraEffect::RotorMomentum
        );
        for _ in 0..3 {
            if let Some(col) = slots.next() {
                if bilinear {
                    *col = [0.0; 3];
                }
            }
        }
    }
    c
}

/// Number of parameters in use: `3 + 3 * (effects present)`.
fn n_params(effects: &[Option<ExtraEffect>; MAX_EFFECTS]) -> usize {
    3 + 3 * effects.iter().filter(|e| e.is_some()).count()
}

/// One scalar RLS update with forgetting factor 1: `k = P x / (r + x^T P x)`,
/// `theta += k (y - x^T theta)`, `P -= k (P x)^T`, then `P` symmetrised. Returns the
/// normalised innovation `e^2 / (r + x^T P x)` (expected 1 when the model and `r` are right;
/// 0 when the row was skipped).
fn rls_row(theta: &mut Vecp, p: &mut Matp, x: &Vecp, y: f32, r: f32) -> f32 {
    let px: Vecp = core::array::from_fn(|i| p.get(i).map_or(0.0, |row| dotp(row, x)));
    let s = r + dotp(x, &px);
    if !(s.is_finite() && s > 0.0) {
        return 0.0;
    }
    let e = y - dotp(x, theta);
    for (t, k) in theta.iter_mut().zip(px.iter()) {
        *t += k / s * e;
    }
    for (row, ki) in p.iter_mut().zip(px.iter()) {
        for (v, kj) in row.iter_mut().zip(px.iter()) {
            *v -= ki * kj / s;
        }
    }
    let pt = *p;
    for (i, row) in p.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            if let Some(o) = pt.get(j).and_then(|rj| rj.get(i)) {
                *v = 0.5 * (*v + o);
            }
        }
    }
    e * e / s
}

fn dotp(a: &Vecp, b: &Vecp) -> f32 {
    a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    let [a0, a1, a2] = a;
    let [b0, b1, b2] = b;
    [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]
}

/// The regressor columns of (E) at `w`, bilinear ones at `a`; unused slots zero.
pub fn columns(
    effects: &[Option<ExtraEffect>; MAX_EFFECTS],
    a: [f32; 3],
    w: [f32; 3],
) -> [[f32; 3]; MAX_PARAMS] {
    let [a1, a2, a3] = a;
    let [x, y, z] = w;
    let mut c: Cols = [[0.0; 3]; MAX_PARAMS];
    let base = [[y * z, 0.0, 0.0], [0.0, z * x, 0.0], [0.0, 0.0, x * y]];
    // J_f by columns: d f / d w_j.
    let jcol = [
        [0.0, a2 * z, a3 * y],
        [a1 * z, 0.0, a3 * x],
        [a1 * y, a2 * x, 0.0],
    ];
    let f = [a1 * y * z, a2 * z * x, a3 * x * y];
    let e = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let jmul = |v: [f32; 3]| -> [f32; 3] {
        let [v0, v1, v2] = v;
        let [j0, j1, j2] = jcol;
        core::array::from_fn(|i| {
            let g = |col: [f32; 3]| col.get(i).copied().unwrap_or(0.0);
            g(j0) * v0 + g(j1) * v1 + g(j2) * v2
        })
    };
    let ratios = inverse_ratios(a);
    let mut slots = c.iter_mut();
    for b in base {
        if let Some(s) = slots.next() {
            *s = b;
        }
    }
    for eff in effects.iter().flatten() {
        for (j, ej) in e.iter().enumerate() {
            let col = match eff {
                ExtraEffect::BodyTorque => *ej,
                ExtraEffect::Damping => {
                    core::array::from_fn(|i| if i == j { -ej_dot(ej, w) } else { 0.0 })
                }
                ExtraEffect::GyroBias => {
                    let jc = jcol.get(j).copied().unwrap_or([0.0; 3]);
                    [-jc[0], -jc[1], -jc[2]]
                }
                ExtraEffect::ProductsOfInertia => {
                    let ef = cross(*ej, f);
                    let jw = jmul(cross(*ej, w));
                    [ef[0] - jw[0], ef[1] - jw[1], ef[2] - jw[2]]
                }
                ExtraEffect::RotorMomentum => {
                    let ew = cross(*ej, w);
                    [ratios[0] * ew[0], ratios[1] * ew[1], ratios[2] * ew[2]]
                }
            };
            if let Some(s) = slots.next() {
                *s = col;
            }
        }
    }
    c
}

fn ej_dot(e: &[f32; 3], w: [f32; 3]) -> f32 {
    e[0] * w[0] + e[1] * w[1] + e[2] * w[2]
}

/// `(1, A1/A2, A1/A3)` from `a`. Any two of the `a_i` give the ratios (with `A1 = 1`):
/// `(a1, a2)`: `A2 = (1+a1)/(1-a2)`, `A3 = (1+a1 a2)/(1-a2)`;
/// `(a3, a1)`: `A2 = (1+a1 a3)/(1+a3)`, `A3 = (1-a1)/(1+a3)`;
/// `(a2, a3)`: `A2 = (1-a3)/(1+a2 a3)`, `A3 = (1+a2)/(1+a2 a3)`.
/// The pair whose denominator is farthest from zero is used (the others amplify errors of
/// `a`, e.g. `1 - a2 = 0.14` for a racquet); a ratio that is not finite and positive is
/// replaced by 1.
pub fn inverse_ratios(a: [f32; 3]) -> [f32; 3] {
    let [a1, a2, a3] = a;
    let cands = [
        (1.0 - a2, 1.0 + a1, 1.0 + a1 * a2),
        (1.0 + a3, 1.0 + a1 * a3, 1.0 - a1),
        (1.0 + a2 * a3, 1.0 - a3, 1.0 + a2),
    ];
    let mut best = (1.0f32, 1.0f32, 1.0f32);
    let mut best_abs = -1.0f32;
    for c in cands {
        if c.0.abs() > best_abs {
            best_abs = c.0.abs();
            best = c;
        }
    }
    let (d, n2, n3) = best;
    let ok = |r: f32| if r.is_finite() && r > 0.0 { r } else { 1.0 };
    [1.0, ok(d / n2), ok(d / n3)]
}

/// The common gyro scale factor `s` that makes `s a` a rigid body:
/// `c(s a) = s (a1 + a2 + a3) + s^3 a1 a2 a3 = 0`, so `s^2 = -(a1 + a2 + a3)/(a1 a2 a3)`.
/// `None` unless `s^2` lies in `[0.25, 4]` (a factor-of-two scale error is not a scale error).
pub fn consistency_scale(a: [f32; 3]) -> Option<f32> {
    let [a1, a2, a3] = a;
    let s2 = -(a1 + a2 + a3) / (a1 * a2 * a3);
    if !(s2.is_finite() && (0.25..=4.0).contains(&s2)) {
        return None;
    }
    Some(sqrt_newton(s2))
}

/// `sqrt(v)` for `v` in `[0.25, 4]` by 8 Newton steps from `(1 + v)/2` (converged to `f32`
/// rounding there), with `+ - * /` only.
fn sqrt_newton(v: f32) -> f32 {
    let mut x = 0.5 * (1.0 + v);
    for _ in 0..8 {
        x = 0.5 * (x + v / x);
    }
    x
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_and_damping_from_exact_samples() {
        for pairs in [1u16, 5] {
            recovers_a_and_damping(pairs);
        }
    }

    fn recovers_a_and_damping(pairs: u16) {
        // w' = a (.) (w2 w3, w3 w1, w1 w2) - d (.) w, integrated finely in f64.
        let a = [0.9f64, 0.2597, -0.94];
        let d = [0.05f64, 0.1, 0.02];
        let f = |w: [f64; 3]| {
            [
                a[0] * w[1] * w[2] - d[0] * w[0],
                a[1] * w[2] * w[0] - d[1] * w[1],
                a[2] * w[0] * w[1] - d[2] * w[2],
            ]
        };
        let mut s = ExtendedSettings::new([Some(ExtraEffect::Damping), None]);
        s.noise_std = 1e-3;
        let mut id = ExtendedIdentifier::new(s).unwrap();
        assert!(id.set_block_pairs(pairs));
        assert!(!id.set_block_pairs(0) && !id.set_bilinear_gate(f32::NAN));
        let mut w = [1.0f64, 1.0, 1.0];
        let dt = 1e-3f64;
        let mut est = id.step([1.0, 1.0, 1.0], dt as f32);
        for _ in 0..5000 {
            for _ in 0..10 {
                let h = dt / 10.0;
                let k1 = f(w);
                let k2 = f(core::array::from_fn(|i| w[i] + 0.5 * h * k1[i]));
                let k3 = f(core::array::from_fn(|i| w[i] + 0.5 * h * k2[i]));
                let k4 = f(core::array::from_fn(|i| w[i] + h * k3[i]));
                w = core::array::from_fn(|i| {
                    w[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                });
            }
            est = id.step(w.map(|v| v as f32), dt as f32);
        }
        for i in 0..3 {
            assert!((est.a[i] as f64 - a[i]).abs() < 2e-3, "{pairs}: {:?}", est);
            assert!(
                (est.effect_params[0][i] as f64 - d[i]).abs() < 2e-3,
                "{:?}",
                est
            );
        }
    }

    #[test]
    fn bad_input_has_a_status_and_state_stays_finite() {
        let mut id = ExtendedIdentifier::new(ExtendedSettings::new([None, None])).unwrap();
        assert_eq!(
            id.step([1.0, 1.0, 1.0], 0.01).status,
            ExtendedStatus::Anchored
        );
        assert_eq!(
            id.step([f32::NAN, 1.0, 1.0], 0.01).status,
            ExtendedStatus::NonFinite
        );
        assert_eq!(
            id.step([1.0, 1.0, 1.0], -1.0).status,
            ExtendedStatus::InvalidTimeStep
        );
        assert_eq!(
            id.step([1.0, 1.0, 1.0], 0.01).status,
            ExtendedStatus::Anchored
        );
        assert_eq!(id.step([1.0, 1.0, 1.0], 1.0).status, ExtendedStatus::Gap);
        assert_eq!(
            id.step([1.0, 1.0, 1.0], 0.01).status,
            ExtendedStatus::Buffered
        );
        let e = id.step([f32::MAX, 1e30, -1e30], 0.01);
        assert!(e.a.iter().all(|v| v.is_finite()), "{e:?}");
        let mut bad =
            ExtendedSettings::new([Some(ExtraEffect::Damping), Some(ExtraEffect::Damping)]);
        assert!(ExtendedIdentifier::new(bad).is_none());
        bad.effects = [None, None];
        bad.noise_std = 0.0;
        assert!(ExtendedIdentifier::new(bad).is_none());
    }

    #[test]
    fn consistency_scale_undoes_a_common_scale_error() {
        let a = [0.9f32, 0.2597, -0.94];
        // Make a exactly consistent by solving for a3.
        let a3 = -(a[0] + a[1]) / (1.0 + a[0] * a[1]);
        let a = [a[0], a[1], a3];
        let s = 1.03f32;
        let fitted = [a[0] / s, a[1] / s, a[2] / s];
        let got = consistency_scale(fitted).unwrap();
        assert!((got - s).abs() < 1e-4, "{got}");
        assert!((sqrt_newton(0.25) - 0.5).abs() < 1e-6 && (sqrt_newton(4.0) - 2.0).abs() < 1e-6);
    }
}
