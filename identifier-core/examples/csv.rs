//! Feeds a gyro log to the refined identifier on the host and prints its estimate.
//!
//! ```sh
//! cargo run -p identifier-core --example csv [NOISE_STD] < gyro.csv
//! ```
//!
//! Input: CSV on standard input, one sample per line, `t,wx,wy,wz` (seconds, rad/s in the body
//! axes). A header line and lines starting with `#` are skipped. `NOISE_STD` is the gyro's
//! noise per sample in rad/s (default 2e-3); it only sets the weight of the prior.
//!
//! Output: the estimate of `a = (a1, a2, a3)`, the inertia ratios it implies, the consistency
//! value (zero for a rigid body), the convergence criterion and what happened to the samples.
//! The exit code is 1 on unreadable input.

use std::io::{self, BufRead};
use std::process::ExitCode;

use identifier_core::{consistency, Refined, RefinedSettings, SampleStatus};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("csv: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let mut settings = RefinedSettings::new();
    if let Some(arg) = std::env::args().nth(1) {
        settings.noise_std = arg
            .parse()
            .map_err(|_| format!("NOISE_STD must be a number of rad/s, got {arg:?}"))?;
    }
    let mut refined = Refined::new(settings).ok_or("invalid settings (NOISE_STD > 0?)")?;

    let mut last_t: Option<f64> = None;
    let (mut rows, mut rejected) = (0u64, 0u64);
    let mut last_step = None;
    for (n, line) in io::stdin().lock().lines().enumerate() {
        let line = line.map_err(|e| format!("reading standard input: {e}"))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || (n == 0 && line.starts_with('t')) {
            continue;
        }
        let fields: Vec<f64> = line
            .split(',')
            .map(|f| f.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("line {}: expected t,wx,wy,wz numbers, got {line:?}", n + 1))?;
        let [t, wx, wy, wz] = fields[..] else {
            return Err(format!(
                "line {}: expected 4 fields, got {}",
                n + 1,
                fields.len()
            ));
        };
        // The first sample only anchors the integral: any positive dt will do (zero would be
        // rejected as an invalid time step).
        let dt = last_t.map_or(1e-3, |t0| t - t0);
        last_t = Some(t);
        let step = refined.step([wx as f32, wy as f32, wz as f32], dt as f32);
        rows += 1;
        if !step.status.integrated() && step.status != SampleStatus::Anchored {
            rejected += 1;
        }
        last_step = Some(step);
    }
    let step = last_step.ok_or("no samples on standard input")?;

    let a = refined.estimate();
    println!("samples: {rows} ({rejected} not integrated)");
    println!("a = {:.6} {:.6} {:.6}", a[0], a[1], a[2]);
    match identifier_core::InertiaRatios::from_a(a) {
        Some(r) => println!("A2/A1 = {:.4}, A3/A1 = {:.4}", r.a2_over_a1, r.a3_over_a1),
        None => println!("A2/A1, A3/A1: none (no finite body has this a)"),
    }
    println!("consistency a1+a2+a3+a1*a2*a3 = {:.2e}", consistency(a));
    println!("convergence: {:?}", step.convergence);
    println!("counters: {:?}", refined.counters());
    Ok(())
}
