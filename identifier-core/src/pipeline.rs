//! The sample path the firmware and the host tool share: free-flight gate, guard delay, gyro
//! bias, tensor estimator.
//!
//! ```text
//! sample -> FreeFlightGate (window fit of (F1)) -> delay line of `delay` samples
//!        -> fed to TensorEstimator only if the gate has held free from `guard_release`
//!           before the sample until `delay` samples after it
//! ```
//!
//! A sample is committed to the estimator only once the gate has seen `delay` samples past it
//! (the catch guard): a catch makes the window that contains it fail the fit within a block or
//! two (the gate's low-pass filter delays a gentle touch by about 10 ms, a hard one by less),
//! and every sample still in the delay line is dropped, so no hand or impact sample reaches the
//! estimator. At the release, samples are fed only from `guard_release` seconds after the
//! start of the first free window. Without an accelerometer every sample is taken as free and
//! the delay is zero.

use crate::free_flight::{FreeFlightGate, GateSettings, WindowFit};
use crate::output_error::StretchOutcome;
use crate::ratio_fit::{FlightRatioFit, RatioFit, RatioFitEstimate};
use crate::refined::{Refined, RefinedSettings};
use crate::refined_bias::RefinedBias;
use crate::status::{physically_possible, precise, SampleStatus, Status};
use crate::tensor::{
    products_wald, TensorEstimate, TensorEstimator, TensorMethod, TensorModel, TensorSettings,
    Uncertainty,
};
use crate::tensor_fit::{FlightTensorFit, TensorFit};

/// Tuning of [`Pipeline`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PipelineSettings {
    /// The estimator.
    pub tensor: TensorSettings,
    /// The ratio estimator fed the same samples ([`Pipeline::ratios`]).
    pub refined: RefinedSettings,
    /// The gate.
    pub gate: GateSettings,
    /// Seconds after the start of the first free window before samples are fed.
    pub guard_release: f32,
    /// Seconds a sample waits in the delay line (the catch guard), at most the line's capacity.
    pub guard_catch: f32,
    /// Nominal sample rate of the input, Hz (turns the guards into sample counts).
    pub rate_hz: f32,
    /// Input samples averaged into one estimator sample (1 to 16). The motion of a thrown body
    /// is slow against a gyro at several kHz; averaging `d` samples keeps the information
    /// (white noise averages down by `sqrt(d)`) and divides the per-sample cost of the gate
    /// and the estimators by `d`. The other settings are for the decimated rate.
    pub decimation: u8,
    /// Time variance of each input reading's own averaging window over its interval squared:
    /// 0 for a gyro read at instants, `s^2 / 12` for one that reports the mean rate over the last
    /// `s` of each interval (PX4's `sensor_combined`: the rate integrated over the sampling period,
    /// `s = 1` when every sample is logged). The output-error fits count it in their block means
    /// ((B0) of the fits' shared block buffer): on a fast tumble logged that way at a low rate,
    /// taking the means for instants puts `a` many standard deviations off while `Converged` (the
    /// test `a_px4_gyro_that_averages_over_its_interval_is_read_as_means`).
    pub reading_window: f32,
    /// Time variance of the gyro's own low-pass filter, s^2 (the second cumulant of its
    /// impulse response: `tau^2` per first-order stage of time constant `tau`), 0 for an
    /// unfiltered gyro; the fits count it in their block means ((B0') of the fits' block
    /// buffer). The filter's delay is taken out of the sample times before the pipeline.
    pub reading_smoothing: f32,
    /// How far a free flight may turn, rad (`sum |w_x| + |w_y| + |w_z|` times the time step,
    /// at least the angle turned), before its output-error fits close a window and start the
    /// next (W1). One trajectory from one initial rate is fitted per window: over a long
    /// tumble (a satellite's minutes to hours, a long toss) `f32` and the model's own
    /// sensitivity to its start make one trajectory drift from the motion by more than the
    /// gyro's noise, and the fit fails. The windows' estimates are pooled by their
    /// information, like the stretches of several throws; memory and the per-sample cost do
    /// not grow with the flight. Only with a rotor momentum and without the free-flight gate
    /// (no accelerometer: a satellite's continuous tumble with its wheels, a log taken whole):
    /// without rotor momentum the fits hold the integrated motion on its two invariants ((F6)
    /// of the tensor fit, the ratio fit likewise), which keeps one trajectory of a long
    /// gyro-only tumble at its bound, and windows would only cost information
    /// (`scripts/bench-estimators.sh`); a gated flight is a throw, which turns less than the
    /// default ([`WINDOW_TURN_RAD`]; 35 rad/s for 0.6 s), and its fits run when it ends,
    /// never inside it. Not finite: no windows.
    pub window_turn_rad: f32,
    /// The gyro's readings were moved to their counts' centres from a truncation toward zero
    /// (`k q -> k q + sign(k) q / 2`, the host's (Q1)). What is left of each count's width is
    /// an error the fits' white noise does not hold, so a tensor from such readings is at most
    /// `ModelMismatch`, as one whose residual is coloured ((F10') of the tensor fit).
    pub centred_readings: bool,
}

/// The default [`PipelineSettings::window_turn_rad`], rad: eight turns of the L1 rate. The
/// test `long_tumbles_are_fitted_in_windows` (in `pipeline`) runs a wheel-driven tumble through
/// several windows.
pub const WINDOW_TURN_RAD: f32 = 50.0;

impl PipelineSettings {
    /// Settings for a gyro at `rate_hz` with white noise `noise_std` rad/s: guards of 50 ms
    /// after the release and 30 ms before the catch.
    ///
    /// Above 1.5 kHz the input is averaged down to about 1 kHz (`decimation = round(rate /
    /// 1000)`: 8 at 8 kHz, 4 at 4 kHz, 2 at 2 kHz, 1 below 1.5 kHz); the estimators and the
    /// gate get the decimated rate and the averaged noise `noise_std / sqrt(decimation)`. A
    /// thrown body turns at most about 35 rad/s (a +-2000 deg/s gyro's full scale): at 1 kHz
    /// that is 0.035 rad per estimator sample, and the output-error fits model each sample as
    /// the mean it is (block means to second order in their time spread), so nothing is lost
    /// that the bound would count, and the per-input cost at 8 kHz is an eighth of a 1 kHz
    /// step.
    pub fn for_rate(rate_hz: f32, noise_std: f32) -> Self {
        let d = rate_hz / 1000.0 + 0.5;
        let decimation: u8 = if d >= 16.0 {
            16
        } else if d >= 1.0 {
            d as u8
        } else {
            1
        };
        let df = decimation as f32;
        let rate = rate_hz / df;
        let noise = noise_std / crate::symmetric::sqrt(df);
        PipelineSettings {
            tensor: TensorSettings::for_rate(rate, noise),
            refined: RefinedSettings::for_rate(rate, noise),
            gate: GateSettings::for_rate(rate),
            guard_release: 0.05,
            guard_catch: 0.03,
            rate_hz,
            decimation,
            reading_window: 0.0,
            reading_smoothing: 0.0,
            window_turn_rad: WINDOW_TURN_RAD,
            centred_readings: false,
        }
    }

