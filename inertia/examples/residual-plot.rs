//! One throw's rate residual under the tensor `inertia identify` reports, two ways, as a
//! picture: one trajectory from one initial rate through the whole flight ((F1) of
//! `identifier_core::tensor_fit`), and the trajectory restarted every segment from its own
//! initial rate (multiple shooting, (F11)). The tensor is held at the reported one; each
//! initial rate is fitted to the gyro by least squares. What a model error does to a single
//! trajectory (it accumulates along the flight) against what it does to short segments (it
//! stays within one) is what the picture shows; the residual is drawn as 5 ms means, its slow
//! part, with the flywheel's vibration averaged out.
//!
//! Usage: `cargo run --release -p inertia --example residual-plot -- LOG OUT.svg
//! [--rotor-inertia KG_M2] [--rotor-poles N] [--segment-ms MS]` (a flywheel on -z, as on the
//! thrown flight-controller rig; defaults: the anchor's 1.689e-6 kg m^2, 14 poles, 40 ms).
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use inertia::identify::{identify, IdentifyOptions, Rotor, RotorHold};
use inertia::RotorSpeed;

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

/// Width of the means the residual is drawn as, s.
const MEAN_S: f64 = 0.005;

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn mul(m: &M3, v: V3) -> V3 {
    std::array::from_fn(|i| (0..3).map(|k| m[i][k] * v[k]).sum())
}

fn inverse(m: &M3) -> Option<M3> {
    let c = |i: usize, j: usize| {
        let (a, b) = ((i + 1) % 3, (i + 2) % 3);
        let (p, q) = ((j + 1) % 3, (j + 2) % 3);
        m[a][p] * m[b][q] - m[a][q] * m[b][p]
    };
    let det: f64 = (0..3).map(|j| m[0][j] * c(0, j)).sum();
    (det.abs() > 0.0).then(|| std::array::from_fn(|i| std::array::from_fn(|j| c(j, i) / det)))
}

/// The flight's samples: time, rate (bias removed) and rotor momentum.
struct Flight {
    t: Vec<f64>,
    w: Vec<V3>,
    h: Vec<V3>,
}

/// The body's rates from `w0` at sample `lo` through sample `hi - 1`: Euler's equation in
/// momentum form, `L' = -w x L`, `w = J^-1 (L - h)` (the known momentum `h` linear between
/// samples), by fourth-order Runge-Kutta on the samples' steps.
fn trajectory(f: &Flight, j: &M3, ji: &M3, lo: usize, hi: usize, w0: V3) -> Vec<V3> {
    let rate = |l: V3, h: V3| mul(ji, std::array::from_fn(|k| l[k] - h[k]));
    let deriv = |l: V3, h: V3| {
        let w = rate(l, h);
        let c = cross(w, l);
        [-c[0], -c[1], -c[2]]
    };
    let jw = mul(j, w0);
    let mut l: V3 = std::array::from_fn(|k| jw[k] + f.h[lo][k]);
    let mut out = vec![w0];
    for i in lo + 1..hi {
        let dt = f.t[i] - f.t[i - 1];
        let (h0, h1) = (f.h[i - 1], f.h[i]);
        let hm: V3 = std::array::from_fn(|k| 0.5 * (h0[k] + h1[k]));
        let add = |a: V3, b: V3, s: f64| -> V3 { std::array::from_fn(|k| a[k] + s * b[k]) };
        let k1 = deriv(l, h0);
        let k2 = deriv(add(l, k1, dt / 2.0), hm);
        let k3 = deriv(add(l, k2, dt / 2.0), hm);
        let k4 = deriv(add(l, k3, dt), h1);
        l = std::array::from_fn(|k| l[k] + dt / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]));
        out.push(rate(l, h1));
    }
    out
}

