//! `inertia export-replay`: the per-sample `f32` inputs `inertia identify` gives its
//! `FlightPipeline` (rate, specific force, rotor speeds, time step), the rotor table and the
//! pipeline's settings, written as the replay file the QEMU firmware reads (`firmware-qemu
//! --replay`, `scripts/run.sh --log`). The layout (version 6) is documented in
//! `firmware/src/replay_format.rs`.
//!
//! Every value is computed as in `identify` (same expressions, same order): the rate is
//! `1 / median dt` of the `f64` log times, the rotor speed `unhold` of the channel (as logged
//! with `--rotor-raw`), the noise from `estimate_noise` unless given, the
//! full scale the recording's, `dt` of sample 0 the median and of sample `i` `t[i] - t[i-1]`
//! rounded once to `f32`, the rotor speed's resolution the smallest change of the channel
//! (`inertia::survey::RotorStep`). The firmware turns the rotor speeds into momentum with the
//! same `identifier_core::Rotors::momentum` as `identify`; the momentum's quantum is written
//! as `identify` computes it (`inertia * resolution`). With a vehicle file (`--vehicle`) the
//! table is its rotors and each sample carries their columns in rad/s (as logged times the
//! file's factor, as `identify` computes them). On an orbiting vehicle's log (attitude and
//! position columns) with a known rotor momentum, where `identify` folds the gravity-gradient
//! torque into the momentum, each sample also carries the log's `f64` time, its attitude and
//! its position (header flag bit 1): the firmware folds the torque with the same function
//! (`identifier_core::gravity`) in the same passes. No sample is flagged as actuated (a log
//! says nothing of actuators).

use std::io::Write;
use std::path::Path;

use inertia::identify::{slow_telemetry, unhold, Rotor, RotorHold};
use inertia::recording::{estimate_noise, median_dt, white_noise};
use inertia::vehicle::Vehicle;
use inertia::Recording;

/// The rotors whose speeds the replay carries.
pub enum Rotors<'a> {
    /// The `--rotor-*` flags' one rotor, or none.
    Flag(Option<Rotor>),
    /// A vehicle file's rotors (`--vehicle`), their speeds from its columns.
    Vehicle(&'a Vehicle),
}

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
    /// Each sample carries its time, attitude and position (the gravity-gradient fold).
    pub orbit: bool,
}

/// Writes the replay file of `rec` to `out`.
pub fn export(
    rec: &Recording,
    rotors: Rotors<'_>,
    noise_std: Option<f32>,
    hold: RotorHold,
    centred: bool,
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
    let (rotor, vehicle) = match rotors {
        Rotors::Flag(r) => (r, None),
        Rotors::Vehicle(v) => (None, Some(v)),
    };
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
    if let Some(r) = &rotor {
        // The same check `identify` makes of its rotor.
        r.rotors()?;
    }
    // A vehicle file's rotors: each column as logged times the factor to rad/s the vehicle
    // file gives it, as `identify` turns them into speeds before `Rotors::momentum`.
    let wheels: Vec<Vec<f32>> = match vehicle {
        None => Vec::new(),
        Some(v) => {
            if rec.wheels.len() != v.rotors.len() || rec.wheels.iter().any(|w| w.len() != n) {
                return Err(format!(
                    "the log gives {} of the vehicle file's {} rotor columns",
                    rec.wheels.len(),
                    v.rotors.len()
                ));
            }
            v.rotors
                .iter()
                .zip(&rec.wheels)
                .map(|(r, w)| {
                    let k = r.to_rad_per_sec().unwrap_or(f32::NAN);
                    w.iter().map(|&x| x * k).collect()
                })
                .collect()
        }
    };
    let table: Vec<(f32, [f32; 3])> = match (vehicle, &rotor) {
        (Some(v), _) => v.rotors.iter().map(|r| (r.inertia_kg_m2, r.axis)).collect(),
        (None, Some(r)) => vec![(r.inertia, r.axis)],
        (None, None) => Vec::new(),
    };
    let with_accel = rec.accel.is_some();
    // The orbit, where `identify` folds the gravity gradient: attitude and position columns
    // and a known rotor momentum.
    let orbit = match (&rec.attitude, &rec.position) {
        (Some(q), Some(r)) if !table.is_empty() => {
            if q.len() != n || r.len() != n {
                return Err("the log's attitude or position columns are short".into());
            }
            Some((q, r))
        }
        _ => None,
    };
    let rotors = table.len() as u32;
    let per_sample = 32 + 4 * table.len() + if orbit.is_some() { 48 } else { 0 };
    let mut b: Vec<u8> = Vec::with_capacity(44 + 16 * table.len() + per_sample * n);
    // Fixed part (44 bytes).
    b.extend_from_slice(b"IRPL");
    b.extend_from_slice(&6u32.to_le_bytes());
    b.extend_from_slice(&rate.to_le_bytes());
    b.extend_from_slice(&noise.to_le_bytes());
    b.extend_from_slice(&rec.gyro_full_scale.to_le_bytes());
    let flags = u32::from(with_accel) | u32::from(orbit.is_some()) << 1 | u32::from(centred) << 2;
    b.extend_from_slice(&flags.to_le_bytes());
    // The momentum's quantum as `identify` computes it (`momentum_quantum`).
    let quantum = match (&rotor, step) {
        (Some(r), Some(q)) => r.inertia * q,
        _ => 0.0f32,
    };
    b.extend_from_slice(&quantum.to_le_bytes());
    b.extend_from_slice(&rec.gyro_averaging.to_le_bytes());
    b.extend_from_slice(&rec.gyro_smoothing().to_le_bytes());
    b.extend_from_slice(&rotors.to_le_bytes());
    b.extend_from_slice(&(n as u32).to_le_bytes());
    // The rotor table (16 bytes a rotor).
    for (j, axis) in &table {
        b.extend_from_slice(&j.to_le_bytes());
        for a in axis {
            b.extend_from_slice(&a.to_le_bytes());
        }
    }
    // The samples (32 bytes, 4 a rotor, 48 with the orbit each).
    for i in 0..n {
        let f = rec.accel.as_ref().map(|a| a[i]).unwrap_or([0.0; 3]);
        for x in rec.gyro[i].iter().chain(f.iter()) {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b.extend_from_slice(&dt_of(i).to_le_bytes());
        // Sample flags: nothing actuated.
        b.extend_from_slice(&0u32.to_le_bytes());
        if let Some(s) = &speed {
            b.extend_from_slice(&s[i].to_le_bytes());
        }
        for w in &wheels {
            b.extend_from_slice(&w[i].to_le_bytes());
        }
        if let Some((q, r)) = orbit {
            b.extend_from_slice(&rec.t[i].to_le_bytes());
            for x in q[i] {
                b.extend_from_slice(&x.to_le_bytes());
            }
            for x in r[i] {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    let mut file = std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?;
    file.write_all(&b)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(Exported {
        samples: n,
        rate_hz: rate,
        noise_std: noise,
        with_accel,
        orbit: orbit.is_some(),
    })
}
