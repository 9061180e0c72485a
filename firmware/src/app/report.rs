//! What the loop reports at [`REPORT_HZ`], and when. A [`Report`] is the one source of every
//! output: the defmt lines (`log_report`, `log_tensor`) and the UART telemetry frames
//! ([`crate::uplink::to_telemetry`]) are each made from it by one function.

use icm42688::Config;
use identifier_core::{Convergence, InertiaRatios, Status, Uncertainty};

use super::SensorStatus;

/// Reports per second (one every `odr / REPORT_HZ` sample periods).
pub const REPORT_HZ: u32 = 10;

/// Report periods without a sample after which a report goes out anyway, marked
/// [`SensorStatus::Failed`] (1.5: the normal stream is late by half a period).
pub const FAILED_REPORT_AFTER: f32 = 1.5;

/// The tensor estimate of the free-flight pipeline, as reported.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorReport {
    /// Why `a` is or is not to be trusted
    /// ([`FlightPipeline::ratios`](identifier_core::FlightPipeline::ratios)).
    pub status: Status,
    /// The recommended ratios `a`
    /// ([`FlightPipeline::ratios`](identifier_core::FlightPipeline::ratios): the tensor's
    /// with a rotor or products of inertia, else the refined identifier's on the same
    /// samples).
    pub a: Option<[f32; 3]>,
    /// Their standard deviations.
    pub std_a: Option<[f32; 3]>,
    /// `J`, kg m^2, when a rotor momentum fixes the scale.
    pub tensor: Option<[[f32; 3]; 3]>,
    /// Free flights that reached the estimator.
    pub throws: u32,
    /// Samples committed to the estimator.
    pub fed: u32,
    /// Samples that left the delay line without being committed (hand, bench, catch).
    pub not_fed: u32,
    /// The gate holds free flight now.
    pub in_free_flight: bool,
    /// Where the tensor's standard deviations come from
    /// ([`TensorEstimate::uncertainty`](identifier_core::TensorEstimate::uncertainty)).
    pub uncertainty: Uncertainty,
    /// The tensor is to be used with its standard deviations
    /// ([`TensorEstimate::usable`](identifier_core::TensorEstimate::usable)).
    pub usable: bool,
}

impl TensorReport {
    /// The report of `pipeline`'s estimate (`not_fed`: the loop's count of samples that left
    /// its delay line unfed).
    pub fn of(pipeline: &identifier_core::FlightPipeline, not_fed: u32) -> Self {
        let (e, r) = pipeline.estimate_and_ratios();
        TensorReport {
            status: r.status,
            a: r.a,
            std_a: r.std_a,
            tensor: e.tensor,
            throws: pipeline.throws(),
            fed: pipeline.fed_inputs(),
            not_fed,
            in_free_flight: pipeline.in_free_flight(),
            uncertainty: e.uncertainty,
            usable: e.usable(),
        }
    }
}

/// The loop's own counters (the identifier keeps finer ones, see
/// [`Counters`](identifier_core::Counters)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopCounters {
    /// Gyro samples read, accepted by the gate and given to both identifiers.
    pub samples: u32,
    /// Samples the paper's identifier did not integrate: rejected (saturated, non-finite),
    /// unidentifiable (`|w1 w2 w3| < w_min`), after a gap, or a numerical fault. The anchor
    /// sample after a start or gap is not counted.
    pub skipped: u32,
    /// Bus transfers that failed (status poll, sample read, `WHO_AM_I` check). The loop
    /// carries on.
    pub bus_errors: u32,
    /// Samples the part marked invalid (-32768).
    pub invalid: u32,
    /// Data-ready waits that timed out.
    pub timeouts: u32,
    /// Samples refused by the plausibility gate, the rate-jump check
    /// ([`gate_rate_bound`](super::gate_rate_bound)); their time is carried to the next
    /// accepted sample.
    pub implausible: u32,
    /// Sample periods that passed without a sample read (by the
    /// [`SampleClock`](super::SampleClock)).
    pub missed: u32,
    /// `WHO_AM_I` read a wrong value (periodic check or re-initialisation).
    pub wrong_id: u32,
    /// Stalled data seen ([`STALLED_AFTER`](super::STALLED_AFTER) identical samples).
    pub stalled: u32,
    /// Samples with a gyro axis at the clip level (the identifiers reject them as
    /// saturated). Counted apart from stalled data: they never re-initialise the part.
    pub saturated: u32,
    /// Samples with an accelerometer axis at the clip level (a catch, a crash).
    pub accel_saturated: u32,
    /// Re-initialisations of the sensor (after [`REINIT_AFTER`](super::REINIT_AFTER)
    /// consecutive failures, a wrong `WHO_AM_I` or stalled data).
    pub reinits: u32,
    /// Initialisation attempts during re-initialisations that failed.
    pub reinit_failures: u32,
    /// Samples the board flagged with an actuator acting on the body
    /// ([`BoardInputs::actuated`](super::BoardInputs::actuated)), kept out of the estimators.
    pub held_out: u32,
}

