//! `inertia identify`: a log through the shared on-board pipeline
//! ([`identifier_core::FlightPipeline`]: free-flight gate, guard delay, gyro bias, tensor
//! estimator), per throw and pooled.
//!
//! The pooled result is the pipeline's own estimate after the whole log, which is what the
//! firmware computes on board from the same samples (same `f32` code, same order of
//! operations). Per-throw results run a fresh pipeline over exactly the samples the pooled
//! pipeline fed during that throw.
//!
//! The log is read as a [`Source`], sample by sample, never held whole (a 10-minute 8 kHz log
//! takes 950 MiB as a [`Recording`]):
//!
//! 1. a first reading ([`crate::survey`]) finds what the pipeline needs from the whole
//!    recording before it runs: sample count, median time step (the rate), gyro
//!    noise, unit warnings, the rotor channel's changes; the medians exactly, reading the log
//!    again when the first reading cannot fix them;
//! 2. the pooled pipeline's reading, per-throw pipelines on worker threads beside it
//!    (module `passes`);
//! 3. only when needed, a reading that feeds again the throws begun with another bias than
//!    the final one.
//!
//! Every number in the report is the same bits as when the whole recording is held (module
//! `reference`, the tests' reference).

pub mod gravity;
mod inputs;
mod passes;
#[cfg(test)]
mod reference;
/// Relative standard deviation below which the gyro's scale factors, not its noise, limit an
/// estimate: a MEMS gyro's are typically within 0.5-1 % uncalibrated, and they move `a` and the
/// tensor's scale by about as much as their differences (README, "Gyro scale factors").
const SCALE_FLOOR: f32 = 2e-3;

/// A warning when the pooled estimate's reported standard deviations are below
/// [`SCALE_FLOOR`] of what they measure: they are the gyro noise's only, and the data cannot
/// show a scale-factor error (it leaves the torque-free equations exactly satisfied with other
/// ratios).
pub(crate) fn scale_floor_warning(p: &EstimateJson) -> Option<String> {
    let rel = |v: f32, s: f32| (v.abs() > 0.05).then(|| s / v.abs());
    let mut worst: Option<f32> = None;
    if let (Some(a), Some(s)) = (p.a, p.std_a) {
        for i in 0..3 {
            if let Some(r) = rel(a[i], s[i]) {
                worst = Some(worst.map_or(r, |w: f32| w.max(r)));
            }
        }
    }
    let below = worst.is_some_and(|w| w.is_finite() && w < SCALE_FLOOR);
    below.then(|| {
        format!(
            "the standard deviation of a (at most {:.3} % of a) is the gyro noise's only: an \
             uncalibrated gyro's scale factors (typically 0.5-1 %) move a by about as much as \
             their differences, and the data cannot show it; calibrate them to trust a beyond \
             that, or give --gyro-scale-tolerance to have it in the report (README, 'Gyro scale \
             factors')",
            worst.unwrap_or(0.0) * 100.0
        )
    })
}

#[cfg(test)]
mod tests;
mod throws;

use std::ops::Range;

use identifier_core::{PipelineSettings, Ratios, Status, TensorEstimate};
use serde::Serialize;

use crate::readers::ReadError;
use crate::recording::Recording;
pub use crate::recording::{estimate_noise, median_dt, white_noise};
use crate::source::{Flow, RecordingSource, Source};
use crate::survey::{survey, Wanted};
pub use crate::unhold::{slow_telemetry, unhold, RotorHold};
use crate::vehicle::Vehicle;

use inputs::{Inputs, RotorInput};

/// A rotor (flywheel, motor) whose momentum is a known input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotor {
    /// Rotor inertia about its axis, kg m^2.
    pub inertia: f32,
    /// Unit axis in the sensor frame (the direction of positive speed).
    pub axis: [f32; 3],
    /// Motor poles (for eRPM channels).
    pub poles: Option<u32>,
}

impl Rotor {
    /// This rotor as the core's [`identifier_core::Rotors`], whose `momentum` the firmware
    /// uses too (same bits on host and MCU), or why it is refused (inertia not positive and
    /// finite, axis not a unit vector).
    pub fn rotors(&self) -> Result<identifier_core::Rotors, String> {
        identifier_core::Rotors::new(&[identifier_core::Rotor::new(self.inertia, self.axis)])
            .map_err(|e| format!("the rotor is refused: {e:?}"))
    }
}

/// Parses `x|y|z|-x|-y|-z`.
pub fn parse_axis(s: &str) -> Result<[f32; 3], String> {
    match s.trim() {
        "x" | "+x" => Ok([1.0, 0.0, 0.0]),
        "y" | "+y" => Ok([0.0, 1.0, 0.0]),
        "z" | "+z" => Ok([0.0, 0.0, 1.0]),
        "-x" => Ok([-1.0, 0.0, 0.0]),
        "-y" => Ok([0.0, -1.0, 0.0]),
        "-z" => Ok([0.0, 0.0, -1.0]),
        o => Err(format!(
            "rotor axis {o:?} is not one of x, y, z, -x, -y, -z"
        )),
    }
}

