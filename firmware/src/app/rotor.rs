//! The optional rotor: its speed input and the momentum it adds.

/// A rotor whose angular momentum goes with each sample to the free-flight pipeline:
/// `h = axis * inertia * speed` (kg m^2/s), the speed from the [`RotorSpeedSource`].
///
/// A speed read from telemetry comes in steps (DShot's eRPM: 100 eRPM, `100 / (poles / 2) *
/// 2 pi / 60` rad/s, 1.75 rad/s for 12 poles): give the pipeline `inertia * step` with
/// [`PipelineSettings::with_momentum_resolution`] so that the tensor's uncertainty counts the
/// steps' error (the QEMU image does, from the replay's header, as `inertia identify` does
/// from the log).
///
/// [`PipelineSettings::with_momentum_resolution`]:
/// identifier_core::PipelineSettings::with_momentum_resolution
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RotorConfig {
    /// Inertia about the rotor's axis, kg m^2.
    pub inertia: f32,
    /// Unit axis in the gyro frame, the direction of positive speed.
    pub axis: [f32; 3],
}

impl RotorConfig {
    /// The rotor momentum at `speed` rad/s, in the order of operations `inertia identify`
    /// uses (`axis_i * inertia * speed`).
    pub fn momentum(&self, speed: f32) -> [f32; 3] {
        self.axis.map(|a| a * self.inertia * speed)
    }
}

/// An optional rotor-speed input (reaction wheel, propeller, motor): the board implements it
/// (from an ESC's telemetry, a Hall sensor, a DShot reply); the QEMU image reads it from the
/// log. The speed goes with each sample to the estimators that model the rotor's angular
/// momentum. `None`: not known for this sample (no rotor, or no fresh reading).
pub trait RotorSpeedSource {
    /// The rotor's speed about its axis, rad/s, signed, at the time of the current sample.
    fn rotor_speed_rad_s(&mut self) -> Option<f32>;
}

/// No rotor input: every sample has `None`.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoRotor;

impl RotorSpeedSource for NoRotor {
    fn rotor_speed_rad_s(&mut self) -> Option<f32> {
        None
    }
}

impl<F: FnMut() -> Option<f32>> RotorSpeedSource for F {
    fn rotor_speed_rad_s(&mut self) -> Option<f32> {
        self()
    }
}