/// What goes out at [`REPORT_HZ`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Report {
    /// Sample periods since the loop started, by the [`SampleClock`](super::SampleClock) (lost
    /// samples included).
    pub tick: u32,
    /// Seconds since the loop started, `tick / odr`.
    pub t: f32,
    /// The paper's identifier: estimate `(a1, a2, a3)` of (12).
    pub a_paper: [f32; 3],
    /// The paper's accuracy criterion on `a_paper`.
    pub convergence_paper: Convergence,
    /// The refined identifier's estimate, open block included
    /// ([`Refined::estimate`](identifier_core::Refined::estimate)).
    pub a_refined: [f32; 3],
    /// Standard deviations of `a_refined`.
    pub std_refined: [f32; 3],
    /// `A2/A1`, `A3/A1` implied by `a_refined`.
    pub ratios: Option<InertiaRatios>,
    /// `a1 + a2 + a3 + a1 a2 a3` of `a_refined` (zero for a rigid body).
    pub consistency: f32,
    /// The paper's accuracy criterion on the refined identifier's block estimates.
    pub convergence_refined: Convergence,
    /// The loop's counters.
    pub counters: LoopCounters,
    /// Samples with a clipped gyro axis since the previous report.
    pub saturated_recent: u32,
    /// The sensor's state.
    pub sensor: SensorStatus,
    /// The rotors' momentum given with the last sample, kg m^2/s (`None`: no rotors, or no
    /// speeds for it).
    pub momentum: Option<[f32; 3]>,
    /// The free-flight pipeline's tensor estimate.
    pub tensor: TensorReport,
}

/// When reports go out: every [`REPORT_HZ`]-th of a second by the sample clock while samples
/// come in, and a [`SensorStatus::Failed`] one after [`FAILED_REPORT_AFTER`] report periods
/// without a sample.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ReportSchedule {
    /// Sample periods between two reports.
    every: u32,
    /// Sample periods since the last report.
    since: u32,
    /// The clock at the last report (stepped or failed), us.
    last_us: u32,
    /// Microseconds without a report after which a failed-sensor report goes out.
    failed_after_us: u32,
    /// The loop's saturated count at the last report.
    saturated_at_last: u32,
}

impl ReportSchedule {
    /// The schedule for a gyro configured with `config`, the clock reading `now_us`.
    pub(crate) fn new(config: &Config, now_us: u32) -> Self {
        let odr = config.odr.hz() as u32;
        let every = (odr / REPORT_HZ).max(1);
        let report_us = every.saturating_mul(config.odr.period_us().max(1));
        ReportSchedule {
            every,
            since: 0,
            last_us: now_us,
            failed_after_us: (report_us as f32 * FAILED_REPORT_AFTER) as u32,
            saturated_at_last: 0,
        }
    }

    /// `periods` more sample periods have passed.
    pub(crate) fn advance(&mut self, periods: u32) {
        self.since = self.since.saturating_add(periods);
    }

    /// True when a periodic report is due at the clock reading `now_us`; it then counts as
    /// sent.
    pub(crate) fn due(&mut self, now_us: u32) -> bool {
        if self.since >= self.every {
            self.since %= self.every;
            self.last_us = now_us;
            true
        } else {
            false
        }
    }

    /// True when a report is due every `every` samples (a replay, which has no clock).
    pub(crate) fn due_every(&mut self, every: u32) -> bool {
        if self.since >= every.max(1) {
            self.since = 0;
            true
        } else {
            false
        }
    }

    /// True when no report has gone out for [`FAILED_REPORT_AFTER`] report periods at the
    /// clock reading `now_us`; the next one is then due a report period from now.
    pub(crate) fn failed_due(&mut self, now_us: u32) -> bool {
        if now_us.wrapping_sub(self.last_us) >= self.failed_after_us {
            self.last_us = now_us.wrapping_sub(self.failed_after_us / 3);
            true
        } else {
            false
        }
    }

    /// Samples with a clipped gyro axis since the last report sent, of `saturated` in all.
    pub(crate) fn saturated_recent(&self, saturated: u32) -> u32 {
        saturated.wrapping_sub(self.saturated_at_last)
    }

    /// A report went out with `saturated` clipped samples in all.
    pub(crate) fn sent(&mut self, saturated: u32) {
        self.saturated_at_last = saturated;
    }
}
