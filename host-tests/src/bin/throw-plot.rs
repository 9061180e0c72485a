//! Writes docs/throw-sim.svg: a simulated throw of the anchor board (`board_throw(1)`): gyro
//! axes, accelerometer magnitude and flywheel speed against time, the true free flight shaded.
//!
//! Usage: `cargo run --release -p host-tests --bin throw-plot -- [OUT.svg] [SEED]`.

use anyhow::{anyhow, Context, Result};
use host_tests::throw_sim::{board_throw, SimThrow};
use plotters::prelude::*;
use std::path::PathBuf;

const COLORS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    sim: &SimThrow,
    title: &str,
    y_label: &str,
    series: &[(&str, Vec<f64>)],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x}");
    let x1 = *sim.t.last().unwrap_or(&1.0);
    let (mut y0, mut y1) = series
        .iter()
        .flat_map(|(_, v)| v.iter())
        .fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
    if y0 >= y1 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let mut ctx = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x1, y0..y1)
        .map_err(e)?;
    ctx.configure_mesh()
        .x_desc("t (s)")
        .y_desc(y_label)
        .draw()
        .map_err(e)?;
    if let (Some(r), Some(c)) = (sim.release_s, sim.catch_s) {
        ctx.draw_series(std::iter::once(Rectangle::new(
            [(r, y0), (c, y1)],
            RGBColor(255, 200, 80).mix(0.3).filled(),
        )))
        .map_err(e)?
        .label("true free flight")
        .legend(|(x, y)| {
            Rectangle::new(
                [(x, y - 5), (x + 20, y + 5)],
                RGBColor(255, 200, 80).mix(0.5).filled(),
            )
        });
    }
    for (i, (name, v)) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        // Three samples per point, the largest in magnitude (keeps the impact spike).
        let pts = (0..v.len()).step_by(3).map(|a| {
            let k = (a..(a + 3).min(v.len()))
                .max_by(|&p, &q| v[p].abs().total_cmp(&v[q].abs()))
                .unwrap_or(a);
            (sim.t[k], v[k])
        });
        ctx.draw_series(LineSeries::new(pts, color.stroke_width(1)))
            .map_err(e)?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(e)?;
    Ok(())
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("docs/throw-sim.svg"));
    let seed: u64 = args.next().map_or(Ok(1), |s| s.parse()).context("SEED")?;
    let sim = board_throw(seed);
    if let Some(dir) = out.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)?;
        }
    }
    let root = SVGBackend::new(&out, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| anyhow!("{x}"))?;
    let areas = root.split_evenly((3, 1));
    let axis = |i: usize| sim.gyro.iter().map(|g| f64::from(g[i])).collect::<Vec<_>>();
    panel(
        &areas[0],
        &sim,
        &format!("board_throw({seed}): gyro (clips at +-34.9 rad/s)"),
        "rad/s",
        &[("wx", axis(0)), ("wy", axis(1)), ("wz", axis(2))],
    )?;
    let amag = sim
        .accel
        .iter()
        .map(|a| a.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt())
        .collect();
    panel(
        &areas[1],
        &sim,
        "accelerometer magnitude (1 g on the bench; only rotation about the CoM in free flight)",
        "m/s^2",
        &[("|f|", amag)],
    )?;
    let rotor = sim.rotor_rad_s.iter().map(|&v| f64::from(v)).collect();
    panel(
        &areas[2],
        &sim,
        "flywheel speed (about -z)",
        "rad/s",
        &[("rotor", rotor)],
    )?;
    root.present()
        .with_context(|| format!("writing {}", out.display()))?;
    println!("{}", sim.summary());
    println!("wrote {}", out.display());
    Ok(())
}