    /// The same settings for readings moved to their counts' centres
    /// ([`PipelineSettings::centred_readings`]).
    pub fn with_centred_readings(mut self, centred: bool) -> Self {
        self.centred_readings = centred;
        self
    }

    /// The same settings for a gyro whose readings are each the mean rate over the last
    /// `span` (0 to 1) of their sample interval ([`PipelineSettings::reading_window`]
    /// `= span^2 / 12`; 1 for PX4's `sensor_combined` logged at its full rate). Other
    /// values: read at instants.
    pub fn with_averaging_gyro(mut self, span: f32) -> Self {
        self.reading_window = if span > 0.0 && span <= 1.0 {
            span * span / 12.0
        } else {
            0.0
        };
        self
    }

    /// The same settings for a gyro whose readings have passed through a low-pass filter of
    /// time variance `smoothing` s^2 ([`PipelineSettings::reading_smoothing`]; Betaflight logs
    /// its filtered gyro). Not finite or negative: no filter.
    pub fn with_filtered_gyro(mut self, smoothing: f32) -> Self {
        self.reading_smoothing = if smoothing > 0.0 && smoothing.is_finite() {
            smoothing
        } else {
            0.0
        };
        self
    }

    /// The same settings with the gyro's full scale (rad/s) given to both estimators: a
    /// sample at or beyond it is saturated.
    pub fn with_full_scale(mut self, full_scale: f32) -> Self {
        self.tensor.full_scale = full_scale;
        self.refined.full_scale = full_scale;
        self
    }

    /// The same settings with the rotor momentum known to `quantum` kg m^2/s (the rotor
    /// inertia times the speed telemetry's step; see
    /// [`TensorSettings::momentum_resolution`]).
    pub fn with_momentum_resolution(mut self, quantum: f32) -> Self {
        self.tensor.momentum_resolution = quantum;
        self
    }
}

/// Which estimator gave [`Pipeline::ratios`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RatioSource {
    /// The tensor estimator (rotor momentum, or products of inertia needed).
    Tensor,
    /// The refined identifier (principal axes, no rotor).
    Refined,
    /// The refined identifier with a constant gyro bias (principal axes, no rotor, a bias
    /// detected).
    RefinedBias,
    /// The output-error fit of the whole trajectory ([`RatioFit`]: principal axes, no rotor,
    /// free flights that have ended), with a constant gyro bias when its test found one.
    Trajectory,
}

/// The recommended ratios: [`Pipeline::ratios`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ratios {
    /// `a = ((A2-A3)/A1, (A3-A1)/A2, (A1-A2)/A3)`, `None` before there is information.
    pub a: Option<[f32; 3]>,
    /// Standard deviations of `a`.
    pub std_a: Option<[f32; 3]>,
    /// Why it is or is not to be trusted.
    pub status: Status,
    /// Which estimator gave them.
    pub source: RatioSource,
}

/// The trajectory fit gives the ratios only while its residual noise is at most this many times
/// the configured gyro noise (the model holds to the noise). On simulated throws the ratio is
/// near 1; on the racquet tosses, where aerodynamic torque leaves a residual tens of times the
/// noise, the whole-trajectory fit spreads more from toss to toss than the refined identifier
/// (measured with `scripts/bench-estimators.sh`, racquet section).
pub const TRAJECTORY_FIT_RATIO: f32 = 2.0;

/// The verdicts about the data themselves (too few samples, no excitation, units, clipping):
/// they hold for every estimate from the same samples. `None` for the others.
fn data_verdict(status: Status) -> Option<Status> {
    match status {
        Status::TooFewSamples
        | Status::NoExcitation
        | Status::UnitsLookWrong
        | Status::Saturated => Some(status),
        _ => None,
    }
}

/// One sample waiting in the delay line.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pending {
    /// Index of the estimator sample since the pipeline started (0-based; after decimation).
    pub index: u32,
    /// Index of the first input sample averaged into it.
    pub first_input: u32,
    /// Input samples averaged into it.
    pub inputs: u8,
    /// Rate, rad/s, as measured.
    pub omega: [f32; 3],
    /// Rotor momentum, kg m^2/s.
    pub h: [f32; 3],
    /// Time step, s.
    pub dt: f32,
}

/// One input sample: rate, specific force, rotor momentum, time step.
type Raw = ([f32; 3], [f32; 3], [f32; 3], f32);

/// Input samples being averaged into one estimator sample.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Group {
    omega: [f32; 3],
    accel: [f32; 3],
    h: [f32; 3],
    dt: f32,
    n: u8,
    first: u32,
    /// A refused input sample (non-finite, bad time step, saturated) in the group: it is
    /// passed on as it is, with the group's time, so the estimators refuse it as before.
    taint: Option<Raw>,
}

impl Group {
    const EMPTY: Group = Group {
        omega: [0.0; 3],
        accel: [0.0; 3],
        h: [0.0; 3],
        dt: 0.0,
        n: 0,
        first: 0,
        taint: None,
    };
}

/// What happened to the sample that left the delay line.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Exit {
    /// The sample, with the gyro bias removed when it was fed.
    pub sample: Pending,
    /// `Some(status)` when it was fed to the estimator, `None` when the gate held it back.
    pub fed: Option<SampleStatus>,
}

/// Gate, delay line and estimator. `N` is the delay line's capacity in samples (the catch guard
/// is at most `N` samples).
///
/// ```
/// use identifier_core::{FlightPipeline, PipelineSettings};
///
/// // On the bench (gravity only) nothing reaches the estimator, and the gyro bias is learnt.
/// let mut p = FlightPipeline::new(PipelineSettings::for_rate(1000.0, 1e-3), true).unwrap();
/// for _ in 0..1000 {
///     let exit = p.step([0.01, 0.0, -0.02], [0.0, 0.0, 9.81], [0.0; 3], 1e-3);
///     assert!(exit.map_or(true, |e| e.fed.is_none()));
/// }
/// assert_eq!(p.throws(), 0);
/// assert!((p.bias()[0] - 0.01).abs() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pipeline<const N: usize> {
    settings: PipelineSettings,
    gate: FreeFlightGate,
    use_gate: bool,
    estimator: TensorEstimator,
    refined: Refined,
    /// The refined identifier with a constant gyro bias, fed the same samples.
    refined_bias: RefinedBias,
    /// The output-error fit of (1), fed the same samples, fitted at each stretch's end.
    trajectory: FlightRatioFit,
    /// The output-error fit of the tensor with the rotor momentum, likewise.
    tensor_fit: FlightTensorFit,
    /// A free flight has ended (the gate closed) and its output-error fits have not run yet.
    fits_pending: bool,
    /// A non-zero rotor momentum reached the estimator.
    rotor_seen: bool,
    /// The caller removed a measured gyro bias from the samples ([`Pipeline::set_bias_removed`]).
    bias_removed: bool,
    line: [Pending; N],
    head: usize,
    len: usize,
    delay: usize,
    guard_release: u32,
    free_since: Option<u32>,
    index: u32,
    /// Input samples so far, and the group being averaged.
    input_index: u32,
    group: Group,
    feeding: bool,
    /// The L1 angle turned since the fits' window began (W1).
    turned: f32,
    throws: u32,
    fed_inputs: u32,
}

