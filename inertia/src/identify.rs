//! `inertia identify`: a [`Recording`] through the shared on-board pipeline
//! ([`identifier_core::FlightPipeline`]: free-flight gate, guard delay, gyro bias, tensor
//! estimator), per throw and pooled.
//!
//! The pooled result is the pipeline's own estimate after the whole log, which is what the
//! firmware computes on board from the same samples (same `f32` code, same order of
//! operations). Per-throw results re-run a fresh [`TensorEstimator`] over exactly the samples
//! the pipeline fed during that throw.

use identifier_core::{FlightPipeline, PipelineSettings, Ratios, TensorEstimate, TensorStatus};
use serde::Serialize;

use crate::recording::Recording;

/// A rotor (flywheel, motor) whose momentum is a known input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotor {
    /// Rotor inertia about its axis, kg m^2.
    pub inertia: f32,
    /// Unit axis in the sensor frame (the direction of positive speed).
    pub axis: [f32; 3],
    /// Motor poles (for eRPM channels).
    pub poles: Option<u32>,
}

/// Parses `x|y|z|-x|-y|-z`.
pub fn parse_axis(s: &str) -> Result<[f32; 3], String> {
    match s.trim() {
        "x" | "+x" => Ok([1.0, 0.0, 0.0]),
        "y" | "+y" => Ok([0.0, 1.0, 0.0]),
        "z" | "+z" => Ok([0.0, 0.0, 1.0]),
        "-x" => Ok([-1.0, 0.0, 0.0]),
        "-y" => Ok([0.0, -1.0, 0.0]),
        "-z" => Ok([0.0, 0.0, -1.0]),
        o => Err(format!(
            "rotor axis {o:?} is not one of x, y, z, -x, -y, -z"
        )),
    }
}

/// One estimate as written to JSON. Tensors are 3x3 in the log's gyro axes as logged.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EstimateJson {
    /// First sample used, s (log time).
    pub start_s: f64,
    /// Last sample used, s.
    pub end_s: f64,
    /// Log samples that reached the estimators (before the pipeline's averaging).
    pub samples: u32,
    /// Why `a` is or is not to be trusted (`Converged` only when it is).
    pub status: String,
    /// Which estimator gave `a`: `Refined` (principal axes, no rotor: the paper's setting) or
    /// `Tensor` (rotor momentum, or products of inertia needed).
    pub a_source: String,
    /// Why the tensor is or is not to be trusted.
    pub tensor_status: String,
    /// `Full` or `Principal` (products of inertia insignificant and set to zero).
    pub model: String,
    /// `J`, kg m^2, when a rotor momentum fixes the scale; else null.
    pub tensor_kg_m2: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of `tensor_kg_m2`.
    pub tensor_std_kg_m2: Option<[[f32; 3]; 3]>,
    /// `J / trace(J)`.
    pub tensor_normalized: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of `tensor_normalized`.
    pub tensor_normalized_std: Option<[[f32; 3]; 3]>,
    /// The paper's ratios `a` from the recommended estimator (`a_source`).
    pub a: Option<[f32; 3]>,
    /// Standard deviations of `a`.
    pub std_a: Option<[f32; 3]>,
    /// Principal moments, ascending (kg m^2 with a tensor, else normalised).
    pub principal_moments: Option<[f32; 3]>,
    /// Principal axes, one unit vector per moment.
    pub principal_axes: Option<[[f32; 3]; 3]>,
    /// Residual over the gyro noise.
    pub residual_ratio: f32,
    /// Information per equation over the noise (about 1 for a still gyro).
    pub excitation: f32,
}

impl EstimateJson {
    fn from(e: &TensorEstimate, r: &Ratios, start_s: f64, end_s: f64) -> Self {
        EstimateJson {
            start_s,
            end_s,
            samples: e.samples,
            status: format!("{:?}", r.status),
            a_source: format!("{:?}", r.source),
            tensor_status: format!("{:?}", e.status),
            model: format!("{:?}", e.model),
            tensor_kg_m2: e.tensor,
            tensor_std_kg_m2: e.tensor_std,
            tensor_normalized: e.normalized,
            tensor_normalized_std: e.normalized_std,
            a: r.a,
            std_a: r.std_a,
            principal_moments: e.principal_moments,
            principal_axes: e.principal_axes,
            residual_ratio: e.residual_ratio,
            excitation: e.excitation,
        }
    }
}

