//! PX4 ULog files, decoded with the `px4-ulog` crate.
//!
//! | topic, field | unit | in the [`Recording`] |
//! |---|---|---|
//! | `sensor_combined.timestamp` | microseconds | `t`, seconds, less half the median `gyro_integral_dt` |
//! | `sensor_combined.gyro_rad[0..2]` | rad/s | `gyro` |
//! | `sensor_combined.gyro_integral_dt` (optional) | microseconds | [`Recording::gyro_averaging`]: its median over the median time step |
//! | `sensor_combined.accelerometer_m_s2[0..2]` | m/s^2 | `accel` |
//! | `esc_status.esc[0].esc_rpm` (optional; not read with a vehicle file's rotor fields) | mechanical rpm | `rotor`, [`RotorSpeed::RadPerSec`], sample-and-hold onto the gyro times |
//! | `sensor_combined.gyro_clipping` (optional) | bit `k` set: axis `k` clipped | that axis at the full scale (saturated) |
//! | a vehicle file's rotor fields (optional): `topic.field`, `topic:N.field` ([`ReadOptions::rotor_columns`]) | as logged; the vehicle file's `speed_unit` | [`Recording::wheels`], the last value at or before each gyro time; gyro samples before a field's first message left out (`ulog_rotors`) |
//!
//! The gyro's range is not in the log. With `gyro_clipping` the full scale is taken as
//! 2000 deg/s (PX4's IMU drivers' range), or the largest unclipped rate when that is higher,
//! and a clipped axis reads at it, so the estimators count it saturated (its value, the mean
//! over an integration interval in which the sensor clipped, is too small). Without the field
//! the full scale is unknown and a clipped toss is left to the model tests.
//!
//! PX4's `gyro_rad` is not the rate at an instant: it is the IMU's delta angle over the last
//! `gyro_integral_dt` divided by it, the mean rate over that interval, stamped with the
//! interval's last reading. Each time is moved to the interval's middle, and the fits are told
//! the readings are means ([`Recording::gyro_averaging`]): taken for instants, a fast tumble
//! logged at 250 Hz comes out many standard deviations off yet `Converged` (the test
//! `a_px4_gyro_that_averages_over_its_interval_is_read_as_means`).
//!
//! The first instance (lowest multi id) of each topic is read (a vehicle file's rotor field may
//! name another, `topic:N.field`). Axes are PX4's body frame as logged.

use std::path::Path;

use px4_ulog::full_parser::read_file;

use super::ulog_rotors::{self, as_f64, first_instance, Topic};
use super::{guard, Location, ReadError, ReadOptions, RotorWrap, Samples, MAX_WHEELS};
use crate::readers::{Recording, RotorSpeed};

/// The gyro range PX4's IMU drivers set, rad/s (2000 deg/s).
const PX4_GYRO_RANGE_RAD_S: f64 = 2000.0 * core::f64::consts::PI / 180.0;

fn column(
    path: &Path,
    topic: &Topic,
    topic_name: &str,
    field: &str,
) -> Result<Vec<f64>, ReadError> {
    topic.get(field).map(as_f64).ok_or_else(|| {
        ReadError::new(
            path,
            format!("ULog topic {topic_name} has no field {field}"),
        )
    })
}

/// Reads a ULog file.
pub fn read_ulog(path: &Path) -> Result<Recording, ReadError> {
    read_ulog_with(path, &ReadOptions::default())
}

