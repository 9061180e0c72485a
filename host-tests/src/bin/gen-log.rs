//! Writes the gyro log the QEMU firmware replays, and the host reference the firmware must
//! reproduce.
//!
//! The body is the paper's, `A = (0.6, 1.54, 1.0)`, spun up at `omega0 = (1, 1, 1)` rad/s,
//! simulated in f64 (RK4) and measured by an aligned gyro with white noise. The log holds
//! those readings as f32 rad/s (`firmware::log_format`).
//!
//! The reference runs the firmware's own [`firmware::SampleLoop`] over the same simulated
//! ICM-42688-P (`icm42688::sim`) fed from the same f32 values, with the same injected bus
//! errors: int16 quantisation at the configured full scale, the driver's conversion, one
//! step of each identifier (the paper's and the refined one) per sample with the ODR period as
//! `dt`. Only the sample source differs (memory here, semihosting file reads on the MCU), so
//! the firmware's final estimates must equal the reference bit for bit: both are IEEE-754 binary32 with round-to-nearest and
//! no fused or reordered operations (Rust does not contract `a * b + c`), and identifier-core
//! uses only `+ - * /`, `abs`, `min`, `max` and comparisons, which are exact the same way on
//! the host's SSE and the Cortex-M4F's FPv4 (and QEMU's soft-float model of it).
//!
//! Output (`--reference`): `key=value` lines read by `scripts/firmware-e2e.sh`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use anyhow::{ensure, Context, Result};
use clap::Parser;
use firmware::log_format::{encode_sample, Header};
use firmware::{NoDelay, Poll, Report, SampleLoop};
use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use icm42688::sim::SimIcm42688;
use icm42688::{Config, Icm42688};

#[derive(Parser)]
#[command(
    about = "Gyro log of a simulated spinning body for the QEMU firmware, plus the host reference"
)]
struct Args {
    /// Log file to write.
    #[arg(long, default_value = "target/firmware-e2e/gyro.log")]
    out: PathBuf,
    /// Every 10 Hz report's two estimates, one `a1 a2 a3 b1 b2 b3` line each (`a` the paper's
    /// identifier, `b` the refined one; Rust's shortest round-trip formatting of the f32
    /// values, as defmt-print prints them), then the final report's.
    #[arg(long, default_value = "target/firmware-e2e/reports.txt")]
    reports: PathBuf,
    /// Reference (key=value lines) to write.
    #[arg(long, default_value = "target/firmware-e2e/reference.txt")]
    reference: PathBuf,
    /// Seconds of motion.
    #[arg(long, default_value_t = 20.0)]
    duration: f64,
    /// Gyro white noise, rad/s per sample.
    #[arg(long, default_value_t = 1e-3)]
    noise: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Inject a bus error every n SPI transfers in the simulated part (0: none). The QEMU
    /// run must be given the same value.
    #[arg(long, default_value_t = 0)]
    bus_error_every: u32,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let config = Config::identifier();
    let rate = f64::from(config.odr.hz());
    let body = Body::free([0.6, 1.54, 1.0]);
    let truth = body.a();
    let trajectory = body.simulate([1.0, 1.0, 1.0], args.duration, rate, 10);
    let readings = GyroModel::noisy(args.noise, args.seed).measure(&trajectory);
    let samples: Vec<[f32; 3]> = readings.iter().map(|w| w.map(|x| x as f32)).collect();

    for p in [&args.out, &args.reference, &args.reports] {
        if let Some(dir) = p.parent() {
            std::fs::create_dir_all(dir)?;
        }
    }
    let mut log = BufWriter::new(File::create(&args.out).context("creating the log")?);
    let header = Header {
        rate_hz: rate as f32,
        samples: u32::try_from(samples.len())?,
    };
    log.write_all(&header.encode())?;
    for w in &samples {
        log.write_all(&encode_sample(*w))?;
    }
    log.flush()?;

    // The reference: the firmware's loop on the host.
    let mut source = samples.clone().into_iter();
    let sim = SimIcm42688::new(move || source.next()).with_bus_error_every(args.bus_error_every);
    // The simulated part's clock, as on QEMU: its latched samples times the period.
    let period_us = config.odr.period_us();
    let clock = move |i: &icm42688::SpiInterface<SimIcm42688<_>>| {
        i.bus().stats().samples.wrapping_mul(period_us)
    };
    let mut app = SampleLoop::new(Icm42688::new_spi(sim), &mut NoDelay, config, clock)
        .map_err(|e| anyhow::anyhow!("gyro init on the simulated part failed: {e:?}"))?;
    let mut reports = 0u32;
    let mut stream = BufWriter::new(File::create(&args.reports)?);
    while !app.gyro().interface().bus().exhausted() {
        if let Poll::Stepped {
            report: Some(r), ..
        } = app.poll(&mut NoDelay)
        {
            reports += 1;
            write_report(&mut stream, &r)?;
        }
    }
    let r = app.report();
    write_report(&mut stream, &r)?;
    stream.flush()?;
    let c = app.counters();
    ensure!(c.samples > 0, "no sample reached the identifier");

    let mut out = BufWriter::new(File::create(&args.reference)?);
    let (a, b) = (r.a_paper, r.a_refined);
    writeln!(out, "samples_in_log={}", samples.len())?;
    for (key, x) in [("paper", a), ("refined", b)] {
        writeln!(out, "a_{key}={},{},{}", x[0], x[1], x[2])?;
        writeln!(
            out,
            "bits_{key}={:#010x},{:#010x},{:#010x}",
            x[0].to_bits(),
            x[1].to_bits(),
            x[2].to_bits()
        )?;
    }
    writeln!(out, "truth={},{},{}", truth[0], truth[1], truth[2])?;
    writeln!(
        out,
        "truth_ratios={},{}",
        body.inertia[1] / body.inertia[0],
        body.inertia[2] / body.inertia[0]
    )?;
    writeln!(out, "samples={}", c.samples)?;
    writeln!(out, "skipped={}", c.skipped)?;
    writeln!(out, "bus_errors={}", c.bus_errors)?;
    writeln!(out, "reports={reports}")?;
    writeln!(out, "convergence_paper={:?}", r.convergence_paper)?;
    writeln!(out, "convergence_refined={:?}", r.convergence_refined)?;
    out.flush()?;

    let err = |x: [f32; 3]| {
        (0..3)
            .map(|i| (f64::from(x[i]) - truth[i]).abs())
            .fold(0.0, f64::max)
    };
    println!(
        "wrote {} ({} samples at {rate} Hz, noise {} rad/s, seed {}) and {}",
        args.out.display(),
        samples.len(),
        args.noise,
        args.seed,
        args.reference.display()
    );
    println!(
        "host reference: truth [{:.6}, {:.6}, {:.6}]; samples {} skipped {} bus errors {}",
        truth[0], truth[1], truth[2], c.samples, c.skipped, c.bus_errors
    );
    for (name, x, conv) in [
        ("paper  ", a, r.convergence_paper),
        ("refined", b, r.convergence_refined),
    ] {
        println!(
            "  {name} a = [{:.6}, {:.6}, {:.6}], max error {:.2e}, {conv:?}",
            x[0],
            x[1],
            x[2],
            err(x)
        );
    }
    Ok(())
}

/// One line of the reports file: the paper's estimate, then the refined one.
fn write_report(w: &mut impl Write, r: &Report) -> std::io::Result<()> {
    let (a, b) = (r.a_paper, r.a_refined);
    writeln!(w, "{} {} {} {} {} {}", a[0], a[1], a[2], b[0], b[1], b[2])
}
