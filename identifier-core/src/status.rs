//! What one step reports: the estimate (12), what happened to the sample, and counters for
//! diagnosis.

use crate::convergence::Convergence;
use crate::inertia::{consistency, InertiaRatios};

/// What [`crate::Identifier::step`] did with one sample. Every input maps to exactly one of
/// these; only [`SampleStatus::Updated`] and [`SampleStatus::SignChange`] move the estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SampleStatus {
    /// The sample was integrated on an identifiable interval (2).
    Updated,
    /// `w1 w2 w3` changed sign between this sample and the previous one, both identifiable;
    /// the step was integrated with the sign-change correction.
    SignChange,
    /// `|w1 w2 w3| < w_min` here or at the previous sample: (2) fails, the estimate is held.
    Unidentifiable,
    /// The first usable sample, or the first after a restart: it anchors the integration.
    Anchored,
    /// The time since the last integrated sample exceeded `max_dt` (dropped samples, a pause):
    /// the integration restarts from this sample, the estimate is held.
    Gap,
    /// A component was NaN or infinite; the sample was ignored and its `dt` carried over.
    NonFinite,
    /// A component reached the gyro full scale; the sample was ignored and its `dt` carried
    /// over.
    Saturated,
    /// `dt` was zero, negative or not a number; the sample was ignored and the next one
    /// restarts the integration, because the time base is no longer known.
    InvalidTimeStep,
    /// The update produced a non-finite value (only reachable with extreme inputs); it was
    /// discarded and the estimate held.
    NumericalFault,
}

impl SampleStatus {
    /// True when the estimate was moved by this sample.
    pub const fn integrated(self) -> bool {
        matches!(self, SampleStatus::Updated | SampleStatus::SignChange)
    }

    /// True when the sample itself was refused (bad value or bad time step).
    pub const fn rejected(self) -> bool {
        matches!(
            self,
            SampleStatus::NonFinite | SampleStatus::Saturated | SampleStatus::InvalidTimeStep
        )
    }
}

/// The result of one step: the estimate of `a` by (12) and its status.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// `(a1, a2, a3)` by (12), in the sensor's axis order. Always finite.
    pub a: [f32; 3],
    /// What happened to this sample.
    pub status: SampleStatus,
    /// The paper's accuracy criterion, evaluated over identifiable time.
    pub convergence: Convergence,
}

impl Estimate {
    /// Inertia ratios `A2/A1`, `A3/A1` implied by `a` (see [`InertiaRatios::from_a`]).
    pub fn ratios(&self) -> Option<InertiaRatios> {
        InertiaRatios::from_a(self.a)
    }

    /// The rigid-body consistency value `a1 + a2 + a3 + a1 a2 a3` (zero for any real body).
    pub fn consistency(&self) -> f32 {
        consistency(self.a)
    }
}

/// Running counts of what the identifier has seen, for telemetry and diagnosis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Every call of `step`.
    pub samples: u32,
    /// Samples that moved the estimate ([`SampleStatus::integrated`]).
    pub integrated: u32,
    /// Samples where (2) failed.
    pub unidentifiable: u32,
    /// Samples refused for their value or time step ([`SampleStatus::rejected`]).
    pub rejected: u32,
    /// Restarts after a gap longer than `max_dt`.
    pub gaps: u32,
    /// Sign changes of `w1 w2 w3` between identifiable stretches, where the correction applied.
    pub sign_changes: u32,
    /// Updates discarded as non-finite.
    pub numerical_faults: u32,
}

impl Counters {
    /// Counts one step's outcome. Saturating: a counter stops at `u32::MAX` rather than wrap.
    pub fn record(&mut self, status: SampleStatus) {
        self.samples = self.samples.saturating_add(1);
        let slot = match status {
            SampleStatus::Updated => &mut self.integrated,
            SampleStatus::SignChange => {
                self.sign_changes = self.sign_changes.saturating_add(1);
                &mut self.integrated
            }
            SampleStatus::Unidentifiable => &mut self.unidentifiable,
            SampleStatus::Gap => &mut self.gaps,
            SampleStatus::NonFinite | SampleStatus::Saturated | SampleStatus::InvalidTimeStep => {
                &mut self.rejected
            }
            SampleStatus::NumericalFault => &mut self.numerical_faults,
            SampleStatus::Anchored => return,
        };
        *slot = slot.saturating_add(1);
    }
}
