//! Plots written by `inertia identify --plots DIR`: the gyro rates over the log with the free
//! flights that reached the estimator shaded. The rates come from [`Trace`]: every `step`-th
//! sample, kept while the log was read (the log is never held whole). And by `inertia
//! calibrate --plots DIR`: each throw's diagonal of the tensor against its group's mean, with
//! the standard deviations the throws reported ([`calibrate_plot`]).
use std::path::Path;

use plotters::prelude::*;

use crate::calibrate::CalibrationReport;
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

/// Writes `DIR/throws.svg`: for every throw of `calibrate` (board, assembly, object, in
/// order), the deviation of `Jxx`, `Jyy`, `Jzz` (log frame) from its group's mean in percent,
/// with the throw's reported standard deviation as an error bar. Where the bars cover the
/// scatter, the reported uncertainty is honest; the board and assembly groups are the
/// calibration's evidence.
pub fn calibrate_plot(rep: &CalibrationReport, dir: &Path) -> anyhow::Result<()> {
    let groups = rep.throws_per_group;
    std::fs::create_dir_all(dir)?;
    let path = dir.join("throws.svg");
    let root = SVGBackend::new(&path, (1100, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    // (throw index, axis, deviation %, std %).
    let mut points: Vec<(usize, usize, f64, f64)> = Vec::new();
    let mut start = 0usize;
    for &n in &groups {
        let throws = rep.throws.get(start..start + n).unwrap_or(&[]);
        for k in 0..3 {
            let mean = throws.iter().map(|t| t.j1[k][k]).sum::<f64>() / n.max(1) as f64;
            for (i, t) in throws.iter().enumerate() {
                let dev = (t.j1[k][k] / mean - 1.0) * 100.0;
                let sd = t.j1_std.map_or(0.0, |s| s[k][k] / mean * 100.0);
                points.push((start + i, k, dev, sd));
            }
        }
        start += n;
    }
    let ymax = points
        .iter()
        .map(|p| p.2.abs() + p.3)
        .fold(1.0f64, f64::max)
        * 1.1;
    let total = start.max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "each throw's Jxx, Jyy, Jzz against its group's mean (board | assembly | object), \
             bars: the throw's reported std",
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.5f64..(total as f64 - 0.5), -ymax..ymax)?;
    // Each throw's log name under its bars (the file name without its extension).
    let names: Vec<String> = rep
        .throws
        .iter()
        .map(|t| {
            let file = t.source.rsplit(['/', '\\']).next().unwrap_or(&t.source);
            file.split('.').next().unwrap_or(file).to_string()
        })
        .collect();
    chart
        .configure_mesh()
        .x_labels(total + 1)
        .x_label_formatter(&|x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .x_desc("throw")
        .y_desc("deviation from the group's mean (%)")
        .draw()?;
    let mut edge = 0usize;
    for &n in &groups[..2] {
        edge += n;
        let x = edge as f64 - 0.5;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(x, -ymax), (x, ymax)],
            BLACK.mix(0.4),
        )))?;
    }
    for (k, color) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
        let off = (k as f64 - 1.0) * 0.15;
        chart
            .draw_series(points.iter().filter(|p| p.1 == k).map(|p| {
                ErrorBar::new_vertical(
                    p.0 as f64 + off,
                    p.2 - p.3,
                    p.2,
                    p.2 + p.3,
                    color.filled(),
                    6,
                )
            }))?
            .label(["Jxx", "Jyy", "Jzz"][k])
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], color));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
