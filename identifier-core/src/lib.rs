//! On-board identification of a rigid body's inertia from gyro samples: `no_std`, no heap, no
//! `unsafe`, no panic path, `f32`, one call per sample.
//!
//! # Which estimator to use
//!
//! | you have | use | gives |
//! |---|---|---|
//! | a thrown or tumbling vehicle with gyro and accelerometer (and rotor speeds, if any rotor turns) | [`FlightPipeline`]: free-flight gate, guards, gyro bias, [`TensorEstimator`] | the tensor `J` in the sensor frame (kg m^2 with a known rotor momentum, else up to scale), principal moments and axes, `a`, standard deviations, a [`Status`] |
//! | gyro samples of a free tumble, axes taken as principal | [`RatioFit`] (output-error fit of the whole flight, all axes jointly, on the Cramer-Rao bound; a gyro bias when its test finds one; fitted once per flight); [`Refined`] (per sample, near the bound); [`FlightPipeline::ratios`] chooses | `a` with standard deviations and a [`Status`] |
//! | the same, for the tensor at the bound | [`TensorFit`] (output error, started from [`TensorEstimator`]'s tensor or the ratio fit's moments; the pipeline uses it when it fits to the noise) | `J` in kg m^2 with its covariance when a known rotor momentum fixes the scale ([`TensorFit::close`]), else `J / trace J` ([`TensorFit::close_normalized`]) |
//! | the paper's method, as published | [`Identifier`] (V.F. Shcherbak's invariant relations, with the sign-change correction) | `a` and the paper's convergence criterion; on noisy data far above the bound (`scripts/bench-estimators.sh`) |
//! | a model with one extra effect (bias, torque, damping, products, rotor) | [`ExtendedIdentifier`] | `a` and the effect |
//! | an orbiting vehicle's attitude and position with its gyro (and wheels) | [`gravity`]: Earth's gravity-gradient torque at a tensor, folded into the known momentum for [`FlightPipeline::step`] | the extra momentum per sample, and the rule that decides when the passes at the tensor found have settled |
//!
//! Nothing is to be trusted unless its status says so: one [`Status`] for every estimator,
//! [`Status::Converged`] given only when the estimate's own standard deviations are within the
//! tolerance, the estimate is physically possible and the data carried information; a
//! still gyro, deg/s data, a wrong time step or a clipped throw says why it is not.
//!
//! ```
//! use identifier_core::{Status, TensorEstimator, TensorSettings};
//!
//! // A torque-free body with principal moments (0.6, 1.54, 1.0), sampled at 1 kHz.
//! let m = [0.6f64, 1.54, 1.0];
//! let mut w = [1.0f64, 1.0, 1.0];
//! let mut est = TensorEstimator::new(TensorSettings::for_rate(1000.0, 1e-3)).unwrap();
//! for _ in 0..20_000 {
//!     est.step([w[0] as f32, w[1] as f32, w[2] as f32], [0.0; 3], 1e-3);
//!     for _ in 0..50 {
//!         // Euler's equations, small explicit steps (an example, not a reference).
//!         let d = [
//!             (m[1] - m[2]) / m[0] * w[1] * w[2],
//!             (m[2] - m[0]) / m[1] * w[2] * w[0],
//!             (m[0] - m[1]) / m[2] * w[0] * w[1],
//!         ];
//!         for k in 0..3 {
//!             w[k] += 2e-5 * d[k];
//!         }
//!     }
//! }
//! let e = est.estimate();
//! let a = e.a.unwrap();
//! assert!((a[0] - 0.9).abs() < 0.01 && (a[2] + 0.94).abs() < 0.01);
//! assert!(e.status != Status::NoExcitation);
//! ```
//!
//! # The paper's method
//!
//! This crate implements V.F. Shcherbak's invariant-relation identifier for the torque-free
//! Euler equations (equation numbers below are the paper's, see `README.md`):
//!
//! ```text
//! w1' = a1 w2 w3,  w2' = a2 w3 w1,  w3' = a3 w1 w2                                   (1)
//! a1 = (A2-A3)/A1, a2 = (A3-A1)/A2, a3 = (A1-A2)/A3
//! ```
//!
//! One call of [`Identifier::step`] per gyro sample advances the auxiliary states alpha of (3)
//! under the controls (7), with `Phi` from (9) for a Hurwitz gain matrix `C` ([`GainMatrix`]),
//! and returns the estimate (12) of `a = (a1, a2, a3)` with a per-sample [`SampleStatus`] and the
//! paper's convergence criterion ([`Convergence`]).
//!
//! The crate is `#![no_std]`, allocates nothing, has no `unsafe` and no panicking path: every
//! input, including NaN, infinite or saturated rates and zero, negative or huge time steps, has
//! a defined [`SampleStatus`] and leaves the state finite.
//!
//! Data flows one way, sensor to report, through [`FlightPipeline::step`] once per sample: the
//! [`FreeFlightGate`] tells free flight from the bench, the hand and the catch (and measures
//! the gyro bias at rest); the samples it passes feed the [`TensorEstimator`] (per sample) and
//! the two output-error fits' block buffers ([`RatioFit`], [`TensorFit`]); when a flight ends,
//! [`FlightPipeline::fit_ended_flight`] runs the fits off the sample path; the estimate and its
//! status come out of [`FlightPipeline::estimate_and_ratios`]. The paper's own path is
//! [`invariant`] (its functions of omega) integrated by [`Identifier`].
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
// No panicking construct outside the unit tests: the step must be total on every input.
#![cfg_attr(
    not(test),
    deny(
        clippy::panic,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing
    )
)]

mod convergence;
mod exact;
pub mod extended;
pub mod free_flight;
pub mod gravity;
mod identifier;
mod inertia;
pub mod invariant;
mod linalg;
mod output_error;
mod pipeline;
mod ratio_fit;
mod refined;
mod refined_bias;
mod rotors;
mod settings;
mod status;
pub mod symmetric;
mod tensor;
mod tensor_fit;

#[cfg(test)]
mod test_motion;

pub use convergence::{Convergence, ConvergenceMonitor};
pub use extended::{
    ExtendedEstimate, ExtendedIdentifier, ExtendedSettings, ExtendedStatus, ExtraEffect,
};
pub use free_flight::{AccelUnits, FreeFlightGate, GateSettings, WindowFit};
pub use identifier::Identifier;
pub use inertia::{consistency, InertiaRatios};
pub use output_error::StretchOutcome;
pub use pipeline::{
    Exit, FlightPipeline, Pending, Pipeline, PipelineSettings, RatioSource, Ratios,
    TRAJECTORY_FIT_RATIO, WINDOW_TURN_RAD,
};
pub use ratio_fit::{FlightRatioFit, RatioFit, RatioFitEstimate};
pub use refined::{Refined, RefinedSettings};
pub use refined_bias::RefinedBias;
pub use rotors::{Rotor, RotorError, Rotors, AXIS_UNIT_TOLERANCE, MAX_ROTORS};
pub use settings::{GainMatrix, Settings, SettingsError, SignChangeCorrection};
pub use status::{Counters, Estimate, SampleStatus};
pub use status::{Exposure, Status, Verdict};
pub use tensor::{
    TensorCounters, TensorEstimate, TensorEstimator, TensorMethod, TensorModel, TensorSettings,
    Uncertainty, MAX_STEP_TURN_RAD,
};
pub use tensor_fit::{FlightTensorFit, TensorFit, TensorFitEstimate};
