//! What one step reports: the estimate (12), what happened to the sample, how far the estimate
//! can be trusted ([`Status`]), and counters for diagnosis.

use crate::convergence::Convergence;
use crate::inertia::{consistency, InertiaRatios};

/// What [`crate::Identifier::step`] did with one sample. Every input maps to exactly one of
/// these; only [`SampleStatus::Updated`] and [`SampleStatus::SignChange`] move the estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SampleStatus {
    /// The sample was integrated on an identifiable interval (2).
    Updated,
    /// `w1 w2 w3` changed sign between this sample and the previous one, both identifiable;
    /// the step was integrated with the sign-change correction.
    SignChange,
    /// `|w1 w2 w3| < w_min` here or at the previous sample: (2) fails, the estimate is held.
    Unidentifiable,
    /// The first usable sample, or the first after a restart: it anchors the integration.
    Anchored,
    /// The time since the last integrated sample exceeded `max_dt` (dropped samples, a pause):
    /// the integration restarts from this sample, the estimate is held.
    Gap,
    /// A component was NaN or infinite; the sample was ignored and its `dt` carried over.
    NonFinite,
    /// A component reached the gyro full scale; the sample was ignored and its `dt` carried
    /// over.
    Saturated,
    /// `dt` was zero, negative or not a number; the sample was ignored and the next one
    /// restarts the integration, because the time base is no longer known.
    InvalidTimeStep,
    /// The update produced a non-finite value (only reachable with extreme inputs); it was
    /// discarded and the estimate held.
    NumericalFault,
}

impl SampleStatus {
    /// True when the estimate was moved by this sample.
    pub const fn integrated(self) -> bool {
        matches!(self, SampleStatus::Updated | SampleStatus::SignChange)
    }

    /// True when the sample itself was refused (bad value or bad time step).
    pub const fn rejected(self) -> bool {
        matches!(
            self,
            SampleStatus::NonFinite | SampleStatus::Saturated | SampleStatus::InvalidTimeStep
        )
    }
}

/// The result of one step: the estimate of `a` by (12) and its status.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// `(a1, a2, a3)` by (12), in the sensor's axis order. Always finite.
    pub a: [f32; 3],
    /// What happened to this sample.
    pub status: SampleStatus,
    /// The paper's accuracy criterion, evaluated over identifiable time.
    pub convergence: Convergence,
    /// How far `a` can be trusted, from the information the data carried (see [`Status`]).
    pub trust: Status,
}

impl Estimate {
    /// Inertia ratios `A2/A1`, `A3/A1` implied by `a` (see [`InertiaRatios::from_a`]);
    /// `None` while the data has carried no information ([`Status::has_information`] false):
    /// before the first samples the estimate is only the initial value, not a body.
    pub fn ratios(&self) -> Option<InertiaRatios> {
        if !self.trust.has_information() {
            return None;
        }
        InertiaRatios::from_a(self.a)
    }

    /// The rigid-body consistency value `a1 + a2 + a3 + a1 a2 a3` (zero for any real body).
    pub fn consistency(&self) -> f32 {
        consistency(self.a)
    }
}

/// Running counts of what the identifier has seen, for telemetry and diagnosis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Every call of `step`.
    pub samples: u32,
    /// Samples that moved the estimate ([`SampleStatus::integrated`]).
    pub integrated: u32,
    /// Samples where (2) failed.
    pub unidentifiable: u32,
    /// Samples refused for their value or time step ([`SampleStatus::rejected`]).
    pub rejected: u32,
    /// Restarts after a gap longer than `max_dt`.
    pub gaps: u32,
    /// Sign changes of `w1 w2 w3` between identifiable stretches, where the correction applied.
    pub sign_changes: u32,
    /// Updates discarded as non-finite.
    pub numerical_faults: u32,
}

impl Counters {
    /// Counts one step's outcome. Saturating: a counter stops at `u32::MAX` rather than wrap.
    pub fn record(&mut self, status: SampleStatus) {
        self.samples = self.samples.saturating_add(1);
        let slot = match status {
            SampleStatus::Updated => &mut self.integrated,
            SampleStatus::SignChange => {
                self.sign_changes = self.sign_changes.saturating_add(1);
                &mut self.integrated
            }
            SampleStatus::Unidentifiable => &mut self.unidentifiable,
            SampleStatus::Gap => &mut self.gaps,
            SampleStatus::NonFinite | SampleStatus::Saturated | SampleStatus::InvalidTimeStep => {
                &mut self.rejected
            }
            SampleStatus::NumericalFault => &mut self.numerical_faults,
            SampleStatus::Anchored => return,
        };
        *slot = slot.saturating_add(1);
    }
}

