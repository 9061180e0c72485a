//! Out-of-sample check of `inertia identify` on `t,wx,wy,wz` CSV logs, exactly as a user (or
//! an independent reviewer) runs it: simulated torque-free bodies that are *not* the
//! benchmark's scenarios (other bodies, rates from 60 Hz to 8 kHz, noise from 5e-5 to 2e-2
//! rad/s, a bias, a fast spin), written as CSV text, identified by the `inertia` binary, and
//! judged by the error of `pooled.a` against the constrained Cramer-Rao bound and by the
//! calibration of `pooled.std_a`.
//!
//! Usage: `sweep-identify [--seeds N] [--inertia PATH] [--only NAME] [--peer] [--arg ARG]...` (`--arg`:
//! one more argument for `inertia identify`, repeatable; the `inertia` binary
//! next to this one by default; build both with `--release`). Prints one table row per
//! scenario: RMS error / bound per axis, RMS(error / reported std) per axis, and the statuses.
//! `--peer` adds a column: the `f64` constrained maximum likelihood (`host_tests::estimators::ml`)
//! on the very samples `inertia` read, RMS error over the same bound, for the free bodies: where
//! it is above the bound too, the bound is not reached by the best estimator of the model on
//! that sample size; where it is not, the difference is `inertia`'s.
//! With `SWEEP_KEEP` set in the environment the CSV logs and JSON reports are kept.

use anyhow::{bail, Context, Result};
use host_tests::crb_tensor::{ratio_bound_constrained_from_crb, ratio_bound_with_bias};
use host_tests::estimators::{ml::MlConstrained, Method};
use host_tests::gyro::GyroModel;
use host_tests::rigid_body::{rk4, Body, Trajectory};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One simulated log plan.
struct Case {
    name: &'static str,
    moments: [f64; 3],
    omega0: [f64; 3],
    rate_hz: f64,
    duration: f64,
    sigma: f64,
    bias: [f64; 3],
    /// What the torque-free model with a constant bias lacks (a trap): `None` for the
    /// accuracy rows.
    trap: Option<Trap>,
}

/// An effect the model lacks. On these rows the question is not the bound but whether the
/// report says `Converged` while `a` is more than 4 of its standard deviations off.
#[derive(Clone, Copy)]
enum Trap {
    /// Linear air drag, torque `-c J_i w_i` (`c` in 1/s).
    Drag(f64),
    /// A constant torque over the moments (rad/s^2 per axis).
    Torque([f64; 3]),
    /// Sampling instants jittered uniformly by this fraction of the period, logged truly.
    JitterLogged(f64),
    /// Sampling instants jittered by this fraction, logged at the nominal instants.
    JitterUnlogged(f64),
    /// This fraction of the samples missing from the log.
    Drops(f64),
    /// A gyro bias that random-walks (rad/s per sqrt(s)).
    BiasWalk(f64),
    /// Per-axis gyro scale factors.
    Scale([f64; 3]),
    /// The log's clock runs this factor fast (a wrong time step: the logged instants are the
    /// true ones times the factor).
    Clock(f64),
    /// The gyro clips at this rate (rad/s): a full scale set too low.
    Clip(f64),
    /// A hand holds the body for the first half second (a torque of this amplitude, rad/s^2,
    /// turning every axis) and catches it in the last 0.3 s (rates damped at 10/s): the log
    /// is cut wider than the free flight.
    Hand(f64),
}

const fn case(
    name: &'static str,
    moments: [f64; 3],
    omega0: [f64; 3],
    rate_hz: f64,
    duration: f64,
    sigma: f64,
) -> Case {
    Case {
        name,
        moments,
        omega0,
        rate_hz,
        duration,
        sigma,
        bias: [0.0; 3],
        trap: None,
    }
}

const fn trap(name: &'static str, trap: Trap) -> Case {
    Case {
        trap: Some(trap),
        ..case(name, [0.8, 1.3, 1.7], [1.2, 0.4, 0.9], 500.0, 6.0, 2e-3)
    }
}

