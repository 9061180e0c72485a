//! What the board knows about the body besides the IMU, per sample: the speeds of its known
//! rotors (reaction wheels, a flywheel, motors) and whether an actuator acts on it.
//!
//! The rotors themselves are an [`identifier_core::Rotors`] (inertia and axis of each, up to
//! [`MAX_ROTORS`]): the loop turns the speeds into the momentum `h = sum_i j_i W_i g_i` with
//! [`Rotors::momentum`], the function `inertia identify` uses, so host and MCU give the same
//! bits.
//!
//! A speed read from telemetry comes in steps (DShot's eRPM: 100 eRPM, `100 / (poles / 2) *
//! 2 pi / 60` rad/s, 1.75 rad/s for 12 poles): give the pipeline the momentum's quantum
//! (`inertia * step`) with [`PipelineSettings::with_momentum_resolution`] so that the tensor's
//! uncertainty counts the steps' error (the QEMU image takes it from the replay's header, as
//! `inertia identify` computes it from the log).
//!
//! [`PipelineSettings::with_momentum_resolution`]:
//! identifier_core::PipelineSettings::with_momentum_resolution

use identifier_core::{Rotors, MAX_ROTORS};

/// The board's per-sample inputs besides the IMU: it implements this (from ESC telemetry, Hall
/// sensors, a DShot reply, the attitude controller's actuator commands); the QEMU image reads
/// them from the replayed log. Both are read once per sample, at the time of the sample.
pub trait BoardInputs {
    /// Fills `speeds` with the rotors' speeds for the current sample, rad/s relative to the
    /// body, positive along each rotor's axis, in the order of the loop's [`Rotors`] (entries
    /// past their number are ignored). False when they are not known for this sample (no
    /// rotor, no fresh reading): the momentum is then zero.
    fn wheel_speeds(&mut self, speeds: &mut [f32; MAX_ROTORS]) -> bool;

    /// True when thrusters, magnetorquers or anything else put a torque on the body during
    /// the current sample: the sample is kept out of the estimators that assume a torque-free
    /// body (the free-flight pipeline's stretch ends before it; see
    /// [`SampleLoop`](super::SampleLoop)).
    fn actuated(&mut self) -> bool {
        false
    }
}

/// No rotor and no actuator: every sample is torque-free with zero momentum.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoBoardInputs;

impl BoardInputs for NoBoardInputs {
    fn wheel_speeds(&mut self, _speeds: &mut [f32; MAX_ROTORS]) -> bool {
        false
    }
}

/// The rotors' speeds the board gives for this sample, and whether it gave them (never
/// without rotors).
pub(crate) fn speeds_of<B: BoardInputs>(
    board: &mut B,
    rotors: &Rotors,
) -> ([f32; MAX_ROTORS], bool) {
    let mut speeds = [0.0f32; MAX_ROTORS];
    let known = !rotors.is_empty() && board.wheel_speeds(&mut speeds);
    (speeds, known)
}
