//! Cramer-Rao bounds of the free flight for the inertia-tensor model with rotor momentum.
//!
//! Model (IMU frame): `J w' = (J w + h) x w - h'` with a known rotor momentum `h(t)`, measured
//! by a gyro `y_k = w(t_k) + b + n_k`, `n_k ~ N(0, sigma^2 I)` white, clipped samples left out
//! (a sample with any axis at full scale is dropped whole, as the on-board step does).
//!
//! Parameters `theta = (p, w(0), [b])`, where `J = J0 + sum_c p_c E_c` for a set of symmetric
//! directions `E_c` (the six unit entries for the absolute tensor, five trace-free ones for the
//! tensor up to scale, two for the diagonal ratios). With `f = w'` and `S = d w / d theta`
//! (3 x (m + 3)), along the motion
//!
//! ```text
//! S' = A S + [B | 0],  S(0) = [0 | I],
//! A  = d f / d w   = J^-1 ([J w + h]x - [w]x J),
//! B_c = d f / d p_c = J^-1 ((E_c w) x w - E_c f),
//! ```
//!
//! integrated by RK4 together with `w` (`f64`). A bias adds the constant columns `I`. The
//! Fisher information is `F = sigma^-2 sum_k H_k^T H_k` over the used samples, `H_k = [S_k | I]`,
//! and the bound is `F^-1` (inverted after a diagonal scaling, the entries of `J` being ~1e-5
//! and those of `w` ~10).
//!
//! Three bounds:
//! * [`absolute_bound`]: the six entries of `J` in kg m^2 (the rotor momentum makes the scale
//!   observable), plus the entries of `J / trace(J)` by the delta method;
//! * [`scale_free_bound`]: without rotor momentum (none, or ignored: the trajectory is the one
//!   without rotor), `J / trace(J)`: five free parameters, bound on all six normalised entries;
//! * [`ratio_bound`]: the paper's ratios `a` of a diagonal body, from the diagonal tensor up to
//!   scale. The rigid body ties the three ratios by `a1 + a2 + a3 + a1 a2 a3 = 0`; [`crate::crb`]
//!   treats them as three free parameters, so its bound is the unconstrained one and
//!   [`ratio_bound_constrained_from_crb`] applies the constraint to it (the two must agree).

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use crate::throw_sim::{cross, inverse3, matvec, Rotor, SimThrow};
use nalgebra::{DMatrix, SMatrix};

/// Order of the six independent entries of a symmetric 3x3 matrix.
pub const ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
/// Names of [`ENTRIES`].
pub const ENTRY_NAMES: [&str; 6] = ["Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"];

/// At most this many tensor directions.
const MAX_DIRS: usize = 6;
const COLS: usize = MAX_DIRS + 3;

/// 6x6 covariance of the tensor entries in [`ENTRIES`] order.
pub type Cov6 = SMatrix<f64, 6, 6>;

/// The free flight a bound is computed for.
#[derive(Clone, Debug)]
pub struct FreeFlight {
    /// Inertia tensor (IMU frame), kg m^2.
    pub inertia: [[f64; 3]; 3],
    /// The rotor; its momentum is a known input.
    pub rotor: Rotor,
    /// Angular velocity at the first sample, rad/s.
    pub omega0: [f64; 3],
    /// Time of the first sample after the release, s (the rotor profile's clock).
    pub s0: f64,
    /// Sample interval, s.
    pub dt: f64,
    /// Number of samples.
    pub n: usize,
    /// Per sample, whether it is used (not clipped); empty: all used.
    pub used: Vec<bool>,
    /// RK4 steps per sample.
    pub substeps: usize,
}

impl FreeFlight {
    /// The true free flight of a simulated throw (samples with `release <= t < catch`),
    /// leaving out the clipped ones.
    pub fn from_throw(sim: &SimThrow) -> Option<Self> {
        let r = sim.free_flight()?;
        if r.is_empty() {
            return None;
        }
        let release = sim.release_s?;
        Some(FreeFlight {
            inertia: sim.config.inertia,
            rotor: sim.config.rotor,
            omega0: sim.omega_true[r.start],
            s0: sim.t[r.start] - release,
            dt: sim.dt(),
            n: r.len(),
            used: sim.gyro_clipped[r.clone()].iter().map(|c| !c).collect(),
            substeps: sim.config.substeps.max(1),
        })
    }