/// The capacity used by the firmware and the host tool (so both give the same bits): a delay
/// line of 128 samples, 64 ms at the at most 3 kHz the estimators run at after decimation
/// (the catch guard needs 30 ms plus one gate block). The whole pipeline, with the two
/// output-error fits' block buffers, is about 36 KB: the firmware keeps its copies on the
/// stack few.
pub type FlightPipeline = Pipeline<128>;

impl<const N: usize> Pipeline<N> {
    /// A pipeline, or `None` when the settings are not usable. `with_accel = false` (a log or
    /// a board without an accelerometer) takes every sample as free flight.
    pub fn new(settings: PipelineSettings, with_accel: bool) -> Option<Self> {
        let gate = FreeFlightGate::new(settings.gate)?;
        let estimator = TensorEstimator::new(settings.tensor)?;
        let refined = Refined::new(settings.refined)?;
        let rs = &settings.refined;
        let refined_bias = RefinedBias::new(rs.block, rs.max_dt, rs.full_scale, rs.noise_std)?;
        let (window, smoothing) = (settings.reading_window, settings.reading_smoothing);
        let trajectory = RatioFit::new(rs.full_scale, rs.max_dt, rs.noise_std)
            .with_reading_window(window)
            .with_reading_smoothing(smoothing);
        let ts = &settings.tensor;
        let tensor_fit = TensorFit::new(ts.full_scale, ts.max_dt, ts.noise_std)
            .with_momentum_resolution(ts.momentum_resolution)
            .with_reading_window(window)
            .with_reading_smoothing(smoothing);
        let rate = settings.rate_hz / settings.decimation as f32;
        let usable = rate.is_finite()
            && rate > 0.0
            && settings.decimation >= 1
            && settings.decimation <= 16
            && settings.guard_release >= 0.0
            && settings.guard_catch >= 0.0;
        if !usable {
            return None;
        }
        let block = settings.gate.block as f32;
        let want = settings.guard_catch * rate + block;
        let delay = if !with_accel {
            0
        } else if want >= N as f32 {
            N
        } else {
            want as usize
        };
        // Without an accelerometer there is no release to guard against: every sample counts.
        let gr = if with_accel {
            settings.guard_release * rate
        } else {
            0.0
        };
        let guard_release = if gr >= 1e6 { 1_000_000 } else { gr as u32 };
        Some(Pipeline {
            settings,
            gate,
            use_gate: with_accel,
            estimator,
            refined,
            refined_bias,
            trajectory,
            tensor_fit,
            fits_pending: false,
            rotor_seen: false,
            bias_removed: false,
            line: [Pending {
                index: 0,
                first_input: 0,
                inputs: 0,
                omega: [0.0; 3],
                h: [0.0; 3],
                dt: 0.0,
            }; N],
            head: 0,
            len: 0,
            delay,
            guard_release,
            free_since: if with_accel { None } else { Some(0) },
            index: 0,
            input_index: 0,
            group: Group::EMPTY,
            feeding: false,
            turned: 0.0,
            throws: 0,
            fed_inputs: 0,
        })
    }

    /// The settings.
    pub fn settings(&self) -> &PipelineSettings {
        &self.settings
    }

    /// The estimate from every sample fed so far.
    ///
    /// Once a free flight has ended and the output-error fit of the tensor ([`TensorFit`]:
    /// in kg m^2 with rotor momentum, else up to scale) fits to the noise (residual at most
    /// [`TRAJECTORY_FIT_RATIO`] times the configured gyro noise), the tensor is that fit's
    /// (efficient for white gyro noise), described and judged by the tensor estimator;
    /// otherwise the tensor estimator's own, `ModelMismatch` instead of `Converged` or
    /// `Converging` when a gyro bias was detected ([`Pipeline::ratios`] from
    /// [`RatioSource::RefinedBias`]): the equation error has no bias model and takes a bias for
    /// products of inertia (during a gyro-only flight with a bias of 2e-3 rad/s it said
    /// `Converged`, with products of inertia on a body that has none). `UnitsLookWrong` when
    /// the accelerometer's still samples say it is not in m/s^2 ([`crate::AccelUnits`]).
    pub fn estimate(&self) -> TensorEstimate {
        self.estimate_and_ratios().0
    }

    /// [`Pipeline::estimate`] from the estimator's own estimate `own`: the output-error fit's
    /// tensor (in kg m^2 with a rotor, else up to scale) when there is one that fits to the
    /// noise, else `own`.
    fn reported(&self, own: TensorEstimate) -> TensorEstimate {
        let noise = self.settings.tensor.noise_std;
        let fit = if self.rotor_seen {
            self.tensor_fit.estimate()
        } else {
            self.tensor_fit.estimate_normalized()
        };
        // With a rotor the fit is reported even when it does not fit to the noise (its status
        // then says `ModelMismatch`): the equation error it would fall back on has the same
        // model error and, on real throws, spread more from throw to throw than the fit from
        // the rotor's spin-up (`TensorFit::close`).
        match fit {
            Some(f) if self.rotor_seen || f.noise <= TRAJECTORY_FIT_RATIO * noise => {
                let t = &f.tensor;
                let j = [t[0][0], t[1][1], t[2][2], t[0][1], t[0][2], t[1][2]];
                // (F13) of the fit: with a walking bias, the residual's level with the walk's.
                let ratio = f.residual / noise;
                let coloured = f.coloured || self.settings.centred_readings;
                if self.rotor_seen {
                    self.estimator.with_tensor(own, j, f.cov, ratio, coloured)
                } else {
                    self.estimator
                        .with_normalized(own, j, f.cov, ratio, coloured)
                }
            }
            _ => own,
        }
    }

    /// The tensor's output-error fit fed the same samples.
    pub fn tensor_fit(&self) -> &FlightTensorFit {
        &self.tensor_fit
    }

    /// The same pipeline with the tensor fit's multiple shooting on (the default) or off
    /// ([`TensorFit::with_multiple_shooting`]).
    pub fn with_multiple_shooting(mut self, on: bool) -> Self {
        self.tensor_fit = self.tensor_fit.with_multiple_shooting(on);
        self
    }