/// Bodies, rates and noise levels chosen away from the benchmark's scenarios.
fn cases() -> Vec<Case> {
    vec![
        case(
            "box-500hz",
            [2.0, 3.0, 4.5],
            [0.5, 2.0, 0.3],
            500.0,
            8.0,
            3e-3,
        ),
        case(
            "phone-flip-400hz",
            [1.0, 2.1, 2.9],
            [0.3, 6.0, 0.4],
            400.0,
            1.5,
            2e-3,
        ),
        case(
            "prolate-4k",
            [1.0, 5.0, 5.3],
            [2.0, 0.7, 0.5],
            4000.0,
            3.0,
            5e-3,
        ),
        case(
            "quiet-1k",
            [0.8, 1.3, 1.7],
            [1.2, 0.4, 0.9],
            1000.0,
            5.0,
            5e-5,
        ),
        case(
            "noise-free-1k",
            [0.8, 1.3, 1.7],
            [1.2, 0.4, 0.9],
            1000.0,
            5.0,
            1e-9,
        ),
        case(
            "quiet-2e-4-1k",
            [0.8, 1.3, 1.7],
            [1.2, 0.4, 0.9],
            1000.0,
            5.0,
            2e-4,
        ),
        case(
            "quiet-5e-4-1k",
            [0.8, 1.3, 1.7],
            [1.2, 0.4, 0.9],
            1000.0,
            5.0,
            5e-4,
        ),
        case(
            "drone-8k-noisy",
            [1.1, 1.2, 2.0],
            [3.0, 2.5, 1.0],
            8000.0,
            2.0,
            1e-2,
        ),
        case(
            "fast-spin-100hz",
            [0.6, 1.54, 1.0],
            [4.0, 15.0, 3.0],
            100.0,
            2.0,
            2e-3,
        ),
        case(
            "slow-60hz",
            [3.0, 4.0, 6.0],
            [0.6, 1.0, 0.5],
            60.0,
            6.0,
            1e-3,
        ),
        case(
            "major-axis-2k",
            [1.0, 1.9, 1.4],
            [0.1, 2.0, 0.12],
            2000.0,
            6.0,
            2e-3,
        ),
        case(
            "long-60s-1k",
            [0.6, 1.54, 1.0],
            [1.0, 1.0, 1.0],
            1000.0,
            60.0,
            2e-3,
        ),
        case(
            "spin-major-8rad",
            [0.6, 1.54, 1.0],
            [0.3, 8.0, 0.3],
            1000.0,
            20.0,
            2e-3,
        ),
        case(
            "fast-tumble-1k",
            [1.0, 2.1, 2.9],
            [3.0, 12.0, 2.0],
            1000.0,
            4.0,
            2e-3,
        ),
        case(
            "toss-0.4s-100hz",
            [1.0, 5.5, 6.2],
            [2.0, 12.0, 1.5],
            100.0,
            0.4,
            1e-2,
        ),
        case(
            "near-sym-1pct-2k",
            [1.0, 1.01, 1.6],
            [1.5, 1.2, 0.8],
            2000.0,
            5.0,
            2e-3,
        ),
        case(
            "weak-motion",
            [0.8, 1.3, 1.7],
            [0.2, 0.1, 0.15],
            500.0,
            4.0,
            2e-3,
        ),
        case(
            "axisymmetric",
            [1.0, 1.0, 1.6],
            [1.5, 1.2, 0.8],
            1000.0,
            5.0,
            2e-3,
        ),
        case(
            "short-150hz-quiet",
            [1.0, 2.1, 2.9],
            [3.0, 9.0, 2.0],
            150.0,
            0.6,
            5e-4,
        ),
        case(
            "fast-tumble-8s",
            [1.0, 2.1, 2.9],
            [3.0, 12.0, 2.0],
            1000.0,
            8.0,
            2e-3,
        ),
        Case {
            bias: [-3e-3, 2e-3, 1.5e-3],
            ..case(
                "bias-250hz",
                [1.5, 2.4, 2.0],
                [1.5, 1.0, 1.2],
                250.0,
                8.0,
                2e-3,
            )
        },
        trap("trap-drag", Trap::Drag(0.01)),
        trap("trap-torque", Trap::Torque([2e-3, -1e-3, 1.5e-3])),
        trap("trap-jitter-logged", Trap::JitterLogged(0.3)),
        trap("trap-jitter-unlogged", Trap::JitterUnlogged(0.3)),
        trap("trap-drops", Trap::Drops(0.05)),
        trap("trap-bias-walk", Trap::BiasWalk(2e-3)),
        trap("trap-scale", Trap::Scale([1.0, 1.005, 0.997])),
        trap("trap-clock-2pct", Trap::Clock(1.02)),
        trap("trap-clock-2x", Trap::Clock(2.0)),
        trap("trap-clip", Trap::Clip(1.2)),
        // Only the top 8 mrad/s of the y axis's peaks (1.4435 rad/s) clipped.
        trap("trap-clip-peak", Trap::Clip(1.435)),
        trap("trap-hand", Trap::Hand(2.0)),
    ]
}