/// Largest `|w_i|`, rad/s, that a thrown or flying rigid body plausibly reaches: a hand toss
/// spins at about 12 rad/s, a racquet at 35 rad/s, a gyro's widest range (+-2000 deg/s) is
/// 34.9 rad/s. A larger accepted rate means the samples are not in rad/s (deg/s data is
/// 57.3x too large): [`Status::UnitsLookWrong`].
pub const MAX_PLAUSIBLE_RATE: f32 = 50.0;

/// Fewest samples that must have entered the reported estimate before it is judged
/// ([`Status::TooFewSamples`] below this).
pub const MIN_SAMPLES: u32 = 10;

/// A rate must swing (largest minus smallest accepted value) by more than this many gyro
/// noise standard deviations on at least two axes for the motion to count as excitation in
/// [`Exposure::moved`]: white noise alone swings by about 8 sigma over `10^4` samples.
pub const SWING_SIGMAS: f32 = 20.0;

/// Absolute allowance on the consistency value `a1 + a2 + a3 + a1 a2 a3` on top of its
/// statistical bound in [`physically_possible`]: `f32` rounding and the discretisation bias
/// of the integrals (below `1e-5` per `a_i`).
pub const CONSISTENCY_FLOOR: f32 = 1e-4;

/// How far an estimate can be trusted, decided from the information the data carried, never
/// from the estimate's stillness alone. One status for every estimator of the crate: the ratio
/// estimators ([`crate::Identifier`], [`crate::Refined`], [`crate::ExtendedIdentifier`], each
/// by its `trust` method and in its estimate's `trust`), the tensor estimator
/// ([`crate::TensorEstimate::status`], also when it describes an output-error fit's tensor)
/// and the pipeline's recommended ratios ([`crate::Ratios::status`]).
///
/// The ratio estimators decide it by [`Status::assess`], the first status, in this order,
/// whose condition holds:
///
/// | status | given when |
/// |---|---|
/// | [`Status::NoInformation`] | no sample has been accepted and none was saturated |
/// | [`Status::Saturated`] | more than 1 % of the samples offered were at full scale (`100 saturated > accepted`) |
/// | [`Status::UnitsLookWrong`] | an accepted rate exceeded `MAX_PLAUSIBLE_RATE` |
/// | [`Status::TooFewSamples`] | fewer than `MIN_SAMPLES` samples are in the reported estimate |
/// | [`Status::NoExcitation`] | the data carried no information about `a` (estimator's rule) |
/// | [`Status::PhysicallyImpossible`] | the estimate is no rigid body beyond its uncertainty (`physically_possible`) |
/// | [`Status::Converging`] | the estimate's own precision is not yet the configured tolerance |
/// | [`Status::Converged`] | none of the above: informative data, a possible body, precise enough |
///
/// They never give [`Status::ModelMismatch`]. The tensor estimator
/// ([`crate::TensorEstimator::estimate`]) judges in its own order: [`Status::UnitsLookWrong`],
/// [`Status::TooFewSamples`], [`Status::NoExcitation`], [`Status::Saturated`],
/// [`Status::ModelMismatch`], [`Status::PhysicallyImpossible`], then [`Status::Converging`] or
/// [`Status::Converged`]. Neither it nor the pipeline ([`crate::Pipeline::estimate_and_ratios`])
/// gives [`Status::NoInformation`]: before any sample they say [`Status::TooFewSamples`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status {
    /// Nothing accepted yet (and nothing saturated): `a` is the initial value. Only the ratio
    /// estimators give it ([`Status::assess`]); the tensor estimator and the pipeline say
    /// [`Status::TooFewSamples`] instead.
    NoInformation,
    /// Too few samples in the reported estimate. Ratio estimators: fewer than `MIN_SAMPLES`.
    /// Tensor estimator: fewer than [`crate::TensorSettings::min_samples`] samples, or fewer
    /// equations than unknowns. The pipeline gives it as well where the refined identifier
    /// says [`Status::NoInformation`].
    TooFewSamples,
    /// The samples are probably not in the units assumed. Ratio estimators: an accepted rate
    /// beyond `MAX_PLAUSIBLE_RATE` (deg/s data read as rad/s?). Tensor estimator: rates above
    /// [`crate::TensorSettings::max_plausible_rate`] were seen, or more than a tenth of the
    /// steps were gaps longer than [`crate::TensorSettings::max_dt`] or than
    /// [`crate::MAX_STEP_TURN_RAD`] of turn (time in ms or us read as seconds?). The pipeline
    /// gives it to both its estimates as well when the accelerometer's still samples say it is
    /// not in m/s^2 ([`crate::AccelUnits`]).
    UnitsLookWrong,
    /// More than 1 % of the samples were at the gyro's full scale (a clipped throw): the
    /// estimate has gaps exactly where the motion is fastest. Widen the gyro's range. Ratio
    /// estimators: `100 saturated > accepted`; tensor estimator: `100 saturated > used +
    /// saturated`.
    Saturated,
    /// The data carried no information to separate the unknowns. Ratio estimators: samples
    /// arrived but did not excite (1): a still gyro, a spin about a principal axis,
    /// `|w1 w2 w3|` too small for too short a time (each estimator's rule is in the docs of
    /// its `trust` method). Tensor estimator: the information matrix is singular or its
    /// excitation below [`crate::TensorSettings::min_excitation`]: still, a pure spin about
    /// one axis, or too little motion to separate the entries.
    NoExcitation,
    /// The model does not explain the data: the residual is far above the gyro noise (wrong
    /// time step, contact, thrust, an effect the model lacks). Tensor estimator: the residual
    /// beyond [`crate::TensorSettings::mismatch_ratio`] times the noise, or an output-error
    /// fit's beyond `OUTPUT_ERROR_FIT_RATIO` times it with an exact rotor momentum, or at the
    /// noise's level but coloured ((F10') of the fit: a walking or truncating gyro). Pipeline:
    /// an unmodelled torque, a body that is not rigid or a gyro bias the tensor's model lacks,
    /// or ratios from a model that does not fit the flight. Never given by
    /// [`Status::assess`].
    ModelMismatch,
    /// The estimate is no rigid body beyond its uncertainty. Ratio estimators: some
    /// `|a_i| >= 1` or the consistency value `a1 + a2 + a3 + a1 a2 a3` far from 0
    /// (`physically_possible`; the paper's identifier by its own rule, once settled). Tensor
    /// estimator: not an inertia tensor by more than three standard deviations: not positive
    /// definite, or a principal moment larger than the sum of the other two. Typical cause: a
    /// wrong time step (`dt` 10x too small gives `a` 10x too large), a gyro scale error, an
    /// unmodelled torque.
    PhysicallyImpossible,
    /// Informative data, a possible body, not yet precise enough: a standard deviation above
    /// the tolerance (the paper's identifier: its criterion not yet met; the tensor estimator:
    /// [`crate::TensorSettings::tolerance`], or the estimate not yet a valid tensor although
    /// within three standard deviations of one). The pipeline also holds a `Converged` here
    /// while a gyro bias has been neither measured nor ruled out.
    Converging,
    /// The estimate's own standard deviations are below the tolerance, it is a possible body,
    /// and the data carried information (the tensor estimator: also its residual within
    /// [`crate::TensorSettings::mismatch_ratio`]). The only status whose estimate is to be
    /// used ([`Status::trusted`]).
    Converged,
}