    /// The recommended ratios `a` with their standard deviations and status, from the samples
    /// fed so far:
    ///
    /// * with a rotor momentum: the tensor's `a` ([`TensorEstimate`]);
    /// * once a free flight has ended, principal axes (or a gyro bias found), and the model
    ///   fitting to the noise (residual at most [`TRAJECTORY_FIT_RATIO`] times the configured
    ///   gyro noise, no constant torque found by its score test, [`RatioFitEstimate::torque`]):
    ///   the output-error fit of the whole trajectory ([`RatioFit`], all three
    ///   axes jointly, the rigid-body constraint built in, a constant bias when its
    ///   likelihood-ratio test finds one), the efficient estimator for white gyro noise;
    /// * once a free flight has ended, that fit not fitting to the noise (or failing outright,
    ///   [`StretchOutcome::Failed`]) and the tensor not `Converged` with products of inertia:
    ///   the refined identifier's, `ModelMismatch` (the torque-free model does not hold; of the
    ///   estimators here it is the least affected on real tosses through air);
    /// * a constant gyro bias detected (the refined identifier and its bias-augmented twin
    ///   [`RefinedBias`] disagree beyond their noise): the bias model's, never `Converged` when
    ///   the tensor also wants products of inertia (the two cannot be told apart);
    /// * no bias, products of inertia needed (the sensor axes are not principal axes): the
    ///   tensor's;
    /// * otherwise (during the first free flight, or no fit) the refined identifier's
    ///   ([`Refined`], fed exactly the same samples): it models the integral's own noise and
    ///   stays near the Cramer-Rao bound, and its standard deviation uses the noise seen in its
    ///   residuals. Its [`Status`] is reported as it is (`NoInformation` as `TooFewSamples`), at
    ///   most `Converging` while no gyro bias was measured and no end-of-flight fit has ruled
    ///   one out (it has no bias model).
    ///
    /// Whatever the source, an accelerometer whose still samples say it is not in m/s^2
    /// ([`crate::AccelUnits`]) makes the status `UnitsLookWrong`.
    pub fn ratios(&self) -> Ratios {
        self.estimate_and_ratios().1
    }

    /// [`Pipeline::estimate`] and [`Pipeline::ratios`] together, the estimator's own estimate
    /// (a few thousand operations) computed once for both: what a report needs.
    pub fn estimate_and_ratios(&self) -> (TensorEstimate, Ratios) {
        let own = self.estimator.estimate();
        let mut t = self.reported(own);
        let converged = |s: Status| matches!(s, Status::Converged | Status::Converging);
        // Whether the sensor axes are principal axes, asked once for everything below.
        let principal = self.principal_axes(&own);
        if (self.torque_suspected(principal) || self.not_rigid(principal)) && converged(t.status) {
            t.status = Status::ModelMismatch;
            t.uncertainty = Uncertainty::Unaccounted;
        }
        if self.bias_unknown(&t) && t.status == Status::Converged {
            t.status = Status::Converging;
        }
        let mut r = self.ratios_from(&t, principal);
        if r.source == RatioSource::Refined
            && r.status == Status::Converged
            && self.refined_bias_unknown()
        {
            r.status = Status::Converging;
        }
        let unmodelled_bias =
            r.source == RatioSource::RefinedBias && t.method == TensorMethod::EquationError;
        if unmodelled_bias && converged(t.status) {
            t.status = Status::ModelMismatch;
            t.uncertainty = Uncertainty::Unaccounted;
        }
        // An accelerometer not in m/s^2 (`AccelUnits`): the gate's free flights and bias
        // mean nothing, so neither does what was fitted to them.
        if self.gate.accel_units().looks_wrong() {
            t.status = Status::UnitsLookWrong;
            r.status = Status::UnitsLookWrong;
        }
        (t, r)
    }

    /// The ratios given the reported tensor estimate `t` and whether the sensor axes are
    /// principal axes ([`Pipeline::principal_axes`] of the estimator's own estimate).
    fn ratios_from(&self, t: &TensorEstimate, principal: bool) -> Ratios {
        if self.rotor_seen {
            return Ratios {
                a: t.a,
                std_a: t.std_a,
                status: t.status,
                source: RatioSource::Tensor,
            };
        }
        // `principal`: a Wald test on the products of inertia (`TensorSettings::products_chi2`).
        // Once a flight has ended `t` is the output-error fit up to scale, which always
        // estimates the products; its `a` is far less precise than the principal-axis ratio
        // fit's where two moments are close (the principal axes are then barely defined, and
        // its `a` is many times the constrained bound on a near-symmetric body), so it is used
        // only where the products are significant.
        let trust = self.refined.trust();
        // The refined identifier's `NoInformation` (no sample yet) is reported as the tensor
        // reports it: `TooFewSamples`.
        let status = match trust {
            Status::NoInformation => Status::TooFewSamples,
            s => s,
        };
        // The tensor's verdicts on the units and the clipping hold for the same samples.
        let status = match t.status {
            Status::UnitsLookWrong | Status::Saturated => t.status,
            _ => status,
        };
        let informed = trust.has_information() && self.refined.noise_estimate().is_some();
        if let Some(fe) = self.trajectory.estimate() {
            // The whole-trajectory fit is efficient when (1) holds to the noise; when its
            // residual is well above the gyro's noise (unmodelled torque, as on real tosses
            // through air) the error it leaves accumulates along the trajectory and biases it,
            // and the refined identifier, which trusts (1) only locally, is the safer choice.
            // A constant torque found by the fit's score test: the motion is not free, and
            // no torque-free model (the ratio fit's, the tensor's) is to be believed.
            // Ratios no rigid body has (the rigid-body test of the fit, a gyro scale-factor
            // error most often): the same.
            let fits = self.fits_to_the_noise(&fe) && !fe.torque && !fe.constraint_rejected;
            if fits && (principal || fe.biased) {
                // With a gyro bias the tensor estimator (which has no bias model) takes the
                // bias for products of inertia; the fit that explains the data to the noise is
                // the principal-axis one with the bias, so the products are not held against it
                // (else the gyro-bias scenario would be `ModelMismatch` although its `a` is
                // within its standard deviation).
                return self.trajectory_ratios(&fe, status, principal || fe.biased);
            }
            // The principal-axis model does not fit to the noise. If the tensor wants products
            // of inertia and is itself `Converged` (its residual within its threshold, precise,
            // physically valid), the sensor axes are simply not principal axes: its `a` below.
            // Otherwise the torque-free model does not hold on these data (on the racquet
            // tosses through air the tensor's `a` spreads by tens of percent): the
            // refined identifier's estimate is the least affected, and marked as such.
            let tensor_fits = !principal && t.status == Status::Converged;
            if !fits && !tensor_fits && informed {
                return self.refined_mismatch(status);
            }
        } else if self.trajectory.last_outcome() == StretchOutcome::Failed
            && t.status != Status::Converged
            && informed
        {
            // The flight ended and its fit found no torque-free motion that the data follow
            // (no fit at all, a stronger verdict than a residual above the noise): the same
            // choice. On a racquet toss through air the equation-error tensor's products would
            // be taken for a misaligned sensor and its `a` reported far off, where the refined
            // identifier's agrees with the other tosses' (both `ModelMismatch`).
            return self.refined_mismatch(status);
        }
        let (a_r, s_r) = (self.refined.block_estimate(), self.refined.std_a());
        // Hausman test of a constant gyro bias: without one, the refined identifier and its
        // bias-augmented twin (same samples) differ only by noise of variance
        // var_bias - var_refined; a bias moves them apart. Beyond 3.5 standard deviations on
        // any axis the bias model is used (its standard deviation is honest with a bias; the
        // refined one is not).
        if let (true, Some(s_b)) = (informed, self.refined_bias.std_a()) {
            let a_b = self.refined_bias.estimate();
            let mut biased = false;
            // The test's noise is at least the configured gyro noise: on (nearly) noise-free
            // data the two discretisations differ by more than their vanishing noise.
            let seen = self.refined_bias.noise_estimate().unwrap_or(0.0);
            let cfg = self.settings.refined.noise_std;
            let k = if seen > 0.0 && cfg > seen {
                cfg / seen
            } else {
                1.0
            };
            for (((ar, ab), sb), sr) in a_r.iter().zip(a_b.iter()).zip(s_b.iter()).zip(s_r.iter()) {
                let (d, vb, vr) = (ar - ab, sb * sb * k * k, sr * sr * k * k);
                let v = if vb > vr { vb - vr } else { 0.0 };
                let v = if v > 1e-4 * vb { v } else { 1e-4 * vb };
                if d * d > 12.25 * v {
                    biased = true;
                }
            }
            // A body whose sensor axes are not principal axes also makes the two disagree
            // (both assume principal axes): when the tensor wants products of inertia, the
            // model whose residual is closer to the gyro noise is taken.
            if biased && !principal {
                let tensor_noise = t.residual_ratio * self.settings.tensor.noise_std;
                let bias_noise = self.refined_bias.noise_estimate().unwrap_or(f32::INFINITY);
                if tensor_noise <= bias_noise {
                    biased = false;
                }
            }
            if biased {
                // The refined identifier's own verdicts on the estimate do not hold for the
                // bias model's: judge it afresh (the data-side verdicts stay). When the tensor
                // also wants products of inertia, a bias and products cannot be told apart
                // from these data: never Converged then.
                let status = self.judge(status, a_b, s_b, principal);
                return Ratios {
                    a: Some(a_b),
                    std_a: Some(s_b),
                    status,
                    source: RatioSource::RefinedBias,
                };
            }
        }
        if !principal {
            // No bias, products of inertia needed: the sensor axes are not principal axes.
            return Ratios {
                a: t.a,
                std_a: t.std_a,
                status: t.status,
                source: RatioSource::Tensor,
            };
        }
        Ratios {
            a: informed.then_some(a_r),
            std_a: informed.then_some(s_r),
            status,
            source: RatioSource::Refined,
        }
    }

