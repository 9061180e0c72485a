//! The firmware's report as a framed binary stream, readable without a debug probe: one
//! [`Report`] per frame, serialised with `postcard` and framed with COBS (a frame ends with a
//! 0x00 byte, which occurs nowhere else), so a reader that joins the stream at any byte
//! resynchronises at the next zero. The firmware sends the frames on a UART beside its defmt
//! log; the host decodes them with [`decode_frame`] or, with the `std` feature, a whole capture
//! with [`Decoder`].
//!
//! `no_std`, no allocation on the firmware side: [`encode`] writes into a caller's buffer of
//! [`MAX_FRAME`] bytes.
#![no_std]
#![deny(missing_docs)]
#![deny(
    clippy::panic,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

#[cfg(feature = "std")]
extern crate std;

use serde::{Deserialize, Serialize};

/// Format version carried in every report; bumped on any change of [`Report`].
pub const VERSION: u8 = 4;

/// Longest frame: the largest serialised [`Report`] (varints at their longest) plus COBS
/// overhead and the terminating zero.
pub const MAX_FRAME: usize = 512;

/// The sensor's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Sensor {
    /// Samples are coming in.
    Ok,
    /// No sample for over 1.5 report periods: estimates held, counters moving.
    Failed,
}

/// The estimate part of a report, with its uncertainty: what is persisted across resets.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// The paper's identifier's `(a1, a2, a3)`.
    pub a_paper: [f32; 3],
    /// Its accuracy criterion met.
    pub converged_paper: bool,
    /// The refined identifier's `(a1, a2, a3)`.
    pub a_refined: [f32; 3],
    /// Standard deviation of each component of `a_refined`.
    pub std_a: [f32; 3],
    /// Its accuracy criterion met.
    pub converged_refined: bool,
    /// `a1 + a2 + a3 + a1 a2 a3` of `a_refined`.
    pub consistency: f32,
    /// Samples integrated when this estimate was made.
    pub samples: u32,
    /// The free-flight pipeline's tensor estimate: set in what is persisted (and restored);
    /// `None` in the periodic reports, which carry it in [`Report::tensor`].
    pub tensor: Option<Tensor>,
}

/// Names of the tensor estimate's status codes ([`Tensor::status`]), in code order: those of
/// identifier-core's `Status` as the tensor estimator gives them (0-7), then 8,
/// `NoInformation` (the ratio estimators' status before any sample, which the firmware's
/// pipeline does not report). A code never changes meaning: new ones are added at the end.
pub const TENSOR_STATUS: [&str; 9] = [
    "TooFewSamples",
    "UnitsLookWrong",
    "Saturated",
    "NoExcitation",
    "ModelMismatch",
    "PhysicallyImpossible",
    "Converging",
    "Converged",
    "NoInformation",
];

/// Names of the codes of where the tensor's standard deviations come from
/// ([`Tensor::uncertainty`]), in code order: identifier-core's `Uncertainty`.
pub const TENSOR_UNCERTAINTY: [&str; 3] = ["Noise", "Residual", "Unaccounted"];

/// The free-flight pipeline's tensor estimate (identifier-core's `FlightPipeline`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tensor {
    /// Status code, an index into [`TENSOR_STATUS`].
    pub status: u8,
    /// The paper's ratios `a` from the tensor, when determined.
    pub a: Option<[f32; 3]>,
    /// Their standard deviations.
    pub std_a: Option<[f32; 3]>,
    /// `J`, kg m^2, when a rotor momentum fixes the scale.
    pub tensor: Option<[[f32; 3]; 3]>,
    /// Free flights that reached the estimator.
    pub throws: u32,
    /// Samples committed to the estimator.
    pub fed: u32,
    /// Samples that left the delay line uncommitted.
    pub not_fed: u32,
    /// The gate holds free flight now.
    pub in_free_flight: bool,
    /// Where the tensor's standard deviations come from, an index into
    /// [`TENSOR_UNCERTAINTY`].
    pub uncertainty: u8,
    /// The tensor is to be used with its standard deviations (identifier-core's
    /// `TensorEstimate::usable`).
    pub usable: bool,
}

impl Tensor {
    /// The uncertainty's name (`"?"` for an unknown code).
    pub fn uncertainty_name(&self) -> &'static str {
        TENSOR_UNCERTAINTY
            .get(usize::from(self.uncertainty))
            .copied()
            .unwrap_or("?")
    }

    /// The status's name (`"?"` for an unknown code).
    pub fn status_name(&self) -> &'static str {
        TENSOR_STATUS
            .get(usize::from(self.status))
            .copied()
            .unwrap_or("?")
    }
}

