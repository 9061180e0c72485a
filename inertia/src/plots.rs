//! Plots written by `inertia identify --plots DIR`: the gyro rates over the log with the free
//! flights that reached the estimator shaded, and the pooled tensor's principal axes and
//! equimomental ellipsoid. The rates come from [`Trace`]: every `step`-th
//! sample, kept while the log was read (the log is never held whole). And by `inertia
//! calibrate --plots DIR`: each throw's diagonal of the tensor against its group's mean, with
//! the standard deviations the throws reported ([`calibrate_plot`]).
use std::path::Path;

use plotters::prelude::*;

use crate::calibrate::CalibrationReport;
use crate::identify::{Report, Trace};

/// Writes `DIR/rates.svg` and, when the pooled estimate has principal axes, `DIR/axes.svg`
/// ([`tensor_axes_plot`]).
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
    let p = &report.pooled;
    if let (Some(m), Some(ax)) = (p.principal_moments, p.principal_axes) {
        let unit = if p.tensor_kg_m2.is_some() {
            "kg m^2"
        } else {
            "(J / trace J)"
        };
        tensor_axes_plot(
            m.map(f64::from),
            ax.map(|r| r.map(f64::from)),
            unit,
            &format!(
                "pooled tensor ({}, {}): equimomental ellipsoid, principal axes",
                p.tensor_status, p.tensor_method
            ),
            &dir.join("axes.svg"),
        )?;
    }
    Ok(())
}

