//! `inertia export-replay`: the per-sample `f32` inputs `inertia identify` gives its
//! `FlightPipeline` (rate, specific force, rotor speed, time step) and the pipeline's
//! settings, written as the replay file the QEMU firmware reads (`firmware-qemu --replay`,
//! `scripts/run.sh --log`). The layout is documented in `firmware/src/replay_format.rs`.
//!
//! Every value is computed as in `identify` (same expressions, same order): the rate is
//! `1 / median dt` of the `f64` log times, the rotor speed `unhold` of the channel (as logged
//! with `--rotor-raw`), the noise from `estimate_noise` unless given, the
//! full scale the recording's, `dt` of sample 0 the median and of sample `i` `t[i] - t[i-1]`
//! rounded once to `f32`, the rotor speed's resolution the smallest change of the channel
//! (`inertia::survey::RotorStep`). The firmware turns the rotor speed into momentum with the
//! same `axis_i * inertia * speed` as `identify`, and the resolution into the momentum's
//! quantum with the same `inertia * resolution`.

use std::io::Write;
use std::path::Path;

use inertia::identify::{slow_telemetry, unhold, Rotor, RotorHold};
use inertia::recording::{estimate_noise, median_dt, white_noise};
use inertia::Recording;

/// What was written.
pub struct Exported {
    /// Samples.
    pub samples: usize,
    /// Rate, Hz.
    pub rate_hz: f32,
    /// Noise, rad/s.
    pub noise_std: f32,
    /// Accelerometer present.
    pub with_accel: bool,
}

/// Writes the replay file of `rec` to `out`.
pub fn export(
    rec: &Recording,
    rotor: Option<Rotor>,
    noise_std: Option<f32>,
    hold: RotorHold,
    out: &Path,
) -> Result<Exported, String> {
    let n = rec.len();
    if n < 10 {
        return Err("the log has fewer than 10 samples".into());
    }
    let dt_med = median_dt(&rec.t);
    let rate = (1.0 / dt_med) as f32;
    if !(rate.is_finite() && rate > 0.0) {
        return Err("the time steps are not positive".into());
    }
    let noise = noise_std.unwrap_or_else(|| {
        white_noise(estimate_noise(&rec.gyro), rec.gyro_filters.as_ref(), dt_med)
    });
    let mut step = None;
    let speed: Option<Vec<f32>> = match &rotor {
        None => None,
        Some(r) => {
            let Some(ch) = &rec.rotor else {
                return Err(
                    "--rotor-inertia was given but the log has no rotor-speed channel".into(),
                );
            };
            let Some(s) = ch.rad_per_sec(r.poles) else {
                return Err("the log gives rotor speed as eRPM: --rotor-poles is needed".into());
            };
            step = inertia::survey::RotorStep::of(&s);
            // As identify: the sample-and-hold channel interpolated unless asked raw.
            Some(if hold.interpolates(slow_telemetry(&rec.t, &s)) {
                unhold(&rec.t, &s)
            } else {
                s
            })
        }
    };
    let dt_of = |i: usize| -> f32 {
        if i == 0 {
            dt_med as f32
        } else {
            (rec.t[i] - rec.t[i - 1]) as f32
        }
    };
    let with_accel = rec.accel.is_some();
    let mut b: Vec<u8> = Vec::with_capacity(56 + 32 * n);
    b.extend_from_slice(b"IRPL");
    b.extend_from_slice(&4u32.to_le_bytes());
    b.extend_from_slice(&rate.to_le_bytes());
    b.extend_from_slice(&noise.to_le_bytes());
    b.extend_from_slice(&rec.gyro_full_scale.to_le_bytes());
    let flags = u32::from(with_accel) | (u32::from(rotor.is_some()) << 1);
    b.extend_from_slice(&flags.to_le_bytes());
    let (j, axis) = rotor.map_or((0.0f32, [0.0f32; 3]), |r| (r.inertia, r.axis));
    b.extend_from_slice(&j.to_le_bytes());
    for a in axis {
        b.extend_from_slice(&a.to_le_bytes());
    }
    let resolution = step.unwrap_or(0.0);
    b.extend_from_slice(&resolution.to_le_bytes());
    b.extend_from_slice(&rec.gyro_averaging.to_le_bytes());
    b.extend_from_slice(&rec.gyro_smoothing().to_le_bytes());
    b.extend_from_slice(&(n as u32).to_le_bytes());
    for i in 0..n {
        let f = rec.accel.as_ref().map(|a| a[i]).unwrap_or([0.0; 3]);
        let s = speed.as_ref().map(|s| s[i]).unwrap_or(0.0);
        for x in rec.gyro[i].iter().chain(f.iter()) {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b.extend_from_slice(&s.to_le_bytes());
        b.extend_from_slice(&dt_of(i).to_le_bytes());
    }
    let mut file = std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?;
    file.write_all(&b)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(Exported {
        samples: n,
        rate_hz: rate,
        noise_std: noise,
        with_accel,
    })
}
