//! The Basilisk spacecraft logs through `inertia identify`, against the Cramer-Rao bound of the
//! model the product fits where the bench has it, and beside derivative least squares (a
//! benchmark: it prints figures, it judges nothing).
//!
//! For each fixture with a `NAME.clean.csv` (the true body rates, `inertia/tests/data/spacecraft`:
//! `sat6u-pyramid-10hz`, `peer-cubesat-1hz`, `leo-gg-1hz`, `mems-walk-10hz`) and each seed, a
//! gyro is made from the clean rates `w_k` (ChaCha8 seeded by the seed, the wheel, attitude and
//! position columns unchanged). The repository's docs have no equation for these gyro models,
//! so they are numbered here, per axis, `k` the log's sample, `n_k` and `e_k` independent
//! standard normal draws:
//!
//! ```text
//! y_k = w_k + sigma n_k                                                                  (Y1)
//! x_k = clamp(x_{k-1} + s e_k, -B, B),   x_{-1} = 0                                       (Y2)
//! y_k = LSB trunc((w_k + sigma n_k + b + x_k) / LSB)                                     (Y3)
//! ```
//!
//! (Y1), white noise of the truth file's `gyro_noise_std_rad_s`, for `sat6u-pyramid-10hz`,
//! `peer-cubesat-1hz` and `leo-gg-1hz`. For `mems-walk-10hz` a gyro of the fixture's kind: the
//! bias random walk (Y2) of the truth's `gyro_bias_walk` (step std `s` per sample, held within
//! `bound_rad_s` = `B`: Basilisk's `imuSensor` Gauss-Markov state with `A = I`, clamped), the
//! truth's constant bias `b` and white noise `sigma`, truncated toward zero to the truth's
//! `gyro_lsb_rad_s` (Y3), in the order the fixture's log was made (its white noise is added to
//! the rate before the `imuSensor`, so it is quantised too). The bench prints the gyro error's
//! mean, std and lag-1 autocorrelation beside those of the fixture's own log.
//!
//! Each log is identified by `inertia::identify::identify` with the vehicle file (the product's
//! path: noise estimated from the data, windows (W1), bias test, and on a log with attitude and
//! position the gravity-gradient torque (G1) folded into the momentum ((G2) of
//! `inertia::identify::gravity`), everything as `inertia identify --vehicle` does), and on the
//! same samples by derivative least squares (the peer's method family, El Hariry et al. 2025):
//! central differences of the gyro and of the wheel momentum, `J w' + w x (J w + h) = -h'`
//! regressed on the six entries over the whole log, its standard deviation the ordinary
//! least-squares one (`s^2 (A^T A)^-1`, `s^2` from its residual). On `leo-gg-1hz` it is also
//! run with the gravity-gradient torque (G1) among its regressors (linear in `J`, from the log's
//! attitude and position).
//!
//! The bound is that of the model the product fits: output error, white noise of the known
//! std, parameters the six entries of `J` and one initial rate per window the product's pipeline
//! closed and fitted on that seed. The windows depend on the noisy rates (the L1 turn of (W1) is
//! summed over the measured rates), so they are read per seed from a `FlightPipeline` fed the
//! inputs `identify` feeds (same settings, rates, momenta and time steps; on a log with attitude
//! and position, `identify`'s passes with the gravity gradient folded in at the previous pass's
//! tensor, and its choice between them); that its pooled tensor equals `identify`'s bit for bit
//! is checked and printed. The sensitivities of Euler's equation
//!
//! ```text
//! J w' = (J w + h) x w - h' + tau(J)                                                     (B1)
//! ```
//!
//! are integrated in `f64` (RK4, steps of at most 20 ms) along the true trajectory, from each
//! window's first clean rate with the true `J`, `h(t)` a natural cubic spline through the logged
//! wheel speeds; the Fisher information of each window's samples is reduced by its initial rate
//! (Schur complement) and summed over the windows. `tau` is the external torque of the true
//! dynamics: zero on `sat6u-pyramid-10hz` and `peer-cubesat-1hz`; on `leo-gg-1hz` (the truth
//! file's `environment` has `gravity_gradient`) the gravity-gradient torque (G1) of
//! `inertia::identify::gravity`,
//!
//! ```text
//! tau(J) = 3 mu / |r|^5 (r_B x J r_B),   r_B = R(q)^T r,   mu = 3.986004418e14 m^3/s^2
//! ```
//!
//! with `r_B(t)` a natural cubic spline per axis through the clean log's attitude and position.
//! With `f = J^-1 g` the right-hand side of (B1) solved for `w'`, the sensitivity to entry `c`
//! (`E_c` its symmetric unit matrix) gains the torque's derivative,
//! `d f / d p_c = J^-1 ((E_c w) x w + 3 mu / |r|^5 (r_B x E_c r_B) - E_c f)`, and
//! `d f / d w` is unchanged (the torque does not depend on `w`). This is the bound of (B1) with
//! the torque's dependence on `J`; the product holds the torque at its previous pass's tensor
//! ((G2)) and fits until the tensor settles, so its fit does not draw on that dependence.
//!
//! On `mems-walk-10hz` the bound is that of the gyro (Y2), (Y3) with its error treated as
//! Gaussian: the model the product fits where it finds the walk ((F12), (F13) of the tensor
//! fit: a constant bias per window, the walk from its first sample, white noise). Per
//! axis `i` and window, `u_k` the output's sensitivity row (the six entries and the window's
//! initial rate) at its sample `k = first..=last`, the gyro's error is
//!
//! ```text
//! y_k - w_k(theta) = c + d_k + v_k,   d_k = d_{k-1} + s e_k,   d_first = 0,
//!                    v_k ~ N(0, r),   r = sigma^2 + LSB^2 / 12                            (C1)
//! ```
//!
//! `c` a free constant per window and axis (the bias `b` plus the walk at the window's first
//! sample), `d` the walk (Y2) from there with the truth's step std `s` per sample, its clamp to
//! `+-B` ignored, `v` the white noise and what is left of the truncation once the product has
//! moved the readings to their counts' centres ((Q1) of `inertia::grid`), taken as uniform over a
//! count and independent of the rest; the axes independent. With `Sigma` the covariance of
//! `d + v` over the window (`Sigma_kl = s^2 min(k, l) + r [k = l]`, `k` and `l` counted from
//! `first`), the information of the window is
//!
//! ```text
//! F = U^T Sigma^-1 U   with the column of c eliminated (Schur complement)                  (C2)
//! ```
//!
//! computed exactly, in `f64`, by whitening each column of `U` with the scalar Kalman filter of
//! the state `c + d_k` started diffuse (an unknown constant with no prior, which eliminates `c`):
//!
//! ```text
//! z = u_first, P = r;   for k > first:  P' = P + s^2,  V_k = P' + r,  nu_k = u_k - z,
//!                       F += nu_k nu_k^T / V_k,  z += (P' / V_k) nu_k,  P = P' r / V_k        (C3)
//! ```
//!
//! (the rows `nu_k / sqrt(V_k)`, `k > first`, are `U` whitened by `Sigma` with `c` taken out:
//! their outer products sum to (C2); the first sample only fixes `c`). The window's initial
//! rate is then reduced out and the windows summed as above. With `s = 0`, (C3) is the
//! white-noise bound of variance `r` with a constant bias per window: the bench prints that
//! check on the first seed's windows against the bias columns kept and eliminated by a Schur
//! complement, and unit tests check (C3) against (C2) with a dense `Sigma`. Beside the bound the
//! bench prints the errors, the stated std and its calibration (RMS(error / stated std)) per
//! status.
//!
//! The figures are printed by `scripts/bench-spacecraft.sh [SEEDS]` (100 seeds by default) and
//! kept in BENCHMARKS.md ("Spacecraft logs with reaction wheels (Basilisk)").
//!
//! Usage: `spacecraft-bench [--seeds N] [--fixture NAME]... [--data DIR]` (100 seeds, every
//! fixture, the repository's data directory by default). `scripts/bench-spacecraft.sh [SEEDS]
//! [--fixture NAME]...`.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use anyhow::{bail, Context, Result};
use clap::Parser;
use identifier_core::{FlightPipeline, PipelineSettings, StretchOutcome};
use inertia::identify::gravity;
use inertia::identify::{identify, median_dt, IdentifyOptions, Report};
use inertia::vehicle::Vehicle;
use inertia::{ReadOptions, Recording};
use nalgebra::{Matrix3, SMatrix, SymmetricEigen};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

type M6 = SMatrix<f64, 6, 6>;
type M9 = SMatrix<f64, 9, 9>;
type M12 = SMatrix<f64, 12, 12>;

/// The six entries, in the product's order `(xx, yy, zz, xy, xz, yz)`.
const ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
const NAMES: [&str; 6] = ["Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"];
/// Longest RK4 step of the bound's integration, s.
const MAX_STEP_S: f64 = 0.02;

#[derive(Parser)]
#[command(about = "Spacecraft logs through inertia identify against the Cramer-Rao bound")]
struct Args {
    /// Monte Carlo seeds per fixture.
    #[arg(long, default_value_t = 100)]
    seeds: u64,
    /// Fixture name (repeatable); every fixture by default.
    #[arg(long)]
    fixture: Vec<String>,
    /// The fixtures' directory.
    #[arg(long)]
    data: Option<PathBuf>,
}

/// The gyro each seed's log gets from the clean rates.
#[derive(Clone, Copy, PartialEq)]
enum Gyro {
    /// (Y1): white noise of the truth's std.
    White,
    /// (Y2), (Y3): the fixture's kind of MEMS gyro, a bounded bias random walk, a constant bias,
    /// white noise, truncated to the LSB.
    Mems,
}

/// The gyro error model of a bound, its white noise of the fixture's variance `r`
/// ([`Fixture::white_var`]).
#[derive(Clone, Copy, PartialEq)]
enum Noise {
    /// White noise, no bias: the model the product fits on a white-noise gyro (Y1).
    White,
    /// White noise and a free constant bias per window and axis, its three columns in the
    /// information and eliminated with the initial rate (Schur complement): (C1) with `s = 0`,
    /// the check of (C3).
    WhiteBias,
    /// (C1): a free constant bias per window and axis, the bias walk of step variance `step_var`
    /// per sample, white noise, whitened by (C3).
    Walk { step_var: f64 },
}

