//! Closing the loop on measured data: identify, compute the residual of the torque-free model,
//! trace it to a library of candidate effects, add the chosen effect(s) to the model and
//! report the error before and after. See [`analysis::analyse`].

pub mod analysis;
pub mod model;
pub mod report;
pub mod stats;