    /// The refined identifier's ratios where the torque-free model does not hold on the flight
    /// (its fit above the noise or failed): `ModelMismatch` unless a data-side verdict of
    /// `status` says more ([`data_verdict`]).
    fn refined_mismatch(&self, status: Status) -> Ratios {
        Ratios {
            a: Some(self.refined.block_estimate()),
            std_a: Some(self.refined.std_a()),
            status: data_verdict(status).unwrap_or(Status::ModelMismatch),
            source: RatioSource::Refined,
        }
    }

    /// The trajectory fit's ratios judged afresh: the data-side verdicts (`status` from the
    /// refined identifier and the tensor: too few samples, no excitation, units, clipping)
    /// stay; then a bias that the tensor would rather explain by products of inertia is
    /// ambiguous (`ModelMismatch`), and `Converged` needs every standard deviation within
    /// `eps`.
    fn trajectory_ratios(&self, fe: &RatioFitEstimate, status: Status, principal: bool) -> Ratios {
        let status = self.judge(status, fe.a, fe.std_a, principal);
        // No estimate where the data carry none (as the refined identifier reports it).
        let informed = !matches!(status, Status::TooFewSamples | Status::NoExcitation);
        Ratios {
            a: informed.then_some(fe.a),
            std_a: informed.then_some(fe.std_a),
            status,
            source: RatioSource::Trajectory,
        }
    }

    /// An estimate of `a` other than the refined identifier's, judged afresh: the data-side
    /// verdicts of `status` stay ([`data_verdict`]); then not physically possible; products of
    /// inertia wanted by the tensor (`!principal`: a model assuming principal axes is not to be
    /// trusted, `ModelMismatch`); `Converged` when every standard deviation is within `eps`.
    fn judge(&self, status: Status, a: [f32; 3], std_a: [f32; 3], principal: bool) -> Status {
        let var = std_a.map(|x| x * x);
        match data_verdict(status) {
            Some(v) => v,
            None if !physically_possible(a, var) => Status::PhysicallyImpossible,
            None if !principal => Status::ModelMismatch,
            None if precise(var, self.settings.refined.eps) => Status::Converged,
            None => Status::Converging,
        }
    }

    /// The output-error fit fed the same samples (its pooled estimate covers the stretches
    /// that have ended).
    pub fn trajectory(&self) -> &FlightRatioFit {
        &self.trajectory
    }

    /// Ends the stretch being fed (a hand-chosen segment ends): the next fed sample starts new
    /// integrals in both estimators; what they learnt is kept. Samples still in the delay line
    /// are unaffected.
    pub fn end_stretch(&mut self) {
        self.close_stretch();
        self.fit_ended_flight();
    }

    /// [`Pipeline::end_stretch`] without running the fits: the stretch being fed ends and its
    /// output-error fits wait ([`Pipeline::fits_pending`]) as when the gate ends a flight, so
    /// that a caller with a sample path to keep runs them elsewhere (on a copy, then
    /// [`Pipeline::adopt_fits`]). The next fed sample runs them itself if nobody did.
    pub fn close_stretch(&mut self) {
        if self.feeding {
            self.estimator.end_stretch();
            self.refined.restart();
            self.refined_bias.restart();
            self.fits_pending = true;
            self.feeding = false;
        }
    }

    /// Takes the fits of the flight (or window, (W1)) that ended from `fitted`: a copy of this
    /// pipeline made while its fits were pending, on which [`Pipeline::fit_ended_flight`] has
    /// run since. Samples this pipeline was given meanwhile and did not feed leave the fits'
    /// inputs as they were, so the result is the same bits as running the fits here at the
    /// time the copy was made. Refused (false, nothing changed) when this pipeline's fits are
    /// not pending, `fitted`'s are, or the two have not fed the same samples (this pipeline
    /// fed one meanwhile and ran the fits itself, or `fitted` is not a copy of it).
    pub fn adopt_fits(&mut self, fitted: &Self) -> bool {
        let same = self.throws == fitted.throws && self.fed_inputs == fitted.fed_inputs;
        if !self.fits_pending || fitted.fits_pending || !same {
            return false;
        }
        self.trajectory = fitted.trajectory;
        self.tensor_fit = fitted.tensor_fit;
        self.fits_pending = false;
        true
    }