/// The sample loop's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[allow(missing_docs)] // the firmware's `LoopCounters`, field for field
pub struct Counters {
    pub samples: u32,
    pub skipped: u32,
    pub bus_errors: u32,
    pub invalid: u32,
    pub timeouts: u32,
    pub implausible: u32,
    pub missed: u32,
    pub wrong_id: u32,
    pub stalled: u32,
    pub reinits: u32,
    pub reinit_failures: u32,
    pub saturated: u32,
    pub accel_saturated: u32,
    pub held_out: u32,
}

/// One report, 10 per second.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// [`VERSION`].
    pub version: u8,
    /// Sample periods since start.
    pub tick: u32,
    /// Seconds since start.
    pub t: f32,
    /// Sensor state.
    pub sensor: Sensor,
    /// The estimates.
    pub estimate: Estimate,
    /// The counters.
    pub counters: Counters,
    /// Gyro samples at the clip level since the previous report.
    pub saturated_recent: u32,
    /// The rotors' momentum given with the last sample, kg m^2/s.
    pub momentum: Option<[f32; 3]>,
    /// The estimate restored from flash at boot, if any.
    pub restored: Option<Estimate>,
    /// The free-flight pipeline's tensor estimate.
    pub tensor: Tensor,
}

/// Serialises `report` as one COBS frame (terminating zero included) into `buf`; returns the
/// frame.
pub fn encode<'a>(report: &Report, buf: &'a mut [u8]) -> Result<&'a mut [u8], postcard::Error> {
    postcard::to_slice_cobs(report, buf)
}

/// Decodes one frame (with or without its terminating zero), in place.
pub fn decode_frame(frame: &mut [u8]) -> Result<Report, postcard::Error> {
    postcard::from_bytes_cobs(frame)
}

/// Longest serialised [`Estimate`] (tensor included), bytes.
pub const MAX_ESTIMATE: usize = 192;

/// Serialises an [`Estimate`] (plain postcard, no framing: for flash).
pub fn encode_estimate<'a>(
    e: &Estimate,
    buf: &'a mut [u8],
) -> Result<&'a mut [u8], postcard::Error> {
    postcard::to_slice(e, buf)
}

/// Deserialises an [`Estimate`] written by [`encode_estimate`].
pub fn decode_estimate(bytes: &[u8]) -> Result<Estimate, postcard::Error> {
    postcard::from_bytes(bytes)
}

/// Host decoder of a captured or live byte stream: feed bytes as they come, get the reports
/// of every complete frame. A frame that does not decode (a torn start, line noise) is counted
/// and skipped.
#[cfg(feature = "std")]
#[derive(Debug, Default)]
pub struct Decoder {
    buf: std::vec::Vec<u8>,
    /// Frames that did not decode.
    pub errors: usize,
}

#[cfg(feature = "std")]
impl Decoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Decoder::default()
    }

    /// Feeds `bytes`; returns the reports completed by them.
    pub fn push(&mut self, bytes: &[u8]) -> std::vec::Vec<Report> {
        let mut out = std::vec::Vec::new();
        for &b in bytes {
            if b == 0 {
                if !self.buf.is_empty() {
                    match decode_frame(&mut self.buf) {
                        Ok(r) => out.push(r),
                        Err(_) => self.errors += 1,
                    }
                    self.buf.clear();
                }
            } else if self.buf.len() < 4 * MAX_FRAME {
                self.buf.push(b);
            }
        }
        out
    }
}

/// Decodes every complete frame of a captured stream.
#[cfg(feature = "std")]
pub fn decode_stream(bytes: &[u8]) -> std::vec::Vec<Report> {
    Decoder::new().push(bytes)
}

