//! Writes a simulated throw (`host_tests::throw_sim`) as a CSV `t,wx,wy,wz,ax,ay,az,rotor_rad_s`
//! (s, rad/s, m/s^2, rad/s), and prints the true release and catch times.
//!
//! `--deg-per-s` and `--time-unit ms` write the gyro in deg/s or the time in ms under the same
//! header: the unit mistakes users make, for the readers' tests.
//!
//! `--format betaflight` writes a Betaflight 4.4 blackbox log instead, as a flight controller
//! would log the same throw: the simulated rate is its gyro loop, the gyro passes through
//! Betaflight's default filters (first-order stages at 250 and 500 Hz; the dynamic notches
//! off) and the accelerometer through its 10 Hz PT2, every `--log-every`-th loop is logged
//! (the gyro in tenths of deg/s, the accelerometer in counts of 2048 per g, the flywheel as
//! `eRPM[0]` of a 12-pole motor), with the filters in the header.
//!
//! `--format px4` writes a PX4 ULog: `sensor_combined` every `--log-every` samples, its gyro
//! and accelerometer the means over that interval (`gyro_integral_dt`), stamped at its end,
//! as PX4's IMU integrator reports them, and `esc_status` at 100 Hz with the flywheel's
//! mechanical rpm (the mean since the previous report, as an ESC that counts commutations
//! measures it).
//!
//! Usage: `gen-throw --scenario board_throw --seed 1 --out throw.csv [--rate 4000]
//! [--format csv|betaflight|px4] [--log-every 4]`.

use anyhow::{bail, Result};
use clap::{Parser, ValueEnum};
use host_tests::throw_sim::{scenario_config, simulate, CsvOptions, SCENARIOS};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Format {
    Csv,
    Betaflight,
    Px4,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum TimeUnit {
    S,
    Ms,
}

#[derive(Parser)]
#[command(about = "Simulated hand throw of a rigid body with a flywheel, as a CSV log")]
struct Args {
    /// Scenario: board_throw, tumbling_with_spinup, no_rotor_toss, clipped_toss, still.
    #[arg(long, default_value = "board_throw")]
    scenario: String,
    /// Seed of the scenario and of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// File to write.
    #[arg(long)]
    out: PathBuf,
    /// `csv`, `betaflight` (a Betaflight blackbox log of the throw) or `px4` (a ULog); see the
    /// module docs.
    #[arg(long, value_enum, default_value = "csv")]
    format: Format,
    /// With `--format betaflight` or `px4`: simulated samples per logged one.
    #[arg(long, default_value_t = 4)]
    log_every: usize,
    /// Write the gyro columns in deg/s (header unchanged).
    #[arg(long)]
    deg_per_s: bool,
    /// Unit of the time column.
    #[arg(long, value_enum, default_value = "s")]
    time_unit: TimeUnit,
    /// Sample rate, Hz (the scenario's own, 4000, by default).
    #[arg(long)]
    rate: Option<f64>,
    /// The centre of mass seen from the IMU, m, `x,y,z` (the scenario's own by default): the
    /// accelerometer's lever arm, to try the free-flight gate on a large object.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    com_from_imu: Option<Vec<f64>>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let Some(mut cfg) = scenario_config(&args.scenario, args.seed) else {
        bail!(
            "unknown scenario {:?}; one of {}",
            args.scenario,
            SCENARIOS.join(", ")
        );
    };
    if let Some(r) = args.rate {
        if !(r.is_finite() && r >= 10.0) {
            bail!("--rate must be at least 10 Hz");
        }
        cfg.rate_hz = r;
        // Keep the internal step near 16 kHz or finer.
        cfg.substeps = ((16000.0 / r).ceil() as usize).max(1);
    }
    if let Some(c) = &args.com_from_imu {
        if c.len() != 3 || !c.iter().all(|x| x.is_finite()) {
            bail!("--com-from-imu must be three finite numbers");
        }
        cfg.com_from_imu = [c[0], c[1], c[2]];
    }
    let sim = simulate(&cfg);
    match args.format {
        Format::Csv => sim.write_csv(
            &args.out,
            CsvOptions {
                deg_per_s: args.deg_per_s,
                time_ms: matches!(args.time_unit, TimeUnit::Ms),
            },
        )?,
        Format::Betaflight | Format::Px4 => {
            if args.deg_per_s || matches!(args.time_unit, TimeUnit::Ms) {
                bail!("--deg-per-s and --time-unit are for --format csv");
            }
            if args.log_every == 0 {
                bail!("--log-every must be at least 1");
            }
            let bytes = if matches!(args.format, Format::Px4) {
                px4_log(&sim, cfg.rate_hz, args.log_every)
            } else {
                betaflight_log(&sim, cfg.rate_hz, args.log_every)
            };
            std::fs::write(&args.out, bytes)?;
        }
    }
    let fmt = |v: Option<f64>| v.map_or("none".to_string(), |x| format!("{x:.6}"));
    println!(
        "{}: {} samples at {} Hz, release_s={} catch_s={} -> {}",
        args.scenario,
        sim.t.len(),
        cfg.rate_hz,
        fmt(sim.release_s),
        fmt(sim.catch_s),
        args.out.display()
    );
    Ok(())
}