/// One estimate as written to JSON. Tensors are 3x3 in the log's gyro axes as logged.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EstimateJson {
    /// First sample used, s (log time).
    pub start_s: f64,
    /// Last sample used, s.
    pub end_s: f64,
    /// Log samples that reached the estimators (before the pipeline's averaging).
    pub samples: u32,
    /// Why `a` is or is not to be trusted (`Converged` only when it is).
    pub status: String,
    /// Which estimator gave `a`: `Trajectory` (the ratio fit once a flight has ended and it
    /// fits to the noise), `Refined` (during a flight, or when the torque-free model does not
    /// fit), `RefinedBias` (a gyro bias during a first flight) or `Tensor` (rotor momentum, or
    /// products of inertia needed).
    pub a_source: String,
    /// Why the tensor is or is not to be trusted.
    pub tensor_status: String,
    /// Which estimator gave the tensor: `OutputError` (the trajectory fitted once the flight
    /// ended, when it fits to the noise) or `EquationError` (the per-sample estimator).
    pub tensor_method: String,
    /// Where the tensor's standard deviations come from (`identifier_core::Uncertainty`):
    /// `Noise` (the gyro's white noise: the model fits to it), `Residual` (the residual seen,
    /// its level and its correlation: the estimate fits to its stated uncertainty) or
    /// `Unaccounted` (an error they do not count: indicative only).
    pub tensor_uncertainty: String,
    /// Whether the tensor is to be used with its standard deviations: `tensor_status`
    /// `Converged`, or `ModelMismatch` with `tensor_uncertainty` `Residual` and a rigid body's
    /// inertia determined beyond three standard deviations
    /// (`identifier_core::TensorEstimate::usable`).
    pub tensor_usable: bool,
    /// `Full` or `Principal` (products of inertia insignificant and set to zero).
    pub model: String,
    /// `J`, kg m^2, when a rotor momentum fixes the scale; else null.
    pub tensor_kg_m2: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of `tensor_kg_m2`.
    pub tensor_std_kg_m2: Option<[[f32; 3]; 3]>,
    /// Covariance of the entries `(xx, yy, zz, xy, xz, yz)` of `tensor_kg_m2`, (kg m^2)^2:
    /// their errors are correlated (one rotor momentum fixes the scale of all of them), which
    /// a function of several entries must count.
    pub tensor_cov_kg2_m4: Option<[[f32; 6]; 6]>,
    /// `J / trace(J)`.
    pub tensor_normalized: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of `tensor_normalized`.
    pub tensor_normalized_std: Option<[[f32; 3]; 3]>,
    /// The paper's ratios `a` from the recommended estimator (`a_source`).
    pub a: Option<[f32; 3]>,
    /// Standard deviations of `a`.
    pub std_a: Option<[f32; 3]>,
    /// Principal moments, ascending (kg m^2 with a tensor, else normalised).
    pub principal_moments: Option<[f32; 3]>,
    /// Principal axes, one unit vector per moment.
    pub principal_axes: Option<[[f32; 3]; 3]>,
    /// Residual over the gyro noise.
    pub residual_ratio: f32,
    /// Information per equation over the noise (about 1 for a still gyro).
    pub excitation: f32,
}

impl EstimateJson {
    fn from(e: &TensorEstimate, r: &Ratios, start_s: f64, end_s: f64) -> Self {
        EstimateJson {
            start_s,
            end_s,
            samples: e.samples,
            status: format!("{:?}", r.status),
            a_source: format!("{:?}", r.source),
            tensor_status: format!("{:?}", e.status),
            tensor_method: format!("{:?}", e.method),
            tensor_uncertainty: format!("{:?}", e.uncertainty),
            tensor_usable: e.usable(),
            model: format!("{:?}", e.model),
            tensor_kg_m2: e.tensor,
            tensor_std_kg_m2: e.tensor_std,
            tensor_cov_kg2_m4: e.tensor_cov,
            tensor_normalized: e.normalized,
            tensor_normalized_std: e.normalized_std,
            a: r.a,
            std_a: r.std_a,
            principal_moments: e.principal_moments,
            principal_axes: e.principal_axes,
            residual_ratio: e.residual_ratio,
            excitation: e.excitation,
        }
    }
}