/// A window's `(first, last)` sample and its noise model's [`Noise::key`].
type WindowKey = (usize, usize, (u8, u64));

impl Noise {
    /// The window cache's key.
    fn key(self) -> (u8, u64) {
        match self {
            Noise::White => (0, 0),
            Noise::WhiteBias => (1, 0),
            Noise::Walk { step_var } => (2, step_var.to_bits()),
        }
    }
}

/// (C3) on one axis: the scalar Kalman filter of the bias `c + d_k` of (C1), started diffuse,
/// applied to a row of `N` sensitivity columns at once (the filter's gain does not depend on the
/// data).
#[derive(Clone, Copy)]
struct Whitener<const N: usize> {
    /// `s^2`, the walk's step variance per sample.
    step_var: f64,
    /// `r`, the white noise's variance.
    white_var: f64,
    /// The filtered bias of each column, `z`.
    z: [f64; N],
    /// Its variance, `P` (`None` before the first sample).
    p: Option<f64>,
}

impl<const N: usize> Whitener<N> {
    fn new(step_var: f64, white_var: f64) -> Self {
        Whitener {
            step_var,
            white_var,
            z: [0.0; N],
            p: None,
        }
    }

    /// The next sample's row `u_k`: its innovation `nu_k` and variance `V_k`, or `None` on the
    /// first sample (it fixes the diffuse bias and carries nothing else).
    fn push(&mut self, u: &[f64; N]) -> Option<([f64; N], f64)> {
        let Some(p) = self.p else {
            self.z = *u;
            self.p = Some(self.white_var);
            return None;
        };
        let predicted = p + self.step_var;
        let var = predicted + self.white_var;
        let nu: [f64; N] = std::array::from_fn(|c| u[c] - self.z[c]);
        let gain = predicted / var;
        for c in 0..N {
            self.z[c] += gain * nu[c];
        }
        self.p = Some(predicted * self.white_var / var);
        Some((nu, var))
    }
}

/// A fixture, the gyro its seeds get, why the bound is not printed (if it is not) and the
/// published figure of its class (if any).
struct Plan {
    name: &'static str,
    gyro: Gyro,
    no_bound: Option<&'static str>,
    published: Option<&'static str>,
    published_percent: Option<f64>,
}

const PLANS: [Plan; 4] = [
    Plan {
        name: "sat6u-pyramid-10hz",
        gyro: Gyro::White,
        no_bound: None,
        published: None,
        published_percent: None,
    },
    Plan {
        name: "peer-cubesat-1hz",
        gyro: Gyro::White,
        no_bound: None,
        published: Some(
            "El Hariry et al. (2025), batch least squares on the CubeSat class at 1 Hz with 0.01 \
             rad/s gyro noise, full-tensor error",
        ),
        published_percent: Some(1.7),
    },
    Plan {
        name: "leo-gg-1hz",
        gyro: Gyro::White,
        no_bound: None,
        published: None,
        published_percent: None,
    },
    Plan {
        name: "mems-walk-10hz",
        gyro: Gyro::Mems,
        no_bound: None,
        published: None,
        published_percent: None,
    },
];

/// The bias random walk of `NAME.truth.toml`.
#[derive(Deserialize, Default, Clone, Copy)]
struct Walk {
    step_std_rad_s_per_sample: f64,
    bound_rad_s: f64,
}

/// The parts of `NAME.truth.toml` used here.
#[derive(Deserialize)]
struct Truth {
    inertia_kg_m2: [[f64; 3]; 3],
    gyro_noise_std_rad_s: f64,
    #[serde(default)]
    gyro_bias_rad_s: [f64; 3],
    #[serde(default)]
    gyro_bias_walk: Walk,
    #[serde(default)]
    gyro_lsb_rad_s: f64,
    #[serde(default)]
    gyro_rounding: Option<String>,
    /// The external torques of the true dynamics (`"gravity_gradient"`, ...).
    #[serde(default)]
    environment: Vec<String>,
    description: String,
}

/// A gyro's error (reading minus true rate) as `make_logs.py` checks it: mean per axis, the
/// standard deviation and lag-1 autocorrelation of the error less its mean, over all axes.
#[derive(Clone, Copy)]
struct ErrorStats {
    mean: [f64; 3],
    std: f64,
    lag1: f64,
}

fn error_stats(y: &[[f32; 3]], w: &[[f64; 3]]) -> ErrorStats {
    let n = y.len().min(w.len());
    let e: Vec<[f64; 3]> = (0..n)
        .map(|k| std::array::from_fn(|i| f64::from(y[k][i]) - w[k][i]))
        .collect();
    let mean: [f64; 3] =
        std::array::from_fn(|i| e.iter().map(|v| v[i]).sum::<f64>() / n.max(1) as f64);
    let d: Vec<[f64; 3]> = e
        .iter()
        .map(|v| std::array::from_fn(|i| v[i] - mean[i]))
        .collect();
    let var = d.iter().flatten().map(|x| x * x).sum::<f64>() / (3 * n.max(1)) as f64;
    let cov1 = d
        .windows(2)
        .map(|p| (0..3).map(|i| p[0][i] * p[1][i]).sum::<f64>())
        .sum::<f64>()
        / (3 * n.saturating_sub(1).max(1)) as f64;
    ErrorStats {
        mean,
        std: var.sqrt(),
        lag1: cov1 / var,
    }
}

/// A natural cubic spline through `(t_k, y_k)`: value and derivative anywhere inside.
struct Spline {
    t: Vec<f64>,
    y: Vec<f64>,
    /// Second derivatives at the knots.
    m: Vec<f64>,
}

impl Spline {
    fn new(t: &[f64], y: &[f64]) -> Self {
        let n = t.len();
        let mut m = vec![0.0; n];
        if n > 2 {
            // Tridiagonal system for the interior second derivatives (Thomas algorithm).
            let mut diag = vec![0.0; n];
            let mut rhs = vec![0.0; n];
            let mut upper = vec![0.0; n];
            for i in 1..n - 1 {
                let (h0, h1) = (t[i] - t[i - 1], t[i + 1] - t[i]);
                diag[i] = 2.0 * (h0 + h1);
                upper[i] = h1;
                rhs[i] = 6.0 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0);
                if i > 1 {
                    let lower = h0;
                    let f = lower / diag[i - 1];
                    diag[i] -= f * upper[i - 1];
                    rhs[i] -= f * rhs[i - 1];
                }
            }
            for i in (1..n - 1).rev() {
                let next = if i + 1 < n - 1 { m[i + 1] } else { 0.0 };
                m[i] = (rhs[i] - upper[i] * next) / diag[i];
            }
        }
        Spline {
            t: t.to_vec(),
            y: y.to_vec(),
            m,
        }
    }

    /// Value and first derivative at `x`.
    fn eval(&self, x: f64) -> (f64, f64) {
        let n = self.t.len();
        let i = self.t.partition_point(|&s| s <= x).clamp(1, n - 1) - 1;
        let h = self.t[i + 1] - self.t[i];
        let a = (self.t[i + 1] - x) / h;
        let b = (x - self.t[i]) / h;
        let (m0, m1) = (self.m[i], self.m[i + 1]);
        let v = a * self.y[i]
            + b * self.y[i + 1]
            + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
        let d = (self.y[i + 1] - self.y[i]) / h - (3.0 * a * a - 1.0) / 6.0 * h * m0
            + (3.0 * b * b - 1.0) / 6.0 * h * m1;
        (v, d)
    }
}