/// Writes `DIR/throws.svg`: for every throw of `calibrate` (board, assembly, object, in
/// order), the deviation of `Jxx`, `Jyy`, `Jzz` (log frame) from its group's mean in percent,
/// with the throw's reported standard deviation as an error bar. Where the bars cover the
/// scatter, the reported uncertainty is honest; the board and assembly groups are the
/// calibration's evidence.
///
/// Also `DIR/board_axes.svg` and, with an object, `DIR/object_axes.svg`: their tensors as
/// [`tensor_axes_plot`] draws them.
pub fn calibrate_plot(rep: &CalibrationReport, dir: &Path) -> anyhow::Result<()> {
    let (m, ax) = crate::calibrate::eigen(&rep.board_tensor_kg_m2);
    tensor_axes_plot(
        m,
        ax,
        "kg m^2",
        "the board (calibrated): equimomental ellipsoid, principal axes",
        &dir.join("board_axes.svg"),
    )?;
    if let (Some(m), Some(ax)) = (
        rep.object_principal_moments_kg_m2,
        rep.object_principal_axes,
    ) {
        tensor_axes_plot(
            m,
            ax,
            "kg m^2",
            "the object (by difference): equimomental ellipsoid, principal axes",
            &dir.join("object_axes.svg"),
        )?;
    }
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
        // The group's mean tensor, as the calibration takes it.
        let (group_mean, _) = crate::calibrate::mean(throws);
        for k in 0..3 {
            let mean = group_mean[k][k];
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

/// Writes `path`: a rigid body's tensor as a picture, in the log's gyro axes. Drawn: the
/// equimomental ellipsoid (the uniform solid ellipsoid with the same principal moments and
/// axes, so the shape a reader would expect of the body: semi-axis along principal axis `i`
/// proportional to `sqrt(I_j + I_k - I_i)`), scaled so its longest semi-axis is 1; each
/// principal axis `v_i` in its colour, labelled with its moment; the gyro's x, y, z in grey.
/// `moments` ascending, `axes` one unit vector (row) per moment. The picture is up to scale
/// (the moments are in the labels): it shows which way the body is long and how its
/// principal axes sit against the sensor's.
///
/// Returns `Ok(false)` and writes nothing when there is no shape to draw (non-finite moments, or
/// a tensor whose equimomental ellipsoid has no positive semi-axis): the JSON still says what
/// was estimated, and the other plots are still written.
pub fn tensor_axes_plot(
    moments: [f64; 3],
    axes: [[f64; 3]; 3],
    unit: &str,
    title: &str,
    path: &Path,
) -> anyhow::Result<bool> {
    // Semi-axes of the equimomental ellipsoid (a physically impossible tensor, which has a
    // negative one, is drawn flat along that axis).
    let sum: f64 = moments.iter().sum();
    let mut semi = moments.map(|m| (sum - 2.0 * m).max(0.0).sqrt());
    let longest = semi.iter().cloned().fold(0.0f64, f64::max);
    let finite = moments
        .iter()
        .chain(axes.iter().flatten())
        .all(|x| x.is_finite());
    if !(finite && longest.is_finite() && longest > 0.0) {
        return Ok(false);
    }
    semi = semi.map(|s| s / longest);
    // The backend writes its file when dropped, so it is made only once there is a shape.
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let root = SVGBackend::new(path, (800, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    // Sensor (x, y, z) drawn as plot (x, z, y): the sensor's z up.
    let to_plot = |p: [f64; 3]| (p[0], p[2], p[1]);
    let point = |u: f64, v: f64| {
        // Unit sphere at longitude u, latitude v, stretched along the principal axes.
        let e = [v.cos() * u.cos(), v.cos() * u.sin(), v.sin()];
        let mut p = [0.0; 3];
        for (k, ax) in axes.iter().enumerate() {
            for c in 0..3 {
                p[c] += semi[k] * e[k] * ax[c];
            }
        }
        to_plot(p)
    };
    let lim = 1.45;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 17))
        .margin(10)
        .build_cartesian_3d(-lim..lim, -lim..lim, -lim..lim)?;
    chart.with_projection(|mut p| {
        p.yaw = 0.6;
        p.pitch = 0.35;
        p.scale = 1.0;
        p.into_matrix()
    });
    let grey = RGBColor(150, 150, 150);
    let n = 48;
    let tau = std::f64::consts::TAU;
    // Parallels and meridians of the ellipsoid.
    for i in 1..8 {
        let v = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * i as f64 / 8.0;
        chart.draw_series(LineSeries::new(
            (0..=n).map(|k| point(tau * k as f64 / n as f64, v)),
            RGBColor(120, 120, 200).mix(0.5),
        ))?;
    }
    for i in 0..12 {
        let u = tau * i as f64 / 12.0;
        chart.draw_series(LineSeries::new(
            (0..=n).map(|k| {
                point(
                    u,
                    -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / n as f64,
                )
            }),
            RGBColor(120, 120, 200).mix(0.5),
        ))?;
    }
    // The gyro's axes.
    for (c, name) in ["x", "y", "z"].iter().enumerate() {
        let mut e = [0.0; 3];
        e[c] = 1.35;
        chart.draw_series(LineSeries::new(
            [to_plot([0.0; 3]), to_plot(e)],
            grey.stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("gyro {name}"),
            to_plot(e),
            ("sans-serif", 14).into_font().color(&grey),
        )))?;
    }
    // The principal axes, both ways, labelled with their moments.
    for (k, color) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
        let a = axes[k];
        let len = 1.2;
        let tip = [a[0] * len, a[1] * len, a[2] * len];
        let tail = tip.map(|x| -x);
        chart
            .draw_series(LineSeries::new(
                [to_plot(tail), to_plot(tip)],
                color.stroke_width(3),
            ))?
            .label(format!(
                "I{} = {:.4e} {unit} along ({:+.3}, {:+.3}, {:+.3})",
                k + 1,
                moments[k],
                a[0],
                a[1],
                a[2]
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 15, y)], color.stroke_width(3))
            });
        chart.draw_series(std::iter::once(Text::new(
            format!("I{}", k + 1),
            to_plot(tip),
            ("sans-serif", 15).into_font().color(&color),
        )))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    const E: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    /// A body is drawn; nothing to draw is not an error (the JSON says what was estimated).
    #[test]
    fn a_tensor_is_drawn_and_a_degenerate_one_skipped() {
        let dir = std::env::temp_dir().join(format!("axes-plot-{}", std::process::id()));
        let path = dir.join("axes.svg");
        let drawn = tensor_axes_plot([1.0, 2.0, 2.5], E, "kg m^2", "t", &path).unwrap();
        assert!(drawn && std::fs::metadata(&path).unwrap().len() > 1000);
        let skipped = dir.join("none.svg");
        for m in [[f64::NAN, 1.0, 1.0], [0.0, 0.0, 0.0], [-1.0, -1.0, -1.0]] {
            assert!(!tensor_axes_plot(m, E, "", "t", &skipped).unwrap());
            assert!(!skipped.exists());
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
