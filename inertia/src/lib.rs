//! The host tool `inertia`: reads the logs users already have, finds the free flights and
//! identifies the inertia tensor with the same `f32` code the firmware runs
//! (`identifier-core`).

pub mod recording;

pub use recording::{Recording, RotorSpeed};