/// A fixture read once.
struct Fixture {
    name: String,
    description: String,
    gyro: Gyro,
    /// The bench's bound is that of the model the product fits (else it is not computed).
    with_bound: bool,
    /// The truth's constant gyro bias, rad/s ((Y2), `Gyro::Mems` only).
    bias: [f64; 3],
    /// The truth's bias random walk ((Y2), `Gyro::Mems` only).
    walk: Walk,
    /// The truth's LSB, rad/s ((Y3), `Gyro::Mems` only).
    lsb: f64,
    /// The bound's gyro error model: [`Noise::White`] for (Y1), [`Noise::Walk`] (C1) for the
    /// MEMS gyro.
    noise: Noise,
    /// Its white noise's variance, (rad/s)^2: `sigma^2` for (Y1), `r = sigma^2 + LSB^2 / 12` of
    /// (C1) for the MEMS gyro (what is left of the truncation once the readings are centred).
    white_var: f64,
    /// The gyro error of the fixture's own log (`NAME.csv` against the clean rates).
    fixture_error: Option<ErrorStats>,
    /// The gravity-gradient torque (G1) per sample as a linear map of the six entries, N m per
    /// kg m^2, when the log has attitude and position (derivative least squares' extra
    /// regressors).
    gg_rows: Option<Vec<[[f64; 6]; 3]>>,
    /// The clean log as `inertia` reads it, with the vehicle's wheel columns.
    clean: Recording,
    vehicle: Vehicle,
    truth: Matrix3<f64>,
    sigma: f64,
    /// Clean rates, rad/s.
    w: Vec<[f64; 3]>,
    /// Wheel momentum at the samples, kg m^2/s, `f64`.
    h: Vec<[f64; 3]>,
    /// `h(t)` per axis.
    h_spline: [Spline; 3],
    /// `r_B(t) = R(q(t))^T r(t)` per axis, m, when the true dynamics have the gravity-gradient
    /// torque (G1): natural cubic splines through the clean log's attitude and position.
    r_b_spline: Option<[Spline; 3]>,
    /// Fisher information of a window's samples on the six entries (its initial rate, and bias
    /// if the noise model has one, reduced out), times `white_var`, by `(first, last)` sample
    /// and noise model; and the RMS of the integrated true trajectory's distance from the clean
    /// rates over the window.
    cache: Mutex<HashMap<WindowKey, (M6, f64)>>,
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn mv(m: &Matrix3<f64>, v: [f64; 3]) -> [f64; 3] {
    let r = m * nalgebra::Vector3::from(v);
    [r[0], r[1], r[2]]
}

fn sym_unit(c: usize) -> Matrix3<f64> {
    let (i, j) = ENTRIES[c];
    let mut e = Matrix3::zeros();
    e[(i, j)] = 1.0;
    e[(j, i)] = 1.0;
    e
}

/// The rate and its sensitivities to the six entries and the window's initial rate.
#[derive(Clone, Copy)]
struct Sens {
    w: [f64; 3],
    s: [[f64; 9]; 3],
}

impl Fixture {
    fn load(dir: &Path, plan: &Plan) -> Result<Self> {
        let name = plan.name;
        let vehicle = Vehicle::load(&dir.join(format!("{name}.toml")))?;
        let truth_path = dir.join(format!("{name}.truth.toml"));
        let text = std::fs::read_to_string(&truth_path)
            .with_context(|| format!("reading {}", truth_path.display()))?;
        let truth: Truth =
            toml::from_str(&text).with_context(|| format!("parsing {}", truth_path.display()))?;
        let clean_path = dir.join(format!("{name}.clean.csv"));
        let opts = ReadOptions {
            rotor_columns: vehicle.columns(),
            ..ReadOptions::default()
        };
        let clean = inertia::read(&clean_path, &opts)
            .with_context(|| format!("reading {}", clean_path.display()))?;
        if clean.wheels.len() != vehicle.rotors.len() {
            bail!("{name}: the clean log lacks wheel columns");
        }
        let n = clean.t.len();
        let w: Vec<[f64; 3]> = clean.gyro.iter().map(|g| g.map(f64::from)).collect();
        let h: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let mut hk = [0.0; 3];
                for (r, col) in vehicle.rotors.iter().zip(&clean.wheels) {
                    let speed = f64::from(col[k]) * f64::from(r.to_rad_per_sec().unwrap_or(1.0));
                    for i in 0..3 {
                        hk[i] += f64::from(r.inertia_kg_m2) * speed * f64::from(r.axis[i]);
                    }
                }
                hk
            })
            .collect();
        let h_spline = std::array::from_fn(|i| {
            let y: Vec<f64> = h.iter().map(|v| v[i]).collect();
            Spline::new(&clean.t, &y)
        });
        let r_b_spline = if truth.environment.iter().any(|e| e == "gravity_gradient") {
            let (Some(q), Some(r)) = (&clean.attitude, &clean.position) else {
                bail!("{name}: gravity gradient on, but the clean log lacks attitude or position");
            };
            let mut r_b = Vec::with_capacity(n);
            for (&q, &r) in q.iter().zip(r) {
                let Some(rot) = gravity::rotation(q) else {
                    bail!("{name}: an unusable attitude quaternion {q:?}");
                };
                r_b.push(gravity::mul_t(&rot, r));
            }
            Some(std::array::from_fn(|i| {
                let y: Vec<f64> = r_b.iter().map(|v| v[i]).collect();
                Spline::new(&clean.t, &y)
            }))
        } else {
            None
        };
        if plan.no_bound.is_none() {
            if let Some(other) = truth
                .environment
                .iter()
                .find(|e| e.as_str() != "gravity_gradient")
            {
                bail!("{name}: the bound has no model of the environment's {other:?}");
            }
        }
        let j = truth.inertia_kg_m2;
        if plan.gyro == Gyro::Mems {
            if !(truth.gyro_bias_walk.step_std_rad_s_per_sample > 0.0 && truth.gyro_lsb_rad_s > 0.0)
            {
                bail!("{name}: the truth file has no bias walk or LSB for a MEMS gyro");
            }
            if truth.gyro_rounding.as_deref() != Some("toward_zero") {
                bail!("{name}: the truth's gyro rounding is not toward zero");
            }
        }
        // The bound's noise model: (Y1)'s white noise, or (C1) for the MEMS gyro.
        let sigma = truth.gyro_noise_std_rad_s;
        let (noise, white_var) = match plan.gyro {
            Gyro::White => (Noise::White, sigma * sigma),
            Gyro::Mems => {
                let s = truth.gyro_bias_walk.step_std_rad_s_per_sample;
                let lsb = truth.gyro_lsb_rad_s;
                (
                    Noise::Walk { step_var: s * s },
                    sigma * sigma + lsb * lsb / 12.0,
                )
            }
        };
        // The fixture's own log, for its gyro's error against the clean rates.
        let fixture_error = inertia::read(&dir.join(format!("{name}.csv")), &opts)
            .ok()
            .filter(|r| r.t.len() == n)
            .map(|r| error_stats(&r.gyro, &w));
        let gg_rows = match (&clean.attitude, &clean.position) {
            (Some(q), Some(r)) => Some(
                q.iter()
                    .zip(r)
                    .map(|(&q, &r)| {
                        let mut rows = [[0.0; 6]; 3];
                        for c in 0..6 {
                            let e = sym_unit(c);
                            let e = std::array::from_fn(|a| std::array::from_fn(|b| e[(a, b)]));
                            let tau = gravity::gravity_gradient_torque(&e, q, r);
                            for i in 0..3 {
                                rows[i][c] = tau[i];
                            }
                        }
                        rows
                    })
                    .collect(),
            ),
            _ => None,
        };
        Ok(Fixture {
            name: name.to_string(),
            description: truth.description,
            gyro: plan.gyro,
            with_bound: plan.no_bound.is_none(),
            bias: truth.gyro_bias_rad_s,
            walk: truth.gyro_bias_walk,
            lsb: truth.gyro_lsb_rad_s,
            noise,
            white_var,
            fixture_error,
            gg_rows,
            clean,
            vehicle,
            truth: Matrix3::from_fn(|r, c| j[r][c]),
            sigma: truth.gyro_noise_std_rad_s,
            w,
            h,
            h_spline,
            r_b_spline,
            cache: Mutex::new(HashMap::new()),
        })
    }

    fn momentum(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let mut h = [0.0; 3];
        let mut dh = [0.0; 3];
        for i in 0..3 {
            (h[i], dh[i]) = self.h_spline[i].eval(t);
        }
        (h, dh)
    }

    /// `d/dt` of the rate and its sensitivities at time `t`.
    fn deriv(&self, jinv: &Matrix3<f64>, t: f64, x: &Sens) -> Sens {
        let j = &self.truth;
        let w = x.w;
        let (h, dh) = self.momentum(t);
        let jw = mv(j, w);
        let l = [jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]];
        let lxw = cross(l, w);
        let mut g = [lxw[0] - dh[0], lxw[1] - dh[1], lxw[2] - dh[2]];
        // The gravity-gradient torque (G1), `k (r_B x J r_B)`, with `k = 3 mu / |r|^5`.
        let gg = self.r_b_spline.as_ref().map(|sp| {
            let rb: [f64; 3] = std::array::from_fn(|i| sp[i].eval(t).0);
            let d2 = rb[0] * rb[0] + rb[1] * rb[1] + rb[2] * rb[2];
            (rb, 3.0 * gravity::EARTH_MU / (d2 * d2 * d2.sqrt()))
        });
        if let Some((rb, k)) = gg {
            let tau = cross(rb, mv(j, rb));
            for i in 0..3 {
                g[i] += k * tau[i];
            }
        }
        let f = mv(jinv, g);
        // A = J^-1 ([L]x - [w]x J): d(L x w)/dw.
        let mut a0 = Matrix3::zeros();
        for c in 0..3 {
            let mut e = [0.0; 3];
            e[c] = 1.0;
            let je = [j[(0, c)], j[(1, c)], j[(2, c)]];
            let lx = cross(l, e);
            let wx = cross(w, je);
            for r in 0..3 {
                a0[(r, c)] = lx[r] - wx[r];
            }
        }
        let a = jinv * a0;
        let mut ds = [[0.0; 9]; 3];
        for r in 0..3 {
            for c in 0..9 {
                ds[r][c] = a[(r, 0)] * x.s[0][c] + a[(r, 1)] * x.s[1][c] + a[(r, 2)] * x.s[2][c];
            }
        }
        // B_c = J^-1 ((E_c w) x w + k (r_B x E_c r_B) - E_c f), the torque's term with (G1).
        for c in 0..6 {
            let e = sym_unit(c);
            let ew = mv(&e, w);
            let ef = mv(&e, f);
            let mut q = cross(ew, w);
            if let Some((rb, k)) = gg {
                let tau = cross(rb, mv(&e, rb));
                for i in 0..3 {
                    q[i] += k * tau[i];
                }
            }
            let b = mv(jinv, [q[0] - ef[0], q[1] - ef[1], q[2] - ef[2]]);
            for r in 0..3 {
                ds[r][c] += b[r];
            }
        }
        Sens { w: f, s: ds }
    }

    /// The window `first..=last`'s information on the six entries times `white_var` under
    /// `noise` (its initial rate, and bias if `noise` has one, reduced out), and the RMS distance
    /// of the integrated true trajectory from the clean rates over it, rad/s.
    fn window_information(&self, first: usize, last: usize, noise: Noise) -> (M6, f64) {
        let key = (first, last, noise.key());
        if let Some(v) = self.cache.lock().ok().and_then(|c| c.get(&key).copied()) {
            return v;
        }
        let r = self.white_var;
        // (C3), one filter per axis (`Noise::Walk`).
        let mut whiteners = [Whitener::<9>::new(
            match noise {
                Noise::Walk { step_var } => step_var,
                _ => 0.0,
            },
            r,
        ); 3];
        // With the bias columns (`Noise::WhiteBias`): the six entries, the initial rate, the
        // bias per axis.
        let mut g = M12::zeros();
        let jinv = self.truth.try_inverse().unwrap_or_else(Matrix3::zeros);
        let t = &self.clean.t;
        let mut x = Sens {
            w: self.w[first],
            s: [[0.0; 9]; 3],
        };
        for i in 0..3 {
            x.s[i][6 + i] = 1.0;
        }
        let mut f = M9::zeros();
        let mut dist2 = 0.0;
        for k in first..=last {
            match noise {
                Noise::White => {
                    for r in 0..9 {
                        for c in 0..9 {
                            f[(r, c)] += x.s[0][r] * x.s[0][c]
                                + x.s[1][r] * x.s[1][c]
                                + x.s[2][r] * x.s[2][c];
                        }
                    }
                }
                Noise::WhiteBias => {
                    for i in 0..3 {
                        let u: [f64; 12] = std::array::from_fn(|c| match c {
                            0..=8 => x.s[i][c],
                            _ if c == 9 + i => 1.0,
                            _ => 0.0,
                        });
                        for a in 0..12 {
                            for b in 0..12 {
                                g[(a, b)] += u[a] * u[b];
                            }
                        }
                    }
                }
                Noise::Walk { .. } => {
                    // (C3): the innovations' information, times `r`.
                    for i in 0..3 {
                        if let Some((nu, v)) = whiteners[i].push(&x.s[i]) {
                            let scale = r / v;
                            for a in 0..9 {
                                for b in 0..9 {
                                    f[(a, b)] += scale * nu[a] * nu[b];
                                }
                            }
                        }
                    }
                }
            }
            dist2 += (0..3).map(|i| (x.w[i] - self.w[k][i]).powi(2)).sum::<f64>();
            if k == last {
                break;
            }
            let span = t[k + 1] - t[k];
            let m = (span / MAX_STEP_S).ceil().max(1.0) as usize;
            let dt = span / m as f64;
            for step in 0..m {
                let s0 = t[k] + step as f64 * dt;
                let add = |x: &Sens, d: &Sens, c: f64| {
                    let mut y = *x;
                    for i in 0..3 {
                        y.w[i] += c * d.w[i];
                        for p in 0..9 {
                            y.s[i][p] += c * d.s[i][p];
                        }
                    }
                    y
                };
                let k1 = self.deriv(&jinv, s0, &x);
                let k2 = self.deriv(&jinv, s0 + dt / 2.0, &add(&x, &k1, dt / 2.0));
                let k3 = self.deriv(&jinv, s0 + dt / 2.0, &add(&x, &k2, dt / 2.0));
                let k4 = self.deriv(&jinv, s0 + dt, &add(&x, &k3, dt));
                for i in 0..3 {
                    x.w[i] += dt / 6.0 * (k1.w[i] + 2.0 * k2.w[i] + 2.0 * k3.w[i] + k4.w[i]);
                    for p in 0..9 {
                        x.s[i][p] += dt / 6.0
                            * (k1.s[i][p] + 2.0 * k2.s[i][p] + 2.0 * k3.s[i][p] + k4.s[i][p]);
                    }
                }
            }
        }
        // Schur complement: the window's initial rate (and with `Noise::WhiteBias` its bias) is
        // a nuisance parameter of its own.
        let reduced = if noise == Noise::WhiteBias {
            let fjj: M6 = g.fixed_view::<6, 6>(0, 0).into_owned();
            let fjn: M6 = g.fixed_view::<6, 6>(0, 6).into_owned();
            let fnn: M6 = g.fixed_view::<6, 6>(6, 6).into_owned();
            match scaled_inverse(&fnn) {
                Some(inv) => fjj - fjn * inv * fjn.transpose(),
                None => M6::zeros(),
            }
        } else {
            let fjj: M6 = f.fixed_view::<6, 6>(0, 0).into_owned();
            let fjw: SMatrix<f64, 6, 3> = f.fixed_view::<6, 3>(0, 6).into_owned();
            let fww: Matrix3<f64> = f.fixed_view::<3, 3>(6, 6).into_owned();
            match fww.try_inverse() {
                Some(inv) => fjj - fjw * inv * fjw.transpose(),
                None => M6::zeros(),
            }
        };
        let rms = (dist2 / (3 * (last - first + 1)) as f64).sqrt();
        if let Ok(mut c) = self.cache.lock() {
            c.insert(key, (reduced, rms));
        }
        (reduced, rms)
    }

    /// The bound of the windows `spans` under the fixture's noise model: the six entries'
    /// covariance and standard deviations, and the largest RMS distance of the integrated truth
    /// from the clean rates over them. `None` when their information is not positive definite
    /// (a reduction by the initial rate that lost its digits to rounding, on a trajectory whose
    /// sensitivities grow over its span, is not a bound).
    fn bound(&self, spans: &[(usize, usize)]) -> Option<Bound> {
        self.bound_under(spans, self.noise)
    }

    /// [`Fixture::bound`] under the noise model `noise` (white noise of variance `white_var`).
    fn bound_under(&self, spans: &[(usize, usize)], noise: Noise) -> Option<Bound> {
        let mut info = M6::zeros();
        let mut worst: f64 = 0.0;
        for &(a, b) in spans {
            let (f, d) = self.window_information(a, b, noise);
            info += f;
            worst = worst.max(d);
        }
        if !positive_definite(&info) {
            return None;
        }
        let cov = scaled_inverse(&info)? * self.white_var;
        Some(Bound {
            std: std::array::from_fn(|i| cov[(i, i)].max(0.0).sqrt()),
            cov,
            fidelity: worst,
        })
    }

    /// The log with the seed's gyro: white noise of the truth's std added to the clean rates
    /// (Y1), or the fixture's kind of MEMS gyro ((Y2), (Y3)).
    fn noisy(&self, seed: u64) -> Recording {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut rec = self.clean.clone();
        let mut walk = [0.0f64; 3];
        for (g, w) in rec.gyro.iter_mut().zip(&self.w) {
            for i in 0..3 {
                let n: f64 = StandardNormal.sample(&mut rng);
                g[i] = match self.gyro {
                    Gyro::White => (w[i] + self.sigma * n) as f32,
                    Gyro::Mems => {
                        let step: f64 = StandardNormal.sample(&mut rng);
                        let bound = self.walk.bound_rad_s;
                        let x = walk[i] + self.walk.step_std_rad_s_per_sample * step;
                        walk[i] = if bound > 0.0 {
                            x.clamp(-bound, bound)
                        } else {
                            x
                        };
                        let v = (w[i] + self.sigma * n) + (walk[i] + self.bias[i]);
                        ((v / self.lsb).trunc() * self.lsb) as f32
                    }
                };
            }
        }
        rec
    }
}

