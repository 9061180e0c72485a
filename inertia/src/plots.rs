//! Plots written by `inertia identify --plots DIR`: the gyro rates over the log with the free
//! flights that reached the estimator shaded.
use std::path::Path;

use plotters::prelude::*;

use crate::identify::Report;
use crate::recording::Recording;

/// Writes `DIR/rates.svg`.
pub fn identify_plots(rec: &Recording, report: &Report, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join("rates.svg");
    let root = SVGBackend::new(&path, (1100, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    let (t0, t1) = (rec.t[0], rec.t[rec.len() - 1]);
    let wmax =
        rec.gyro
            .iter()
            .flat_map(|w| w.iter())
            .fold(1.0f32, |m, x| if x.abs() > m { x.abs() } else { m });
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
    let step = (rec.len() / 20000).max(1);
    for (k, color) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
        chart
            .draw_series(LineSeries::new(
                (0..rec.len())
                    .step_by(step)
                    .map(|i| (rec.t[i], rec.gyro[i][k] as f64)),
                color,
            ))?
            .label(["wx", "wy", "wz"][k])
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], color));
    }
    chart.configure_series_labels().border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