/// The whole report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// The input file and format.
    pub input: String,
    /// Samples in the log.
    pub log_samples: usize,
    /// Median sample rate, Hz.
    pub rate_hz: f32,
    /// Gyro white noise used as the floor of the uncertainty, rad/s.
    pub noise_std: f32,
    /// Gyro bias removed (the mean over the log's longest still run), rad/s; zero when
    /// none was measured ([`Report::gyro_bias_measured`]).
    pub gyro_bias: [f32; 3],
    /// Whether a still stretch of the log gave the bias in [`Report::gyro_bias`]: when
    /// false nothing was removed, and a constant bias is left to the end-of-flight fits' own
    /// test (the report warns).
    pub gyro_bias_measured: bool,
    /// Whether the free flights were found from the accelerometer (else the whole log or the
    /// given segments were taken).
    pub free_flight_detection: bool,
    /// The rotor momentum's quantum the fits assumed, kg m^2/s: the rotor inertia times the
    /// speed channel's smallest step (the telemetry's resolution; (F7) and (F8) of
    /// `identifier_core::tensor_fit`). Absent without a rotor or when the speed never changed.
    #[serde(
        rename = "rotor_momentum_quantum_kg_m2_s",
        skip_serializing_if = "Option::is_none"
    )]
    pub rotor_momentum_quantum: Option<f32>,
    /// The gravity-gradient torque (G1) was folded into the known momentum ((G2) of
    /// [`gravity`]): the log has attitude and position columns and a rotor momentum fixes the
    /// scale. Absent otherwise.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub gravity_gradient: bool,
    /// Every free flight.
    pub throws: Vec<EstimateJson>,
    /// All throws together (the on-board result).
    pub pooled: EstimateJson,
    /// Warnings for the user.
    pub warnings: Vec<String>,
    /// Indices of the samples fed to the estimator, as ranges, one list per throw (for
    /// follow-up analyses such as `inertia calibrate`; not written to JSON).
    #[serde(skip)]
    pub fed_runs: Vec<Vec<Range<usize>>>,
    /// The rates to plot, when asked for ([`IdentifyOptions::trace`]; not written to JSON).
    #[serde(skip)]
    pub trace: Option<Trace>,
    /// How far the gyro's scale-factor tolerance moves the pooled estimate, when asked for
    /// (`--gyro-scale-tolerance`, [`scale_systematic`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_scale: Option<ScaleSystematic>,
    /// The gyro scale factor the readings were divided by (`--gyro-scale`, from `inertia
    /// calibrate`), when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_scale_factor: Option<f64>,
    /// The clock scale factor the log's times were divided by (`--clock-scale`, from `inertia
    /// calibrate`), when one was given: the report's times are that clock's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clock_scale_factor: Option<f64>,
    /// The gyro's readings on a grid and the two fits `identify` compared ((Q1) of
    /// [`crate::grid`]). Absent when the readings are not on a grid or the first fit's residual
    /// is not within [`GRID_RESIDUAL_COUNTS`] counts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_grid: Option<GyroGrid>,
    /// Each gyro axis's LSB, rad/s, when the readings are whole counts (the survey's
    /// [`crate::grid::GridStats`]; not written to JSON).
    #[serde(skip)]
    pub gyro_lsb: Option<[f32; 3]>,
    /// The gyro bias's random walk the tensor's fit found and whitened its residual by ((F12),
    /// (F13) of the tensor fit): its rate random walk, rad/s per sqrt(s) (the step std per
    /// sample times the square root of the rate). Absent where none was found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_bias_walk_rad_s_per_sqrt_s: Option<f32>,
}

/// The warning of a report whose log has no still stretch (or no accelerometer to find one
/// with).
pub const NO_BIAS_WARNING: &str =
    "no still stretch of the gyro in the log: no bias was measured or removed \
     (gyro_bias is zero); a constant bias of a few mrad/s looks like products of inertia the body \
     need not have, and only the end-of-flight fits' own bias test guards the tensor (hold the \
     body still for a second before the first throw)";

/// The fit's residual, in counts of the gyro's grid, below which `identify` also fits the
/// readings moved to their cells' centres ((Q1) of [`crate::grid`]): above it the rounding's
/// half count is lost in the residual.
pub const GRID_RESIDUAL_COUNTS: f32 = 4.0;

/// What `identify` found of a gyro reading whole counts.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct GyroGrid {
    /// Each axis's LSB, rad/s.
    pub lsb_rad_s: [f32; 3],
    /// The pooled fit's residual (its ratio times the noise) with the readings as logged,
    /// rad/s.
    pub residual_as_read_rad_s: f32,
    /// The same with the readings moved to their cells' centres as under truncation toward
    /// zero ((Q1)), rad/s.
    pub residual_centred_rad_s: f32,
    /// The readings were taken as truncated toward zero, moved to their cells' centres: the
    /// report is that fit's.
    pub centred: bool,
}

/// The rates of every `step`-th sample (`step = max(n / 20000, 1)`), the whole log's time
/// span and largest rate: what `inertia identify --plots` draws, 20000 to 40000 points
/// whatever the log's length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Keep every `step`-th sample.
    pub step: usize,
    /// Time and rate of the samples kept.
    pub points: Vec<(f64, [f32; 3])>,
    /// First and last time of the log, s.
    pub span: (f64, f64),
    /// Largest absolute rate, at least 1 rad/s.
    pub rate_max: f32,
    /// A whole reading was traced.
    done: bool,
}