/// The whole report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// The input file and format.
    pub input: String,
    /// Samples in the log.
    pub log_samples: usize,
    /// Median sample rate, Hz.
    pub rate_hz: f32,
    /// Gyro white noise used as the floor of the uncertainty, rad/s.
    pub noise_std: f32,
    /// Gyro bias removed (from the last still window before the last throw), rad/s.
    pub gyro_bias: [f32; 3],
    /// Whether the free flights were found from the accelerometer (else the whole log or the
    /// given segments were taken).
    pub free_flight_detection: bool,
    /// Every free flight.
    pub throws: Vec<EstimateJson>,
    /// All throws together (the on-board result).
    pub pooled: EstimateJson,
    /// Warnings for the user.
    pub warnings: Vec<String>,
    /// Indices of the samples fed to the estimator, one list per throw (for follow-up
    /// analyses such as `inertia calibrate`; not written to JSON).
    #[serde(skip)]
    pub fed_runs: Vec<Vec<usize>>,
}

/// Why no estimate could be given at all.
#[derive(Debug, PartialEq)]
pub enum IdentifyError {
    /// Too few samples to do anything.
    TooShort,
    /// The gate found no free flight.
    NoFreeFlight,
    /// A rotor was given but the log has no rotor-speed channel, or eRPM without poles.
    Rotor(String),
    /// Settings could not be built (rate or noise not finite).
    Settings(String),
}

impl std::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IdentifyError::TooShort => write!(f, "the log has fewer than 10 samples"),
            IdentifyError::NoFreeFlight => write!(
                f,
                "no free flight found: the accelerometer never read pure rotation about the \
                 centre of mass (give --segments to choose the stretches by hand)"
            ),
            IdentifyError::Rotor(m) => write!(f, "{m}"),
            IdentifyError::Settings(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for IdentifyError {}

/// Median time step of the recording, s.
pub fn median_dt(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    d[d.len() / 2]
}

/// Gyro white noise estimated from the data: the median absolute third difference per axis
/// (third differences cancel any quadratic motion; for white noise their variance is
/// `20 sigma^2`), turned into a standard deviation, smallest over the axes. Floored at
/// `1e-4 rad/s`.
pub fn estimate_noise(gyro: &[[f32; 3]]) -> f32 {
    let mut best = f32::INFINITY;
    for ax in 0..3 {
        let mut d: Vec<f32> = gyro
            .windows(4)
            .map(|w| (w[3][ax] - 3.0 * w[2][ax] + 3.0 * w[1][ax] - w[0][ax]).abs())
            .filter(|x| x.is_finite())
            .collect();
        if d.is_empty() {
            continue;
        }
        d.sort_by(|a, b| a.total_cmp(b));
        let mad = d[d.len() / 2];
        let s = mad / 0.6745 / 20f32.sqrt();
        if s < best {
            best = s;
        }
    }
    if best.is_finite() {
        best.max(1e-4)
    } else {
        2e-3
    }
}

/// Options of one identification.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IdentifyOptions {
    /// Known rotor.
    pub rotor: Option<Rotor>,
    /// Hand-chosen stretches `(start_s, end_s)`; the gate is not used.
    pub segments: Option<Vec<(f64, f64)>>,
    /// Gyro noise, rad/s; estimated from the data when `None`.
    pub noise_std: Option<f32>,
    /// Use the rotor speed exactly as logged (sample and hold) instead of [`unhold`].
    pub rotor_raw: bool,
}

