//! The close-loop's view of a log: the samples of a [`Recording`] (read by [`crate::read`]) in
//! `f64`, with the free-flight segments, checked before anything is fitted.
//!
//! Checks that stop the analysis with a message saying what to fix (the tool must not report
//! a confident number it cannot stand behind):
//!
//! * units: sustained rates above 50 rad/s look like deg/s, a median time step above 0.1 s or
//!   below 1e-5 s looks like ms or us read as seconds; the user can declare the units
//!   (`--gyro-unit`, `--time-unit`) to convert or to confirm them ([`check_units`]);
//! * segments: one that lies outside the log, or two that overlap (their samples would count
//!   twice), are errors naming the segments ([`Log::new`]); rows of a segments file with
//!   `keep` false are skipped before their numbers are read ([`crate::readers::phyphox::read_segments`]: phyphox writes
//!   rejected rows such as `28,,,false,random noise`).
//!
//! And one repair: isolated spikes (a single sample that neither side of its neighbourhood
//! predicts, such as one 100 rad/s or 1e30 reading in a clean log) are replaced by the mean of
//! their neighbours before the fit ([`gate_spikes`]), so one bad sample invents no effect.

use std::path::PathBuf;

use crate::readers::phyphox::Segment;
use crate::readers::{DEG_PER_SEC_SUSPECT_RAD_S, SUSTAINED_S};
use crate::Recording;

/// A gyro log with its free-flight segments (sorted by start time, not overlapping).
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// Where it came from (for a phyphox folder, its `Raw Data.csv`).
    pub source: PathBuf,
    /// Sample times, strictly increasing, seconds.
    pub t: Vec<f64>,
    /// Angular velocity, rad/s, sensor axes.
    pub omega: Vec<[f64; 3]>,
    /// Free-flight windows; the whole log when no segments file was given.
    pub segments: Vec<Segment>,
}

impl Log {
    /// The log of `rec` with `segments` (`None`: the whole log is one free flight), checked:
    /// every segment must overlap the log and no two may overlap each other. A segment that
    /// only partly covers the log is kept (the part inside is used).
    pub fn new(
        source: PathBuf,
        rec: &Recording,
        segments: Option<Vec<Segment>>,
    ) -> Result<Log, String> {
        if rec.t.len() < 2 {
            return Err(format!("{}: fewer than two samples", source.display()));
        }
        let (t0, t1) = (rec.t[0], rec.t[rec.t.len() - 1]);
        let mut segments = segments.unwrap_or_else(|| {
            vec![Segment {
                label: "all".into(),
                start: t0,
                end: t1,
            }]
        });
        if segments.is_empty() {
            return Err("no kept segment".into());
        }
        segments.sort_by(|a, b| a.start.total_cmp(&b.start));
        for s in &segments {
            if s.end < t0 || s.start > t1 {
                return Err(format!(
                    "segment {} [{} s, {} s] lies outside the log, which runs from {t0} s to \
                     {t1} s: segment times must be in the log's own time base",
                    s.label, s.start, s.end
                ));
            }
        }
        for w in segments.windows(2) {
            if w[1].start < w[0].end {
                return Err(format!(
                    "segments {} [{} s, {} s] and {} [{} s, {} s] overlap: their common samples \
                     would count twice; fix the segments file",
                    w[0].label, w[0].start, w[0].end, w[1].label, w[1].start, w[1].end
                ));
            }
        }
        Ok(Log {
            source,
            t: rec.t.clone(),
            omega: rec.gyro.iter().map(|w| w.map(f64::from)).collect(),
            segments,
        })
    }

    /// Sample index ranges `[i0, i1)` of each segment.
    pub fn segment_ranges(&self) -> Vec<(usize, usize)> {
        self.segments
            .iter()
            .map(|s| {
                let i0 = self.t.partition_point(|&t| t < s.start);
                let i1 = self.t.partition_point(|&t| t <= s.end);
                (i0, i1.max(i0))
            })
            .collect()
    }