/// A Cramer-Rao bound on the six entries.
#[derive(Clone, Copy)]
struct Bound {
    /// Standard deviations, kg m^2.
    std: [f64; 6],
    /// Covariance, (kg m^2)^2.
    cov: M6,
    /// The worst window's RMS distance of the integrated truth from the clean rates, rad/s.
    fidelity: f64,
}

/// Mean and RMS of the relative Frobenius error (percent) of a Gaussian error of each of the
/// covariances `covs` in turn (`draws` in all, a fixed seed).
fn frobenius_at(covs: &[M6], truth: &Matrix3<f64>, draws: usize) -> Option<(f64, f64)> {
    let factors: Vec<M6> = covs
        .iter()
        .filter_map(|c| c.cholesky().map(|l| l.l()))
        .collect();
    if factors.is_empty() {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let (mut sum, mut sum2) = (0.0, 0.0);
    for d in 0..draws {
        let z = SMatrix::<f64, 6, 1>::from_fn(|_, _| StandardNormal.sample(&mut rng));
        let e = factors[d % factors.len()] * z;
        let f = frobenius_percent(&(matrix_of(&std::array::from_fn(|c| e[c])) + truth), truth);
        sum += f;
        sum2 += f * f;
    }
    let n = draws as f64;
    Some((sum / n, (sum2 / n).sqrt()))
}

/// Whether `f` is positive definite (Cholesky after a diagonal scaling).
fn positive_definite(f: &M6) -> bool {
    let d: [f64; 6] = std::array::from_fn(|i| f[(i, i)]);
    d.iter().all(|&v| v > 0.0)
        && M6::from_fn(|r, c| f[(r, c)] / (d[r] * d[c]).sqrt())
            .cholesky()
            .is_some()
}

/// `F^-1` after a diagonal scaling (the entries' information spans orders of magnitude).
fn scaled_inverse(f: &M6) -> Option<M6> {
    let d: [f64; 6] = std::array::from_fn(|i| {
        let v = f[(i, i)];
        if v > 0.0 {
            1.0 / v.sqrt()
        } else {
            0.0
        }
    });
    if d.contains(&0.0) {
        return None;
    }
    let s = M6::from_fn(|r, c| f[(r, c)] * d[r] * d[c]);
    let inv = s.try_inverse()?;
    Some(M6::from_fn(|r, c| inv[(r, c)] * d[r] * d[c]))
}

/// The windows the product's pipeline closed on `rec` and what became of each fit, read from a
/// `FlightPipeline` fed what `identify` feeds it; with that pipeline's pooled tensor, its std
/// and residual ratio, and whether the gravity gradient was folded in.
struct Windows {
    spans: Vec<(usize, usize, StretchOutcome)>,
    tensor: Option<[[f32; 3]; 3]>,
    tensor_std: Option<[[f32; 3]; 3]>,
    residual_ratio: f32,
    gravity: bool,
}

/// [`product_windows`] through `identify`'s passes: on a log with attitude and position, the
/// passes with the gravity gradient folded in at the previous pass's tensor until it moves by
/// less than a tenth of its std (at most `gravity::MAX_PASSES`), kept when their residual is
/// smaller (`inertia::identify::identify_source`).
///
/// Where `identify` took the gyro's readings as truncated toward zero (`Report::gyro_grid`),
/// the pipeline is fed them moved to their counts' centres, as `identify` fed its own ((Q1) of
/// `inertia::grid`).
fn replica(rec: &Recording, vehicle: &Vehicle, report: &Report) -> Result<Windows> {
    let centred;
    let rec = match &report.gyro_grid {
        Some(g) if g.centred => {
            let mut c = rec.clone();
            inertia::grid::centre_readings(&mut c.gyro, g.lsb_rad_s);
            centred = c;
            &centred
        }
        _ => rec,
    };
    let free = product_windows(rec, vehicle, report, None)?;
    if rec.attitude.is_none() || rec.position.is_none() {
        return Ok(free);
    }
    let mut last: Option<Windows> = None;
    for _ in 0..gravity::MAX_PASSES {
        let Some(j) = last.as_ref().map_or(free.tensor, |w| w.tensor) else {
            break;
        };
        let next = product_windows(rec, vehicle, report, Some(j))?;
        let moved = identifier_core::gravity::tensor_moved(&j, next.tensor, next.tensor_std);
        last = Some(next);
        if identifier_core::gravity::settled(moved) {
            break;
        }
    }
    match last {
        Some(w) if identifier_core::gravity::keep_folded(w.residual_ratio, free.residual_ratio) => {
            Ok(w)
        }
        _ => Ok(free),
    }
}

fn product_windows(
    rec: &Recording,
    vehicle: &Vehicle,
    report: &Report,
    fold_at: Option<[[f32; 3]; 3]>,
) -> Result<Windows> {
    let mut fold = fold_at.map(gravity::GravityFold::new);
    let settings = PipelineSettings::for_rate(report.rate_hz, report.noise_std)
        .with_full_scale(rec.gyro_full_scale)
        .with_momentum_resolution(0.0)
        .with_averaging_gyro(rec.gyro_averaging)
        .with_filtered_gyro(rec.gyro_smoothing())
        .with_centred_readings(report.gyro_grid.as_ref().is_some_and(|g| g.centred));
    let with_accel = rec.accel.is_some();
    let mut p = FlightPipeline::new(settings, with_accel).context("pipeline settings")?;
    let dt_med = median_dt(&rec.t);
    let mut spans = Vec::new();
    let mut open: Option<(usize, usize)> = None;
    let mut wheels = vec![0.0f32; rec.wheels.len()];
    for k in 0..rec.t.len() {
        for (w, col) in wheels.iter_mut().zip(&rec.wheels) {
            *w = col[k];
        }
        let mut h = vehicle.momentum(&wheels);
        if let (Some(f), Some(q), Some(r)) = (&mut fold, &rec.attitude, &rec.position) {
            let e = f.step(rec.t[k], q[k], r[k]);
            h = [h[0] + e[0], h[1] + e[1], h[2] + e[2]];
        }
        let dt = if k == 0 {
            dt_med as f32
        } else {
            (rec.t[k] - rec.t[k - 1]) as f32
        };
        let accel = rec.accel.as_ref().map_or([0.0; 3], |a| a[k]);
        if let Some(exit) = p.step(rec.gyro[k], accel, h, dt) {
            if exit.fed.is_some() {
                let first = exit.sample.first_input as usize;
                let last = first + usize::from(exit.sample.inputs).max(1) - 1;
                open = Some(open.map_or((first, last), |(a, _)| (a, last)));
            }
        }
        if p.fits_pending() {
            // A window (W1) closed (or the flight ended): its fits, now.
            p.fit_ended_flight();
            if let Some((a, b)) = open.take() {
                spans.push((a, b, p.tensor_fit().last_outcome()));
            }
        }
    }
    p.end_stretch();
    if let Some((a, b)) = open.take() {
        spans.push((a, b, p.tensor_fit().last_outcome()));
    }
    let e = p.estimate();
    Ok(Windows {
        spans,
        tensor: e.tensor,
        tensor_std: e.tensor_std,
        residual_ratio: e.residual_ratio,
        gravity: fold_at.is_some(),
    })
}

/// Derivative least squares over the whole log: central differences of the rate and of the
/// wheel momentum, `J w' + w x (J w + h) = -h'` for the six entries; with `gg` (the
/// gravity-gradient torque (G1) per sample as a linear map of the entries) `J w' + w x (J w +
/// h) - tau(J) = -h'`. The estimate and the ordinary least-squares standard deviations.
fn derivative_ls(
    t: &[f64],
    y: &[[f64; 3]],
    h: &[[f64; 3]],
    gg: Option<&[[[f64; 6]; 3]]>,
) -> Option<([f64; 6], [f64; 6])> {
    let n = t.len();
    if n < 5 {
        return None;
    }
    // `J v` as a linear map of the six entries.
    let jv = |v: [f64; 3]| -> [[f64; 6]; 3] {
        [
            [v[0], 0.0, 0.0, v[1], v[2], 0.0],
            [0.0, v[1], 0.0, v[0], 0.0, v[2]],
            [0.0, 0.0, v[2], 0.0, v[0], v[1]],
        ]
    };
    let mut rows: Vec<([f64; 6], f64)> = Vec::with_capacity(3 * n);
    for k in 1..n - 1 {
        let span = t[k + 1] - t[k - 1];
        let dw: [f64; 3] = std::array::from_fn(|i| (y[k + 1][i] - y[k - 1][i]) / span);
        let dh: [f64; 3] = std::array::from_fn(|i| (h[k + 1][i] - h[k - 1][i]) / span);
        let w = y[k];
        let a1 = jv(dw);
        let a2 = jv(w);
        let wxh = cross(w, h[k]);
        for r in 0..3 {
            // (w x (J w))_r = sum over the cross product's terms of the rows of J w.
            let (p, q) = ((r + 1) % 3, (r + 2) % 3);
            let tau = |c: usize| gg.map_or(0.0, |g| g[k][r][c]);
            let row: [f64; 6] =
                std::array::from_fn(|c| a1[r][c] + w[p] * a2[q][c] - w[q] * a2[p][c] - tau(c));
            rows.push((row, -dh[r] - wxh[r]));
        }
    }
    let mut ata = M6::zeros();
    let mut atb = SMatrix::<f64, 6, 1>::zeros();
    for (row, b) in &rows {
        for r in 0..6 {
            atb[r] += row[r] * b;
            for c in 0..6 {
                ata[(r, c)] += row[r] * row[c];
            }
        }
    }
    let inv = scaled_inverse(&ata)?;
    let theta = inv * atb;
    let rss: f64 = rows
        .iter()
        .map(|(row, b)| {
            let fit: f64 = (0..6).map(|c| row[c] * theta[c]).sum();
            (b - fit).powi(2)
        })
        .sum();
    let s2 = rss / (rows.len() - 6) as f64;
    Some((
        std::array::from_fn(|i| theta[i]),
        std::array::from_fn(|i| (s2 * inv[(i, i)]).max(0.0).sqrt()),
    ))
}

fn entries_of(m: &Matrix3<f64>) -> [f64; 6] {
    std::array::from_fn(|c| m[ENTRIES[c]])
}

fn matrix_of(e: &[f64; 6]) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for (c, &(i, j)) in ENTRIES.iter().enumerate() {
        m[(i, j)] = e[c];
        m[(j, i)] = e[c];
    }
    m
}