fn ratios(m: [f64; 3]) -> [f64; 3] {
    [
        (m[1] - m[2]) / m[0],
        (m[2] - m[0]) / m[1],
        (m[0] - m[1]) / m[2],
    ]
}

/// The CSV text of one seed: time with 6 decimals, rates with 7 significant digits, the way
/// loggers write them.
fn csv(c: &Case, seed: u64) -> String {
    let sub = ((16000.0 / c.rate_hz).ceil() as usize).max(1);
    let (tr, logged_t) = match c.trap {
        None => {
            let tr = Body::free(c.moments).simulate(c.omega0, c.duration, c.rate_hz, sub);
            let t = tr.t.clone();
            (tr, t)
        }
        Some(trap) => simulate_trap(c, trap, sub, seed),
    };
    let mut g = GyroModel::noisy(c.sigma, seed);
    g.bias = c.bias;
    if let Some(Trap::Scale(k)) = c.trap {
        g.scale = k;
    }
    let mut y = g.measure(&tr);
    if let Some(Trap::Clip(limit)) = c.trap {
        for w in y.iter_mut() {
            *w = w.map(|x| x.clamp(-limit, limit));
        }
    }
    if let Some(Trap::BiasWalk(q)) = c.trap {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let mut b = [0.0f64; 3];
        let dt = 1.0 / c.rate_hz;
        for w in y.iter_mut() {
            for (bi, wi) in b.iter_mut().zip(w.iter_mut()) {
                let z: f64 = StandardNormal.sample(&mut rng);
                *bi += q * dt.sqrt() * z;
                *wi += *bi;
            }
        }
    }
    let drop = match c.trap {
        Some(Trap::Drops(f)) => f,
        _ => 0.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xd209);
    let mut s = String::with_capacity(48 * y.len() + 16);
    s.push_str("t,wx,wy,wz\n");
    for (t, w) in logged_t.iter().zip(&y) {
        if drop > 0.0 && rng.gen::<f64>() < drop {
            continue;
        }
        let _ = writeln!(s, "{t:.6},{:.7e},{:.7e},{:.7e}", w[0], w[1], w[2]);
    }
    s
}

/// The times and rates of a CSV text [`csv`] wrote.
fn parse_rows(text: &str) -> (Vec<f64>, Vec<[f64; 3]>) {
    let mut t = Vec::new();
    let mut y = Vec::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').filter_map(|x| x.parse().ok()).collect();
        if let [ti, a, b, c] = v[..] {
            t.push(ti);
            y.push([a, b, c]);
        }
    }
    (t, y)
}

