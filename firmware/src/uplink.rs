//! Telemetry without a debug probe: each [`Report`] as one `telemetry` frame (postcard +
//! COBS, see the `telemetry` crate) on a byte sink, a UART on the board (USART1, PA9) and
//! under QEMU (USART1 of `netduinoplus2`, captured with `-serial file:...`). The host decodes a
//! capture with `inertia telemetry --input FILE`.

use identifier_core::{Convergence, Status, Uncertainty};

use crate::app::{LoopCounters, Report, SensorStatus};

/// Where frames go: a UART's transmitter, blocking until each byte is taken.
pub trait ByteSink {
    /// Sends `bytes` in order.
    fn send(&mut self, bytes: &[u8]);
}

/// The code of a status in [`telemetry::TENSOR_STATUS`]: 0-7 for those the tensor estimator
/// gives, 8 for [`Status::NoInformation`] (added after them; codes never change).
pub fn tensor_status_code(s: Status) -> u8 {
    match s {
        Status::TooFewSamples => 0,
        Status::UnitsLookWrong => 1,
        Status::Saturated => 2,
        Status::NoExcitation => 3,
        Status::ModelMismatch => 4,
        Status::PhysicallyImpossible => 5,
        Status::Converging => 6,
        Status::Converged => 7,
        Status::NoInformation => 8,
    }
}

/// The code of an uncertainty in [`telemetry::TENSOR_UNCERTAINTY`].
pub fn uncertainty_code(u: Uncertainty) -> u8 {
    match u {
        Uncertainty::Noise => 0,
        Uncertainty::Residual => 1,
        Uncertainty::Unaccounted => 2,
    }
}

fn counters(c: &LoopCounters) -> telemetry::Counters {
    telemetry::Counters {
        samples: c.samples,
        skipped: c.skipped,
        bus_errors: c.bus_errors,
        invalid: c.invalid,
        timeouts: c.timeouts,
        implausible: c.implausible,
        missed: c.missed,
        wrong_id: c.wrong_id,
        stalled: c.stalled,
        reinits: c.reinits,
        reinit_failures: c.reinit_failures,
        saturated: c.saturated,
        accel_saturated: c.accel_saturated,
        held_out: c.held_out,
    }
}

/// The firmware's report in the telemetry format (`restored`: the estimate restored at boot).
pub fn to_telemetry(r: &Report, restored: Option<telemetry::Estimate>) -> telemetry::Report {
    let t = &r.tensor;
    telemetry::Report {
        version: telemetry::VERSION,
        tick: r.tick,
        t: r.t,
        sensor: match r.sensor {
            SensorStatus::Ok => telemetry::Sensor::Ok,
            SensorStatus::Failed => telemetry::Sensor::Failed,
        },
        estimate: telemetry::Estimate {
            a_paper: r.a_paper,
            converged_paper: r.convergence_paper == Convergence::Converged,
            a_refined: r.a_refined,
            std_a: r.std_refined,
            converged_refined: r.convergence_refined == Convergence::Converged,
            consistency: r.consistency,
            samples: r.counters.samples,
            tensor: None,
        },
        counters: counters(&r.counters),
        saturated_recent: r.saturated_recent,
        momentum: r.momentum,
        restored,
        tensor: tensor(t),
    }
}

/// The tensor estimate in the telemetry format.
pub fn tensor(t: &crate::app::TensorReport) -> telemetry::Tensor {
    telemetry::Tensor {
        status: tensor_status_code(t.status),
        a: t.a,
        std_a: t.std_a,
        tensor: t.tensor,
        throws: t.throws,
        fed: t.fed,
        not_fed: t.not_fed,
        in_free_flight: t.in_free_flight,
        uncertainty: uncertainty_code(t.uncertainty),
        usable: t.usable,
    }
}

/// What is persisted: the report's estimate with its tensor estimate.
pub fn persisted(r: &Report) -> telemetry::Estimate {
    let mut e = to_telemetry(r, None).estimate;
    e.tensor = Some(tensor(&r.tensor));
    e
}

/// Encodes `r` as one frame and sends it; false when it did not encode (cannot happen with
/// [`telemetry::MAX_FRAME`], checked by the telemetry crate's tests).
pub fn send_report(
    sink: &mut impl ByteSink,
    r: &Report,
    restored: Option<telemetry::Estimate>,
) -> bool {
    let mut buf = [0u8; telemetry::MAX_FRAME];
    match telemetry::encode(&to_telemetry(r, restored), &mut buf) {
        Ok(frame) => {
            sink.send(frame);
            true
        }
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    extern crate std;
    use super::*;

    struct Capture(std::vec::Vec<u8>);
    impl ByteSink for Capture {
        fn send(&mut self, bytes: &[u8]) {
            self.0.extend_from_slice(bytes);
        }
    }

    #[test]
    fn reports_round_trip_through_the_uart_stream() {
        use icm42688::sim::SimIcm42688;
        use icm42688::{Config, Icm42688, SpiInterface};
        type Src = fn() -> Option<[f32; 3]>;
        let none: Src = || None;
        let lp = crate::SampleLoop::new(
            Icm42688::new_spi(SimIcm42688::new(none)),
            &mut crate::NoDelay,
            Config::identifier(),
            |_: &SpiInterface<SimIcm42688<Src>>| 0u32,
        )
        .unwrap();
        let r = lp.report();
        let mut uart = Capture(std::vec::Vec::new());
        assert!(send_report(&mut uart, &r, None));
        assert!(send_report(&mut uart, &r, None));
        let got = telemetry::decode_stream(&uart.0);
        assert_eq!(got.len(), 2);
        assert_eq!(got[1], to_telemetry(&r, None));
        assert_eq!(got[1].tensor.status_name(), "TooFewSamples");
        assert_eq!(got[1].tensor.a, None);
    }

    #[test]
    fn status_codes_follow_the_names() {
        use Status::*;
        let all = [
            TooFewSamples,
            UnitsLookWrong,
            Saturated,
            NoExcitation,
            ModelMismatch,
            PhysicallyImpossible,
            Converging,
            Converged,
            NoInformation,
        ];
        for (code, s) in all.into_iter().enumerate() {
            assert_eq!(usize::from(tensor_status_code(s)), code, "{s:?}");
            let name = telemetry::TENSOR_STATUS[usize::from(tensor_status_code(s))];
            assert_eq!(name, std::format!("{s:?}"));
        }
        assert_eq!(telemetry::TENSOR_STATUS.len(), all.len());
        let all = [
            Uncertainty::Noise,
            Uncertainty::Residual,
            Uncertainty::Unaccounted,
        ];
        for (code, u) in all.into_iter().enumerate() {
            assert_eq!(usize::from(uncertainty_code(u)), code, "{u:?}");
            let name = telemetry::TENSOR_UNCERTAINTY[code];
            assert_eq!(name, std::format!("{u:?}"));
        }
        assert_eq!(telemetry::TENSOR_UNCERTAINTY.len(), all.len());
    }
}
