//! Line charts written as SVG: the close-loop report (`residual.svg`, `estimates.svg`) and the
//! repository's figures (`host-tests` re-exports this module).

use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::Path;

/// One named line.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// `(x, y)` points; non-finite points are dropped.
    pub points: Vec<(f64, f64)>,
}

/// A chart: title, axis labels, optional fixed y range, and its series.
pub struct Chart<'a> {
    /// Caption above the plot.
    pub title: &'a str,
    /// X axis label.
    pub x_label: &'a str,
    /// Y axis label.
    pub y_label: &'a str,
    /// Fixed y range; `None` fits the data.
    pub y_range: Option<(f64, f64)>,
    /// The lines, drawn in order.
    pub series: Vec<Series>,
}

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(0, 0, 0),
];

/// A residual's time (s) and its value per axis before and after the effects (kg m^2/s).
pub type Residual = (f64, [f64; 3], [f64; 3]);

/// `residuals.svg` in `dir`: one chart per axis of the residual of `equation` (a block's Euler
/// equation, kg m^2/s) before and after the effects were added, from `(t, before, after)`.
pub fn write_residuals(
    dir: &Path,
    title: &str,
    equation: &str,
    residuals: &[Residual],
) -> Result<()> {
    let titles: Vec<String> = ["x", "y", "z"]
        .iter()
        .map(|a| format!("{title}: residual of {equation}, {a} row, before and after"))
        .collect();
    let line = |name: &str, pick: &dyn Fn(&Residual) -> (f64, f64)| Series {
        name: name.into(),
        points: residuals.iter().map(pick).collect(),
    };
    let charts: Vec<Chart> = (0..3)
        .map(|k| Chart {
            title: &titles[k],
            x_label: "t (s)",
            y_label: "1e-6 kg m^2/s",
            y_range: None,
            series: vec![
                line("tensor alone", &|(t, b, _)| (*t, 1e6 * b[k])),
                line("with the effects added", &|(t, _, a)| (*t, 1e6 * a[k])),
            ],
        })
        .collect();
    write_svg(&dir.join("residuals.svg"), &charts)
}

/// Draws the charts stacked vertically into one SVG file at `path`.
pub fn write_svg(path: &Path, charts: &[Chart]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let height = 320 * charts.len().max(1) as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((charts.len().max(1), 1));
    for (chart, area) in charts.iter().zip(areas.iter()) {
        draw(chart, area)?;
    }
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

fn draw<DB: DrawingBackend>(
    chart: &Chart,
    area: &DrawingArea<DB, plotters::coord::Shift>,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let pts = || {
        chart
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let (mut x0, mut x1) = pts().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (mut y0, mut y1) = chart
        .y_range
        .unwrap_or_else(|| pts().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1))));
    if x0 >= x1 {
        x0 -= 1.0;
        x1 += 1.0;
    }
    if y0 >= y1 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let mut ctx = ChartBuilder::on(area)
        .caption(chart.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    ctx.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    for (i, s) in chart.series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let clipped: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| (x, y.clamp(y0, y1)))
            .collect();
        ctx.draw_series(LineSeries::new(clipped, color.stroke_width(2)))
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