/// Relative Frobenius error, percent.
fn frobenius_percent(est: &Matrix3<f64>, truth: &Matrix3<f64>) -> f64 {
    100.0 * (est - truth).norm() / truth.norm()
}

/// Angle between each estimated principal axis and the true one, degrees, the axes in the
/// order of ascending moments.
fn axis_errors(est: &Matrix3<f64>, truth: &Matrix3<f64>) -> [f64; 3] {
    let sorted = |m: &Matrix3<f64>| {
        let e = SymmetricEigen::new(*m);
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]));
        idx.map(|i| e.eigenvectors.column(i).into_owned())
    };
    let (a, b) = (sorted(est), sorted(truth));
    std::array::from_fn(|i| a[i].dot(&b[i]).abs().min(1.0).acos().to_degrees())
}

/// One seed's results.
struct Seed {
    report_error: Option<String>,
    status: String,
    tensor_status: String,
    tensor_method: String,
    model: String,
    /// Product's estimate and stated std of the six entries.
    product: Option<([f64; 6], [f64; 6])>,
    /// The replica pipeline's tensor equals identify's, bit for bit.
    replica_matches: bool,
    windows: Vec<(usize, usize, StretchOutcome)>,
    /// The bound of the fitted windows (all windows when none was fitted), and whether only
    /// fitted windows were used.
    bound: Option<[f64; 6]>,
    /// Its covariance.
    cov: Option<M6>,
    bound_fitted_only: bool,
    /// The windows of the bound, `(first, last)` sample.
    bound_spans: Vec<(usize, usize)>,
    fidelity: f64,
    peer: Option<([f64; 6], [f64; 6])>,
    /// Derivative least squares with the gravity-gradient torque among its regressors, on a
    /// log with attitude and position.
    peer_gg: Option<([f64; 6], [f64; 6])>,
    noise_estimate: f32,
    /// The gyro bias's rate random walk `identify` found, rad/s per sqrt(s) (`None`: none).
    walk_estimate: Option<f32>,
    /// `identify` kept the fit with the gravity gradient folded in.
    gravity: bool,
    /// The replica's choice of fold agrees with `identify`'s.
    replica_gravity_matches: bool,
    /// The seed's gyro error against the clean rates.
    gyro_error: ErrorStats,
}

fn run_seed(fx: &Fixture, seed: u64) -> Result<Seed> {
    let rec = fx.noisy(seed);
    let opts = IdentifyOptions {
        vehicle: Some(fx.vehicle.clone()),
        ..IdentifyOptions::default()
    };
    let y: Vec<[f64; 3]> = rec.gyro.iter().map(|g| g.map(f64::from)).collect();
    let peer = derivative_ls(&rec.t, &y, &fx.h, None);
    let peer_gg = fx
        .gg_rows
        .as_deref()
        .and_then(|g| derivative_ls(&rec.t, &y, &fx.h, Some(g)));
    let gyro_error = error_stats(&rec.gyro, &fx.w);
    let report = match identify(&rec, &opts) {
        Ok(r) => r,
        Err(e) => {
            return Ok(Seed {
                report_error: Some(e.to_string()),
                status: "error".into(),
                tensor_status: "error".into(),
                tensor_method: "-".into(),
                model: "-".into(),
                product: None,
                replica_matches: false,
                windows: Vec::new(),
                bound: None,
                cov: None,
                bound_fitted_only: false,
                bound_spans: Vec::new(),
                fidelity: f64::NAN,
                peer,
                peer_gg,
                noise_estimate: f32::NAN,
                walk_estimate: None,
                gravity: false,
                replica_gravity_matches: false,
                gyro_error,
            })
        }
    };
    let win = replica(&rec, &fx.vehicle, &report)?;
    let p = &report.pooled;
    let replica_matches = win.tensor.map(|t| t.map(|r| r.map(f32::to_bits)))
        == p.tensor_kg_m2.map(|t| t.map(|r| r.map(f32::to_bits)));
    let fitted: Vec<(usize, usize)> = win
        .spans
        .iter()
        .filter(|s| matches!(s.2, StretchOutcome::Fitted | StretchOutcome::FittedWithBias))
        .map(|s| (s.0, s.1))
        .collect();
    let bound_fitted_only = !fitted.is_empty();
    let used: Vec<(usize, usize)> = if bound_fitted_only {
        fitted
    } else {
        win.spans.iter().map(|s| (s.0, s.1)).collect()
    };
    let (bound, cov, fidelity) = match if fx.with_bound { fx.bound(&used) } else { None } {
        Some(b) => (Some(b.std), Some(b.cov), b.fidelity),
        None => (None, None, f64::NAN),
    };
    let product = p.tensor_kg_m2.zip(p.tensor_std_kg_m2).map(|(t, s)| {
        let t = Matrix3::from_fn(|r, c| f64::from(t[r][c]));
        let s = Matrix3::from_fn(|r, c| f64::from(s[r][c]));
        (entries_of(&t), entries_of(&s))
    });
    Ok(Seed {
        report_error: None,
        status: p.status.clone(),
        tensor_status: p.tensor_status.clone(),
        tensor_method: p.tensor_method.clone(),
        model: p.model.clone(),
        product,
        replica_matches,
        windows: win.spans,
        bound,
        cov,
        bound_fitted_only,
        bound_spans: used,
        fidelity,
        peer,
        peer_gg,
        noise_estimate: report.noise_std,
        walk_estimate: report.gyro_bias_walk_rad_s_per_sqrt_s,
        gravity: report.gravity_gradient,
        replica_gravity_matches: win.gravity == report.gravity_gradient,
        gyro_error,
    })
}