    /// A torque-free body without rotor, `n` samples at `rate_hz` from `omega0`.
    pub fn free(inertia: [[f64; 3]; 3], omega0: [f64; 3], n: usize, rate_hz: f64) -> Self {
        FreeFlight {
            inertia,
            rotor: Rotor::none(),
            omega0,
            s0: 0.0,
            dt: 1.0 / rate_hz,
            n,
            used: Vec::new(),
            substeps: if rate_hz < 500.0 { 20 } else { 2 },
        }
    }

    fn is_used(&self, k: usize) -> bool {
        self.used.get(k).copied().unwrap_or(true)
    }

    /// Number of samples used.
    pub fn samples_used(&self) -> usize {
        (0..self.n).filter(|&k| self.is_used(k)).count()
    }
}

/// `omega` and `S` at one sample.
#[derive(Clone, Copy, Debug)]
pub struct SensState {
    /// Angular velocity, rad/s.
    pub w: [f64; 3],
    /// `S[i][c] = d w_i / d theta_c`: `c < m` tensor directions, then `w(0)` at `m..m + 3`.
    pub s: [[f64; COLS]; 3],
}

fn sym_unit(i: usize, j: usize) -> [[f64; 3]; 3] {
    let mut e = [[0.0; 3]; 3];
    e[i][j] = 1.0;
    e[j][i] = 1.0;
    e
}

/// The six unit directions of [`ENTRIES`].
pub fn entry_directions() -> Vec<[[f64; 3]; 3]> {
    ENTRIES.iter().map(|&(i, j)| sym_unit(i, j)).collect()
}

/// Five trace-free directions: `diag(1,0,-1)`, `diag(0,1,-1)`, and the three products.
/// Their map to the six entries is [`trace_free_map`].
pub fn trace_free_directions() -> Vec<[[f64; 3]; 3]> {
    let mut d1 = [[0.0; 3]; 3];
    d1[0][0] = 1.0;
    d1[2][2] = -1.0;
    let mut d2 = [[0.0; 3]; 3];
    d2[1][1] = 1.0;
    d2[2][2] = -1.0;
    vec![d1, d2, sym_unit(0, 1), sym_unit(0, 2), sym_unit(1, 2)]
}

/// `d (six entries) / d (five trace-free parameters)`.
pub fn trace_free_map() -> DMatrix<f64> {
    let mut m = DMatrix::zeros(6, 5);
    m[(0, 0)] = 1.0;
    m[(1, 1)] = 1.0;
    m[(2, 0)] = -1.0;
    m[(2, 1)] = -1.0;
    m[(3, 2)] = 1.0;
    m[(4, 3)] = 1.0;
    m[(5, 4)] = 1.0;
    m
}