impl Trace {
    fn push(&mut self, x: &inputs::Input) {
        if !self.done && x.i.is_multiple_of(self.step) {
            self.points.push((x.t, x.gyro));
        }
    }
}

/// Why no estimate could be given at all.
#[derive(Debug, PartialEq)]
pub enum IdentifyError {
    /// Too few samples to do anything.
    TooShort,
    /// The gate found no free flight.
    NoFreeFlight,
    /// The gate found no free flight, and the accelerometer's or the gyro's unit looks wrong, or
    /// stretches fitted rotation about a point beyond the gate's offset (the sentence).
    NoFreeFlightUnits(String),
    /// A rotor was given but the log has no rotor-speed channel, or eRPM without poles.
    Rotor(String),
    /// Settings could not be built (rate or noise not finite).
    Settings(String),
    /// The log could not be read.
    Read(ReadError),
    /// Something that should not happen (a worker thread stopped).
    Internal(String),
}

impl std::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IdentifyError::TooShort => write!(f, "the log has fewer than 10 samples"),
            IdentifyError::NoFreeFlight => write!(
                f,
                "no free flight found: the accelerometer never read pure rotation about the \
                 centre of mass (give --segments to choose the stretches by hand)"
            ),
            IdentifyError::NoFreeFlightUnits(m) => write!(f, "no free flight found: {m}"),
            IdentifyError::Rotor(m) => write!(f, "{m}"),
            IdentifyError::Settings(m) => write!(f, "{m}"),
            IdentifyError::Read(e) => write!(f, "{e}"),
            IdentifyError::Internal(m) => write!(f, "internal error: {m}"),
        }
    }
}

impl std::error::Error for IdentifyError {}

impl From<ReadError> for IdentifyError {
    fn from(e: ReadError) -> Self {
        IdentifyError::Read(e)
    }
}

/// Options of one identification.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IdentifyOptions {
    /// Known rotor (the `--rotor-*` shorthand: one rotor on a gyro axis, its speed from the
    /// log's rotor channel).
    pub rotor: Option<Rotor>,
    /// The vehicle file's rotors (`--vehicle`), their speeds from the columns it names: the
    /// source must have been opened with [`crate::vehicle::Vehicle::columns`] as
    /// [`crate::ReadOptions::rotor_columns`]. Not with [`IdentifyOptions::rotor`].
    pub vehicle: Option<Vehicle>,
    /// Hand-chosen stretches `(start_s, end_s)`; the gate is not used.
    pub segments: Option<Vec<(f64, f64)>>,
    /// Gyro noise, rad/s; estimated from the data when `None`.
    pub noise_std: Option<f32>,
    /// The rotor speed as logged, interpolated ([`unhold`]), or decided from the log's update
    /// intervals ([`RotorHold`]).
    pub rotor_hold: RotorHold,
    /// Keep the rates to plot ([`Report::trace`]).
    pub trace: bool,
}

/// Where `identify` is, for a progress bar.
pub trait Progress {
    /// A stage begins: `"checking"` (the first readings), `"identifying"`, `"re-running"`.
    fn stage(&mut self, _name: &str) {}
    /// The fraction of the stage done.
    fn update(&mut self, _fraction: f32) {}
}

/// No progress shown.
pub struct Quiet;

impl Progress for Quiet {}

impl IdentifyOptions {
    /// A rotor momentum is known (`--rotor-*` or `--vehicle`): the tensor comes in kg m^2.
    pub fn momentum_known(&self) -> bool {
        self.rotor.is_some() || self.vehicle.is_some()
    }
}

/// The rotor momentum's quantum, kg m^2/s: the rotor inertia times the speed channel's
/// resolution ([`crate::survey::RotorStep`]; 0 without a rotor or a speed that never changed).
pub(crate) fn momentum_quantum(opts: &IdentifyOptions, speed_step: Option<f32>) -> f32 {
    match (&opts.rotor, speed_step) {
        (Some(r), Some(q)) => r.inertia * q,
        _ => 0.0,
    }
}

/// Runs the identification on a recording held in memory.
pub fn identify(rec: &Recording, opts: &IdentifyOptions) -> Result<Report, IdentifyError> {
    identify_source(&RecordingSource::new(rec), opts, &mut Quiet)
}

fn bits(v: [f32; 3]) -> [u32; 3] {
    v.map(f32::to_bits)
}

/// The fastest a rotor of a vehicle turns, rad/s (about 57,000 rpm: a small drone motor
/// without its propeller; reaction wheels turn at a tenth of it). A faster speed is a unit
/// read wrong (eRPM or rpm taken for rad/s): the momentum, and with it the tensor's scale, is
/// then off by the same factor while the fit stays perfect, so the estimate is
/// `UnitsLookWrong`.
pub const MAX_PLAUSIBLE_ROTOR_RAD_S: f32 = 6000.0;