fn counts<S: Into<String>>(items: impl Iterator<Item = S>) -> String {
    let mut m: BTreeMap<String, usize> = BTreeMap::new();
    for s in items {
        *m.entry(s.into()).or_default() += 1;
    }
    m.iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NAN, f64::max)
}

/// A number to 3 significant digits, or `-`.
fn g3(x: f64) -> String {
    if !x.is_finite() {
        return "-".into();
    }
    let a = x.abs();
    if a != 0.0 && !(1e-2..1e4).contains(&a) {
        format!("{x:.2e}")
    } else if a >= 100.0 {
        format!("{x:.0}")
    } else if a >= 10.0 {
        format!("{x:.1}")
    } else if a >= 1.0 {
        format!("{x:.2}")
    } else {
        format!("{x:.3}")
    }
}

/// Errors, error over bound, error over stated std, per entry, for the seeds with both.
struct EntryStats {
    err: [Vec<f64>; 6],
    over_bound: [Vec<f64>; 6],
    over_std: [Vec<f64>; 6],
    std: [Vec<f64>; 6],
    bound: [Vec<f64>; 6],
    std_over_bound: [Vec<f64>; 6],
    frob: Vec<f64>,
    axes: [Vec<f64>; 3],
}

impl EntryStats {
    fn new() -> Self {
        EntryStats {
            err: Default::default(),
            over_bound: Default::default(),
            over_std: Default::default(),
            std: Default::default(),
            bound: Default::default(),
            std_over_bound: Default::default(),
            frob: Vec::new(),
            axes: Default::default(),
        }
    }

    fn add(&mut self, truth: &Matrix3<f64>, est: &([f64; 6], [f64; 6]), bound: Option<[f64; 6]>) {
        let t = entries_of(truth);
        for c in 0..6 {
            let e = est.0[c] - t[c];
            self.err[c].push(e);
            self.over_std[c].push(e / est.1[c]);
            self.std[c].push(est.1[c]);
            if let Some(b) = bound {
                self.over_bound[c].push(e / b[c]);
                self.bound[c].push(b[c]);
                self.std_over_bound[c].push(est.1[c] / b[c]);
            }
        }
        let m = matrix_of(&est.0);
        self.frob.push(frobenius_percent(&m, truth));
        let ax = axis_errors(&m, truth);
        for i in 0..3 {
            self.axes[i].push(ax[i]);
        }
    }
}

/// The product against derivative least squares (and, on a log with attitude and position,
/// derivative least squares with the gravity-gradient torque among its regressors): Frobenius
/// errors and principal axes.
fn comparison(fx: &Fixture, prod: &EntryStats, peer: &EntryStats, peer_gg: Option<&EntryStats>) {
    let cols: Vec<&EntryStats> = [Some(prod), Some(peer), peer_gg]
        .into_iter()
        .flatten()
        .collect();
    let row = |label: &str, f: &dyn Fn(&EntryStats) -> String| {
        let cells: Vec<String> = cols.iter().map(|c| f(c)).collect();
        println!("| {label} | {} |", cells.join(" | "));
    };
    if peer_gg.is_some() {
        println!(
            "| | product (`inertia identify`) | derivative least squares | derivative least squares with (G1) |"
        );
        println!("|---|---|---|---|");
    } else {
        println!("| | product (`inertia identify`) | derivative least squares |");
        println!("|---|---|---|");
    }
    row("seeds with an estimate", &|c| c.frob.len().to_string());
    row("Frobenius error, mean / max", &|c| {
        format!("{} % / {} %", g3(mean(&c.frob)), g3(max(&c.frob)))
    });
    row("Frobenius error, RMS", &|c| {
        format!("{} %", g3(rms(&c.frob)))
    });
    let e = SymmetricEigen::new(fx.truth);
    let mut moments: Vec<f64> = e.eigenvalues.iter().copied().collect();
    moments.sort_by(f64::total_cmp);
    for i in 0..3 {
        // The axis of a moment repeated to 0.1 % is not determined by the truth either: its
        // direction within the pair's plane is arbitrary (the products split the pair).
        let gap = (0..3)
            .filter(|&k| k != i)
            .map(|k| (moments[k] - moments[i]).abs() / moments[i])
            .fold(f64::INFINITY, f64::min);
        let note = if gap < 1e-3 {
            format!(
                " (repeated to {} %: the axis is not determined)",
                g3(100.0 * gap)
            )
        } else {
            String::new()
        };
        row(
            &format!(
                "principal axis of the moment {} kg m^2{note}, error mean / max",
                g3(moments[i])
            ),
            &|c| format!("{} / {} deg", g3(mean(&c.axes[i])), g3(max(&c.axes[i]))),
        );
    }
    row("per entry: RMS(error / stated std)", &|c| {
        let v: Vec<f64> = (0..6).map(|k| rms(&c.over_std[k])).collect();
        format!(
            "{}-{}",
            g3(v.iter().copied().fold(f64::INFINITY, f64::min)),
            g3(max(&v))
        )
    });
    println!();
}

/// The std's calibration per status (a `Converged` estimate must be within its std): per status,
/// its seeds and the range of RMS(error / stated std) over the entries.
fn status_lines(fx: &Fixture, seeds: &[Seed]) {
    let mut statuses: Vec<&str> = seeds.iter().map(|s| s.status.as_str()).collect();
    statuses.sort_unstable();
    statuses.dedup();
    for st in statuses {
        let mut by = EntryStats::new();
        for s in seeds.iter().filter(|s| s.status == st) {
            if let Some(p) = &s.product {
                by.add(&fx.truth, p, None);
            }
        }
        let v: Vec<f64> = (0..6).map(|k| rms(&by.over_std[k])).collect();
        println!(
            "- status {st}: {} seeds, RMS(error / stated std) per entry {}-{}",
            by.over_std[0].len(),
            g3(v.iter().copied().fold(f64::INFINITY, f64::min)),
            g3(max(&v))
        );
    }
}

/// The check of (C3) on one seed's windows: with the walk's step set to 0 it must give the
/// white-noise bound of variance `r` with a constant bias per window, computed with the bias
/// columns kept and eliminated by a Schur complement (`Noise::WhiteBias`). Beside it, what the
/// walk adds to that bound and what the bias adds to the white-noise bound of variance `r`.
fn bound_check(fx: &Fixture, seed: &Seed) {
    let spans = &seed.bound_spans;
    let under = |noise: Noise| fx.bound_under(spans, noise).map(|b| b.std);
    let (Some(walk), Some(still), Some(biased), Some(white)) = (
        under(fx.noise),
        under(Noise::Walk { step_var: 0.0 }),
        under(Noise::WhiteBias),
        under(Noise::White),
    ) else {
        println!("- the bound's check: a bound is not positive definite on the seed's windows");
        return;
    };
    let range = |v: [f64; 6]| {
        format!(
            "{}-{}",
            g3(v.iter().copied().fold(f64::INFINITY, f64::min)),
            g3(max(&v))
        )
    };
    let worst = (0..6)
        .map(|c| (still[c] / biased[c] - 1.0).abs())
        .fold(0.0, f64::max);
    println!(
        "- the bound's check on the first seed's windows with a bound: with the walk's step set \
         to 0, (C3) gives the white-noise bound of variance sigma^2 + LSB^2/12 with a constant \
         bias per window (the bias columns kept and eliminated by a Schur complement instead) to \
         {:.1e} relative at most over the entries. There the walk raises that bound {} times \
         per entry, and the bias per window raises the white-noise bound of that variance \
         without a bias {} times.",
        worst,
        range(std::array::from_fn(|c| walk[c] / biased[c])),
        range(std::array::from_fn(|c| biased[c] / white[c])),
    );
}

/// The figures of a fixture whose bound is not the model the product fits: errors, stated std
/// and its calibration, no ratio to a bound.
fn report_without_bound(fx: &Fixture, seeds: &[Seed]) {
    let t = entries_of(&fx.truth);
    let mut prod = EntryStats::new();
    let mut peer = EntryStats::new();
    let mut peer_gg = EntryStats::new();
    for s in seeds {
        if let Some(p) = &s.product {
            prod.add(&fx.truth, p, None);
        }
        if let Some(p) = &s.peer {
            peer.add(&fx.truth, p, None);
        }
        if let Some(p) = &s.peer_gg {
            peer_gg.add(&fx.truth, p, None);
        }
    }
    println!(
        "| entry | truth, kg m^2 | RMS error | mean error | stated std (RMS over seeds) | RMS error / RMS stated std | RMS(error / stated std) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for c in 0..6 {
        println!(
            "| {} | {} | {} | {} | {} | {} | {} |",
            NAMES[c],
            g3(t[c]),
            g3(rms(&prod.err[c])),
            g3(mean(&prod.err[c])),
            g3(rms(&prod.std[c])),
            g3(rms(&prod.err[c]) / rms(&prod.std[c])),
            g3(rms(&prod.over_std[c])),
        );
    }
    println!();
    status_lines(fx, seeds);
    println!();
    let mut tables = vec![("Derivative least squares on the same logs:", &peer)];
    if fx.gg_rows.is_some() {
        tables.push((
            "Derivative least squares with the gravity-gradient torque (G1) among its regressors \
             (linear in J, from the log's attitude and position) on the same logs:",
            &peer_gg,
        ));
    }
    for (title, st) in tables {
        println!("{title}");
        println!();
        println!("| entry | RMS error | mean error | RMS(error / stated std) |");
        println!("|---|---|---|---|");
        for c in 0..6 {
            println!(
                "| {} | {} | {} | {} |",
                NAMES[c],
                g3(rms(&st.err[c])),
                g3(mean(&st.err[c])),
                g3(rms(&st.over_std[c])),
            );
        }
        println!();
    }
    comparison(fx, &prod, &peer, fx.gg_rows.is_some().then_some(&peer_gg));
}