/// Rotor speed reconstructed from a sample-and-hold telemetry channel.
///
/// ESC telemetry (eRPM) arrives every one to a few milliseconds and the log holds each value
/// until the next: a staircase that lags the true speed by about half an update interval. On
/// the thrown-FC logs this lag was the largest effect the model lacked (the residual of the
/// rotor axis correlated -0.79 with the rotor's speed changes). Each new value is taken as the
/// speed at the middle of the interval it replaced and the speed is interpolated linearly
/// between those points; before the first change the log is kept as it is (a rotor at rest).
pub fn unhold(t: &[f64], speed: &[f32]) -> Vec<f32> {
    let n = speed.len().min(t.len());
    let mut knots: Vec<(f64, f32)> = Vec::new();
    let mut prev_change = 0usize;
    for i in 1..n {
        if speed[i] != speed[i - 1] {
            knots.push((0.5 * (t[i] + t[prev_change]), speed[i]));
            prev_change = i;
        }
    }
    if knots.len() < 2 {
        return speed.to_vec();
    }
    let first_change = {
        let mut k = 1;
        while k < n && speed[k] == speed[k - 1] {
            k += 1;
        }
        k
    };
    let mut out = speed[..n].to_vec();
    let mut j = 0usize;
    for (i, o) in out.iter_mut().enumerate().skip(first_change) {
        let ti = t[i];
        while j + 1 < knots.len() && knots[j + 1].0 <= ti {
            j += 1;
        }
        let (t0, v0) = knots[j];
        *o = if j + 1 < knots.len() && ti >= t0 {
            let (t1, v1) = knots[j + 1];
            let f = ((ti - t0) / (t1 - t0)) as f32;
            v0 + (v1 - v0) * f
        } else if ti < t0 {
            // Between the first change and the first knot's time: interpolate from the held
            // value before it.
            let (tp, vp) = (t[first_change - 1], speed[first_change - 1]);
            let f = ((ti - tp) / (t0 - tp)) as f32;
            vp + (v0 - vp) * f
        } else {
            v0
        };
    }
    out
}

