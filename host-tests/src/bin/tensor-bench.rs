//! Tensor estimator against the Cramer-Rao bound of the tensor model on simulated board
//! throws (non-diagonal J, flywheel spin-up, white gyro noise, clipping at +-2000 deg/s):
//! `cargo run --release -p host-tests --bin tensor-bench -- [SEEDS] [off]` (`off`: the logged
//! rotor speed and gyro not quantised).
//!
//! Three paths per seed: the estimator fed the true free flight (the estimator's own quality),
//! the whole log through the shared pipeline (gate, guards, bias) as the firmware runs it, and
//! the output-error fit ([`TensorFit`]) of the true free flight started from the estimator's
//! tensor.
//! Prints per entry: RMS error / CRB, and RMS(error / reported std) (calibration). With
//! `--plot FILE`, writes the pipeline's `|error| / reported std` per entry, sorted, against the
//! quantiles of `|N(0, 1)|` (an honest standard deviation follows the diagonal) as SVG.
use host_tests::crb_tensor::{absolute_bound, FreeFlight};
use host_tests::throw_sim::{board_throw_config, simulate};
use identifier_core::{
    FlightPipeline, PipelineSettings, TensorEstimate, TensorEstimator, TensorFit, TensorSettings,
};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(20);
    // `off`: no quantisation of the logged rotor speed and gyro (the estimator against the
    // bound of its own model); default: quantised as the thrown-FC logs are.
    let quant = if args.iter().any(|a| a == "off") {
        "off"
    } else {
        ""
    };
    let plot = args
        .iter()
        .position(|a| a == "--plot")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);
    // The pipeline's error over its reported std, per entry and seed (for `--plot`).
    let mut zs: [Vec<f64>; 6] = Default::default();
    let names = ["Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"];
    let idx = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
    let mut sq = [[0.0f64; 6]; 3];
    let mut crb = [0.0f64; 6];
    // The bound of the samples the pipeline fed (its guards and gate leave some of the free
    // flight out): the pipeline's efficiency on what it used.
    let mut crb_fed = [0.0f64; 6];
    let mut n_fed = 0usize;
    let mut z2 = [[0.0f64; 6]; 3];
    let mut own2 = [[0.0f64; 6]; 3];
    let mut n = [0usize; 3];
    for seed in 1..=seeds {
        let mut cfg = board_throw_config(seed);
        if quant == "off" {
            cfg.quantize_rotor_speed = false;
            cfg.gyro.quantize = false;
        }
        let sim = simulate(&cfg);
        let Some(range) = sim.free_flight() else {
            continue;
        };
        let sigma = sim.config.gyro.noise_std;
        let Some(ff) = FreeFlight::from_throw(&sim) else {
            continue;
        };
        let Some(b) = absolute_bound(&ff, sigma, false) else {
            continue;
        };
        let rate = sim.config.rate_hz as f32;
        let j_r = sim.config.rotor.inertia as f32;
        let axis = sim.config.rotor.unit_axis().map(|x| x as f32);
        let h = |k: usize| axis.map(|a| a * j_r * sim.rotor_rad_s[k]);
        // The rotor momentum's quantum as `inertia identify` finds it in such a log (the
        // speed's step); 0 when the speed is logged exactly.
        let quantum = if sim.config.quantize_rotor_speed {
            j_r * host_tests::throw_sim::ROTOR_SPEED_QUANTUM_RAD_S as f32
        } else {
            0.0
        };
        let mut ts = TensorSettings::for_rate(rate, sigma as f32);
        ts.full_scale = 34.9;
        let mut e = TensorEstimator::new(ts).unwrap();
        // TRIM_START / TRIM_END (s): the true free flight shortened, to separate the effect of
        // the gate's guards from the rest of the pipeline.
        let trim = |v: &str| -> usize {
            std::env::var(v)
                .ok()
                .and_then(|x| x.parse::<f64>().ok())
                .map(|s| (s / sim.dt()) as usize)
                .unwrap_or(0)
        };
        let (t0, t1) = (trim("TRIM_START"), trim("TRIM_END"));
        let mut fit =
            TensorFit::<256>::new(34.9, ts.max_dt, sigma as f32).with_momentum_resolution(quantum);
        for k in (range.start + t0)..(range.end.saturating_sub(t1)) {
            e.step(sim.gyro[k], h(k), sim.dt() as f32);
            fit.step(sim.gyro[k], h(k), sim.dt() as f32);
        }
        // The output-error fit of the same true flight, from the estimator's tensor.
        let fitted = {
            let base = e.estimate();
            let outcome = fit.close(base.tensor);
            if std::env::var_os("DEBUG_FIT").is_some() {
                if let Some(f) = fit.estimate() {
                    let z: Vec<String> = idx
                        .iter()
                        .enumerate()
                        .map(|(q, &(r, c))| {
                            let sd = f.cov[q][q].max(0.0).sqrt();
                            format!(
                                "{:+.1}",
                                (f.tensor[r][c] as f64 - sim.config.inertia[r][c]) / sd as f64
                            )
                        })
                        .collect();
                    eprintln!(
                        "seed {seed}: {outcome:?} noise/sigma {:.2} z {}",
                        f.noise / sigma as f32,
                        z.join(" ")
                    );
                }
            }
            match fit.estimate() {
                Some(f) => {
                    let t = &f.tensor;
                    let j = [t[0][0], t[1][1], t[2][2], t[0][1], t[0][2], t[1][2]];
                    e.with_tensor(base, j, f.cov, f.noise / sigma as f32, f.coloured)
                }
                None => TensorEstimate {
                    tensor: None,
                    ..base
                },
            }
        };
        let mut ps = PipelineSettings::for_rate(rate, sigma as f32);
        if std::env::var_os("NO_BIAS").is_some() {
            // No still period is recognised: no gyro bias is subtracted.
            ps.gate.still_spread = 1e-12;
        }
        if std::env::var_os("NO_DECIMATION").is_some() {
            // The pipeline without its averaging (the settings at the input rate).
            ps = PipelineSettings::for_rate(1000.0, sigma as f32);
            ps.tensor = identifier_core::TensorSettings::for_rate(rate, sigma as f32);
            ps.refined = identifier_core::RefinedSettings::for_rate(rate, sigma as f32);
            ps.gate = identifier_core::GateSettings::for_rate(rate);
            ps.rate_hz = rate;
            ps.decimation = 1;
        }
        ps.tensor.full_scale = 34.9;
        ps.tensor.momentum_resolution = quantum;
        let mut p = FlightPipeline::new(ps, true).unwrap();
        let mut fed = vec![false; sim.t.len()];
        for k in 0..sim.t.len() {
            if let Some(x) = p.step(sim.gyro[k], sim.accel[k], h(k), sim.dt() as f32) {
                if x.fed.is_some() {
                    let a = x.sample.first_input as usize;
                    for f in fed.iter_mut().skip(a).take(x.sample.inputs as usize) {
                        *f = true;
                    }
                }
            }
        }
        let fed_bound = {
            let mut f = ff.clone();
            f.used = (0..f.n)
                .map(|i| f.used.get(i).copied().unwrap_or(true) && fed[range.start + i])
                .collect();
            absolute_bound(&f, sigma, false)
        };
        // The log ends: the ended flight's fits run (as `inertia identify` does).
        p.end_stretch();
        if let (Some(fb), Some(_)) = (&fed_bound, p.estimate().tensor) {
            n_fed += 1;
            for (q, &(r, c)) in idx.iter().enumerate() {
                crb_fed[q] += fb.std_j[r][c].powi(2);
            }
        }
        for (path, est) in [e.estimate(), p.estimate(), fitted].iter().enumerate() {
            let (Some(t), Some(s)) = (est.tensor, est.tensor_std) else {
                println!(
                    "seed {seed} path {path}: no absolute tensor ({:?})",
                    est.status
                );
                continue;
            };
            n[path] += 1;
            for (q, &(r, c)) in idx.iter().enumerate() {
                let err = t[r][c] as f64 - sim.config.inertia[r][c];
                sq[path][q] += err * err;
                z2[path][q] += (err / s[r][c] as f64).powi(2);
                if path == 1 {
                    zs[q].push(err / s[r][c] as f64);
                }
                own2[path][q] += (err / b.std_j[r][c]).powi(2);
                if path == 0 {
                    crb[q] += b.std_j[r][c].powi(2);
                }
            }
        }
    }
    println!(
        "{} seeds; ratio = RMS error / CRB, calib = RMS(error / reported std)",
        seeds
    );
    println!(
        "{:<5} {:>10} {:>12} {:>8} {:>8} {:>12} {:>8} {:>8} {:>12} {:>8} {:>8}",
        "entry",
        "CRB",
        "true flight",
        "ratio",
        "calib",
        "pipeline",
        "ratio",
        "calib",
        "OE fit",
        "ratio",
        "calib"
    );
    let mut fed_ratios = Vec::new();
    for q in 0..6 {
        let c = (crb[q] / n[0].max(1) as f64).sqrt();
        let r0 = (sq[0][q] / n[0].max(1) as f64).sqrt();
        let r1 = (sq[1][q] / n[1].max(1) as f64).sqrt();
        let r2 = (sq[2][q] / n[2].max(1) as f64).sqrt();
        println!(
            "{:<5} {:>10.3e} {:>12.3e} {:>8.2} {:>8.2} {:>12.3e} {:>8.2} {:>8.2} {:>12.3e} {:>8.2} {:>8.2}",
            names[q],
            c,
            r0,
            r0 / c,
            (z2[0][q] / n[0].max(1) as f64).sqrt(),
            r1,
            r1 / c,
            (z2[1][q] / n[1].max(1) as f64).sqrt(),
            r2,
            r2 / c,
            (z2[2][q] / n[2].max(1) as f64).sqrt()
        );
        let cf = (crb_fed[q] / n_fed.max(1) as f64).sqrt();
        fed_ratios.push(format!("{} {:.2} (bound {:.3e})", names[q], r1 / cf, cf));
    }
    // Each seed throws differently and has its own bound: the error over the seed's own bound,
    // RMS over seeds (less Monte Carlo spread than the ratio of the RMS above).
    for (path, label) in [(1usize, "pipeline"), (2, "OE fit")] {
        let v: Vec<String> = (0..6)
            .map(|q| {
                format!(
                    "{} {:.2}",
                    names[q],
                    (own2[path][q] / n[path].max(1) as f64).sqrt()
                )
            })
            .collect();
        println!("{label}, RMS(error / own seed's CRB): {}", v.join(", "));
    }
    println!(
        "pipeline against the bound of the samples it fed ({} seeds): {}",
        n_fed,
        fed_ratios.join(", ")
    );
    if let Some(path) = plot {
        let quantised = if quant == "off" {
            "logged exactly"
        } else {
            "quantised as logged"
        };
        let title = format!(
            "pipeline, {} simulated board throws, rotor speed {quantised}: |error| / reported std",
            n[1]
        );
        match write_honesty(&path, &title, &names, &zs) {
            Ok(()) => println!("wrote {}", path.display()),
            Err(e) => {
                eprintln!("tensor-bench: {e:#}");
                std::process::exit(1);
            }
        }
    }
}

