//! Flight logs written from simulated data, in the formats `inertia` reads: one writer per
//! format, shared by the readers' tests (`inertia/tests`) and the log generator
//! (`host-tests`' `gen-throw --format`), so both exercise what the same bytes mean.
//!
//! Only what a test needs is written: a Betaflight blackbox log of intra frames, and the
//! message framing of a ULog file.
#![forbid(unsafe_code)]

pub mod blackbox;
pub mod ulog;
