//! `identify` on the whole log held as a [`Recording`], the reference for the tests: the
//! streaming `identify` must give the same report bit for bit.

use std::ops::Range;

use identifier_core::{FlightPipeline, PipelineSettings, Status};

use super::{
    estimate_noise, median_dt, slow_telemetry, unhold, white_noise, EstimateJson, IdentifyError,
    IdentifyOptions, Report,
};
use crate::recording::Recording;

/// Sorted indices as ranges of consecutive ones.
fn ranges(idx: &[usize]) -> Vec<Range<usize>> {
    let mut out: Vec<Range<usize>> = Vec::new();
    for &i in idx {
        match out.last_mut() {
            Some(r) if r.end == i => r.end += 1,
            _ => out.push(i..i + 1),
        }
    }
    out
}

/// Runs the identification.
pub(super) fn identify(rec: &Recording, opts: &IdentifyOptions) -> Result<Report, IdentifyError> {
    let progress = |_: usize| {};
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
    let noise = opts.noise_std.unwrap_or_else(|| {
        white_noise(estimate_noise(&rec.gyro), rec.gyro_filters.as_ref(), dt_med)
    });
    // Rotor momentum per sample, and the speed channel's resolution.
    let mut step = None;
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
            step = crate::survey::RotorStep::of(&speed);
            let speed = if opts.rotor_hold.interpolates(slow_telemetry(&rec.t, &speed)) {
                unhold(&rec.t, &speed)
            } else {
                speed
            };
            let rotors = r.rotors().map_err(IdentifyError::Rotor)?;
            speed.iter().map(|s| rotors.momentum(&[*s])).collect()
        }
    };
    if opts.rotor.is_none() && rec.rotor.is_some() {
        warnings.push(
            "the log has a rotor-speed channel but no --rotor-inertia was given: rotor \
             momentum is ignored and the tensor is determined up to scale only"
                .into(),
        );
    }
    let quantum = super::momentum_quantum(opts, step);
    let settings = PipelineSettings::for_rate(rate, noise)
        .with_full_scale(rec.gyro_full_scale)
        .with_momentum_resolution(quantum)
        .with_averaging_gyro(rec.gyro_averaging)
        .with_filtered_gyro(rec.gyro_smoothing());
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
    let bias_measured;
    let detection;
    if let Some(segs) = &opts.segments {
        detection = false;
        // The bias measured on the bench before the first segment, as the whole log's
        // reading measures it (`passes::bench_bias`).
        let measured = match rec.accel.as_ref() {
            Some(accel) => {
                let first = segs.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
                let mut p = FlightPipeline::new(settings, true)
                    .ok_or_else(|| IdentifyError::Settings("invalid pipeline settings".into()))?;
                for i in (0..n).take_while(|&i| rec.t[i] < first) {
                    p.step(rec.gyro[i], accel[i], h[i], dt_of(i));
                }
                p.measured_bias()
            }
            None => None,
        };
        bias = measured.unwrap_or([0.0; 3]);
        bias_measured = measured.is_some();
        let mut pooled = FlightPipeline::new(settings, false)
            .ok_or_else(|| IdentifyError::Settings("invalid estimator settings".into()))?;
        pooled.set_bias_removed(bias_measured);
        for &(s, e) in segs {
            let idx: Vec<usize> = (0..n).filter(|&i| rec.t[i] >= s && rec.t[i] <= e).collect();
            if idx.is_empty() {
                warnings.push(format!("segment {s}..{e} s holds no sample of the log"));
                continue;
            }
            for &i in &idx {
                let w = rec.gyro[i];
                let w = [w[0] - bias[0], w[1] - bias[1], w[2] - bias[2]];
                pooled.step(w, [0.0; 3], h[i], dt_of(i));
            }
            pooled.end_stretch();
            fed_runs.push(idx);
        }
        progress(n);
        (pooled_est, pooled_ratios) = pooled.estimate_and_ratios();
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
        (pooled_est, pooled_ratios) = p.estimate_and_ratios();
        pooled_inputs = p.fed_inputs();
        bias = p.bias();
        bias_measured = p.measured_bias().is_some();
    }
    if fed_runs.iter().all(|r| r.is_empty()) {
        return Err(IdentifyError::NoFreeFlight);
    }
    let throws: Vec<EstimateJson> = fed_runs
        .iter()
        .filter(|r| !r.is_empty())
        .map(|run| {
            let mut e = FlightPipeline::new(settings, false).expect("settings validated above");
            e.set_bias_removed(bias_measured);
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
            let (est, ratios) = e.estimate_and_ratios();
            let mut j = EstimateJson::from(&est, &ratios, rec.t[a], rec.t[b]);
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
    if pooled_ratios.status != Status::Converged {
        warnings.push(format!(
            "pooled estimate is not to be trusted: {:?}",
            pooled_ratios.status
        ));
    }
    warnings.extend(super::scale_floor_warning(&pooled));
    if !bias_measured {
        warnings.push(super::NO_BIAS_WARNING.into());
    }
    Ok(Report {
        input: rec.source.clone(),
        log_samples: n,
        rate_hz: rate,
        noise_std: noise,
        gyro_bias: bias,
        gyro_bias_measured: bias_measured,
        free_flight_detection: detection,
        rotor_momentum_quantum: (quantum > 0.0).then_some(quantum),
        gravity_gradient: false,
        gyro_grid: None,
        gyro_lsb: None,
        gyro_bias_walk_rad_s_per_sqrt_s: None,
        throws,
        pooled,
        warnings,
        fed_runs: fed_runs
            .into_iter()
            .filter(|r| !r.is_empty())
            .map(|r| ranges(&r))
            .collect(),
        trace: None,
        gyro_scale: None,
        gyro_scale_factor: None,
        clock_scale_factor: None,
    })
}
