//! On-board identifier of a rigid body's inertia ratios from gyro samples.
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
//! Data flows one way: [`invariant`] holds the paper's functions of omega, [`Identifier`]
//! integrates them, [`convergence`] watches the result and [`inertia`] turns `a` into ratios.
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

pub mod convergence;
pub mod extended;
pub mod free_flight;
pub mod identifier;
pub mod inertia;
pub mod invariant;
mod linalg;
pub mod pipeline;
pub mod refined;
pub mod settings;
pub mod status;
pub mod symmetric;
pub mod tensor;

pub use convergence::{Convergence, ConvergenceMonitor};
pub use extended::{
    ExtendedEstimate, ExtendedIdentifier, ExtendedSettings, ExtendedStatus, ExtraEffect,
};
pub use free_flight::{FreeFlightGate, GateSettings, WindowFit};
pub use identifier::Identifier;
pub use inertia::{consistency, InertiaRatios};
pub use pipeline::{Exit, FlightPipeline, Pending, Pipeline, PipelineSettings};
pub use refined::{Refined, RefinedSettings};
pub use settings::{GainMatrix, Settings, SettingsError, SignChangeCorrection};
pub use status::{Counters, Estimate, SampleStatus};
pub use status::{Exposure, Trust, Verdict};
pub use tensor::{
    TensorCounters, TensorEstimate, TensorEstimator, TensorModel, TensorSettings, TensorStatus,
};