/// Runs the identification.
pub fn identify(
    rec: &Recording,
    opts: &IdentifyOptions,
    mut progress: impl FnMut(usize),
) -> Result<Report, IdentifyError> {
    let n = rec.len();
    if n < 10 {
        return Err(IdentifyError::TooShort);
    }
    let mut warnings = rec.warnings.clone();
    let dt_med = median_dt(&rec.t);
    let rate = (1.0 / dt_med) as f32;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(IdentifyError::Settings(
            "the time steps are not positive".into(),
        ));
    }
    let noise = opts.noise_std.unwrap_or_else(|| estimate_noise(&rec.gyro));
    // Rotor momentum per sample.
    let h: Vec<[f32; 3]> = match &opts.rotor {
        None => vec![[0.0; 3]; n],
        Some(r) => {
            let Some(ch) = &rec.rotor else {
                return Err(IdentifyError::Rotor(
                    "--rotor-inertia was given but the log has no rotor-speed channel".into(),
                ));
            };
            let Some(speed) = ch.rad_per_sec(r.poles) else {
                return Err(IdentifyError::Rotor(
                    "the log gives rotor speed as eRPM: --rotor-poles is needed".into(),
                ));
            };
            let speed = if opts.rotor_raw {
                speed
            } else {
                unhold(&rec.t, &speed)
            };
            speed
                .iter()
                .map(|s| r.axis.map(|a| a * r.inertia * s))
                .collect()
        }
    };
    if opts.rotor.is_none() && rec.rotor.is_some() {
        warnings.push(
            "the log has a rotor-speed channel but no --rotor-inertia was given: rotor \
             momentum is ignored and the tensor is determined up to scale only"
                .into(),
        );
    }
    let settings = PipelineSettings::for_rate(rate, noise).with_full_scale(rec.gyro_full_scale);
    let dt_of = |i: usize| -> f32 {
        if i == 0 {
            dt_med as f32
        } else {
            (rec.t[i] - rec.t[i - 1]) as f32
        }
    };

    // Which samples count as free flight, and the pooled on-board estimate.
    let mut fed_runs: Vec<Vec<usize>> = Vec::new();
    let pooled_est;
    let pooled_ratios;
    let pooled_inputs;
    let bias;
    let detection;
    if let Some(segs) = &opts.segments {
        detection = false;
        bias = [0.0; 3];
        let mut pooled = FlightPipeline::new(settings, false)
            .ok_or_else(|| IdentifyError::Settings("invalid estimator settings".into()))?;
        for &(s, e) in segs {
            let idx: Vec<usize> = (0..n).filter(|&i| rec.t[i] >= s && rec.t[i] <= e).collect();
            if idx.is_empty() {
                warnings.push(format!("segment {s}..{e} s holds no sample of the log"));
                continue;
            }
            for &i in &idx {
                pooled.step(rec.gyro[i], [0.0; 3], h[i], dt_of(i));
            }
            pooled.end_stretch();
            fed_runs.push(idx);
        }
        progress(n);
        pooled_est = pooled.estimate();
        pooled_ratios = pooled.ratios_with(&pooled_est);
        pooled_inputs = pooled.fed_inputs();
    } else {
        let accel = rec.accel.as_ref();
        detection = accel.is_some();
        let mut p = FlightPipeline::new(settings, accel.is_some())
            .ok_or_else(|| IdentifyError::Settings("invalid pipeline settings".into()))?;
        let mut last_fed: Option<usize> = None;
        let max_gap = (0.1 * rate as f64).max(2.0) as usize;
        for i in 0..n {
            let f = accel.map(|a| a[i]).unwrap_or([0.0; 3]);
            if let Some(exit) = p.step(rec.gyro[i], f, h[i], dt_of(i)) {
                if exit.fed.is_some() {
                    // The estimator sample averages `inputs` log samples from `first_input`.
                    let k = exit.sample.first_input as usize;
                    let new_run = last_fed.is_none_or(|l| k > l + max_gap);
                    if new_run {
                        fed_runs.push(Vec::new());
                    }
                    let end = (k + exit.sample.inputs as usize).min(n);
                    if let Some(run) = fed_runs.last_mut() {
                        run.extend(k..end);
                    }
                    last_fed = Some(end.saturating_sub(1));
                }
            }
            if i % 65536 == 0 {
                progress(i);
            }
        }
        progress(n);
        // The log ends: a free flight still open is fitted now (the trajectory fit runs at
        // each stretch's end, as the firmware's does at the catch).
        p.end_stretch();
        pooled_est = p.estimate();
        pooled_ratios = p.ratios_with(&pooled_est);
        pooled_inputs = p.fed_inputs();
        bias = p.bias();
    }
    if fed_runs.iter().all(|r| r.is_empty()) {
        return Err(IdentifyError::NoFreeFlight);
    }
    let throws: Vec<EstimateJson> = fed_runs
        .iter()
        .filter(|r| !r.is_empty())
        .map(|run| {
            let mut e = FlightPipeline::new(settings, false).expect("settings validated above");
            let mut prev: Option<usize> = None;
            for &i in run {
                // Stretches of a throw separated by held-back samples: no integral across.
                if prev.is_some_and(|p| i != p + 1) {
                    e.end_stretch();
                }
                prev = Some(i);
                let w = rec.gyro[i];
                let w = [w[0] - bias[0], w[1] - bias[1], w[2] - bias[2]];
                e.step(w, [0.0; 3], h[i], dt_of(i));
            }
            e.end_stretch();
            let (a, b) = (run[0], run[run.len() - 1]);
            let est = e.estimate();
            let mut j = EstimateJson::from(&est, &e.ratios_with(&est), rec.t[a], rec.t[b]);
            j.samples = e.fed_inputs();
            j
        })
        .collect();
    let first = fed_runs
        .iter()
        .find(|r| !r.is_empty())
        .map(|r| r[0])
        .unwrap_or(0);
    let last = fed_runs
        .iter()
        .rev()
        .find(|r| !r.is_empty())
        .map(|r| r[r.len() - 1])
        .unwrap_or(0);
    let mut pooled = EstimateJson::from(&pooled_est, &pooled_ratios, rec.t[first], rec.t[last]);
    pooled.samples = pooled_inputs;
    if pooled_ratios.status != TensorStatus::Converged {
        warnings.push(format!(
            "pooled estimate is not to be trusted: {:?}",
            pooled_ratios.status
        ));
    }
    Ok(Report {
        input: rec.source.clone(),
        log_samples: n,
        rate_hz: rate,
        noise_std: noise,
        gyro_bias: bias,
        free_flight_detection: detection,
        throws,
        pooled,
        warnings,
        fed_runs: fed_runs.into_iter().filter(|r| !r.is_empty()).collect(),
    })
}