impl Status {
    /// False for [`Status::NoInformation`], [`Status::TooFewSamples`] and
    /// [`Status::NoExcitation`]: the estimate is still (mostly) the initial value, and
    /// [`Estimate::ratios`] gives `None`.
    pub const fn has_information(self) -> bool {
        !matches!(
            self,
            Status::NoInformation | Status::TooFewSamples | Status::NoExcitation
        )
    }

    /// True only for [`Status::Converged`].
    pub const fn trusted(self) -> bool {
        matches!(self, Status::Converged)
    }

    /// The rule of the table on [`Status`]: the data-side conditions from `exposure`, the
    /// estimator-side ones from `verdict`.
    pub fn assess(exposure: &Exposure, verdict: Verdict) -> Status {
        if exposure.accepted == 0 && exposure.saturated == 0 {
            Status::NoInformation
        } else if exposure.saturated > 0
            && u64::from(exposure.saturated) * 100 > u64::from(exposure.accepted)
        {
            Status::Saturated
        } else if exposure.peak_rate > MAX_PLAUSIBLE_RATE {
            Status::UnitsLookWrong
        } else if !verdict.enough {
            Status::TooFewSamples
        } else if !verdict.excited {
            Status::NoExcitation
        } else if !verdict.possible {
            Status::PhysicallyImpossible
        } else if !verdict.settled {
            Status::Converging
        } else {
            Status::Converged
        }
    }
}

