//! The host tool `inertia`: reads the logs users already have, finds the free flights and
//! identifies the inertia tensor with the same `f32` code the firmware runs
//! (`identifier-core`).

pub mod calibrate;
pub mod close_loop;
pub mod export;
pub mod grid;
pub mod identify;
pub mod plots;
pub mod pool;
pub mod readers;
pub mod recording;
pub mod select;
pub mod source;
pub mod survey;
pub mod unhold;
pub mod vehicle;

pub use readers::{read, AccelUnit, Format, GyroUnit, ReadError, ReadOptions, TimeUnit};
pub use recording::{Recording, RotorSpeed};