/// Integrates `w` and its sensitivities to the tensor directions `dirs` (at most 6) and to
/// `w(0)`; the rotor momentum is used when `with_rotor`.
pub fn sensitivities(ff: &FreeFlight, dirs: &[[[f64; 3]; 3]], with_rotor: bool) -> Vec<SensState> {
    assert!(dirs.len() <= MAX_DIRS, "at most {MAX_DIRS} directions");
    let m = dirs.len();
    let j = ff.inertia;
    let jinv = inverse3(&j);
    let momentum = |s: f64| {
        if with_rotor {
            ff.rotor.momentum(s)
        } else {
            ([0.0; 3], [0.0; 3])
        }
    };
    let deriv = |s: f64, x: &SensState| -> SensState {
        let w = x.w;
        let (h, dh) = momentum(s);
        let jw = matvec(&j, w);
        let l = [jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]];
        let lxw = cross(l, w);
        let f = matvec(&jinv, [lxw[0] - dh[0], lxw[1] - dh[1], lxw[2] - dh[2]]);
        // A = J^-1 ([L]x - [w]x J).
        let mut a0 = [[0.0; 3]; 3];
        for c in 0..3 {
            let mut e = [0.0; 3];
            e[c] = 1.0;
            let je = [j[0][c], j[1][c], j[2][c]];
            let lx = cross(l, e);
            let wx = cross(w, je);
            for r in 0..3 {
                a0[r][c] = lx[r] - wx[r];
            }
        }
        let mut a = [[0.0; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                a[r][c] = jinv[r][0] * a0[0][c] + jinv[r][1] * a0[1][c] + jinv[r][2] * a0[2][c];
            }
        }
        let mut ds = [[0.0; COLS]; 3];
        for c in 0..m + 3 {
            let col = [x.s[0][c], x.s[1][c], x.s[2][c]];
            let mut v = matvec(&a, col);
            if c < m {
                let ew = matvec(&dirs[c], w);
                let ef = matvec(&dirs[c], f);
                let g = cross(ew, w);
                let b = matvec(&jinv, [g[0] - ef[0], g[1] - ef[1], g[2] - ef[2]]);
                for r in 0..3 {
                    v[r] += b[r];
                }
            }
            for r in 0..3 {
                ds[r][c] = v[r];
            }
        }
        SensState { w: f, s: ds }
    };
    let axpy = |x: &SensState, k: &SensState, h: f64| -> SensState {
        let mut y = *x;
        for r in 0..3 {
            y.w[r] += h * k.w[r];
            for c in 0..m + 3 {
                y.s[r][c] += h * k.s[r][c];
            }
        }
        y
    };
    let mut x = SensState {
        w: ff.omega0,
        s: [[0.0; COLS]; 3],
    };
    for r in 0..3 {
        x.s[r][m + r] = 1.0;
    }
    let sub = ff.substeps.max(1);
    let h = ff.dt / sub as f64;
    let mut out = Vec::with_capacity(ff.n);
    for k in 0..ff.n {
        out.push(x);
        if k + 1 == ff.n {
            break;
        }
        for q in 0..sub {
            let s = ff.s0 + k as f64 * ff.dt + q as f64 * h;
            let k1 = deriv(s, &x);
            let k2 = deriv(s + h / 2.0, &axpy(&x, &k1, h / 2.0));
            let k3 = deriv(s + h / 2.0, &axpy(&x, &k2, h / 2.0));
            let k4 = deriv(s + h, &axpy(&x, &k3, h));
            for r in 0..3 {
                x.w[r] += h / 6.0 * (k1.w[r] + 2.0 * k2.w[r] + 2.0 * k3.w[r] + k4.w[r]);
                for c in 0..m + 3 {
                    x.s[r][c] +=
                        h / 6.0 * (k1.s[r][c] + 2.0 * k2.s[r][c] + 2.0 * k3.s[r][c] + k4.s[r][c]);
                }
            }
        }
    }
    out
}

/// `sum_k H_k^T H_k` over the used samples (Fisher information times `sigma^2`), with
/// `H_k = [S_k | I]` when `bias`.
pub fn gram(ff: &FreeFlight, traj: &[SensState], m: usize, bias: bool) -> DMatrix<f64> {
    let p = m + 3 + if bias { 3 } else { 0 };
    let mut g = DMatrix::zeros(p, p);
    let mut row = vec![0.0; p];
    for (k, x) in traj.iter().enumerate() {
        if !ff.is_used(k) {
            continue;
        }
        for r in 0..3 {
            row[..m + 3].copy_from_slice(&x.s[r][..m + 3]);
            if bias {
                for b in 0..3 {
                    row[m + 3 + b] = if b == r { 1.0 } else { 0.0 };
                }
            }
            for a in 0..p {
                if row[a] == 0.0 {
                    continue;
                }
                for c in a..p {
                    g[(a, c)] += row[a] * row[c];
                }
            }
        }
    }
    for a in 0..p {
        for c in 0..a {
            g[(a, c)] = g[(c, a)];
        }
    }
    g
}

