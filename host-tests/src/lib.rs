//! Host-side companions of `identifier-core`: a reference simulator of a spinning rigid body,
//! a gyro model, and shared helpers for the tests, benchmarks and analysis tools.
//!
//! Everything here is `f64` and `std`; the identifier under test is the very same
//! `identifier-core` code the firmware runs.

pub mod crb;
pub mod crb_tensor;
pub mod estimators;
pub mod gyro;
pub mod paper;
pub mod plot;
pub mod reference;
pub mod replay;
pub mod rigid_body;
pub mod throw_sim;
