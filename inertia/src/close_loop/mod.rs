//! Closing the loop on measured data: identify, compute the residual of the torque-free model,
//! trace it to a library of candidate effects, add the chosen effect(s) to the model and
//! report the error before and after. See [`analysis::analyse`]; the command is
//! `inertia close-loop` ([`load`] reads and checks its input). The binary goes through the
//! API re-exported here ([`load`], [`analyse`] and its report, [`analyse_tensor`] and its
//! report); nothing in the product path (`identify`, `calibrate`, `pool`, `export`) uses this
//! module.
//!
//! Input goes through the crate's readers ([`crate::read`]: phyphox, named-column CSV,
//! blackbox, ULog), the segments through [`crate::readers::phyphox::read_segments`]; [`input`] holds the checks
//! that refuse what cannot be trusted (units, segments) and the spike gate.

pub mod analysis;
pub mod input;
pub mod model;
pub mod plot;
pub mod report;
pub mod selection;
pub mod stats;
pub mod tensor;
pub mod vehicle_loop;

// The API of `inertia close-loop` (all the binary uses). The modules above stay public for
// the research tests that take the analysis apart.
pub use analysis::{analyse, Analysis, Options};
pub use input::{check_series_units, check_series_units_up_to, MAX_MEDIAN_STEP_VEHICLE_S};
pub use report::{markdown, plots, summary_line};
pub use selection::LoopError;
pub use tensor::{
    analyse_tensor, markdown as tensor_markdown, plots as tensor_plots,
    summary_line as tensor_summary_line, TensorAnalysis, TensorOptions,
};
pub use vehicle_loop::{
    analyse_vehicle, markdown as vehicle_markdown, plots as vehicle_plots,
    summary_line as vehicle_summary_line, VehicleAnalysis, VehicleEffect, VehicleOptions,
};

use std::path::Path;

use crate::readers::{self, phyphox, Format, ReadOptions};
use input::Log;

/// Reads the log at `input` (format detected from the content when `format` is `None`) with
/// the segments from `segments` (default: a phyphox export's `meta/segments.csv`, else the
/// whole log), then checks the units ([`input::check_units`], skipped for the units declared
/// in `units`) and the segments ([`Log::new`]). Returns the log and the readers' warnings.
pub fn load(
    input: &Path,
    format: Option<Format>,
    segments: Option<&Path>,
    units: &ReadOptions,
) -> Result<(Log, Vec<String>), String> {
    let format = match format {
        Some(f) => f,
        None => readers::detect(input).map_err(|e| e.to_string())?,
    };
    let rec = match format {
        Format::Phyphox => phyphox::read_phyphox(input),
        Format::Csv => readers::csv::read_csv(input, units),
        Format::Blackbox => readers::blackbox::read_blackbox(input),
        Format::Ulog => readers::ulog::read_ulog(input),
    }
    .map_err(|e| e.to_string())?;
    let seg_file = match segments {
        Some(p) => Some(p.to_path_buf()),
        None if format == Format::Phyphox => phyphox::segments_file(input),
        None => None,
    };
    let segs = match &seg_file {
        Some(p) => {
            let s = crate::readers::phyphox::read_segments(p).map_err(|e| e.to_string())?;
            if s.is_empty() {
                return Err(format!("{}: no kept segment", p.display()));
            }
            Some(s)
        }
        None => None,
    };
    let source = readers::data_file(input);
    let log = Log::new(source.clone(), &rec, segs).map_err(|e| match &seg_file {
        Some(p) => format!("{}: {e}", p.display()),
        None => format!("{}: {e}", source.display()),
    })?;
    input::check_units(&log, units.gyro_unit.is_some(), units.time_unit.is_some())
        .map_err(|e| format!("{}: {e}", source.display()))?;
    let mut warnings = rec.warnings;
    let partial = log.partial_segments();
    if !partial.is_empty() {
        warnings.push(format!(
            "segments reaching beyond the log (only their part inside it is used): {}",
            partial.join(", ")
        ));
    }
    Ok((log, warnings))
}
