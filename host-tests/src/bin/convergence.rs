//! Writes docs/convergence.svg: all three estimates against time on the paper's body with a
//! noisy gyro (white noise 2e-3 rad/s per sample at 1 kHz), lambda = 3, and their errors.
//!
//! Usage: `cargo run --release -p host-tests --bin convergence -- [OUT.svg]`.

use host_tests::gyro::GyroModel;
use host_tests::plot::{write_svg, Chart, Series};
use host_tests::{paper, replay};
use identifier_core::Settings;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("docs/convergence.svg"));
    let body = paper::body();
    let a = body.a();
    let tr = body.simulate(paper::OMEGA0, 20.0, 1000.0, 4);
    let noise = 2e-3;
    let meas = GyroModel::noisy(noise, 1).measure(&tr);
    let run = replay::run(Settings::with_lambda(3.0), &tr.t, &meas);
    let names = ["a1", "a2", "a3"];
    let mut est = Vec::new();
    let mut err = Vec::new();
    for i in 0..3 {
        let pts = |f: &dyn Fn(f64) -> f64| -> Vec<(f64, f64)> {
            run.t
                .iter()
                .zip(&run.estimates)
                .step_by(5)
                .map(|(t, e)| (*t, f(f64::from(e.a[i]))))
                .collect()
        };
        est.push(Series {
            name: format!("{} (true {:+.4})", names[i], a[i]),
            points: pts(&|x| x),
        });
        err.push(Series {
            name: format!("log10 |{} error|", names[i]),
            points: pts(&|x| (x - a[i]).abs().max(1e-9).log10()),
        });
    }
    for i in 0..3 {
        let tail: Vec<f64> = run
            .t
            .iter()
            .zip(&run.estimates)
            .filter(|(t, _)| **t >= 15.0)
            .map(|(_, e)| f64::from(e.a[i]) - a[i])
            .collect();
        let rms = (tail.iter().map(|x| x * x).sum::<f64>() / tail.len() as f64).sqrt();
        println!(
            "{}: true {:+.5}, final {:+.5}, RMS error over t in [15, 20] s: {rms:.2e}",
            names[i],
            a[i],
            run.final_a()[i]
        );
    }
    write_svg(
        &out,
        &[
            Chart {
                title: "Estimates, paper's body, omega0 = (1,1,1) rad/s, 1 kHz, noise 2e-3 rad/s, lambda = 3",
                x_label: "t, s",
                y_label: "a",
                y_range: Some((-1.2, 1.2)),
                series: est,
            },
            Chart {
                title: "Error",
                x_label: "t, s",
                y_label: "log10 |error|",
                y_range: Some((-6.0, 0.5)),
                series: err,
            },
        ],
    )?;
    println!("wrote {}", out.display());
    Ok(())
}