/// The estimator's side of [`Status::assess`]: four answers each estimator gives by its own
/// rule (documented on the estimator's `trust` method).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Verdict {
    /// At least `MIN_SAMPLES` samples are in the reported estimate.
    pub enough: bool,
    /// The data carried information about `a`.
    pub excited: bool,
    /// The estimate is a rigid body within its uncertainty.
    pub possible: bool,
    /// The estimate's precision meets the configured tolerance.
    pub settled: bool,
}

impl Verdict {
    /// Before any estimate: nothing known, nothing excluded.
    pub const NONE: Verdict = Verdict {
        enough: false,
        excited: false,
        possible: true,
        settled: false,
    };
}

/// What the data offered an estimator, whatever the estimator: counts, the largest rate and
/// the excitation `E = integral |w1 w2 w3| dt` of the identifiability condition (2). Fixed
/// size (40 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Exposure {
    /// Samples accepted (finite, below full scale, valid `dt`).
    pub accepted: u32,
    /// Samples refused at full scale.
    pub saturated: u32,
    /// Largest `|w_i|` among accepted samples, rad/s.
    pub peak_rate: f32,
    /// `E = integral |w1 w2 w3| dt` over the intervals the estimator integrated, by the
    /// trapezoid, (rad/s)^3 s.
    pub excitation: f32,
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Default for Exposure {
    fn default() -> Self {
        Self::new()
    }
}

impl Exposure {
    /// Nothing seen.
    pub const fn new() -> Self {
        Exposure {
            accepted: 0,
            saturated: 0,
            peak_rate: 0.0,
            excitation: 0.0,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
        }
    }

    /// Counts an accepted sample: `peak_rate = max |w_i|`, and each axis's range.
    #[inline]
    pub fn accept(&mut self, omega: [f32; 3]) {
        self.accepted = self.accepted.saturating_add(1);
        for ((lo, hi), w) in self.lo.iter_mut().zip(self.hi.iter_mut()).zip(omega) {
            *lo = lo.min(w);
            *hi = hi.max(w);
            self.peak_rate = self.peak_rate.max(w.abs());
        }
    }

    /// Counts a sample refused at full scale.
    #[inline]
    pub fn saturate(&mut self) {
        self.saturated = self.saturated.saturating_add(1);
    }

    /// Adds `1/2 (|p0| + |p1|) h` to [`Exposure::excitation`] for an integrated interval of
    /// `h` seconds between samples with triple products `p0`, `p1` (ignored unless finite).
    #[inline]
    pub fn excite(&mut self, p0: f32, p1: f32, h: f32) {
        let e = self.excitation + 0.5 * (p0.abs() + p1.abs()) * h;
        if e.is_finite() {
            self.excitation = e;
        }
    }

    /// `max w_i - min w_i` over the accepted samples, per axis (0 before any).
    pub fn swing(&self) -> [f32; 3] {
        let mut s = [0.0; 3];
        for ((si, lo), hi) in s.iter_mut().zip(self.lo).zip(self.hi) {
            let d = hi - lo;
            *si = if d.is_finite() { d } else { 0.0 };
        }
        s
    }

    /// True when at least two axes swung by more than `SWING_SIGMAS` `noise_std`: the
    /// rates changed beyond what noise (or a constant bias) explains, so (1) was exercised.
    pub fn moved(&self, noise_std: f32) -> bool {
        let bar = SWING_SIGMAS * noise_std;
        self.swing().iter().filter(|d| **d > bar).count() >= 2
    }
}

