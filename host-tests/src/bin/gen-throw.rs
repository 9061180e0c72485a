//! Writes a simulated throw (`host_tests::throw_sim`) as a CSV `t,wx,wy,wz,ax,ay,az,rotor_rad_s`
//! (s, rad/s, m/s^2, rad/s), and prints the true release and catch times.
//!
//! `--deg-per-s` and `--time-unit ms` write the gyro in deg/s or the time in ms under the same
//! header: the unit mistakes users make, for the readers' tests.
//!
//! Usage: `gen-throw --scenario board_throw --seed 1 --out throw.csv [--rate 4000]`.

use anyhow::{bail, Result};
use clap::{Parser, ValueEnum};
use host_tests::throw_sim::{scenario_config, simulate, CsvOptions, SCENARIOS};
use std::path::PathBuf;

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
    /// CSV file to write.
    #[arg(long)]
    out: PathBuf,
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
    sim.write_csv(
        &args.out,
        CsvOptions {
            deg_per_s: args.deg_per_s,
            time_ms: matches!(args.time_unit, TimeUnit::Ms),
        },
    )?;
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