/// The warning for a vehicle rotor whose speed, in rad/s as its file's unit reads it, goes
/// beyond [`MAX_PLAUSIBLE_ROTOR_RAD_S`] (`None` when none does).
fn rotor_units_warning(src: &dyn Source, v: &Vehicle) -> Result<Option<String>, IdentifyError> {
    let mut fastest = vec![0.0f32; v.rotors.len()];
    src.read_all(
        &mut |s| {
            for ((m, &w), r) in fastest.iter_mut().zip(&s.extra.wheels).zip(&v.rotors) {
                let k = r.to_rad_per_sec().unwrap_or(1.0);
                *m = m.max((w * k).abs());
            }
            Ok(Flow::Continue)
        },
        &mut |_| {},
    )?;
    let over = v
        .rotors
        .iter()
        .zip(&fastest)
        .find(|(_, &m)| m > MAX_PLAUSIBLE_ROTOR_RAD_S);
    Ok(over.map(|(r, m)| {
        format!(
            "rotor {:?} reaches {m:.0} rad/s ({:.0} rpm) as its column {:?} is read ({:?}): no \
             motor or wheel turns that fast, so its unit looks wrong (speed_unit, poles?) and \
             the tensor's scale with it",
            r.name,
            m * 60.0 / core::f32::consts::TAU,
            r.column,
            r.unit()
        )
    }))
}

/// Runs the identification on a log read sample by sample (see the module documentation).
/// An orbiting vehicle's log (attitude and position columns, a known rotor momentum) is
/// identified with the gravity-gradient torque folded into the momentum ([`gravity`]),
/// refitted at the tensor found until it settles.
///
/// When the gyro reads whole counts ([`crate::grid::detect`]) and the fit's residual is within
/// [`GRID_RESIDUAL_COUNTS`] counts, the log is identified once more with its readings moved to
/// their cells' centres as under truncation toward zero ((Q1) of [`crate::grid`]); the fit
/// with the smaller residual is reported (the two have the same parameters), with
/// [`Report::gyro_grid`] saying which.
pub fn identify_source(
    src: &dyn Source,
    opts: &IdentifyOptions,
    progress: &mut dyn Progress,
) -> Result<Report, IdentifyError> {
    let as_read = identify_model(src, opts, progress)?;
    let residual = |r: &Report| r.pooled.residual_ratio * r.noise_std;
    let Some(lsb) = as_read.gyro_lsb else {
        return Ok(as_read);
    };
    let largest = lsb.iter().copied().fold(0.0f32, f32::max);
    let within = residual(&as_read) < GRID_RESIDUAL_COUNTS * largest;
    if !within {
        return Ok(as_read);
    }
    let centred_src = crate::grid::centred(src, lsb);
    let centred = identify_model(&centred_src, opts, progress)?;
    let grid = |c: bool| GyroGrid {
        lsb_rad_s: lsb,
        residual_as_read_rad_s: residual(&as_read),
        residual_centred_rad_s: residual(&centred),
        centred: c,
    };
    Ok(if residual(&centred) < residual(&as_read) {
        let mut r = centred.clone();
        r.warnings.push(format!(
            "the gyro reads whole counts ({:.3e}, {:.3e}, {:.3e} rad/s) and the fit's residual \
             is smaller with them taken as truncated toward zero ({:.3e} against {:.3e} rad/s \
             as read): the readings were moved to their counts' centres",
            lsb[0],
            lsb[1],
            lsb[2],
            residual(&centred),
            residual(&as_read)
        ));
        r.gyro_grid = Some(grid(true));
        r
    } else {
        let mut r = as_read.clone();
        r.gyro_grid = Some(grid(false));
        r
    })
}

/// The identification of the log as `src` reads it: torque-free, and on an orbiting vehicle's
/// log with the gravity gradient folded in.
fn identify_model(
    src: &dyn Source,
    opts: &IdentifyOptions,
    progress: &mut dyn Progress,
) -> Result<Report, IdentifyError> {
    let free = identify_pass(src, opts, None, progress)?;
    let ch = src.channels();
    if !(opts.momentum_known() && ch.attitude && ch.position) {
        return Ok(free);
    }
    let mut report = free.clone();
    for _ in 0..gravity::MAX_PASSES {
        let Some(j) = report.pooled.tensor_kg_m2 else {
            break;
        };

        let mut next = identify_pass(src, opts, Some(j), progress)?;
        next.gravity_gradient = true;
        // (G3): the rule the firmware's replay of an orbit log applies too.
        let moved = identifier_core::gravity::tensor_moved(
            &j,
            next.pooled.tensor_kg_m2,
            next.pooled.tensor_std_kg_m2,
        );
        report = next;
        if identifier_core::gravity::settled(moved) {
            break;
        }
    }
    // The model with the gravity gradient has no more free parameters than the one without:
    // the one whose residual is smaller is the likelier (a simulated orbit without the
    // torque keeps the torque-free model).
    let ratio = |r: &Report| r.pooled.residual_ratio;
    if report.gravity_gradient
        && identifier_core::gravity::keep_folded(ratio(&report), ratio(&free))
    {
        Ok(report)
    } else {
        Ok(free)
    }
}