/// Physical validity of an estimate `a` with per-axis variances `var` (actual units, not per
/// `sigma^2`; axes taken independent), beyond its uncertainty:
///
/// * every `|a_i| < 1` (the triangle inequality `|A_j - A_k| < A_i`), or above 1 by at most
///   3 standard deviations: `(|a_i| - 1)^2 <= 9 var_i`;
/// * the consistency value `c = a1 + a2 + a3 + a1 a2 a3` within 4 of its standard deviations
///   plus [`CONSISTENCY_FLOOR`]: `(|c| - floor)^2 <= 16 var_c` with
///   `var_c = sum_i (1 + a_j a_k)^2 var_i` (`dc/da_i = 1 + a_j a_k`).
///
/// Together these make the inertia ratios of [`InertiaRatios::from_a`] positive. Uses no
/// square root (comparisons of squares). Non-finite input is not possible.
pub fn physically_possible(a: [f32; 3], var: [f32; 3]) -> bool {
    let [a1, a2, a3] = a;
    let [v1, v2, v3] = var;
    let axis_ok = |ai: f32, vi: f32| {
        let over = ai.abs() - 1.0;
        over < 0.0 || over * over <= 9.0 * vi
    };
    let d = [1.0 + a2 * a3, 1.0 + a3 * a1, 1.0 + a1 * a2];
    let var_c = d[0] * d[0] * v1 + d[1] * d[1] * v2 + d[2] * d[2] * v3;
    let over = consistency(a).abs() - CONSISTENCY_FLOOR;
    let c_ok = over <= 0.0 || over * over <= 16.0 * var_c;
    axis_ok(a1, v1) && axis_ok(a2, v2) && axis_ok(a3, v3) && c_ok
}

/// True when every standard deviation is below `tolerance`: `var_i < tolerance^2`.
pub fn precise(var: [f32; 3], tolerance: f32) -> bool {
    let t2 = tolerance * tolerance;
    var.iter().all(|v| *v < t2)
}

/// `ln(x)` for finite `x > 0` (0 otherwise) with `+ - * /` only: `x = 2^e m`,
/// `ln x = e ln 2 + 2 artanh((m - 1)/(m + 1))`, three terms of the series (error below
/// `3e-4`). Used once per settings, for thresholds.
pub(crate) fn ln_approx(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) || x < f32::MIN_POSITIVE {
        return 0.0;
    }
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let ln_m = 2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * 0.2));
    e as f32 * core::f32::consts::LN_2 + ln_m
}

#[cfg(test)]
mod trust_tests {
    use super::*;

    #[test]
    fn ln_approx_is_close() {
        for x in [1e-3f32, 0.5, 1.0, 2.0, 10.0, 1234.5] {
            let want = (x as f64).ln() as f32;
            assert!((ln_approx(x) - want).abs() < 3e-4, "{x}");
        }
        assert_eq!(ln_approx(-1.0), 0.0);
    }

    #[test]
    fn order_of_the_table() {
        let mut e = Exposure::new();
        let all = Verdict {
            enough: true,
            excited: true,
            possible: true,
            settled: true,
        };
        assert_eq!(Status::assess(&e, all), Status::NoInformation);
        for _ in 0..100 {
            e.accept([1.0, -2.0, 3.0]);
        }
        assert_eq!(Status::assess(&e, all), Status::Converged);
        assert_eq!(
            Status::assess(
                &e,
                Verdict {
                    settled: false,
                    ..all
                }
            ),
            Status::Converging
        );
        assert_eq!(
            Status::assess(
                &e,
                Verdict {
                    possible: false,
                    ..all
                }
            ),
            Status::PhysicallyImpossible
        );
        assert_eq!(
            Status::assess(
                &e,
                Verdict {
                    excited: false,
                    ..all
                }
            ),
            Status::NoExcitation
        );
        assert_eq!(Status::assess(&e, Verdict::NONE), Status::TooFewSamples);
        e.saturate();
        assert_eq!(Status::assess(&e, all), Status::Converged);
        e.saturate();
        assert_eq!(Status::assess(&e, all), Status::Saturated);
        let mut e = Exposure::new();
        e.accept([60.0, 0.0, 0.0]);
        assert_eq!(Status::assess(&e, all), Status::UnitsLookWrong);
        assert_eq!(e.swing(), [0.0; 3]);
    }

    #[test]
    fn physical_validity() {
        let a = [0.9f32, 0.4 / 1.54, -0.94];
        assert!(physically_possible(a, [0.0; 3]));
        assert!(!physically_possible(a.map(|x| 10.0 * x), [1e-4; 3]));
        assert!(!physically_possible(a.map(|x| x / 57.3), [1e-8; 3]));
        // Within its uncertainty a slightly inconsistent estimate is still a body.
        assert!(physically_possible(a.map(|x| x / 1.01), [1e-3; 3]));
        assert!(precise([1e-8; 3], 1e-3) && !precise([2e-6, 0.0, 0.0], 1e-3));
    }
}