/// `F^-1` of a symmetric positive definite `F`, by Cholesky after scaling to a unit diagonal.
pub fn inverse_spd(f: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let p = f.nrows();
    let d: Vec<f64> = (0..p).map(|i| f[(i, i)]).collect();
    if d.iter().any(|&v| v <= 0.0 || !v.is_finite()) {
        return None;
    }
    let s = DMatrix::from_fn(p, p, |i, j| f[(i, j)] / (d[i] * d[j]).sqrt());
    let inv = s.cholesky()?.inverse();
    let out = DMatrix::from_fn(p, p, |i, j| inv[(i, j)] / (d[i] * d[j]).sqrt());
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// A bound on the tensor (absolute or normalised) and the other parameters.
#[derive(Clone, Debug)]
pub struct TensorBound {
    /// Names of the parameters, in the order of `cov`.
    pub params: Vec<String>,
    /// Covariance bound of all parameters (`sigma^2 (sum H^T H)^-1`).
    pub cov: DMatrix<f64>,
    /// Covariance bound of the six entries of the tensor ([`ENTRIES`] order): kg^2 m^4 for
    /// [`absolute_bound`], dimensionless (normalised by the trace) for [`scale_free_bound`].
    pub cov_j: Cov6,
    /// Standard deviation per entry of the tensor, as a symmetric 3x3.
    pub std_j: [[f64; 3]; 3],
    /// Standard deviation per entry of `J / trace(J)` (delta method for the absolute bound).
    pub std_j_normalized: [[f64; 3]; 3],
    /// Standard deviation of `w(0)`, rad/s.
    pub std_omega0: [f64; 3],
    /// Standard deviation of the gyro bias, rad/s, when estimated.
    pub std_bias: Option<[f64; 3]>,
    /// Samples used.
    pub samples: usize,
}

fn to_sym(v: [f64; 6]) -> [[f64; 3]; 3] {
    let mut s = [[0.0; 3]; 3];
    for (e, &(i, j)) in ENTRIES.iter().enumerate() {
        s[i][j] = v[e];
        s[j][i] = v[e];
    }
    s
}

fn std_of(c: &Cov6) -> [[f64; 3]; 3] {
    to_sym(std::array::from_fn(|e| c[(e, e)].max(0.0).sqrt()))
}

/// `d (J / trace J) / d J` over the six entries.
fn normalize_jacobian(j: &[[f64; 3]; 3]) -> Cov6 {
    let tr = j[0][0] + j[1][1] + j[2][2];
    Cov6::from_fn(|e, f| {
        let (i, k) = ENTRIES[e];
        let diag_f = f < 3;
        (if e == f { 1.0 / tr } else { 0.0 }) - if diag_f { j[i][k] / (tr * tr) } else { 0.0 }
    })
}

fn param_names(first: &[&str], bias: bool) -> Vec<String> {
    let mut v: Vec<String> = first.iter().map(|s| s.to_string()).collect();
    v.extend(["w0x", "w0y", "w0z"].iter().map(|s| s.to_string()));
    if bias {
        v.extend(["bx", "by", "bz"].iter().map(|s| s.to_string()));
    }
    v
}

fn finish(
    params: Vec<String>,
    cov: DMatrix<f64>,
    cov_j: Cov6,
    m: usize,
    bias: bool,
    norm_jac: Option<Cov6>,
    samples: usize,
) -> TensorBound {
    let sd = |i: usize| cov[(i, i)].max(0.0).sqrt();
    let std_j = std_of(&cov_j);
    let std_j_normalized = match norm_jac {
        Some(g) => std_of(&(g * cov_j * g.transpose())),
        None => std_j,
    };
    TensorBound {
        params,
        std_j,
        std_j_normalized,
        cov_j,
        std_omega0: [sd(m), sd(m + 1), sd(m + 2)],
        std_bias: bias.then(|| [sd(m + 3), sd(m + 4), sd(m + 5)]),
        cov,
        samples,
    }
}

/// (a) The absolute tensor with known rotor momentum: parameters the six entries of `J`,
/// `w(0)` and optionally a constant gyro bias; white gyro noise `sigma` (rad/s per sample).
/// `None` when the information is singular (e.g. no rotor momentum: the scale is free).
pub fn absolute_bound(ff: &FreeFlight, sigma: f64, bias: bool) -> Option<TensorBound> {
    let dirs = entry_directions();
    let traj = sensitivities(ff, &dirs, true);
    let g = gram(ff, &traj, 6, bias);
    let cov = inverse_spd(&g)? * (sigma * sigma);
    let cov_j = Cov6::from_fn(|a, b| cov[(a, b)]);
    Some(finish(
        param_names(&ENTRY_NAMES, bias),
        cov,
        cov_j,
        6,
        bias,
        Some(normalize_jacobian(&ff.inertia)),
        ff.samples_used(),
    ))
}

/// (b) The tensor up to scale, `J / trace(J)`, from the motion without rotor momentum (the
/// rotor of `ff` is ignored): five free parameters and `w(0)` (and optionally a bias); the
/// bound is given on all six normalised entries.
pub fn scale_free_bound(ff: &FreeFlight, sigma: f64, bias: bool) -> Option<TensorBound> {
    let j = ff.inertia;
    let tr = j[0][0] + j[1][1] + j[2][2];
    let jn = j.map(|r| r.map(|v| v / tr));
    let ffn = FreeFlight {
        inertia: jn,
        ..ff.clone()
    };
    let dirs = trace_free_directions();
    let traj = sensitivities(&ffn, &dirs, false);
    let g = gram(&ffn, &traj, 5, bias);
    let cov = inverse_spd(&g)? * (sigma * sigma);
    let c5 = cov.view((0, 0), (5, 5)).into_owned();
    let mm = trace_free_map();
    let c6 = &mm * c5 * mm.transpose();
    let cov_j = Cov6::from_fn(|a, b| c6[(a, b)]);
    Some(finish(
        param_names(&["d1", "d2", "Jxy/tr", "Jxz/tr", "Jyz/tr"], bias),
        cov,
        cov_j,
        5,
        bias,
        None,
        ffn.samples_used(),
    ))
}

/// A bound on the paper's ratios `a`.
#[derive(Clone, Debug)]
pub struct RatioBound {
    /// Standard deviation of `(a1, a2, a3)`.
    pub std_a: [f64; 3],
    /// Covariance of `a`.
    pub cov_a: SMatrix<f64, 3, 3>,
}

/// The paper's `a` of a tensor `j`: its principal moments, each assigned to the sensor axis its
/// principal axis lies closest to (as the on-board estimators report them),
/// `a1 = (A2 - A3) / A1` and cyclic.
pub fn a_of_tensor(j: &[[f64; 3]; 3]) -> [f64; 3] {
    let e = nalgebra::SymmetricEigen::new(nalgebra::Matrix3::from_fn(|r, c| j[r][c]));
    let mut m = [f64::NAN; 3];
    for k in 0..3 {
        let v = e.eigenvectors.column(k);
        let axis = (0..3)
            .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
            .unwrap_or(k);
        m[axis] = e.eigenvalues[k];
    }
    [
        (m[1] - m[2]) / m[0],
        (m[2] - m[0]) / m[1],
        (m[0] - m[1]) / m[2],
    ]
}

/// `d a / d (J1, J2, J3)` at the principal moments `m`.
pub fn ratio_jacobian(m: [f64; 3]) -> SMatrix<f64, 3, 3> {
    let [j1, j2, j3] = m;
    SMatrix::<f64, 3, 3>::new(
        -(j2 - j3) / (j1 * j1),
        1.0 / j1,
        -1.0 / j1,
        -1.0 / j2,
        -(j3 - j1) / (j2 * j2),
        1.0 / j2,
        1.0 / j3,
        -1.0 / j3,
        -(j1 - j2) / (j3 * j3),
    )
}

/// (c) The ratios `a = ((J2-J3)/J1, (J3-J1)/J2, (J1-J2)/J3)` of a torque-free diagonal body
/// with principal moments `moments` (any scale), from `n` samples at `rate_hz` from `omega0`,
/// white noise `sigma`. `products_known_zero`: the estimator knows the axes are principal
/// (two free parameters); otherwise the products of inertia are unknown too (five).
pub fn ratio_bound(
    moments: [f64; 3],
    omega0: [f64; 3],
    n: usize,
    rate_hz: f64,
    sigma: f64,
    products_known_zero: bool,
) -> Option<RatioBound> {
    let tr = moments[0] + moments[1] + moments[2];
    let mn = moments.map(|v| v / tr);
    let jn = [[mn[0], 0.0, 0.0], [0.0, mn[1], 0.0], [0.0, 0.0, mn[2]]];
    let ff = FreeFlight::free(jn, omega0, n, rate_hz);
    let cov3 = if products_known_zero {
        principal_moments_cov(&ff, sigma, false)?
    } else {
        let b = scale_free_bound(&ff, sigma, false)?;
        SMatrix::<f64, 3, 3>::from_fn(|a, c| b.cov_j[(a, c)])
    };
    let g = ratio_jacobian(mn);
    let cov_a = g * cov3 * g.transpose();
    Some(RatioBound {
        std_a: std::array::from_fn(|i| cov_a[(i, i)].max(0.0).sqrt()),
        cov_a,
    })
}

/// Covariance bound of the three trace-1 principal moments of a diagonal body (two free
/// directions `diag(1,0,-1)`, `diag(0,1,-1)`, with `w(0)` and, if `bias`, a constant gyro bias).
fn principal_moments_cov(ff: &FreeFlight, sigma: f64, bias: bool) -> Option<SMatrix<f64, 3, 3>> {
    let dirs = trace_free_directions()[..2].to_vec();
    let traj = sensitivities(ff, &dirs, false);
    let cov = inverse_spd(&gram(ff, &traj, 2, bias))? * (sigma * sigma);
    let c2 = SMatrix::<f64, 2, 2>::from_fn(|a, b| cov[(a, b)]);
    let m = SMatrix::<f64, 3, 2>::new(1.0, 0.0, 0.0, 1.0, -1.0, -1.0);
    Some(m * c2 * m.transpose())
}

/// (d) The ratios `a` of a torque-free diagonal body, principal axes known, with an unknown
/// constant gyro bias `b` (`y_k = w(t_k) + b + n_k`): parameters `(p, w(0), b)`, two moments up
/// to scale, eight in all. The bound of the model [`identifier_core::RatioFit`] uses when its
/// test finds a bias.
pub fn ratio_bound_with_bias(
    moments: [f64; 3],
    omega0: [f64; 3],
    n: usize,
    rate_hz: f64,
    sigma: f64,
) -> Option<RatioBound> {
    let tr = moments[0] + moments[1] + moments[2];
    let mn = moments.map(|v| v / tr);
    let jn = [[mn[0], 0.0, 0.0], [0.0, mn[1], 0.0], [0.0, 0.0, mn[2]]];
    let ff = FreeFlight::free(jn, omega0, n, rate_hz);
    let g = ratio_jacobian(mn);
    let cov_a = g * principal_moments_cov(&ff, sigma, true)? * g.transpose();
    Some(RatioBound {
        std_a: std::array::from_fn(|i| cov_a[(i, i)].max(0.0).sqrt()),
        cov_a,
    })
}

/// The bound of [`crate::crb`] (parameters `a` and `w(0)`, `a` free in R^3) with the rigid-body
/// constraint `a1 + a2 + a3 + a1 a2 a3 = 0` applied:
/// `C_c = C - C g (g^T C g)^-1 g^T C`, `g` the constraint's gradient. Equals
/// [`ratio_bound`] with `products_known_zero`. Returns `(unconstrained, constrained)` standard
/// deviations of `a`.
pub fn ratio_bound_constrained_from_crb(
    a: [f64; 3],
    omega0: [f64; 3],
    n: usize,
    rate_hz: f64,
    sigma: f64,
) -> Option<([f64; 3], [f64; 3])> {
    let sub = if rate_hz < 500.0 { 20 } else { 2 };
    let traj = crate::crb::sensitivities(a, omega0, n, 1.0 / rate_hz, sub);
    let f = crate::crb::gram(&traj);
    let fd = DMatrix::from_fn(6, 6, |i, j| f[(i, j)]);
    let c = inverse_spd(&fd)? * (sigma * sigma);
    let mut g = DMatrix::zeros(6, 1);
    g[(0, 0)] = 1.0 + a[1] * a[2];
    g[(1, 0)] = 1.0 + a[0] * a[2];
    g[(2, 0)] = 1.0 + a[0] * a[1];
    let cg = &c * &g;
    let gcg = (g.transpose() * &cg)[(0, 0)];
    let cc = &c - &cg * cg.transpose() / gcg;
    let sd = |m: &DMatrix<f64>, i: usize| m[(i, i)].max(0.0).sqrt();
    Some((
        std::array::from_fn(|i| sd(&c, i)),
        std::array::from_fn(|i| sd(&cc, i)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::throw_sim::RotorProfile;

    /// The variational equations against central differences of the trajectory.
    #[test]
    fn sensitivities_match_finite_differences() {
        let ff = FreeFlight {
            inertia: crate::throw_sim::BOARD_INERTIA,
            rotor: Rotor {
                profile: RotorProfile::board_spin_up(),
                ..Rotor::board()
            },
            omega0: [9.0, -8.0, -13.0],
            s0: 0.05,
            dt: 1.0 / 4000.0,
            n: 1601,
            used: Vec::new(),
            substeps: 2,
        };
        let dirs = entry_directions();
        let tr = sensitivities(&ff, &dirs, true);
        let k = ff.n - 1;
        for c in 0..9 {
            let run = |e: f64| {
                let mut f2 = ff.clone();
                if c < 6 {
                    let (i, j) = ENTRIES[c];
                    f2.inertia[i][j] += e;
                    if i != j {
                        f2.inertia[j][i] += e;
                    }
                } else {
                    f2.omega0[c - 6] += e;
                }
                sensitivities(&f2, &[], true)[k].w
            };
            let e = if c < 6 { 1e-9 } else { 1e-5 };
            let (p, m) = (run(e), run(-e));
            for r in 0..3 {
                let fd = (p[r] - m[r]) / (2.0 * e);
                let s = tr[k].s[r][c];
                let scale = (0..3).map(|q| tr[k].s[q][c].abs()).fold(0.0, f64::max);
                assert!(
                    (fd - s).abs() <= 1e-5 * scale,
                    "col {c} row {r}: fd {fd} vs {s} (scale {scale})"
                );
            }
        }
    }
}