    /// Runs the output-error fits of the free flight that ended, if they have not run yet;
    /// true when they ran. They cost up to about 10^8 instructions on a Cortex-M4F (a fraction
    /// of a second to a second at 168 MHz, see `README.md`), so [`Pipeline::step`] does not run
    /// them when the gate ends a flight: the firmware calls this outside its time-critical
    /// path (with its watchdog stretched), [`Pipeline::end_stretch`] calls it, and the first
    /// sample of the next free flight runs them before it is fed if nobody did. The result
    /// does not depend on when they run.
    pub fn fit_ended_flight(&mut self) -> bool {
        if !self.fits_pending {
            return false;
        }
        self.fits_pending = false;
        if self.rotor_seen {
            // With a rotor the ratios are the tensor's (`ratios_from`): the ratio fit's result
            // would never be used, and it is most of the cost of a flight's end.
            self.trajectory.discard();
        } else {
            self.trajectory.close();
        }
        self.close_tensor_fit();
        true
    }

    /// True when a free flight has ended and its fits wait for [`Pipeline::fit_ended_flight`].
    pub fn fits_pending(&self) -> bool {
        self.fits_pending
    }

    /// Fits the stretch that ended with the tensor's output-error fit: in kg m^2 from the
    /// tensor estimator's estimate when a rotor momentum was seen; otherwise up to scale, from
    /// the better of the estimator's normalised tensor (products of inertia included) and the
    /// ratio fit's principal moments (closed just before; efficient, but principal axes only).
    fn close_tensor_fit(&mut self) {
        let e = self.estimator.estimate();
        if self.rotor_seen {
            let start = e.tensor.or_else(|| self.estimator.absolute_guess());
            // A bias measured on the bench was removed from every sample: none is looked for.
            // Without an accelerometer nothing measures it (a satellite, a log taken whole):
            // the bias model is also taken where it moves the tensor (Hausman's test).
            if self.bias_measured() {
                self.tensor_fit.close_without_bias(start);
            } else if !self.use_gate {
                self.tensor_fit.close_with_bias(start);
            } else {
                self.tensor_fit.close(start);
            }
        } else {
            let fe = self.trajectory.estimate();
            let principal = fe.map(|f| {
                let m = f.moments;
                [[m[0], 0.0, 0.0], [0.0, m[1], 0.0], [0.0, 0.0, m[2]]]
            });
            // A bias is looked for when the principal-axis fit found one or does not explain
            // the data (see `TensorFit::close_normalized`).
            let test_bias = fe.is_none_or(|f| f.biased || !self.fits_to_the_noise(&f));
            let mut inits = [[[0.0f32; 3]; 3]; 2];
            let mut n = 0;
            for j in [e.normalized, principal].into_iter().flatten() {
                if let Some(dst) = inits.get_mut(n) {
                    *dst = j;
                    n += 1;
                }
            }
            self.tensor_fit
                .close_normalized(inits.get(..n).unwrap_or(&[]), test_bias);
        }
    }

    /// Whether a constant torque explains the flight at least as well as the torque-free
    /// models do (gyro-only flights; with a rotor the fits' residual speaks): the tensor's fit
    /// up to scale rejected the torque-free model by its score test; or the principal-axis
    /// ratio fit's test did and either the sensor axes are principal axes, or the tensor's
    /// products of inertia (with a bias if its fit found one) do not lower the cost below the
    /// ratio fit's with the torque by the products' own test threshold
    /// (`TensorSettings::products_chi2` times the residual variance).
    ///
    /// Why the comparison: a small constant torque on a principal body is fitted by the tensor
    /// as a gyro bias and products of inertia (its own torque test does not reject there), and
    /// its `a`, many standard deviations off, would be reported `Converged` (`sweep-identify`,
    /// row `trap-torque`, counts such flights). A gyro mounted off the principal axes
    /// makes the ratio fit's test reject too (it lacks the products), with or without a bias;
    /// there the products explain the data and the torque does not.
    fn torque_suspected(&self, principal: bool) -> bool {
        if self.rotor_seen {
            return false;
        }
        let tf = self.tensor_fit.estimate_normalized();
        if tf.is_some_and(|f| f.torque || f.scale_rejected) {
            return true;
        }
        let Some(fe) = self.trajectory.estimate().filter(|f| f.torque) else {
            return false;
        };
        if principal {
            return true;
        }
        let Some(tf) = tf else {
            return true;
        };
        // The two explanations are weighed against the residual variance of the one that fits
        // better (never below the configured noise's). Not the ratio fit's own residual: that
        // is the model's without either, and on a body with products of inertia it is the
        // products' misfit, against which a torque that took up part of it would be judged
        // insignificant and the products rejected (a simulated toss without a rotor,
        // `gen-throw --scenario no_rotor_toss --seed 1`, shows it).
        let cfg = self.settings.tensor.noise_std;
        let torque_var = fe.noise * fe.noise * (fe.cost_with_torque / fe.cost);
        let tensor_var = tf.noise * tf.noise;
        let best = if tensor_var < torque_var {
            tensor_var
        } else {
            torque_var
        };
        if !best.is_finite() {
            return true;
        }
        let s2 = best.max(cfg * cfg);
        // NaN anywhere leaves the torque suspected.
        let products_explain =
            tf.cost + self.settings.tensor.products_chi2 * s2 < fe.cost_with_torque;
        !products_explain
    }