#[cfg(all(test, feature = "std"))]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn report(k: u32) -> Report {
        let estimate = Estimate {
            a_paper: [0.9, 0.26, -0.94],
            converged_paper: false,
            a_refined: [0.8999, f32::MIN_POSITIVE, -0.93999],
            std_a: [1e-5, 2e-5, f32::INFINITY],
            converged_refined: true,
            consistency: -1.3e-6,
            samples: u32::MAX - k,
            tensor: None,
        };
        Report {
            version: VERSION,
            tick: k * 100,
            t: k as f32 * 0.1,
            sensor: if k.is_multiple_of(2) {
                Sensor::Ok
            } else {
                Sensor::Failed
            },
            estimate,
            counters: Counters {
                samples: u32::MAX,
                saturated: k,
                ..Counters::default()
            },
            saturated_recent: k,
            momentum: k.is_multiple_of(3).then_some([-123.25, 0.5, 1e-3]),
            restored: (k == 1).then_some(estimate),
            tensor: Tensor {
                status: (k % 8) as u8,
                a: Some([0.5, -0.25, f32::MAX]),
                std_a: None,
                tensor: (k == 2).then_some([[1e-5; 3]; 3]),
                throws: k,
                fed: 1000 * k,
                not_fed: 7,
                in_free_flight: k == 3,
                uncertainty: (k % 3) as u8,
                usable: k == 1,
            },
        }
    }

    #[test]
    fn status_names_by_code() {
        let name = |status| {
            Tensor {
                status,
                ..report(0).tensor
            }
            .status_name()
        };
        assert_eq!(name(0), "TooFewSamples");
        assert_eq!(name(4), "ModelMismatch");
        assert_eq!(name(7), "Converged");
        assert_eq!(name(8), "NoInformation");
        assert_eq!(name(9), "?");
    }

    #[test]
    fn round_trip_through_a_stream_with_garbage_and_a_torn_frame() {
        let mut stream = std::vec![0x55, 0x13, 0x00]; // a torn frame before the first
        for k in 0..5 {
            let mut buf = [0u8; MAX_FRAME];
            let frame = encode(&report(k), &mut buf).unwrap();
            assert_eq!(frame.last(), Some(&0));
            assert_eq!(frame.iter().filter(|&&b| b == 0).count(), 1);
            stream.extend_from_slice(frame);
        }
        // Byte by byte, as from a UART.
        let mut d = Decoder::new();
        let mut got = std::vec::Vec::new();
        for b in &stream {
            got.extend(d.push(core::slice::from_ref(b)));
        }
        assert_eq!(got.len(), 5);
        for (k, r) in got.iter().enumerate() {
            assert_eq!(*r, report(k as u32));
        }
        assert_eq!(d.errors, 1);
        assert_eq!(decode_stream(&stream).len(), 5);
    }

    #[test]
    fn the_largest_report_fits_a_frame_and_estimates_round_trip() {
        let mut r = report(1);
        r.counters = Counters {
            samples: u32::MAX,
            skipped: u32::MAX,
            bus_errors: u32::MAX,
            invalid: u32::MAX,
            timeouts: u32::MAX,
            implausible: u32::MAX,
            missed: u32::MAX,
            wrong_id: u32::MAX,
            stalled: u32::MAX,
            reinits: u32::MAX,
            reinit_failures: u32::MAX,
            saturated: u32::MAX,
            accel_saturated: u32::MAX,
            held_out: u32::MAX,
        };
        r.tick = u32::MAX;
        r.saturated_recent = u32::MAX;
        r.momentum = Some([1.0, -2.0, 3.0]);
        let big = Tensor {
            status: 7,
            a: Some([1.0; 3]),
            std_a: Some([1.0; 3]),
            tensor: Some([[1.0; 3]; 3]),
            throws: u32::MAX,
            fed: u32::MAX,
            not_fed: u32::MAX,
            in_free_flight: true,
            uncertainty: 2,
            usable: true,
        };
        r.estimate.tensor = Some(big);
        r.restored = Some(r.estimate);
        r.tensor = Tensor {
            status: 7,
            a: Some([1.0; 3]),
            std_a: Some([1.0; 3]),
            tensor: Some([[1.0; 3]; 3]),
            throws: u32::MAX,
            fed: u32::MAX,
            not_fed: u32::MAX,
            in_free_flight: true,
            uncertainty: 2,
            usable: true,
        };
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(&r, &mut buf).unwrap().len();
        assert!(n <= MAX_FRAME, "{n}");
        assert_eq!(decode_frame(&mut buf[..n]).unwrap(), r);
        let mut b = [0u8; 256];
        let bytes = encode_estimate(&r.estimate, &mut b).unwrap();
        assert!(bytes.len() <= MAX_ESTIMATE, "{}", bytes.len());
        assert_eq!(decode_estimate(bytes).unwrap(), r.estimate);
    }
}
