//! Plots written by `inertia identify --plots DIR`: the gyro rates over the log with the free
//! flights that reached the estimator shaded. The rates come from [`Trace`]: every `step`-th
//! sample, kept while the log was read (the log is never held whole).
use std::path::Path;

use plotters::prelude::*;

use crate::identify::{Report, Trace};

/// Writes `DIR/rates.svg`.
pub fn identify_plots(trace: &Trace, report: &Report, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join("rates.svg");
    let root = SVGBackend::new(&path, (1100, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    let (t0, t1) = trace.span;
    let wmax = trace.rate_max;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "gyro rates; shaded: samples fed to the estimator",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(t0..t1, -(wmax as f64)..(wmax as f64))?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc("rad/s")
        .draw()?;
    for th in &report.throws {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(th.start_s, -(wmax as f64)), (th.end_s, wmax as f64)],
            RGBColor(200, 230, 200).filled(),
        )))?;
    }
    for (k, color) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
        chart
            .draw_series(LineSeries::new(
                trace.points.iter().map(|&(t, w)| (t, w[k] as f64)),
                color,
            ))?
            .label(["wx", "wy", "wz"][k])
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], color));
    }
    chart.configure_series_labels().border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