    /// Whether the products of inertia are not significant (the sensor axes are principal
    /// axes): the Wald statistic `z^T C_zz^-1 z` of the products `z` below
    /// `TensorSettings::products_chi2`. Taken from the output-error fit up to scale once it
    /// fits to the noise (efficient, and its discretisation error far below the noise), else
    /// from the equation error (`own`'s model). The equation error's own error does not shrink
    /// with the noise: with a quiet gyro it calls the products of a principal body
    /// significant, and the ratios would then come from the tensor's `a`, several times the
    /// bound off (the test `a_quiet_gyro_gets_the_trajectory_fit`).
    fn principal_axes(&self, own: &TensorEstimate) -> bool {
        if !self.rotor_seen {
            if let Some(f) = self.tensor_fit.estimate_normalized() {
                let cfg = self.settings.tensor.noise_std;
                if f.noise > 0.0 && f.noise <= TRAJECTORY_FIT_RATIO * cfg {
                    let t = &f.tensor;
                    let j = [t[0][0], t[1][1], t[2][2], t[0][1], t[0][2], t[1][2]];
                    // The test never assumes less noise than configured (as the equation
                    // error's and the bias test): on noise-free data the fit's f32 rounding
                    // would otherwise make products of 1e-7 significant.
                    let k = if f.noise < cfg {
                        (f.noise / cfg) * (f.noise / cfg)
                    } else {
                        1.0
                    };
                    let chi2 = self.settings.tensor.products_chi2;
                    if k * products_wald(&j, &f.cov) < chi2 {
                        return true;
                    }
                    // Confirmed by the likelihood ratio against the ratio fit (the same model
                    // with the products held at zero, fitted to the same blocks with the same
                    // bias choice): on short flights the Wald test, which trusts the fit's
                    // local curvature, can call a principal body's products significant, and
                    // the ratios would then come from the tensor, far less precise than the
                    // ratio fit's (the test `a_short_toss_keeps_the_principal_axes`).
                    if let Some(fe) = self.trajectory.estimate() {
                        if fe.biased == f.biased {
                            let s2 = self.fit_variance(&fe);
                            let products_explain = fe.cost - f.cost > chi2 * s2;
                            // Nor significantly better than the gyro's scale factors would,
                            // where the ratio fit's rigid-body test found ratios no rigid body
                            // has (a principal body read a few tenths of a percent off on two
                            // axes: products found, the tensor's `a` `Converged` and many std
                            // off; `sweep-identify`, row `trap-scale`). The same margin as
                            // against the ratio fit: the products have two parameters more, and
                            // with a bare `<=` they would win on noise now and then.
                            let scale_explains =
                                fe.constraint_rejected && fe.cost_with_scale <= f.cost + chi2 * s2;
                            return !products_explain || scale_explains;
                        }
                    }
                    return false;
                }
            }
        }
        own.model == TensorModel::Principal || own.normalized.is_none()
    }

    /// Whether the ratio fit's rigid-body test ((T5) of [`RatioFit`]) rejected a body whose
    /// sensor axes are principal axes (gyro-only flights): its rates fit a torque-free body
    /// only with ratios no rigid body has, which a gyro scale-factor error does (the tensor
    /// up to scale, fitted to the same rates, inherits the error). With products of inertia
    /// the ratio fit lacks them and its test says nothing about the tensor.
    fn not_rigid(&self, principal: bool) -> bool {
        !self.rotor_seen
            && principal
            && self
                .trajectory
                .estimate()
                .is_some_and(|f| f.constraint_rejected)
    }

    /// The ratio fit's residual variance per sample, never below the configured gyro noise's
    /// (the variance its own and the tensor's tests are scaled by).
    fn fit_variance(&self, fe: &RatioFitEstimate) -> f32 {
        let cfg = self.settings.tensor.noise_std;
        if fe.noise > cfg {
            fe.noise * fe.noise
        } else {
            cfg * cfg
        }
    }

    /// Whether a gyro bias was measured on a still stretch (and is removed from every sample
    /// fed) or the caller removed one ([`Pipeline::set_bias_removed`]).
    fn bias_measured(&self) -> bool {
        self.gate.bias().is_some() || self.bias_removed
    }

    /// Whether the reported tensor is the equation error's while no gyro bias was measured on
    /// a still stretch (nor removed by the caller): a constant gyro bias `b` enters Euler's
    /// equation through `y = w + b` as `-(y x J b + b x J y)`, which the equation error (it
    /// has no bias model) absorbs into the principal moments and then into products of inertia
    /// that the body need not have, and its standard deviations do not know it. Only the
    /// end-of-flight output-error fits, which test a bias, tell a bias apart; until then such
    /// an estimate is at most `Converging` (a bias of a few mrad/s would otherwise let it say
    /// `Converged` several standard deviations off within seconds; the test
    /// `online_gyro_bias`).
    fn bias_unknown(&self, t: &TensorEstimate) -> bool {
        t.method == TensorMethod::EquationError && !self.bias_measured()
    }

    /// Whether the refined identifier's ratios may carry a gyro bias nobody tested for: none
    /// measured on a still stretch (nor removed by the caller) and no end-of-flight ratio fit
    /// that found none. The refined identifier has no bias model either (the same reason as
    /// [`Pipeline::bias_unknown`]); its Hausman test against [`RefinedBias`] needs a second or
    /// two to see a bias of a few mrad/s, and until then its ratios could say `Converged`
    /// standard deviations off (the test `online_gyro_bias`).
    fn refined_bias_unknown(&self) -> bool {
        !self.bias_measured() && self.trajectory.estimate().is_none_or(|f| f.biased)
    }

    /// True when the ratio fit's residual is at most [`TRAJECTORY_FIT_RATIO`] times the
    /// configured gyro noise: the torque-free principal-axis model explains the data.
    fn fits_to_the_noise(&self, fe: &RatioFitEstimate) -> bool {
        fe.noise <= TRAJECTORY_FIT_RATIO * self.settings.refined.noise_std
    }

    /// The refined identifier fed the same samples (until a rotor momentum is seen: from then
    /// on the ratios are the tensor's and it is no longer fed).
    pub fn refined(&self) -> &Refined {
        &self.refined
    }

    /// The estimator (for its counters).
    pub fn estimator(&self) -> &TensorEstimator {
        &self.estimator
    }

    /// The latest window fit of the gate.
    pub fn gate_fit(&self) -> Option<WindowFit> {
        self.gate.last_fit()
    }

    /// Gyro bias in use (from the latest still window), rad/s.
    pub fn bias(&self) -> [f32; 3] {
        self.gate.bias().unwrap_or([0.0; 3])
    }

    /// The gyro bias measured on a still stretch and removed from every sample fed, `None`
    /// while no still stretch was seen.
    pub fn measured_bias(&self) -> Option<[f32; 3]> {
        self.gate.bias()
    }

    /// Says that the samples this pipeline is fed had a gyro bias measured elsewhere removed
    /// (the host tool's per-throw pipelines get the pooled pipeline's bench bias so): like a
    /// bias its own gate measured, the output-error fit with a rotor then looks for none
    /// ([`TensorFit::close_without_bias`]).
    pub fn set_bias_removed(&mut self, removed: bool) {
        self.bias_removed = removed;
    }

    /// Free flights that reached the estimator so far.
    pub fn throws(&self) -> u32 {
        self.throws
    }

    /// Input samples (before decimation) that reached the estimators.
    pub fn fed_inputs(&self) -> u32 {
        self.fed_inputs
    }

    /// True while the gate holds free flight.
    pub fn in_free_flight(&self) -> bool {
        self.free_since.is_some()
    }