    /// Segments that reach beyond the log (only their part inside is used), for a warning.
    pub fn partial_segments(&self) -> Vec<String> {
        let (t0, t1) = (self.t[0], self.t[self.t.len() - 1]);
        self.segments
            .iter()
            .filter(|s| s.start < t0 || s.end > t1)
            .map(|s| format!("{} [{} s, {} s]", s.label, s.start, s.end))
            .collect()
    }
}

/// Median time step above which the time column looks like ms or us read as seconds, s.
pub const MAX_MEDIAN_STEP_S: f64 = 0.1;
/// Median time step below which the time base looks wrong, s.
pub const MIN_MEDIAN_STEP_S: f64 = 1e-5;

/// Units sanity: an error with the fix when the rates look like deg/s (above
/// [`DEG_PER_SEC_SUSPECT_RAD_S`] for at least [`SUSTAINED_S`]) or the median time step like ms
/// or us, unless the user declared that unit (`gyro_declared`, `time_declared`).
pub fn check_units(log: &Log, gyro_declared: bool, time_declared: bool) -> Result<(), String> {
    check_series_units(&log.t, &log.omega, gyro_declared, time_declared)
}

/// [`check_units`] on plain series: times (s) and rates (rad/s as read).
pub fn check_series_units(
    t: &[f64],
    w: &[[f64; 3]],
    gyro_declared: bool,
    time_declared: bool,
) -> Result<(), String> {
    check_series_units_up_to(t, w, gyro_declared, time_declared, MAX_MEDIAN_STEP_S)
}

/// Median time step above which a vehicle log (`--vehicle`: a spacecraft's attitude log, often
/// at 1 Hz or slower) looks like ms or us read as seconds, s.
pub const MAX_MEDIAN_STEP_VEHICLE_S: f64 = 10.0;