/// Reads a ULog file with the rotor fields `opts` names ([`ReadOptions::rotor_columns`],
/// `topic.field` or `topic:N.field`) held onto the gyro's times into
/// [`Recording::wheels`], as logged (see the module documentation). The units `opts` gives
/// are for CSV logs and are not used.
pub fn read_ulog_with(path: &Path, opts: &ReadOptions) -> Result<Recording, ReadError> {
    let Some(name) = path.to_str() else {
        return Err(ReadError::new(
            path,
            "the ULog reader needs a UTF-8 file name",
        ));
    };
    let parsed = guard(path, "ULog", || read_file(name))?
        .map_err(|e| ReadError::new(path, format!("not a readable ULog: {e}")))?;
    let mut warnings = Vec::new();
    if parsed.completeness.is_incomplete() {
        warnings.push(format!(
            "the ULog ends early ({:?}): read up to there",
            parsed.completeness
        ));
    }
    let sc = "sensor_combined";
    let Some(topic) = first_instance(&parsed.messages, sc) else {
        return Err(ReadError::new(path, "no sensor_combined data in the ULog"));
    };
    let t = column(path, topic, sc, "timestamp")?;
    let mut gyro = Vec::new();
    for k in 0..3 {
        gyro.push(column(path, topic, sc, &format!("gyro_rad[{k}]"))?);
    }
    let accel: Option<Vec<Vec<f64>>> = (0..3)
        .map(|k| topic.get(&format!("accelerometer_m_s2[{k}]")).map(as_f64))
        .collect();
    let clipping = topic.get("gyro_clipping").map(as_f64);
    let integral = topic.get("gyro_integral_dt").map(as_f64);
    let n = t.len();
    if clipping.as_ref().is_some_and(|c| c.len() != n)
        || integral.as_ref().is_some_and(|c| c.len() != n)
        || gyro.iter().any(|g| g.len() != n)
        || accel
            .as_ref()
            .is_some_and(|a| a.iter().any(|c| c.len() != n))
    {
        return Err(ReadError::new(
            path,
            "sensor_combined fields differ in length",
        ));
    }

    // Each reading is the mean over its integration interval, which ends at its timestamp:
    // the time moves to the interval's middle (by the median half-interval, so the order of
    // the times is kept), and the interval's share of the time step is what the fits need.
    let (shift_us, averaging) = integral
        .as_ref()
        .and_then(|i| averaging_of(&t, i))
        .unwrap_or((0.0, 0.0));
    let t: Vec<f64> = t.iter().map(|&x| x - shift_us).collect();

    // The vehicle file's rotor fields, held onto the gyro's (moved) times.
    if opts.rotor_columns.len() > MAX_WHEELS {
        return Err(ReadError::new(
            path,
            format!("more than {MAX_WHEELS} rotor fields"),
        ));
    }
    let series = opts
        .rotor_columns
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let name = opts.rotor_names.get(k).map_or("", String::as_str);
            ulog_rotors::series(path, &parsed.messages, c, name)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let held = ulog_rotors::hold(path, &series, &t)?;
    warnings.extend(held.warnings);

    // esc_status: esc[0].esc_rpm, sample-and-hold onto the gyro times (the `--rotor-*`
    // flags' rotor; not read when a vehicle file names the rotors).
    let esc_status = if opts.rotor_columns.is_empty() {
        first_instance(&parsed.messages, "esc_status")
    } else {
        None
    };
    let rotor = match esc_status {
        Some(esc) => {
            let te = column(path, esc, "esc_status", "timestamp")?;
            let rpm = column(path, esc, "esc_status", "esc[0].esc_rpm")?;
            if te.len() != rpm.len() || te.is_empty() {
                return Err(ReadError::new(
                    path,
                    "esc_status fields differ in length or are empty",
                ));
            }
            if te.windows(2).any(|w| w[1] < w[0]) {
                return Err(ReadError::new(path, "esc_status time goes backwards"));
            }
            if t.first().is_some_and(|&t0| te[0] > t0) {
                warnings.push(format!(
                    "esc_status starts {:.3} s after the gyro: its first value is held before",
                    (te[0] - t[0]) * 1e-6
                ));
            }
            let k = 2.0 * core::f64::consts::PI / 60.0;
            let held: Vec<f64> = t
                .iter()
                .map(|&ti| {
                    let j = te.partition_point(|&x| x <= ti).saturating_sub(1);
                    rpm[j] * k
                })
                .collect();
            Some(held)
        }
        None => None,
    };

    // Bit k of gyro_clipping: axis k clipped (exact small integers, so the test is exact).
    let clipped = |i: usize, k: usize| {
        clipping
            .as_ref()
            .and_then(|c| c.get(i))
            .is_some_and(|&bits| bits >= 0.0 && (bits as u64 >> k) & 1 == 1)
    };
    let full_scale = clipping.as_ref().map(|_| {
        let widest = (0..n)
            .flat_map(|i| (0..3).filter(move |&k| !clipped(i, k)).map(move |k| (i, k)))
            .map(|(i, k)| gyro[k][i].abs())
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max);
        // Strictly above every unclipped rate: only the clipped axes read at it.
        PX4_GYRO_RANGE_RAD_S.max(widest * (1.0 + 1e-6)) as f32
    });
    let mut samples = Samples::new(path).with_wheels(series.len());
    let mut clipped_samples = 0usize;
    let mut wheels = vec![0.0; series.len()];
    for i in held.skip..n {
        for (o, v) in wheels.iter_mut().zip(&held.values) {
            *o = v[i - held.skip];
        }
        let a = accel.as_ref().map(|a| [a[0][i], a[1][i], a[2][i]]);
        let r = rotor.as_ref().map(|r| r[i]);
        let mut w = [gyro[0][i], gyro[1][i], gyro[2][i]];
        if let Some(fs) = full_scale {
            let mut any = false;
            for (k, x) in w.iter_mut().enumerate() {
                if clipped(i, k) && x.is_finite() {
                    *x = f64::from(fs).copysign(*x);
                    any = true;
                }
            }
            clipped_samples += usize::from(any);
        }
        samples.push(Location::Frame(i), t[i] * 1e-6, w, a, r, &wheels)?;
    }
    if clipped_samples > 0 {
        warnings.push(format!(
            "sensor_combined.gyro_clipping marks {clipped_samples} sample(s) clipped: read as \
             saturated"
        ));
    }
    let mut rec = samples.finish(
        format!("{} (ulog)", path.display()),
        rotor.map(|_| RotorSpeed::RadPerSec as RotorWrap),
        full_scale.unwrap_or(f32::INFINITY),
        warnings,
    )?;
    rec.gyro_averaging = averaging;
    Ok(rec)
}

/// From the timestamps `t` and the integration intervals `integral` (both microseconds): half
/// the median interval (the shift to the intervals' middles) and the median interval over the
/// median time step (at most 1: a log that dropped messages has longer steps, not longer
/// intervals). `None` without a positive finite median of both.
fn averaging_of(t: &[f64], integral: &[f64]) -> Option<(f64, f32)> {
    let median = |mut v: Vec<f64>| -> Option<f64> {
        v.retain(|x| x.is_finite() && *x > 0.0);
        if v.is_empty() {
            return None;
        }
        let k = v.len() / 2;
        let (_, m, _) = v.select_nth_unstable_by(k, f64::total_cmp);
        Some(*m)
    };
    let dt = median(t.windows(2).map(|w| w[1] - w[0]).collect())?;
    let span = median(integral.to_vec())?;
    Some((span / 2.0, (span / dt).min(1.0) as f32))
}