fn report_fixture(fx: &Fixture, seeds: &[Seed], plan: &Plan, elapsed: f64) {
    let n = seeds.len();
    let t = entries_of(&fx.truth);
    let samples = fx.clean.t.len();
    let rate = 1.0 / median_dt(&fx.clean.t);
    println!("### {}", fx.name);
    println!();
    let gyro = match fx.gyro {
        Gyro::White => format!(
            "gyro noise {} rad/s added to the clean rates (Y1)",
            g3(fx.sigma)
        ),
        Gyro::Mems => format!(
            "a gyro of the fixture's kind made from the clean rates per seed ((Y2), (Y3)): white \
             noise {} rad/s, constant bias ({}, {}, {}) rad/s, bias random walk of {} rad/s per \
             sample held within +-{} rad/s, truncated toward zero to the LSB {} rad/s",
            g3(fx.sigma),
            g3(fx.bias[0]),
            g3(fx.bias[1]),
            g3(fx.bias[2]),
            g3(fx.walk.step_std_rad_s_per_sample),
            g3(fx.walk.bound_rad_s),
            g3(fx.lsb)
        ),
    };
    println!(
        "{} ({} samples at {} Hz, {gyro}, {n} seeds, {:.1} s)",
        fx.description,
        samples,
        g3(rate),
        elapsed
    );
    println!();
    // Statuses and windows.
    println!(
        "- `inertia identify` statuses: status {}; tensor_status {}; tensor_method {}; model {}",
        counts(seeds.iter().map(|s| s.status.as_str())),
        counts(seeds.iter().map(|s| s.tensor_status.as_str())),
        counts(seeds.iter().map(|s| s.tensor_method.as_str())),
        counts(seeds.iter().map(|s| s.model.as_str())),
    );
    let errors: Vec<&str> = seeds
        .iter()
        .filter_map(|s| s.report_error.as_deref())
        .collect();
    if let Some(e) = errors.first() {
        println!("- `identify` failed on {} seeds: {e}", errors.len());
    }
    let with_tensor = seeds.iter().filter(|s| s.product.is_some()).count();
    println!("- seeds with a tensor: {with_tensor} of {n}");
    let noise: Vec<f64> = seeds
        .iter()
        .map(|s| f64::from(s.noise_estimate))
        .filter(|x| x.is_finite())
        .collect();
    println!(
        "- gyro noise the product estimated from the data: mean {} rad/s (range {}-{}; truth {})",
        g3(mean(&noise)),
        g3(noise.iter().copied().fold(f64::INFINITY, f64::min)),
        g3(max(&noise)),
        g3(fx.sigma)
    );
    let walks: Vec<f64> = seeds
        .iter()
        .filter_map(|s| s.walk_estimate.map(f64::from))
        .collect();
    let truth_walk = if fx.gyro == Gyro::Mems {
        format!(
            "truth {} rad/s per sqrt(s), its step per sample times sqrt(rate)",
            g3(fx.walk.step_std_rad_s_per_sample * (1.0 / median_dt(&fx.clean.t)).sqrt())
        )
    } else {
        "truth none".to_string()
    };
    if walks.is_empty() {
        println!("- gyro bias walk the product found ((F12) of the tensor fit): none on {n} seeds ({truth_walk})");
    } else {
        let mut sorted = walks.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "- gyro bias walk the product found ((F12), (F13) of the tensor fit; the largest of a seed's windows): on {} of {n} seeds, median {} rad/s per sqrt(s) (range {}-{}; {truth_walk})",
            walks.len(),
            g3(sorted[sorted.len() / 2]),
            g3(sorted[0]),
            g3(sorted[sorted.len() - 1]),
        );
    }
    if fx.gyro == Gyro::Mems {
        let stats = |e: &ErrorStats| {
            format!(
                "mean ({}, {}, {}) rad/s, std {} rad/s, lag-1 autocorrelation {}",
                g3(e.mean[0]),
                g3(e.mean[1]),
                g3(e.mean[2]),
                g3(e.std),
                g3(e.lag1)
            )
        };
        let of = |f: &dyn Fn(&ErrorStats) -> f64| -> Vec<f64> {
            seeds.iter().map(|s| f(&s.gyro_error)).collect()
        };
        let span = |v: &[f64]| {
            format!(
                "{} to {}",
                g3(v.iter().copied().fold(f64::INFINITY, f64::min)),
                g3(max(v))
            )
        };
        let seeds_mean = ErrorStats {
            mean: std::array::from_fn(|i| mean(&of(&|e| e.mean[i]))),
            std: mean(&of(&|e| e.std)),
            lag1: mean(&of(&|e| e.lag1)),
        };
        println!(
            "- the gyro's error (reading minus clean rate; std and autocorrelation of the error \
             less its mean): mean over the seeds {} (the seeds' range: mean x {}, y {}, z {}; \
             std {}; lag-1 {}); the fixture's own log (Basilisk's imuSensor): {}",
            stats(&seeds_mean),
            span(&of(&|e| e.mean[0])),
            span(&of(&|e| e.mean[1])),
            span(&of(&|e| e.mean[2])),
            span(&of(&|e| e.std)),
            span(&of(&|e| e.lag1)),
            fx.fixture_error.as_ref().map_or("-".into(), stats)
        );
    }
    if fx.gg_rows.is_some() {
        let folded = seeds.iter().filter(|s| s.gravity).count();
        let agree = seeds.iter().filter(|s| s.replica_gravity_matches).count();
        println!(
            "- the log has attitude and position: `identify` kept the fit with the \
             gravity-gradient torque folded into the momentum ((G1), (G2)) on {folded} of {n} \
             seeds (the replica below chose the same on {agree})"
        );
    }
    let win_count = counts(seeds.iter().map(|s| {
        let fitted = s
            .windows
            .iter()
            .filter(|w| matches!(w.2, StretchOutcome::Fitted | StretchOutcome::FittedWithBias))
            .count();
        format!("{} windows ({} fitted)", s.windows.len(), fitted)
    }));
    println!("- windows (W1) the product closed, per seed: {win_count}");
    let outcomes = counts(
        seeds
            .iter()
            .flat_map(|s| s.windows.iter().map(|w| format!("{:?}", w.2))),
    );
    println!("- their fits' outcomes (all windows of all seeds): {outcomes}");
    if let Some(s) = seeds.iter().find(|s| !s.windows.is_empty()) {
        let spans: Vec<String> = s
            .windows
            .iter()
            .map(|w| format!("{}-{} s", g3(fx.clean.t[w.0]), g3(fx.clean.t[w.1])))
            .collect();
        println!("- seed 0's windows: {}", spans.join(", "));
    }
    let matched = seeds.iter().filter(|s| s.replica_matches).count();
    println!(
        "- the windows are read from a `FlightPipeline` fed what `identify` feeds (same settings, \
         rates, wheel momenta{}, time steps): its pooled tensor equals `identify`'s bit for bit \
         on {matched} of {n} seeds",
        if fx.gg_rows.is_some() {
            ", each pass's gravity-gradient fold"
        } else {
            ""
        }
    );
    if let Some(reason) = plan.no_bound {
        println!("- bound: none here: {reason}");
        println!();
        report_without_bound(fx, seeds);
        return;
    }
    let fitted_only = seeds.iter().filter(|s| s.bound_fitted_only).count();
    let fid: Vec<f64> = seeds
        .iter()
        .map(|s| s.fidelity)
        .filter(|x| x.is_finite())
        .collect();
    let dynamics = if fx.r_b_spline.is_some() {
        "`J w' = (J w + h) x w - h' + tau(J)` with the gravity-gradient torque (G1) of the true \
         dynamics, its dependence on J in the sensitivities (the product folds the torque into \
         the momentum at its previous pass's tensor (G2) and fits until the tensor settles)"
    } else {
        "`J w' = (J w + h) x w - h'`"
    };
    if let Noise::Walk { step_var } = fx.noise {
        println!(
            "- bound: the Cramer-Rao bound of the MEMS gyro (Y2), (Y3) with its error treated as \
             Gaussian (C1), the model the product fits where it finds the walk ((F12), (F13) \
             of the tensor fit): per axis and window a free constant bias, the bias walk of step std {} rad/s \
             per sample (its clamp to +-{} rad/s ignored) and white noise of variance sigma^2 + \
             LSB^2/12 = ({} rad/s)^2 (the white noise and what is left of the truncation once \
             the readings are at their counts' centres), the axes independent; the information \
             U^T Sigma^-1 U (C2), each sensitivity column whitened by a scalar Kalman filter per \
             axis started diffuse (C3); {dynamics}; parameters the six entries and one initial \
             rate and bias per window the product fitted on that seed ({} seeds had no window \
             fitted and take the bound of all their windows), per seed, sensitivities \
             integrated in f64 along the true trajectory (its worst window's RMS distance from \
             the clean rates: {} of the gyro noise). The one-trajectory bound (the whole log \
             from one initial rate and one bias, the walk throughout; `-` where its information \
             reduced by the initial rate is not positive definite in f64) is shown for what the \
             windows cost.",
            g3(step_var.sqrt()),
            g3(fx.walk.bound_rad_s),
            g3(fx.white_var.sqrt()),
            n - fitted_only,
            g3(max(&fid) / fx.sigma)
        );
        if let Some(s) = seeds.iter().find(|s| !s.bound_spans.is_empty()) {
            bound_check(fx, s);
        }
    } else {
        println!(
            "- bound: the Cramer-Rao bound of the model the product fits (output error, white \
             noise of the truth's std; {dynamics}; parameters the six entries and one initial \
             rate per window the product fitted on that seed, since its windows are separate \
             trajectories sharing J and a window whose fit failed is out of its pooled tensor; \
             {} seeds had no window fitted and take the bound of all their windows), per seed, \
             sensitivities integrated in f64 along the true trajectory (its worst window's RMS \
             distance from the clean rates: {} of the gyro noise). The one-trajectory bound (the \
             whole log from one initial rate; `-` where its information reduced by the initial \
             rate is not positive definite in f64) is shown for what the windows cost.",
            n - fitted_only,
            g3(max(&fid) / fx.sigma)
        );
    }
    let whole_bound = fx.bound(&[(0, samples - 1)]);
    let whole = whole_bound.map(|b| b.std);
    println!();

    let mut prod = EntryStats::new();
    let mut peer = EntryStats::new();
    let mut peer_gg = EntryStats::new();
    for s in seeds {
        if let Some(p) = &s.product {
            prod.add(&fx.truth, p, s.bound);
        }
        if let Some(p) = &s.peer {
            peer.add(&fx.truth, p, s.bound);
        }
        if let Some(p) = &s.peer_gg {
            peer_gg.add(&fx.truth, p, s.bound);
        }
    }
    let bound_all: [Vec<f64>; 6] =
        std::array::from_fn(|c| seeds.iter().filter_map(|s| s.bound.map(|b| b[c])).collect());

    println!(
        "| entry | truth, kg m^2 | bound (RMS over seeds) | one-trajectory bound | RMS error | RMS error / RMS bound | RMS(error / own seed's bound) | stated std / bound (mean) | RMS(error / stated std) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for c in 0..6 {
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            NAMES[c],
            g3(t[c]),
            g3(rms(&bound_all[c])),
            whole.map_or("-".into(), |w| g3(w[c])),
            g3(rms(&prod.err[c])),
            g3(rms(&prod.err[c]) / rms(&prod.bound[c])),
            g3(rms(&prod.over_bound[c])),
            g3(mean(&prod.std_over_bound[c])),
            g3(rms(&prod.over_std[c])),
        );
    }
    println!();
    if fx.gyro == Gyro::Mems {
        // The truncation's bias, if the centring (Q1) left any: the mean error beside the RMS.
        let means: Vec<String> = (0..6).map(|c| g3(mean(&prod.err[c]))).collect();
        let share: Vec<f64> = (0..6)
            .map(|c| mean(&prod.err[c]).abs() / rms(&prod.err[c]))
            .collect();
        println!(
            "- the product's mean error per entry (Jxx to Jyz): {} kg m^2, |mean| / RMS error {}-{}",
            means.join(", "),
            g3(share.iter().copied().fold(f64::INFINITY, f64::min)),
            g3(max(&share))
        );
        status_lines(fx, seeds);
        println!();
    }
    let mut tables = vec![("Derivative least squares on the same noisy logs:", &peer)];
    if fx.gg_rows.is_some() {
        tables.push((
            "Derivative least squares with the gravity-gradient torque (G1) among its regressors \
             (linear in J, from the log's attitude and position) on the same noisy logs:",
            &peer_gg,
        ));
    }
    for (title, st) in tables {
        println!("{title}");
        println!();
        println!(
            "| entry | RMS error | mean error | RMS error / RMS bound | RMS(error / stated std) |"
        );
        println!("|---|---|---|---|---|");
        for c in 0..6 {
            println!(
                "| {} | {} | {} | {} | {} |",
                NAMES[c],
                g3(rms(&st.err[c])),
                g3(mean(&st.err[c])),
                g3(rms(&st.err[c]) / rms(&st.bound[c])),
                g3(rms(&st.over_std[c])),
            );
        }
        println!();
    }
    comparison(fx, &prod, &peer, fx.gg_rows.is_some().then_some(&peer_gg));
    let covs: Vec<M6> = seeds.iter().filter_map(|s| s.cov).collect();
    let windowed = frobenius_at(&covs, &fx.truth, 20_000);
    let single = whole_bound.and_then(|b| frobenius_at(&[b.cov], &fx.truth, 20_000));
    let pair = |x: Option<(f64, f64)>| {
        x.map_or("-".to_string(), |(m, r)| {
            format!("mean {} %, RMS {} %", g3(m), g3(r))
        })
    };
    let (model, unknown) = match fx.noise {
        Noise::Walk { .. } => ("the product's windows under (C1)", "initial rate and bias"),
        _ => ("the product's windowed model", "initial rate"),
    };
    println!(
        "Frobenius error at the bound (a Gaussian error of the bound's covariance, 20000 draws): \
         {model} {}; one trajectory over the whole log (the samples' whole information on J, the \
         {unknown} unknown) {}.",
        pair(windowed),
        pair(single)
    );
    println!();
    if let (Some(text), Some(pct)) = (plan.published, plan.published_percent) {
        let product = if prod.frob.is_empty() {
            format!("no tensor on any of the {n} seeds")
        } else {
            format!(
                "{} % mean Frobenius error ({} seeds with a tensor)",
                g3(mean(&prod.frob)),
                prod.frob.len()
            )
        };
        println!(
            "Published: {text} {} %. Here, on this log of the class: the product {product}; \
             derivative least squares {} % mean; at this log's one-trajectory bound {} mean.",
            g3(pct),
            g3(mean(&peer.frob)),
            single.map_or("-".to_string(), |(m, _)| format!("{} %", g3(m)))
        );
        println!();
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    let dir = args.data.clone().unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../inertia/tests/data/spacecraft")
    });
    let plans: Vec<&Plan> = if args.fixture.is_empty() {
        PLANS.iter().collect()
    } else {
        let mut v = Vec::new();
        for f in &args.fixture {
            match PLANS.iter().find(|p| p.name == f) {
                Some(p) => v.push(p),
                None => {
                    let known: Vec<&str> = PLANS.iter().map(|p| p.name).collect();
                    bail!("unknown fixture {f:?} (known: {})", known.join(", "))
                }
            }
        }
        v
    };
    let start = Instant::now();
    println!(
        "## Spacecraft logs (generated by `scripts/bench-spacecraft.sh {}`)",
        args.seeds
    );
    println!();
    for plan in plans {
        let t0 = Instant::now();
        let fx = Fixture::load(&dir, plan)?;
        let seeds: Vec<Seed> = (0..args.seeds)
            .into_par_iter()
            .map(|s| run_seed(&fx, s))
            .collect::<Result<_>>()?;
        report_fixture(&fx, &seeds, plan, t0.elapsed().as_secs_f64());
    }
    println!("Total {:.1} s.", start.elapsed().as_secs_f64());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::Rng;

    /// (C3)'s information on `N` columns of `u` (the first row fixes the diffuse bias).
    fn filtered<const N: usize>(u: &[[f64; N]], step_var: f64, white_var: f64) -> DMatrix<f64> {
        let mut w = Whitener::<N>::new(step_var, white_var);
        let mut f = DMatrix::zeros(N, N);
        for row in u {
            if let Some((nu, v)) = w.push(row) {
                for a in 0..N {
                    for b in 0..N {
                        f[(a, b)] += nu[a] * nu[b] / v;
                    }
                }
            }
        }
        f
    }

    /// (C2) with a dense `Sigma`: `[U 1]^T Sigma^-1 [U 1]`, the bias column then eliminated by a
    /// Schur complement.
    fn dense<const N: usize>(u: &[[f64; N]], step_var: f64, white_var: f64) -> DMatrix<f64> {
        let n = u.len();
        let a = DMatrix::from_fn(n, N + 1, |k, c| if c < N { u[k][c] } else { 1.0 });
        let sigma = DMatrix::from_fn(n, n, |k, l| {
            step_var * k.min(l) as f64 + if k == l { white_var } else { 0.0 }
        });
        let inv = sigma.cholesky().expect("Sigma positive definite").inverse();
        let g = a.transpose() * inv * &a;
        let fjj = g.view((0, 0), (N, N)).into_owned();
        let fjb = g.view((0, N), (N, 1)).into_owned();
        let fbb = g[(N, N)];
        fjj - &fjb * fjb.transpose() / fbb
    }

    fn rows<const N: usize>(n: usize, seed: u64) -> Vec<[f64; N]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // A slow trend plus scatter, like sensitivities growing along a trajectory.
        (0..n)
            .map(|k| {
                std::array::from_fn(|c| (c as f64 + 1.0) * k as f64 / n as f64 + rng.gen::<f64>())
            })
            .collect()
    }

    fn relative(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).abs().max() / b.abs().max()
    }

    /// (C3) is (C2) exactly: the diffuse filter's innovations whiten the columns with the bias
    /// eliminated, at unit scales and at the MEMS fixture's (`s^2` against `r`).
    #[test]
    fn whitener_is_the_dense_information() {
        for (step_var, white_var) in [(0.3, 1.0), (1e-3, 2.0), (9e-12, 4.6e-8)] {
            let u = rows::<3>(80, 7);
            let f = filtered(&u, step_var, white_var);
            let d = dense(&u, step_var, white_var);
            assert!(
                relative(&f, &d) < 1e-9,
                "s^2 {step_var}, r {white_var}: {f} against {d}"
            );
        }
    }

    /// With the walk's step 0, (C3) is the white-noise information of variance `r` with a
    /// constant bias eliminated: `(U^T U - U^T 1 1^T U / n) / r`.
    #[test]
    fn still_walk_is_white_noise_with_a_bias() {
        let white_var = 4.6e-8;
        let u = rows::<4>(50, 11);
        let n = u.len();
        let m = DMatrix::from_fn(n, 4, |k, c| u[k][c]);
        let ones = DMatrix::from_element(n, 1, 1.0);
        let sum = m.transpose() * &ones;
        let white = (m.transpose() * &m - &sum * sum.transpose() / n as f64) / white_var;
        let f = filtered(&u, 0.0, white_var);
        assert!(relative(&f, &white) < 1e-10, "{f} against {white}");
    }
}