/// [`check_series_units`] with the largest median time step taken as seconds given
/// (`max_step_s`; the vehicle base model takes [`MAX_MEDIAN_STEP_VEHICLE_S`]).
pub fn check_series_units_up_to(
    t: &[f64],
    w: &[[f64; 3]],
    gyro_declared: bool,
    time_declared: bool,
    max_step_s: f64,
) -> Result<(), String> {
    if !gyro_declared {
        let limit = f64::from(DEG_PER_SEC_SUSPECT_RAD_S);
        let (mut best, mut start) = (0.0f64, None::<usize>);
        for (i, v) in w.iter().enumerate() {
            if (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() > limit {
                let s = *start.get_or_insert(i);
                best = best.max(t[i] - t[s]);
            } else {
                start = None;
            }
        }
        if best >= SUSTAINED_S {
            return Err(format!(
                "the gyro rate stays above {limit} rad/s for {best:.3} s: that looks like deg/s \
                 read as rad/s; give --gyro-unit deg/s to convert (or --gyro-unit rad/s if the \
                 rates really are that high)"
            ));
        }
    }
    if !time_declared {
        let mut dt: Vec<f64> = t.windows(2).map(|p| p[1] - p[0]).collect();
        let mid = dt.len() / 2;
        let (_, median, _) = dt.select_nth_unstable_by(mid, f64::total_cmp);
        let median = *median;
        if median > max_step_s {
            return Err(format!(
                "the median time step is {median} s ({:.3} Hz): that looks like a time column \
                 in ms or us read as seconds; give --time-unit ms or --time-unit us to convert \
                 (or --time-unit s if the log really is that slow)",
                1.0 / median
            ));
        }
        if median < MIN_MEDIAN_STEP_S {
            return Err(format!(
                "the median time step is {median:e} s (above 100 kHz): that does not look like \
                 a gyro log in seconds; check the time column (--time-unit s|ms|us)"
            ));
        }
    }
    Ok(())
}

/// A sample replaced by [`gate_spikes`].
#[derive(Clone, Debug, PartialEq)]
pub struct Spike {
    /// Sample index.
    pub index: usize,
    /// Its time, s.
    pub t: f64,
    /// The reading that was replaced, rad/s.
    pub was: [f64; 3],
}

/// How many robust standard deviations of the prediction error make a spike.
pub const SPIKE_SIGMAS: f64 = 20.0;
/// A spike must also miss both predictions by at least this much, rad/s.
pub const SPIKE_FLOOR_RAD_S: f64 = 2.0;
/// ... and by at least this fraction of the rate of its neighbours.
pub const SPIKE_RELATIVE: f64 = 0.25;

/// Plausibility gate for isolated spikes in the free flights. Each sample inside a segment is
/// predicted by straight-line extrapolation from the two samples on its left and, separately,
/// from the two on its right; its error is the smaller of the two misses (largest axis). A
/// step (a catch, a release) is predicted by one side and passes; a single bad sample is
/// predicted by neither. A sample whose error exceeds the largest of `SPIKE_SIGMAS` robust
/// standard deviations of all in-segment errors, [`SPIKE_FLOOR_RAD_S`] and [`SPIKE_RELATIVE`]
/// times its neighbours' rate is replaced by the mean of its two neighbours.
///
/// On the racquet recordings the largest in-flight error is 1.4 rad/s at 39 rad/s (0.04 of the
/// rate): nothing there is touched.
pub fn gate_spikes(log: &mut Log) -> Vec<Spike> {
    let w = &log.omega;
    let n = w.len();
    if n < 5 {
        return Vec::new();
    }
    let miss = |k: usize| -> f64 {
        let side = |a: usize, b: usize| -> f64 {
            (0..3)
                .map(|i| (w[k][i] - (2.0 * w[a][i] - w[b][i])).abs())
                .fold(0.0, f64::max)
        };
        let left = (k >= 2).then(|| side(k - 1, k - 2));
        let right = (k + 2 < n).then(|| side(k + 1, k + 2));
        match (left, right) {
            (Some(l), Some(r)) => l.min(r),
            (Some(x), None) | (None, Some(x)) => x,
            (None, None) => 0.0,
        }
    };
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let mut inside = vec![false; n];
    for (i0, i1) in log.segment_ranges() {
        inside[i0..i1].iter_mut().for_each(|x| *x = true);
    }
    let d: Vec<f64> = (0..n)
        .map(|k| if inside[k] { miss(k) } else { 0.0 })
        .collect();
    let mut sorted: Vec<f64> = (0..n)
        .filter(|&k| inside[k] && d[k].is_finite())
        .map(|k| d[k])
        .collect();
    if sorted.is_empty() {
        return Vec::new();
    }
    let mid = sorted.len() / 2;
    let (_, med, _) = sorted.select_nth_unstable_by(mid, f64::total_cmp);
    let base = (SPIKE_SIGMAS * 1.4826 * *med).max(SPIKE_FLOOR_RAD_S);
    let flagged: Vec<bool> = (0..n)
        .map(|k| {
            if !inside[k] {
                return false;
            }
            let nb = [k.checked_sub(1), Some(k + 1)]
                .into_iter()
                .flatten()
                .filter(|&j| j < n)
                .map(|j| norm(w[j]))
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max);
            // A NaN error counts as a spike.
            d[k].is_nan() || d[k] > base.max(SPIKE_RELATIVE * nb)
        })
        .collect();
    let mut out = Vec::new();
    for k in (0..n).filter(|&k| flagged[k]) {
        // Neighbours that are themselves flagged are not used.
        let nb: Vec<usize> = [k.checked_sub(1), Some(k + 1)]
            .into_iter()
            .flatten()
            .filter(|&j| j < n && !flagged[j])
            .collect();
        if nb.is_empty() {
            continue;
        }
        let was = log.omega[k];
        let rep: [f64; 3] = std::array::from_fn(|i| {
            nb.iter().map(|&j| log.omega[j][i]).sum::<f64>() / nb.len() as f64
        });
        log.omega[k] = rep;
        out.push(Spike {
            index: k,
            t: log.t[k],
            was,
        });
    }
    out
}
