//! `inertia telemetry`: decodes a captured telemetry stream (the firmware's UART: postcard +
//! COBS frames of `telemetry::Report`) to JSON lines, one per report, and optionally writes
//! the last report's estimate as the JSON `scripts/run.sh --json` gives.

use std::path::Path;

use serde::Serialize;

/// One report as a JSON line: the frame's fields (`f32` written as the shortest decimal that
/// reads back to the same `f32`) and the tensor status by name.
#[derive(Serialize)]
pub struct ReportLine<'a> {
    /// The frame.
    #[serde(flatten)]
    pub report: &'a ::telemetry::Report,
    /// `tensor.status` by name.
    pub tensor_status: &'static str,
}

/// The final on-board estimate as `scripts/run.sh --json` writes it.
#[derive(Serialize)]
pub struct FinalEstimate {
    /// The tensor estimate's status (`Converged` only when it is to be trusted).
    pub status: &'static str,
    /// Where the tensor's standard deviations come from (`Noise`, `Residual`, `Unaccounted`:
    /// identifier-core's `Uncertainty`).
    pub tensor_uncertainty: &'static str,
    /// The tensor is to be used with its standard deviations (`TensorEstimate::usable`).
    pub tensor_usable: bool,
    /// The paper's ratios from the tensor.
    pub a: Option<[f32; 3]>,
    /// Their standard deviations.
    pub std_a: Option<[f32; 3]>,
    /// `J`, kg m^2, or null.
    pub tensor_kg_m2: Option<[[f32; 3]; 3]>,
    /// Free flights found on board.
    pub throws_detected: u32,
    /// Samples committed to the estimator.
    pub samples_fed: u32,
    /// Samples the gate kept out.
    pub samples_not_fed: u32,
    /// The gate held free flight at the end.
    pub in_free_flight: bool,
    /// Seconds of samples.
    pub t: f32,
    /// Samples.
    pub tick: u32,
    /// The sample loop's counters.
    pub counters: ::telemetry::Counters,
}

/// The last report's estimate.
pub fn final_estimate(r: &::telemetry::Report) -> FinalEstimate {
    let t = &r.tensor;
    FinalEstimate {
        status: t.status_name(),
        tensor_uncertainty: t.uncertainty_name(),
        tensor_usable: t.usable,
        a: t.a,
        std_a: t.std_a,
        tensor_kg_m2: t.tensor,
        throws_detected: t.throws,
        samples_fed: t.fed,
        samples_not_fed: t.not_fed,
        in_free_flight: t.in_free_flight,
        t: r.t,
        tick: r.tick,
        counters: r.counters,
    }
}

/// Decodes `input`; prints the JSON lines to stdout; writes the last report's estimate to
/// `final_out` when given. Returns (reports, frames that did not decode).
pub fn run(input: &Path, final_out: Option<&Path>) -> Result<(usize, usize), String> {
    let bytes = std::fs::read(input).map_err(|e| format!("{}: {e}", input.display()))?;
    let mut d = ::telemetry::Decoder::new();
    let reports = d.push(&bytes);
    let mut out = String::new();
    for r in &reports {
        let line = ReportLine {
            report: r,
            tensor_status: r.tensor.status_name(),
        };
        out.push_str(&serde_json::to_string(&line).map_err(|e| e.to_string())?);
        out.push('\n');
    }
    print!("{out}");
    if let Some(path) = final_out {
        let Some(last) = reports.last() else {
            return Err(format!("{}: no telemetry frame decoded", input.display()));
        };
        let text =
            serde_json::to_string_pretty(&final_estimate(last)).map_err(|e| e.to_string())?;
        std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok((reports.len(), d.errors))
}