/// The throw as a Betaflight 4.4 flight controller would log it (see the module docs): the
/// firmware's filters run at the simulated rate (its gyro loop), every `every`-th loop logged.
fn betaflight_log(sim: &host_tests::throw_sim::SimThrow, rate: f64, every: usize) -> Vec<u8> {
    use log_writers::blackbox::{blackbox, Frame};
    let dt = 1.0 / rate;
    // Betaflight's first-order gain at `hz` (pt1FilterGain), and its PT2's per-stage cutoff
    // correction 1/sqrt(2^(1/2) - 1).
    let gain = |hz: f64| {
        let x = 2.0 * std::f64::consts::PI * hz * dt;
        x / (1.0 + x)
    };
    let (g1, g2) = (gain(250.0), gain(500.0));
    let ga = gain(10.0 / (2f64.sqrt() - 1.0).sqrt());
    let first = |v: Option<&[f32; 3]>| v.map_or([0.0; 3], |x| x.map(f64::from));
    let (mut p1, mut p2) = (first(sim.gyro.first()), first(sim.gyro.first()));
    let (mut a1, mut a2) = (first(sim.accel.first()), first(sim.accel.first()));
    let mut frames = Vec::new();
    for (i, (t, w, a, r)) in samples(sim).enumerate() {
        for k in 0..3 {
            p1[k] += g1 * (f64::from(w[k]) - p1[k]);
            p2[k] += g2 * (p1[k] - p2[k]);
            a1[k] += ga * (f64::from(a[k]) - a1[k]);
            a2[k] += ga * (a1[k] - a2[k]);
        }
        if i % every == 0 {
            let erpm = f64::from(r) * 6.0 * 60.0 / (2.0 * std::f64::consts::PI) / 100.0;
            frames.push(Frame {
                time_us: 1_000_000 + (t * 1e6).round() as u64,
                gyro: p2.map(|v| (v.to_degrees() * 10.0).round() as i64),
                accel: Some(a2.map(|v| (v / 9.80665 * 2048.0).round() as i64)),
                erpm: Some(erpm.abs().round() as u64),
            });
        }
    }
    let header: Vec<(&str, String)> = [
        ("blackbox_high_resolution", "1".to_string()),
        ("looptime", format!("{}", (dt * 1e6).round())),
        ("gyro_lpf1_type", "0".into()),
        ("gyro_lpf1_static_hz", "250".into()),
        ("gyro_lpf1_dyn_hz", "0,0".into()),
        ("gyro_lpf2_type", "0".into()),
        ("gyro_lpf2_static_hz", "500".into()),
        ("dyn_notch_count", "0".into()),
        ("acc_lpf_hz", "1000".into()),
    ]
    .into_iter()
    .collect();
    blackbox("Betaflight 4.4.2 (sim) STM32F405", &header, &frames)
}

/// The throw as PX4 logs it (see the module docs): `sensor_combined` every `every` simulated
/// samples, gyro and accelerometer the means over that interval, stamped at its last sample,
/// and `esc_status` every 10 ms (the flywheel's mean mechanical rpm since the last one).
fn px4_log(sim: &host_tests::throw_sim::SimThrow, rate: f64, every: usize) -> Vec<u8> {
    use log_writers::ulog::{add_logged, header, msg};
    let mut f = header(0);
    msg(
        &mut f,
        b'F',
        b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;float[3] accelerometer_m_s2;",
    );
    msg(&mut f, b'F', b"esc_report:int32_t esc_rpm;");
    msg(
        &mut f,
        b'F',
        b"esc_status:uint64_t timestamp;uint8_t esc_count;esc_report[1] esc;",
    );
    add_logged(&mut f, 0, "sensor_combined");
    add_logged(&mut f, 1, "esc_status");
    let stamp = |t: f64| 1_000_000 + (t * 1e6).round() as u64;
    let interval = (every as f64 / rate * 1e6).round() as u32;
    let esc_every = ((0.01 * rate).round() as usize).max(1);
    let (mut gsum, mut asum) = ([0.0f64; 3], [0.0f64; 3]);
    let (mut rsum, mut rn) = (0.0f64, 0usize);
    for (i, (t, w, a, r)) in samples(sim).enumerate() {
        for k in 0..3 {
            gsum[k] += f64::from(w[k]);
            asum[k] += f64::from(a[k]);
        }
        rsum += f64::from(r);
        rn += 1;
        if i % esc_every == 0 {
            // An ESC counts commutations: its rpm is the mean speed since its last report.
            let mean = rsum / rn as f64;
            (rsum, rn) = (0.0, 0);
            let rpm = (mean * 60.0 / (2.0 * std::f64::consts::PI)).round() as i32;
            let mut d = 1u16.to_le_bytes().to_vec();
            d.extend_from_slice(&stamp(t).to_le_bytes());
            d.push(1);
            d.extend_from_slice(&rpm.to_le_bytes());
            msg(&mut f, b'D', &d);
        }
        if (i + 1) % every == 0 {
            let n = every as f64;
            let mut d = 0u16.to_le_bytes().to_vec();
            d.extend_from_slice(&stamp(t).to_le_bytes());
            for g in gsum {
                d.extend_from_slice(&((g / n) as f32).to_le_bytes());
            }
            d.extend_from_slice(&interval.to_le_bytes());
            for a in asum {
                d.extend_from_slice(&((a / n) as f32).to_le_bytes());
            }
            msg(&mut f, b'D', &d);
            (gsum, asum) = ([0.0; 3], [0.0; 3]);
        }
    }
    f
}

/// The simulated samples in order: time (s), gyro (rad/s), accelerometer (m/s^2) and the
/// reported flywheel speed (rad/s).
fn samples(
    sim: &host_tests::throw_sim::SimThrow,
) -> impl Iterator<Item = (f64, &[f32; 3], &[f32; 3], f32)> {
    sim.t
        .iter()
        .zip(&sim.gyro)
        .zip(&sim.accel)
        .zip(&sim.rotor_rad_s)
        .map(|(((&t, w), a), &r)| (t, w, a, r))
}