/// The true motion of a trap case (its own RK4: torques, jittered instants) and the times the
/// log gives for its samples.
fn simulate_trap(c: &Case, trap: Trap, sub: usize, seed: u64) -> (Trajectory, Vec<f64>) {
    let m = c.moments;
    let rhs = |w: [f64; 3]| -> [f64; 3] {
        let free = [
            (m[1] - m[2]) / m[0] * w[1] * w[2],
            (m[2] - m[0]) / m[1] * w[2] * w[0],
            (m[0] - m[1]) / m[2] * w[0] * w[1],
        ];
        match trap {
            Trap::Drag(k) => std::array::from_fn(|i| free[i] - k * w[i]),
            Trap::Torque(q) => std::array::from_fn(|i| free[i] + q[i]),
            _ => free,
        }
    };
    // The hand's torque and the catch's damping at time `t`.
    let hand = |t: f64, w: [f64; 3]| -> [f64; 3] {
        let Trap::Hand(amp) = trap else {
            return [0.0; 3];
        };
        if t < 0.5 {
            [
                amp * (7.0 * t).sin(),
                amp * (5.0 * t).cos(),
                amp * (3.0 * t + 1.0).sin(),
            ]
        } else if t > c.duration - 0.3 {
            w.map(|x| -10.0 * x)
        } else {
            [0.0; 3]
        }
    };
    let n = (c.duration * c.rate_hz).round() as usize + 1;
    let period = 1.0 / c.rate_hz;
    let jitter = match trap {
        Trap::JitterLogged(f) | Trap::JitterUnlogged(f) => f,
        _ => 0.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7177);
    let nominal: Vec<f64> = (0..n).map(|k| k as f64 * period).collect();
    let actual: Vec<f64> = nominal
        .iter()
        .enumerate()
        .map(|(k, t)| {
            if k == 0 || jitter == 0.0 {
                *t
            } else {
                t + jitter * period * (rng.gen::<f64>() - 0.5)
            }
        })
        .collect();
    let mut w = c.omega0;
    let mut omega = Vec::with_capacity(n);
    let mut prev = 0.0;
    for t in &actual {
        let h = (t - prev) / sub as f64;
        for k in 0..sub {
            let at = prev + k as f64 * h;
            let push = hand(at, w);
            w = rk4(
                |v| {
                    let f = rhs(v);
                    std::array::from_fn(|i| f[i] + push[i])
                },
                w,
                h,
            );
        }
        prev = *t;
        omega.push(w);
    }
    let logged = match trap {
        Trap::JitterUnlogged(_) => nominal,
        Trap::Clock(f) => actual.iter().map(|t| t * f).collect(),
        _ => actual.clone(),
    };
    (Trajectory { t: actual, omega }, logged)
}

/// What one run of `inertia identify` reported.
struct Outcome {
    a: Option<[f64; 3]>,
    std_a: Option<[f64; 3]>,
    status: String,
}

fn identify(exe: &Path, extra: &[String], dir: &Path, c: &Case, seed: u64) -> Result<Outcome> {
    let input = dir.join(format!("{}-{seed}.csv", c.name));
    let json = dir.join(format!("{}-{seed}.json", c.name));
    std::fs::write(&input, csv(c, seed))?;
    let o = Command::new(exe)
        .arg("identify")
        .arg("--input")
        .arg(&input)
        .arg("--json")
        .arg(&json)
        .args(extra)
        .output()
        .with_context(|| format!("running {}", exe.display()))?;
    let v: serde_json::Value = std::fs::read_to_string(&json)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    if std::env::var_os("SWEEP_KEEP").is_none() {
        let _ = std::fs::remove_file(&input);
        let _ = std::fs::remove_file(&json);
    }
    let arr = |k: &str| -> Option<[f64; 3]> {
        let a = v["pooled"][k].as_array()?;
        let x: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
        (x.len() == 3).then(|| [x[0], x[1], x[2]])
    };
    let status = v["pooled"]["status"]
        .as_str()
        .map(str::to_string)
        .unwrap_or_else(|| format!("exit {}", o.status.code().unwrap_or(-1)));
    Ok(Outcome {
        a: arr("a"),
        std_a: arr("std_a"),
        status,
    })
}