/// One identification, with the gravity gradient of a body of inertia `gravity` folded into
/// the momentum when given.
fn identify_pass(
    src: &dyn Source,
    opts: &IdentifyOptions,
    gravity: Option<[[f32; 3]; 3]>,
    progress: &mut dyn Progress,
) -> Result<Report, IdentifyError> {
    let ch = src.channels();
    // The rotor channel's factor to rad/s; `None` when the rotor cannot be used, which is an
    // error reported after the checks that come first.
    let factor = match (&opts.rotor, ch.rotor) {
        (Some(r), Some(unit)) => unit.factor(r.poles),
        _ => None,
    };
    let wanted = Wanted {
        noise: opts.noise_std.is_none(),
        unhold: if opts.rotor_hold == RotorHold::Raw {
            None
        } else {
            factor
        },
        rotor_step: factor,
    };
    progress.stage("checking");
    let mut sv = survey(src, wanted, &mut |f| progress.update(f))?;
    // Fast telemetry is taken as logged (`RotorHold::Auto`): no interpolation plan then.
    if sv
        .unhold
        .as_ref()
        .is_some_and(|p| !opts.rotor_hold.interpolates(p.holds.is_slow()))
    {
        sv.unhold = None;
    }
    let n = sv.samples;
    if n < 10 {
        return Err(IdentifyError::TooShort);
    }
    let mut warnings = src.warnings(sv.warnings.clone());
    let dt_med = sv.median_dt.unwrap_or(f64::NAN);
    let rate = (1.0 / dt_med) as f32;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(IdentifyError::Settings(
            "the time steps are not positive".into(),
        ));
    }
    let filters = src.gyro_filters();
    let noise = opts
        .noise_std
        .or(sv.noise.map(|m| white_noise(m, filters.as_ref(), dt_med)))
        .unwrap_or(2e-3);
    if let Some(v) = &opts.vehicle {
        if opts.rotor.is_some() {
            return Err(IdentifyError::Rotor(
                "--vehicle and --rotor-inertia/--rotor-axis exclude each other".into(),
            ));
        }
        if ch.wheels != v.rotors.len() {
            return Err(IdentifyError::Rotor(format!(
                "the log was read with {} of the vehicle file's {} rotor columns (CSV columns, \
                 blackbox fields and ULog topic fields are named)",
                ch.wheels,
                v.rotors.len()
            )));
        }
    }
    let rotor = match &opts.rotor {
        None => None,
        Some(r) => {
            if ch.rotor.is_none() {
                return Err(IdentifyError::Rotor(
                    "--rotor-inertia was given but the log has no rotor-speed channel".into(),
                ));
            }
            let Some(factor) = factor else {
                return Err(IdentifyError::Rotor(
                    "the log gives rotor speed as eRPM: --rotor-poles is needed".into(),
                ));
            };
            Some(RotorInput {
                rotor: *r,
                factor,
                plan: sv.unhold.as_ref(),
            })
        }
    };
    if !opts.momentum_known() && ch.rotor.is_some() {
        warnings.push(
            "the log has a rotor-speed channel but no --rotor-inertia was given: rotor \
             momentum is ignored and the tensor is determined up to scale only"
                .into(),
        );
    }
    let quantum = momentum_quantum(opts, sv.rotor_step);
    let settings = PipelineSettings::for_rate(rate, noise)
        .with_full_scale(src.full_scale())
        .with_momentum_resolution(quantum)
        .with_averaging_gyro(src.gyro_averaging())
        .with_filtered_gyro(filters.as_ref().map_or(0.0, |f| f.smoothing(dt_med) as f32))
        .with_centred_readings(src.gyro_centred());
    let inputs = Inputs {
        src,
        samples: n,
        dt_med,
        rotor,
        vehicle: opts.vehicle.as_ref(),
        gravity,
    };
    let mut trace = opts.trace.then(|| Trace {
        step: (n / 20000).max(1),
        points: Vec::new(),
        span: sv.span,
        rate_max: sv.rate_max,
        done: false,
    });

    // Which samples count as free flight, and the pooled on-board estimate.
    progress.stage("identifying");
    let detection;
    let mut far = passes::FarRotation::default();
    let (pooled, runs, mut throws) = match &opts.segments {
        Some(segs) => {
            detection = false;
            let first = segs.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
            let bias = if ch.accel {
                passes::bench_bias(&inputs, settings, first, progress)?
            } else {
                None
            };
            let (p, runs, throws, held) =
                passes::segments(&inputs, settings, segs, bias, &mut trace, progress)?;
            for (&(s, e), held) in segs.iter().zip(held) {
                if !held {
                    warnings.push(format!("segment {s}..{e} s holds no sample of the log"));
                }
            }
            (p, runs, throws)
        }
        None => {
            detection = ch.accel;
            let (p, runs, throws, f) =
                passes::gate(&inputs, settings, ch.accel, rate, &mut trace, progress)?;
            far = f;
            (p, runs, throws)
        }
    };
    if let Some(t) = &mut trace {
        t.done = true;
    }
    if runs.is_empty() {
        let why = sv.accel_units.take().or(sv.gyro_units.take());
        return Err(match why.or_else(|| far.describe(&settings.gate)) {
            Some(m) => IdentifyError::NoFreeFlightUnits(m),
            None => IdentifyError::NoFreeFlight,
        });
    }
    // Throws begun with another bias than the final one are fed again with the final one.
    let again: Vec<&passes::Run> = runs
        .iter()
        .filter(|r| r.bias.map(bits) != pooled.bias.map(bits))
        .collect();
    if !again.is_empty() {
        progress.stage("re-running");
        for (k, j) in passes::rerun(&inputs, settings, &again, pooled.bias, progress)? {
            if let Some(slot) = throws.get_mut(k) {
                *slot = (k, j);
            }
        }
    }
    let ordered = throws.len() == runs.len() && throws.iter().enumerate().all(|(k, t)| t.0 == k);
    if !ordered {
        return Err(IdentifyError::Internal(
            "a throw's estimate is missing".into(),
        ));
    }
    let (first, last) = (runs[0].span.0, runs[runs.len() - 1].span.1);
    let mut pooled_json = EstimateJson::from(&pooled.estimate, &pooled.ratios, first, last);
    pooled_json.samples = pooled.fed_inputs;
    // An accelerometer not in m/s^2 misleads the gate (a hand's motion taken for free flight,
    // no bench for the bias), and a gyro read in the wrong unit feeds the fits only what its
    // full scale or the plausible rates let through: nothing found with either is to be
    // trusted, whatever the fits say.
    let mut status = pooled.ratios.status;
    // A slow tumble logged in deg/s stays below the sustained-rate check; its ratios, 57 times
    // too small, give it away (only where the unit was assumed).
    if sv.gyro_units.is_none() && !src.gyro_unit_stated() {
        if let Some(w) = pooled
            .ratios
            .a
            .and_then(|a| crate::readers::ratios_warning(a, sv.rate_max))
        {
            warnings.push(w.clone());
            sv.gyro_units = Some(w);
        }
    }
    let rotor_units = match &opts.vehicle {
        Some(v) => rotor_units_warning(src, v)?,
        None => None,
    };
    if let Some(w) = &rotor_units {
        warnings.push(w.clone());
    }
    if sv.accel_units.is_some() || sv.gyro_units.is_some() || rotor_units.is_some() {
        status = Status::UnitsLookWrong;
        let wrong = format!("{status:?}");
        for j in throws.iter_mut().map(|(_, j)| j).chain([&mut pooled_json]) {
            j.status.clone_from(&wrong);
            j.tensor_status.clone_from(&wrong);
            j.tensor_usable = false;
        }
    }
    if status != Status::Converged {
        warnings.push(format!("pooled estimate is not to be trusted: {status:?}"));
    }
    // A throw whose output-error fit failed (no motion of the model follows its samples: a
    // hand, a catch, a stretch the gate should not have passed) is not in the pooled fit;
    // say which, since the pooled sample count includes it. (With a rotor the fit is
    // reported whenever it ran; without one also only where it fits to the noise.)
    if opts.momentum_known() && pooled_json.tensor_method == "OutputError" {
        for (k, j) in &throws {
            if j.tensor_method != "OutputError" {
                warnings.push(format!(
                    "throw {k} ({:.3}-{:.3} s): its output-error fit failed (the model follows \
                     none of its motion: a hand or a catch?), so the pooled tensor leaves it out",
                    j.start_s, j.end_s
                ));
            }
        }
    }
    warnings.extend(scale_floor_warning(&pooled_json));
    if pooled.bias.is_none() {
        warnings.push(NO_BIAS_WARNING.into());
    }
    // The walk's step is per pipeline sample (the log's rate over the decimation).
    let walk = (pooled.bias_walk > 0.0)
        .then(|| pooled.bias_walk * (settings.rate_hz / f32::from(settings.decimation)).sqrt());
    if let Some(k) = walk {
        warnings.push(format!(
            "the gyro's bias walks (a rate random walk of {k:.3e} rad/s per sqrt(s)): the fit \
             whitened its residual by the walk, and the tensor is at most ModelMismatch, its \
             standard deviation the walk's"
        ));
    }
    Ok(Report {
        input: src.name(),
        log_samples: n,
        rate_hz: rate,
        noise_std: noise,
        gyro_bias: pooled.bias.unwrap_or([0.0; 3]),
        gyro_bias_measured: pooled.bias.is_some(),
        free_flight_detection: detection,
        rotor_momentum_quantum: (quantum > 0.0).then_some(quantum),
        gravity_gradient: false,
        gyro_grid: None,
        gyro_lsb: sv.gyro_lsb,
        gyro_bias_walk_rad_s_per_sqrt_s: walk,
        throws: throws.into_iter().map(|(_, j)| j).collect(),
        pooled: pooled_json,
        warnings,
        fed_runs: runs.into_iter().map(|r| r.ranges).collect(),
        trace,
        gyro_scale: None,
        gyro_scale_factor: None,
        clock_scale_factor: None,
    })
}