/// The residual `y - w` of samples `lo..hi` with the initial rate fitted to them
/// (Gauss-Newton, its Jacobian by finite differences).
fn fitted_residual(f: &Flight, j: &M3, ji: &M3, lo: usize, hi: usize) -> Vec<V3> {
    let res = |w0: V3| -> Vec<V3> {
        trajectory(f, j, ji, lo, hi, w0)
            .iter()
            .zip(&f.w[lo..hi])
            .map(|(m, y)| std::array::from_fn(|k| y[k] - m[k]))
            .collect()
    };
    let mut w0 = f.w[lo];
    let d = 1e-6;
    for _ in 0..10 {
        let r = res(w0);
        // Columns of the Jacobian d(residual)/d(w0_c), one per component of w0.
        let jac: Vec<Vec<V3>> = (0..3)
            .map(|c| {
                let mut p = w0;
                p[c] += d;
                res(p)
                    .iter()
                    .zip(&r)
                    .map(|(x, y)| std::array::from_fn(|k| (x[k] - y[k]) / d))
                    .collect()
            })
            .collect();
        let dot = |a: &[V3], b: &[V3]| -> f64 {
            a.iter()
                .zip(b)
                .map(|(x, y)| (0..3).map(|k| x[k] * y[k]).sum::<f64>())
                .sum()
        };
        let a: M3 = std::array::from_fn(|c| std::array::from_fn(|c2| dot(&jac[c], &jac[c2])));
        let g: V3 = std::array::from_fn(|c| dot(&jac[c], &r));
        let Some(ai) = inverse(&a) else { break };
        let step = mul(&ai, g);
        for k in 0..3 {
            w0[k] -= step[k];
        }
        if step.iter().map(|s| s.abs()).fold(0.0, f64::max) < 1e-9 {
            break;
        }
    }
    res(w0)
}

/// `MEAN_S` means of the residual: (time, mean) per full window.
fn means(t: &[f64], r: &[V3]) -> Vec<(f64, V3)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < t.len() {
        let mut k = i;
        while k < t.len() && t[k] - t[i] < MEAN_S {
            k += 1;
        }
        let n = (k - i) as f64;
        let m: V3 = std::array::from_fn(|a| r[i..k].iter().map(|v| v[a]).sum::<f64>() / n);
        out.push((0.5 * (t[i] + t[k - 1]), m));
        i = k;
    }
    out
}

fn rms(v: &[V3]) -> f64 {
    let s: f64 = v.iter().map(|x| x.iter().map(|c| c * c).sum::<f64>()).sum();
    (s / (3 * v.len().max(1)) as f64).sqrt()
}