fn main() -> Result<()> {
    let mut seeds = 50u64;
    let mut exe: Option<PathBuf> = None;
    let mut only: Option<String> = None;
    let mut peer = false;
    let mut extra: Vec<String> = Vec::new();
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--seeds" => seeds = it.next().context("--seeds N")?.parse()?,
            "--inertia" => exe = Some(it.next().context("--inertia PATH")?.into()),
            "--only" => only = Some(it.next().context("--only NAME")?),
            "--arg" => extra.push(it.next().context("--arg ARG")?),
            "--peer" => peer = true,
            other => bail!("unknown argument {other:?}"),
        }
    }
    let exe = match exe {
        Some(p) => p,
        None => std::env::current_exe()?
            .parent()
            .context("no directory of this binary")?
            .join("inertia"),
    };
    if !exe.exists() {
        bail!(
            "{} not found: build it (cargo build --release -p inertia) or pass --inertia",
            exe.display()
        );
    }
    let dir = std::env::temp_dir().join(format!("sweep-identify-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    if peer {
        println!("| scenario | samples | RMS error (bound) | RMS error / constrained bound | RMS(error / reported std) | statuses | `Converged` more than 4 std off | f64 constrained ML on the same samples / bound |");
        println!("|---|---|---|---|---|---|---|---|");
    } else {
        println!("| scenario | samples | RMS error (bound) | RMS error / constrained bound | RMS(error / reported std) | statuses | `Converged` more than 4 std off |");
        println!("|---|---|---|---|---|---|---|");
    }
    for c in cases() {
        if only.as_deref().is_some_and(|n| n != c.name) {
            continue;
        }
        let n = (c.duration * c.rate_hz).round() as usize + 1;
        let truth = ratios(c.moments);
        let bound = if c.bias.iter().any(|b| *b != 0.0) {
            ratio_bound_with_bias(c.moments, c.omega0, n, c.rate_hz, c.sigma).map(|b| b.std_a)
        } else {
            ratio_bound_constrained_from_crb(truth, c.omega0, n, c.rate_hz, c.sigma).map(|b| b.1)
        }
        .unwrap_or([f64::NAN; 3]);
        let runs: Vec<Outcome> = (1..=seeds)
            .into_par_iter()
            .map(|s| identify(&exe, &extra, &dir, &c, s))
            .collect::<Result<_>>()?;
        let mut statuses = BTreeMap::<String, usize>::new();
        let mut confident_wrong = 0usize;
        let (mut se, mut sz, mut m) = ([0.0f64; 3], [0.0f64; 3], 0usize);
        for r in &runs {
            *statuses.entry(r.status.clone()).or_default() += 1;
            if let (Some(a), Some(s)) = (r.a, r.std_a) {
                let off = (0..3).any(|i| ((a[i] - truth[i]) / s[i]).abs() > 4.0);
                if off && r.status == "Converged" {
                    confident_wrong += 1;
                }
                m += 1;
                for i in 0..3 {
                    let e = a[i] - truth[i];
                    se[i] += e * e;
                    sz[i] += (e / s[i]).powi(2);
                }
            }
        }
        let rms = |v: [f64; 3]| v.map(|x| (x / m.max(1) as f64).sqrt());
        let (re, rz) = (rms(se), rms(sz));
        let st: Vec<String> = statuses.iter().map(|(k, v)| format!("{k} {v}")).collect();
        // The f64 constrained maximum likelihood of the torque-free, bias-free model on the
        // very samples `inertia` read (the CSV text parsed back): where it too is above the
        // bound, the sample is too small for the bound to be reached, not the estimator
        // short of it. Free bodies only (the peer has no bias, and needs even steps).
        let peer_col = if peer && c.trap.is_none() && c.bias.iter().all(|b| *b == 0.0) {
            let errs: Vec<[f64; 3]> = (1..=seeds)
                .into_par_iter()
                .map(|seed| {
                    let (t, y) = parse_rows(&csv(&c, seed));
                    let a = MlConstrained.estimate(&t, &y);
                    [0, 1, 2].map(|i| (a[i] - truth[i]).powi(2))
                })
                .collect();
            let k = errs.len().max(1) as f64;
            let r = [0, 1, 2].map(|i| (errs.iter().map(|e| e[i]).sum::<f64>() / k).sqrt());
            format!(
                " {:.2}, {:.2}, {:.2} |",
                r[0] / bound[0],
                r[1] / bound[1],
                r[2] / bound[2]
            )
        } else if peer {
            " |".to_string()
        } else {
            String::new()
        };
        println!(
            "| {} | {n} | {:.1e} ({:.1e}) | {:.2}, {:.2}, {:.2} | {:.2}, {:.2}, {:.2} | {} (a on {m} of {seeds}) | {confident_wrong} |{peer_col}",
            c.name,
            re.iter().fold(0.0f64, |x, y| x.max(*y)),
            bound.iter().fold(0.0f64, |x, y| x.max(*y)),
            re[0] / bound[0],
            re[1] / bound[1],
            re[2] / bound[2],
            rz[0],
            rz[1],
            rz[2],
            st.join(", ")
        );
    }
    if std::env::var_os("SWEEP_KEEP").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        println!("logs and reports kept in {}", dir.display());
    }
    Ok(())
}