/// `|z|` per entry, sorted, against the quantiles of `|N(0, 1)|` at `(i + 1/2) / n`: an honest
/// standard deviation puts the points on the diagonal, an overconfident one above it.
fn write_honesty(
    path: &std::path::Path,
    title: &str,
    names: &[&str; 6],
    zs: &[Vec<f64>; 6],
) -> anyhow::Result<()> {
    use host_tests::plot::{write_svg, Chart, Series};
    let mut series: Vec<Series> = names
        .iter()
        .zip(zs)
        .map(|(name, z)| {
            let mut a: Vec<f64> = z
                .iter()
                .map(|x| x.abs())
                .filter(|x| x.is_finite())
                .collect();
            a.sort_by(f64::total_cmp);
            let n = a.len() as f64;
            Series {
                name: (*name).to_string(),
                points: a
                    .iter()
                    .enumerate()
                    .map(|(i, &y)| (normal_quantile(0.5 + 0.5 * (i as f64 + 0.5) / n), y))
                    .collect(),
            }
        })
        .collect();
    series.push(Series {
        name: "honest (y = x)".into(),
        points: vec![(0.0, 0.0), (3.5, 3.5)],
    });
    write_svg(
        path,
        &[Chart {
            title,
            x_label: "quantile of |N(0, 1)|",
            y_label: "|error| / reported std, sorted",
            y_range: Some((0.0, 5.0)),
            series,
        }],
    )
}

/// The standard normal's quantile at `p` in (0, 1) (Acklam's rational approximation, relative
/// error below 1.2e-9).
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::normal_quantile;

    #[test]
    fn normal_quantiles_match_tables() {
        for (p, z) in [
            (0.5, 0.0),
            (0.975, 1.959_963_985),
            (0.01, -2.326_347_874),
            (0.999, 3.090_232_306),
        ] {
            assert!(
                (normal_quantile(p) - z).abs() < 1e-8,
                "{p}: {}",
                normal_quantile(p)
            );
        }
    }
}
