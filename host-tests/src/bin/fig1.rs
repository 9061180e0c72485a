//! Writes the paper's Fig. 1 scenario as an SVG: the estimate of a1 = 0.9 against time for
//! lambda = 0.5 and lambda = 3.0, with and without the sign-change correction.
//!
//! Usage: `cargo run --release -p host-tests --bin fig1 -- [OUT.svg]` (default `docs/fig1.svg`).

use host_tests::paper;
use host_tests::plot::{write_svg, Chart, Series};
use identifier_core::{Convergence, SignChangeCorrection};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("docs/fig1.svg"));
    let a1 = paper::body().a()[0];
    let mut charts = Vec::new();
    for lambda in [0.5f32, 3.0] {
        let mut series = Vec::new();
        for (corr, label) in [
            (
                SignChangeCorrection::Disabled,
                "as in Fig. 1 (no correction)",
            ),
            (
                SignChangeCorrection::Enabled,
                "with the sign-change correction",
            ),
        ] {
            let run = paper::fig1_run(lambda, corr);
            let met = run
                .t
                .iter()
                .zip(&run.estimates)
                .find(|(_, e)| e.convergence == Convergence::Converged)
                .map(|(t, _)| *t);
            println!(
                "lambda={lambda}: {label}: final a1 = {:.6} (true {a1}), criterion (eps={}, h={} s) met at {}",
                run.final_a()[0],
                paper::EPS,
                paper::H,
                met.map_or("never".to_string(), |t| format!("t={t:.3} s")),
            );
            series.push(Series {
                name: format!("a1 estimate, {label}"),
                points: run
                    .t
                    .iter()
                    .zip(&run.estimates)
                    .map(|(t, e)| (*t, f64::from(e.a[0])))
                    .collect(),
            });
        }
        series.push(Series {
            name: "true a1 = 0.9".into(),
            points: vec![(0.0, a1), (paper::DURATION, a1)],
        });
        charts.push((lambda, series));
    }
    let titles: Vec<String> = charts
        .iter()
        .map(|(l, _)| {
            format!("A = (0.6, 1.54, 1.0), omega0 = (1, 1, 1) rad/s, C = -lambda E, lambda = {l}")
        })
        .collect();
    let charts: Vec<Chart> = charts
        .into_iter()
        .zip(&titles)
        .map(|((_, series), title)| Chart {
            title,
            x_label: "t, s",
            y_label: "a1",
            y_range: Some((-6.0, 1.5)),
            series,
        })
        .collect();
    write_svg(&out, &charts)?;
    println!("wrote {}", out.display());
    Ok(())
}