    /// Adds one sample: rate (rad/s), specific force (m/s^2; ignored without an
    /// accelerometer), rotor momentum (kg m^2/s), time step (s). Returns the sample that left
    /// the delay line, if one did, and what was done with it.
    pub fn step(&mut self, omega: [f32; 3], accel: [f32; 3], h: [f32; 3], dt: f32) -> Option<Exit> {
        let input = self.input_index;
        self.input_index = self.input_index.saturating_add(1);
        let d = self.settings.decimation;
        if d <= 1 {
            return self.step_decimated(omega, accel, h, dt, input, 1);
        }
        let g = &mut self.group;
        if g.n == 0 {
            g.first = input;
        }
        // This runs on every input sample (8 kHz), so it is kept to a few comparisons: a NaN
        // fails every `<`; an infinite rate fails `< full_scale` unless the full scale is
        // infinite, and then `< INFINITY`; the other six are finite exactly when their sum is
        // (a sum of finite readings beyond `f32::MAX` is refused too, which no accelerometer or
        // rotor reaches).
        let fs = self.settings.tensor.full_scale;
        let inf = f32::INFINITY;
        let good_dt = dt > 0.0 && dt < inf;
        let [o0, o1, o2] = omega;
        let [a0, a1, a2] = accel;
        let [h0, h1, h2] = h;
        let (m0, m1, m2) = (o0.abs(), o1.abs(), o2.abs());
        let rest = a0 + a1 + a2 + h0 + h1 + h2;
        let accepted =
            good_dt && m0 < fs && m1 < fs && m2 < fs && m0 + m1 + m2 < inf && rest.is_finite();
        if accepted {
            let [go0, go1, go2] = &mut g.omega;
            *go0 += o0;
            *go1 += o1;
            *go2 += o2;
            let [ga0, ga1, ga2] = &mut g.accel;
            *ga0 += a0;
            *ga1 += a1;
            *ga2 += a2;
            let [gh0, gh1, gh2] = &mut g.h;
            *gh0 += h0;
            *gh1 += h1;
            *gh2 += h2;
        } else if g.taint.is_none() {
            g.taint = Some((omega, accel, h, dt));
        }
        if good_dt {
            g.dt += dt;
        }
        g.n += 1;
        if g.n < d {
            return None;
        }
        self.close_group()
    }

    /// The group is complete: its mean (or its refused sample) goes on as one estimator
    /// sample. Kept out of line so the other `d - 1` calls of [`Pipeline::step`] stay a few
    /// dozen instructions (no floating-point registers to save).
    #[inline(never)]
    fn close_group(&mut self) -> Option<Exit> {
        let g = &mut self.group;
        let done = *g;
        *g = Group::EMPTY;
        let good = f32::from(done.n) - if done.taint.is_some() { 1.0 } else { 0.0 };
        let (o, a, hh, step) = match done.taint {
            // The refused sample goes on with the group's time (a bad dt stays bad).
            Some((o, a, hh, t)) => (o, a, hh, if t.is_finite() && t > 0.0 { done.dt } else { t }),
            None => {
                let k = 1.0 / good;
                (
                    done.omega.map(|x| x * k),
                    done.accel.map(|x| x * k),
                    done.h.map(|x| x * k),
                    done.dt,
                )
            }
        };
        self.step_decimated(o, a, hh, step, done.first, done.n)
    }

    /// One estimator sample (after decimation) through gate, delay line and estimators.
    fn step_decimated(
        &mut self,
        omega: [f32; 3],
        accel: [f32; 3],
        h: [f32; 3],
        dt: f32,
        first_input: u32,
        inputs: u8,
    ) -> Option<Exit> {
        let index = self.index;
        self.index = self.index.saturating_add(1);
        if self.use_gate {
            let good = omega.iter().chain(accel.iter()).all(|x| x.is_finite())
                && dt.is_finite()
                && dt > 0.0;
            let bad = !good;
            if bad {
                // A bad sample breaks the window: nothing is known to be free until a new
                // window has been fitted.
                self.free_since = None;
            }
            if let Some(fit) = self.gate.step(omega, accel, dt) {
                if fit.free {
                    if self.free_since.is_none() {
                        let start = (index + 1).saturating_sub(fit.samples);
                        self.free_since = Some(start);
                    }
                } else {
                    self.free_since = None;
                }
            }
        }
        let pending = Pending {
            index,
            first_input,
            inputs,
            omega,
            h,
            dt,
        };
        if self.delay == 0 {
            return Some(self.release(pending));
        }
        // Push into the ring.
        let tail = (self.head + self.len) % N;
        if let Some(slot) = self.line.get_mut(tail) {
            *slot = pending;
        }
        self.len += 1;
        if self.len <= self.delay {
            return None;
        }
        let out = self.line.get(self.head).copied();
        self.head = (self.head + 1) % N;
        self.len -= 1;
        out.map(|p| self.release(p))
    }

    /// Feeds `p` to the estimator when the gate allows it.
    fn release(&mut self, mut p: Pending) -> Exit {
        let allowed = self
            .free_since
            .is_some_and(|s| p.index >= s.saturating_add(self.guard_release));
        if !allowed {
            if self.feeding {
                self.estimator.end_stretch();
                self.refined.restart();
                self.refined_bias.restart();
                // The free flight has ended: its fits wait for `fit_ended_flight` (too long
                // for one step).
                self.fits_pending = true;
                self.feeding = false;
            }
            return Exit {
                sample: p,
                fed: None,
            };
        }
        if !self.feeding {
            // The previous flight's fits must run before this one fills the blocks.
            self.fit_ended_flight();
            self.feeding = true;
            self.turned = 0.0;
            self.throws = self.throws.saturating_add(1);
        } else if self.fits_pending {
            // A window (W1) closed and nobody ran its fits: they run before the next window
            // fills the blocks.
            self.fit_ended_flight();
        }
        let b = self.bias();
        p.omega = [p.omega[0] - b[0], p.omega[1] - b[1], p.omega[2] - b[2]];
        self.fed_inputs = self.fed_inputs.saturating_add(u32::from(p.inputs));
        let status = self.estimator.step(p.omega, p.h, p.dt);
        self.rotor_seen |= p.h.iter().any(|x| *x != 0.0);
        // Once a rotor has been seen the ratios are the tensor's (`ratios_from`): the
        // torque-free ratio estimators' model no longer holds and their results are never
        // used, so they are not fed (the ratio fit's blocks are discarded unfitted by
        // `fit_ended_flight`). On a flywheel throw at 8 kHz this is about a third of the
        // per-sample work.
        if !self.rotor_seen {
            self.refined.step(p.omega, p.dt);
            self.refined_bias.step(p.omega, p.dt);
            // A decimated sample is the mean of `inputs` readings: their time spread is part
            // of the block means' time variance in the output-error fits.
            self.trajectory.step_mean(p.omega, p.dt, p.inputs);
        }
        self.tensor_fit.step_mean(p.omega, p.h, p.dt, p.inputs);
        // (W1): the window closes when the flight has turned far enough; its fits wait for
        // `fit_ended_flight` like a flight's end.
        let [w0, w1, w2] = p.omega;
        let turn = (w0.abs() + w1.abs() + w2.abs()) * p.dt;
        if turn.is_finite() {
            self.turned += turn;
        }
        if !self.use_gate && self.rotor_seen && self.turned > self.settings.window_turn_rad {
            self.turned = 0.0;
            self.fits_pending = true;
        }
        Exit {
            sample: p,
            fed: Some(status),
        }
    }
}