/// The systematic uncertainty of the pooled estimate from the gyro's scale factors, which the
/// data cannot show (a scale-factor error leaves the torque-free equations satisfied with other
/// ratios): the log identified again with each gyro axis reading `tolerance` high in turn.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ScaleSystematic {
    /// The 1-sigma relative tolerance of each axis's scale factor, percent.
    pub gyro_scale_tolerance_percent: f32,
    /// `a` with gyro axis x, y, z (one row each) reading the tolerance high, minus the pooled
    /// `a` (`None` where either has no `a`).
    pub a_shift: [Option<[f32; 3]>; 3],
    /// `sqrt(sum over axes of the shift^2)`: the standard deviation of `a` from independent
    /// scale-factor errors of that size.
    pub std_a: Option<[f32; 3]>,
    /// `sqrt(std_a(noise)^2 + std_a(scale)^2)`.
    pub total_std_a: Option<[f32; 3]>,
    /// The same standard deviation for each entry of the tensor (kg m^2 with a rotor, else
    /// `J / trace J`).
    pub std_tensor: Option<[[f32; 3]; 3]>,
}

/// [`ScaleSystematic`] for `base`, the report of `src` under `opts`, and a tolerance in percent:
/// three more identifications (one per gyro axis) of the same samples scaled by
/// `1 + tolerance / 100`, to first order in the tolerance.
pub fn scale_systematic(
    src: &dyn Source,
    opts: &IdentifyOptions,
    base: &Report,
    tolerance_percent: f32,
) -> Result<ScaleSystematic, IdentifyError> {
    let opts = IdentifyOptions {
        trace: false,
        ..opts.clone()
    };
    let tensor_of = |p: &EstimateJson| p.tensor_kg_m2.or(p.tensor_normalized);
    let (a0, t0) = (base.pooled.a, tensor_of(&base.pooled));
    let mut a_shift = [None; 3];
    let mut t_shift = [None; 3];
    for k in 0..3 {
        let mut scale = [1.0f32; 3];
        scale[k] += tolerance_percent / 100.0;
        let scaled = crate::source::MappedSource::scaled(src, scale);
        let rep = identify_source(&scaled, &opts, &mut Quiet)?;
        a_shift[k] = a0
            .zip(rep.pooled.a)
            .map(|(a, b)| std::array::from_fn(|i| b[i] - a[i]));
        t_shift[k] = t0.zip(tensor_of(&rep.pooled)).map(|(a, b)| {
            std::array::from_fn::<[f32; 3], 3, _>(|r| std::array::from_fn(|c| b[r][c] - a[r][c]))
        });
    }
    let std_a = root_sum_square(a_shift);
    let total_std_a = std_a
        .zip(base.pooled.std_a)
        .map(|(s, n): ([f32; 3], [f32; 3])| std::array::from_fn(|i| s[i].hypot(n[i])));
    let rows: [Option<[f32; 3]>; 3] =
        std::array::from_fn(|r| root_sum_square(t_shift.map(|t| t.map(|d| d[r]))));
    let std_tensor = match rows {
        [Some(x), Some(y), Some(z)] => Some([x, y, z]),
        _ => None,
    };
    Ok(ScaleSystematic {
        gyro_scale_tolerance_percent: tolerance_percent,
        a_shift,
        std_a,
        total_std_a,
        std_tensor,
    })
}

/// `sqrt(x^2 + y^2 + z^2)` entry by entry over the three axes' shifts; `None` unless all three
/// are there.
fn root_sum_square(shifts: [Option<[f32; 3]>; 3]) -> Option<[f32; 3]> {
    let [Some(x), Some(y), Some(z)] = shifts else {
        return None;
    };
    Some(std::array::from_fn(|i| {
        (x[i] * x[i] + y[i] * y[i] + z[i] * z[i]).sqrt()
    }))
}