fn arg(argv: &[String], name: &str) -> Option<f64> {
    argv.iter()
        .position(|a| a == name)
        .and_then(|i| argv.get(i + 1))
        .and_then(|v| v.parse().ok())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let argv: Vec<String> = std::env::args().collect();
    let (Some(log), Some(out)) = (argv.get(1), argv.get(2)) else {
        eprintln!(
            "usage: residual-plot LOG OUT.svg [--rotor-inertia KG_M2] [--rotor-poles N] [--segment-ms MS]"
        );
        std::process::exit(2);
    };
    let jr = arg(&argv, "--rotor-inertia").unwrap_or(1.689e-6);
    let poles = arg(&argv, "--rotor-poles").unwrap_or(14.0);
    let seg_s = arg(&argv, "--segment-ms").unwrap_or(40.0) * 1e-3;
    let rec = inertia::read(Path::new(log), &Default::default())?;
    let opts = IdentifyOptions {
        rotor: Some(Rotor {
            inertia: jr as f32,
            axis: [0.0, 0.0, -1.0],
            poles: Some(poles as u32),
        }),
        vehicle: None,
        segments: None,
        noise_std: None,
        rotor_hold: RotorHold::Auto,
        trace: false,
    };
    let rep = identify(&rec, &opts)?;
    let p = &rep.pooled;
    let j: M3 = p
        .tensor_kg_m2
        .ok_or("no tensor in kg m^2")?
        .map(|r| r.map(f64::from));
    let ji = inverse(&j).ok_or("singular tensor")?;
    let speed = |i: usize| -> f64 {
        match &rec.rotor {
            Some(RotorSpeed::Erpm(v)) => {
                f64::from(v[i]) / (poles / 2.0) * std::f64::consts::TAU / 60.0
            }
            Some(RotorSpeed::RadPerSec(v)) => f64::from(v[i]),
            None => 0.0,
        }
    };
    let bias = rep.gyro_bias.map(f64::from);
    let idx: Vec<usize> = (0..rec.len())
        .filter(|&i| rec.t[i] >= p.start_s && rec.t[i] <= p.end_s)
        .collect();
    let flight = Flight {
        t: idx.iter().map(|&i| rec.t[i]).collect(),
        w: idx
            .iter()
            .map(|&i| std::array::from_fn(|k| f64::from(rec.gyro[i][k]) - bias[k]))
            .collect(),
        h: idx.iter().map(|&i| [0.0, 0.0, -jr * speed(i)]).collect(),
    };
    let n = flight.t.len();
    if n < 10 {
        return Err("too few samples in the flight".into());
    }
    let single = fitted_residual(&flight, &j, &ji, 0, n);
    let mut shot = Vec::with_capacity(n);
    let mut lo = 0;
    while lo < n {
        let mut hi = lo;
        while hi < n && flight.t[hi] - flight.t[lo] < seg_s {
            hi += 1;
        }
        // A last piece shorter than half a segment joins the one before it.
        if n - hi < 4 || flight.t[n - 1] - flight.t[hi.min(n - 1)] < seg_s / 2.0 {
            hi = n;
        }
        shot.extend(fitted_residual(&flight, &j, &ji, lo, hi));
        lo = hi;
    }
    let (ms, mm) = (means(&flight.t, &single), means(&flight.t, &shot));
    let slow = |m: &[(f64, V3)]| rms(&m.iter().map(|x| x.1).collect::<Vec<_>>());
    println!(
        "{log}: {} samples, {:.3}-{:.3} s, tensor {} ({})",
        n, p.start_s, p.end_s, p.tensor_status, p.tensor_method
    );
    println!(
        "one trajectory: residual RMS {:.1} mrad/s, its {:.0} ms means {:.1} mrad/s",
        rms(&single) * 1e3,
        MEAN_S * 1e3,
        slow(&ms) * 1e3
    );
    println!(
        "segments of {:.0} ms: residual RMS {:.1} mrad/s, its {:.0} ms means {:.1} mrad/s",
        seg_s * 1e3,
        rms(&shot) * 1e3,
        MEAN_S * 1e3,
        slow(&mm) * 1e3
    );
    draw(Path::new(out), &ms, &mm, seg_s, log)?;
    println!("plot: {out}");
    Ok(())
}

fn draw(
    path: &Path,
    single: &[(f64, V3)],
    shot: &[(f64, V3)],
    seg_s: f64,
    log: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let t0 = single.first().map_or(0.0, |x| x.0);
    let t1 = single.last().map_or(1.0, |x| x.0);
    let ymax = single
        .iter()
        .chain(shot)
        .flat_map(|x| x.1)
        .fold(1e-3f64, |a, v| a.max(v.abs()))
        * 1e3
        * 1.1;
    let root = SVGBackend::new(path, (1000, 620)).into_drawing_area();
    root.fill(&WHITE)?;
    let name = PathBuf::from(log)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let panels = root.split_evenly((2, 1));
    let titles = [
        format!("{name}: one trajectory through the flight (5 ms means of gyro - model)"),
        format!(
            "{name}: restarted every {:.0} ms, multiple shooting (5 ms means)",
            seg_s * 1e3
        ),
    ];
    for ((area, series), title) in panels.iter().zip([single, shot]).zip(titles) {
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d((0.0)..(t1 - t0), -ymax..ymax)?;
        chart
            .configure_mesh()
            .x_desc("time in flight (s)")
            .y_desc("mrad/s")
            .draw()?;
        for (k, color) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
            chart
                .draw_series(LineSeries::new(
                    series.iter().map(|&(t, r)| (t - t0, r[k] * 1e3)),
                    color,
                ))?
                .label(["x", "y", "z"][k])
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], color));
        }
        chart.configure_series_labels().border_style(BLACK).draw()?;
    }
    root.present()?;
    Ok(())
}
