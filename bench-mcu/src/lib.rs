//! Pieces of the Cortex-M4F instruction-count benchmark that are plain `no_std` code: an `f32`
//! joint state and parameter EKF written the way the host peer is (dense 6x6 covariance), and
//! deterministic test signals (the paper's body from `omega0 = (1, 1, 1)` at 1 kHz, a fast
//! racquet-like toss at 100 Hz, and a board throw with a flywheel spinning up at 2 kHz, all
//! with pseudo-random noise).
#![no_std]
#![allow(clippy::needless_range_loop)]

/// 6x6 matrix, rows.
pub type M6 = [[f32; 6]; 6];

/// Joint EKF on `x = (w1, w2, w3, a1, a2, a3)` for (1) with `a' = 0`: RK4 prediction, the
/// transition `I + hJ + (hJ)^2 / 2`, dense covariance, update with `H = [I 0]`. The same
/// algorithm as `host_tests::estimators::ekf`, in `f32`.
#[derive(Clone, Copy, Debug)]
pub struct Ekf32 {
    /// State.
    pub x: [f32; 6],
    /// Covariance.
    pub p: M6,
    r: f32,
    q: f32,
}

fn rhs(x: &[f32; 6]) -> [f32; 6] {
    [
        x[3] * x[1] * x[2],
        x[4] * x[2] * x[0],
        x[5] * x[0] * x[1],
        0.0,
        0.0,
        0.0,
    ]
}

fn add(x: &[f32; 6], k: &[f32; 6], h: f32) -> [f32; 6] {
    let mut y = *x;
    for i in 0..6 {
        y[i] += h * k[i];
    }
    y
}

fn mul(a: &M6, b: &M6) -> M6 {
    let mut c = [[0.0; 6]; 6];
    for i in 0..6 {
        for j in 0..6 {
            let mut s = 0.0;
            for k in 0..6 {
                s += a[i][k] * b[k][j];
            }
            c[i][j] = s;
        }
    }
    c
}

fn mul_t(a: &M6, b: &M6) -> M6 {
    let mut c = [[0.0; 6]; 6];
    for i in 0..6 {
        for j in 0..6 {
            let mut s = 0.0;
            for k in 0..6 {
                s += a[i][k] * b[j][k];
            }
            c[i][j] = s;
        }
    }
    c
}

impl Ekf32 {
    /// Starts at `omega = y0`, `a = 0`, wide prior on `a`.
    pub fn new(y0: [f32; 3], sigma: f32) -> Self {
        let mut p = [[0.0; 6]; 6];
        for i in 0..3 {
            p[i][i] = sigma * sigma;
            p[3 + i][3 + i] = 1.0;
        }
        Ekf32 {
            x: [y0[0], y0[1], y0[2], 0.0, 0.0, 0.0],
            p,
            r: sigma * sigma,
            q: (1e-3 * sigma) * (1e-3 * sigma),
        }
    }

    /// One predict-update cycle for the sample `y` taken `h` after the previous one.
    pub fn step(&mut self, y: [f32; 3], h: f32) {
        let x = self.x;
        let k1 = rhs(&x);
        let k2 = rhs(&add(&x, &k1, 0.5 * h));
        let k3 = rhs(&add(&x, &k2, 0.5 * h));
        let k4 = rhs(&add(&x, &k3, h));
        for i in 0..6 {
            self.x[i] = x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        let (w, a) = ([x[0], x[1], x[2]], [x[3], x[4], x[5]]);
        let mut jh = [[0.0f32; 6]; 6];
        jh[0][1] = h * a[0] * w[2];
        jh[0][2] = h * a[0] * w[1];
        jh[1][0] = h * a[1] * w[2];
        jh[1][2] = h * a[1] * w[0];
        jh[2][0] = h * a[2] * w[1];
        jh[2][1] = h * a[2] * w[0];
        jh[0][3] = h * w[1] * w[2];
        jh[1][4] = h * w[2] * w[0];
        jh[2][5] = h * w[0] * w[1];
        let jj = mul(&jh, &jh);
        let mut phi = [[0.0f32; 6]; 6];
        for i in 0..6 {
            for j in 0..6 {
                phi[i][j] = jh[i][j] + 0.5 * jj[i][j] + if i == j { 1.0 } else { 0.0 };
            }
        }
        let mut p = mul_t(&mul(&phi, &self.p), &phi);
        for i in 0..3 {
            p[i][i] += self.q;
        }
        // S = P[0..3, 0..3] + r I, inverted by cofactors.
        let s = [
            [p[0][0] + self.r, p[0][1], p[0][2]],
            [p[1][0], p[1][1] + self.r, p[1][2]],
            [p[2][0], p[2][1], p[2][2] + self.r],
        ];
        let c00 = s[1][1] * s[2][2] - s[1][2] * s[2][1];
        let c01 = s[1][2] * s[2][0] - s[1][0] * s[2][2];
        let c02 = s[1][0] * s[2][1] - s[1][1] * s[2][0];
        let det = s[0][0] * c00 + s[0][1] * c01 + s[0][2] * c02;
        if det == 0.0 || det.is_nan() {
            self.p = p;
            return;
        }
        let id = 1.0 / det;
        let si = [
            [
                c00 * id,
                (s[0][2] * s[2][1] - s[0][1] * s[2][2]) * id,
                (s[0][1] * s[1][2] - s[0][2] * s[1][1]) * id,
            ],
            [
                c01 * id,
                (s[0][0] * s[2][2] - s[0][2] * s[2][0]) * id,
                (s[0][2] * s[1][0] - s[0][0] * s[1][2]) * id,
            ],
            [
                c02 * id,
                (s[0][1] * s[2][0] - s[0][0] * s[2][1]) * id,
                (s[0][0] * s[1][1] - s[0][1] * s[1][0]) * id,
            ],
        ];
        let mut k = [[0.0f32; 3]; 6];
        for i in 0..6 {
            for j in 0..3 {
                k[i][j] = p[i][0] * si[0][j] + p[i][1] * si[1][j] + p[i][2] * si[2][j];
            }
        }
        let e = [y[0] - self.x[0], y[1] - self.x[1], y[2] - self.x[2]];
        for i in 0..6 {
            self.x[i] += k[i][0] * e[0] + k[i][1] * e[1] + k[i][2] * e[2];
        }
        let mut pn = p;
        for i in 0..6 {
            for j in 0..6 {
                pn[i][j] -= k[i][0] * p[0][j] + k[i][1] * p[1][j] + k[i][2] * p[2][j];
            }
        }
        for i in 0..6 {
            for j in 0..i {
                let m = 0.5 * (pn[i][j] + pn[j][i]);
                pn[i][j] = m;
                pn[j][i] = m;
            }
        }
        self.p = pn;
    }

    /// The current `a`.
    pub fn a(&self) -> [f32; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }
}

/// `a` of (1) of the paper's body, moments `(0.6, 1.54, 1.0)`.
pub const PAPER_A: [f32; 3] = [0.9, 0.259_740_26, -0.94];

/// Principal moments of the racquet-like body of [`Signal::toss`].
pub const RACQUET_MOMENTS: [f32; 3] = [12.3, 1.0, 13.3];

/// `a` of (1) for principal moments `m`: `a1 = (m2 - m3)/m1` and cyclic.
pub fn ratios(m: [f32; 3]) -> [f32; 3] {
    [
        (m[1] - m[2]) / m[0],
        (m[2] - m[0]) / m[1],
        (m[0] - m[1]) / m[2],
    ]
}

/// Uniform pseudo-random number on `[-0.5, 0.5)` (standard deviation `1/sqrt(12)`) from a
/// linear congruential generator with state `seed`.
fn uniform(seed: &mut u32) -> f32 {
    *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    (*seed >> 8) as f32 / 16_777_216.0 - 0.5
}

/// Deterministic test signal: a body with ratios `a` from `omega0`, integrated in `f32` with
/// classical RK4 (`substeps` steps per sample period `dt`), plus uniform pseudo-random noise of
/// standard deviation `sigma` (a linear congruential generator).
pub struct Signal {
    a: [f32; 3],
    w: [f32; 3],
    dt: f32,
    substeps: u32,
    sigma: f32,
    seed: u32,
}

impl Signal {
    /// The paper's body (`a = (0.9, 0.2597, -0.94)`) from `omega0 = (1, 1, 1)` at 1 kHz with
    /// `sigma = 2e-3 rad/s`; one RK4 step per sample (the motion is slow against 1 kHz).
    pub fn paper() -> Self {
        Signal {
            a: PAPER_A,
            w: [1.0, 1.0, 1.0],
            dt: 1e-3,
            substeps: 1,
            sigma: 2e-3,
            seed: 12345,
        }
    }

    /// A short fast toss of a racquet-like body, moments `(12.3, 1.0, 13.3)` (about the
    /// unstable intermediate axis: it flips), from `omega0 = (7.9, -1.8, 0.5)` rad/s at 100 Hz
    /// with `sigma = 1e-2 rad/s`. Ten RK4 steps per sample: at about 8 rad/s one 10 ms step
    /// would leave a truncation error per sample of the order of the `f32` rounding of the
    /// rates; with 1 ms steps it is far below it.
    pub fn toss() -> Self {
        Signal {
            a: ratios(RACQUET_MOMENTS),
            w: [7.9, -1.8, 0.5],
            dt: 1e-2,
            substeps: 10,
            sigma: 1e-2,
            seed: 54321,
        }
    }

    /// `a` of the body.
    pub fn a(&self) -> [f32; 3] {
        self.a
    }

    /// Sample period.
    pub fn dt(&self) -> f32 {
        self.dt
    }

    /// White noise per sample and axis, rad/s.
    pub fn sigma(&self) -> f32 {
        self.sigma
    }

    fn uniform(&mut self) -> f32 {
        uniform(&mut self.seed)
    }

    /// The next noisy sample.
    pub fn next_sample(&mut self) -> [f32; 3] {
        let a = self.a;
        let f = |w: [f32; 3]| [a[0] * w[1] * w[2], a[1] * w[2] * w[0], a[2] * w[0] * w[1]];
        // `dt / 1` is `dt` exactly: the paper's signal is the same bits as with one step.
        let h = self.dt / self.substeps as f32;
        let w = self.w;
        for _ in 0..self.substeps {
            let x = self.w;
            let k1 = f(x);
            let k2 = f([
                x[0] + 0.5 * h * k1[0],
                x[1] + 0.5 * h * k1[1],
                x[2] + 0.5 * h * k1[2],
            ]);
            let k3 = f([
                x[0] + 0.5 * h * k2[0],
                x[1] + 0.5 * h * k2[1],
                x[2] + 0.5 * h * k2[2],
            ]);
            let k4 = f([x[0] + h * k3[0], x[1] + h * k3[1], x[2] + h * k3[2]]);
            for i in 0..3 {
                self.w[i] = x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        // Uniform on [-0.5, 0.5) has std 1/sqrt(12).
        let s = self.sigma * 3.464_101_6;
        let n = [self.uniform(), self.uniform(), self.uniform()];
        [w[0] + s * n[0], w[1] + s * n[1], w[2] + s * n[2]]
    }
}

/// The anchor board's inertia tensor about its centre of mass, IMU frame, kg m^2 (the host
/// simulator's `host_tests::throw_sim::BOARD_INERTIA`): products of inertia, no principal axes
/// along the sensor's.
pub const BOARD_INERTIA: [[f32; 3]; 3] = [
    [7.5e-5, -1.7e-6, 1.1e-6],
    [-1.7e-6, 2.2e-5, 6.8e-6],
    [1.1e-6, 6.8e-6, 8.8e-5],
];

/// The board's flywheel inertia about its axis (`-z`), kg m^2.
pub const BOARD_ROTOR_INERTIA: f32 = 1.689e-6;

/// `cos(pi x)` for `x` in `[0, 1]`, as `-sin(pi (x - 1/2))` by its Taylor series to the 11th
/// power (`no_std` has no `cos`): the series' error is below `6e-8` on `|y| <= pi/2`, under
/// the `f32` rounding of the result, so this is the cosine as `f32` can hold it.
fn cos_pi(x: f32) -> f32 {
    let y = core::f32::consts::PI * (x - 0.5);
    let y2 = y * y;
    let sin = y
        * (1.0
            - y2 / 6.0
                * (1.0 - y2 / 20.0 * (1.0 - y2 / 42.0 * (1.0 - y2 / 72.0 * (1.0 - y2 / 110.0)))));
    -sin
}

/// `J^-1` by the adjugate (`J` positive definite, so `det > 0`).
fn inverse3(j: &[[f32; 3]; 3]) -> [[f32; 3]; 3] {
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| j[r0][c0] * j[r1][c1] - j[r0][c1] * j[r1][c0];
    let adj = [
        [c(1, 2, 1, 2), -c(0, 2, 1, 2), c(0, 1, 1, 2)],
        [-c(1, 2, 0, 2), c(0, 2, 0, 2), -c(0, 1, 0, 2)],
        [c(1, 2, 0, 1), -c(0, 2, 0, 1), c(0, 1, 0, 1)],
    ];
    let det = j[0][0] * adj[0][0] + j[0][1] * adj[1][0] + j[0][2] * adj[2][0];
    adj.map(|row| row.map(|x| x / det))
}

fn mat_vec(m: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    m.map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2])
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Deterministic free flight of a thrown board ([`BOARD_INERTIA`]) with a flywheel on `-z`
/// ([`BOARD_ROTOR_INERTIA`]) spinning up from 175 to 1250 rad/s by a raised-cosine ramp over
/// 0.15 s that starts 0.08 s after the release, from `omega0 = (9, -8, -13)` rad/s; 0.6 s at
/// 2 kHz, the rate the flight pipeline decimates a 4 kHz log to, with the averaged noise of
/// that log (`2e-3 / sqrt(2)` rad/s, uniform pseudo-random as [`Signal`]'s). What the
/// pipeline hands [`identifier_core::TensorFit`] for one free flight.
///
/// The body's total angular momentum `L = J w + h` (body frame) obeys `L' = L x w` with
/// `w = J^-1 (L - h(t))`, integrated in `f32` by RK4, [`Throw::SUBSTEPS`] steps per sample.
/// The sum of `L` is compensated (Kahan): `|L|` is about `2e-3` kg m^2/s and `J^-1` up to
/// `5e4` per kg m^2, so the rounding of a plain `f32` sum of `L`, amplified into the rates,
/// drifts them by `1.3e-4` rad/s from an `f64` reference over the flight; compensated they
/// stay within `4e-5` rad/s (the test below), far under the `1.4e-3` rad/s of noise, so the
/// fit checked on the target sees the model it fits.
pub struct Throw {
    j_inv: [[f32; 3]; 3],
    l: [f32; 3],
    /// Compensation of `l`'s running sum.
    lc: [f32; 3],
    /// Samples emitted.
    n: u32,
    sigma: f32,
    seed: u32,
}

impl Throw {
    /// Sample rate, Hz.
    pub const RATE_HZ: f32 = 2000.0;
    /// Samples in the free flight (0.6 s).
    pub const SAMPLES: u32 = 1200;
    /// RK4 steps per sample period.
    pub const SUBSTEPS: u32 = 8;

    /// The board's throw (see the type's docs).
    pub fn board() -> Self {
        let j = BOARD_INERTIA;
        let w0 = [9.0, -8.0, -13.0];
        let jw = mat_vec(&j, w0);
        let h0 = Self::rotor_momentum(0.0);
        Throw {
            j_inv: inverse3(&j),
            l: [jw[0] + h0[0], jw[1] + h0[1], jw[2] + h0[2]],
            lc: [0.0; 3],
            n: 0,
            sigma: 2e-3 * core::f32::consts::FRAC_1_SQRT_2,
            seed: 20_240_611,
        }
    }

    /// The true tensor, kg m^2.
    pub fn tensor(&self) -> [[f32; 3]; 3] {
        BOARD_INERTIA
    }

    /// Sample period, s.
    pub fn dt(&self) -> f32 {
        1.0 / Self::RATE_HZ
    }

    /// White noise per sample and axis, rad/s.
    pub fn sigma(&self) -> f32 {
        self.sigma
    }

    /// Flywheel speed `t` seconds after the release, rad/s: idle, a raised-cosine ramp (speed
    /// and acceleration continuous), then the peak.
    pub fn rotor_speed(t: f32) -> f32 {
        const IDLE: f32 = 175.0;
        const PEAK: f32 = 1250.0;
        const START: f32 = 0.08;
        const RAMP: f32 = 0.15;
        let u = t - START;
        if u <= 0.0 {
            IDLE
        } else if u < RAMP {
            IDLE + (PEAK - IDLE) * 0.5 * (1.0 - cos_pi(u / RAMP))
        } else {
            PEAK
        }
    }

    /// Rotor momentum in the body frame `t` seconds after the release, kg m^2/s.
    pub fn rotor_momentum(t: f32) -> [f32; 3] {
        [0.0, 0.0, -BOARD_ROTOR_INERTIA * Self::rotor_speed(t)]
    }

    /// `L' = L x w`, `w = J^-1 (L - h(t))`.
    fn rhs(&self, l: [f32; 3], t: f32) -> [f32; 3] {
        let h = Self::rotor_momentum(t);
        let w = mat_vec(&self.j_inv, [l[0] - h[0], l[1] - h[1], l[2] - h[2]]);
        cross(l, w)
    }

    /// The next sample: the noisy rate (rad/s) and the exact rotor momentum (kg m^2/s), the
    /// first at the release.
    pub fn next_sample(&mut self) -> ([f32; 3], [f32; 3]) {
        let hs = self.dt() / Self::SUBSTEPS as f32;
        // Times from integer step counts, so that they do not drift over the flight.
        let first = self.n * Self::SUBSTEPS;
        let h = Self::rotor_momentum(first as f32 * hs);
        let l = self.l;
        let w = mat_vec(&self.j_inv, [l[0] - h[0], l[1] - h[1], l[2] - h[2]]);
        for i in 0..Self::SUBSTEPS {
            let t = (first + i) as f32 * hs;
            let x = self.l;
            let k1 = self.rhs(x, t);
            let k2 = self.rhs(
                [
                    x[0] + 0.5 * hs * k1[0],
                    x[1] + 0.5 * hs * k1[1],
                    x[2] + 0.5 * hs * k1[2],
                ],
                t + 0.5 * hs,
            );
            let k3 = self.rhs(
                [
                    x[0] + 0.5 * hs * k2[0],
                    x[1] + 0.5 * hs * k2[1],
                    x[2] + 0.5 * hs * k2[2],
                ],
                t + 0.5 * hs,
            );
            let k4 = self.rhs(
                [x[0] + hs * k3[0], x[1] + hs * k3[1], x[2] + hs * k3[2]],
                (first + i + 1) as f32 * hs,
            );
            for k in 0..3 {
                let d = hs / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]) - self.lc[k];
                let s = self.l[k] + d;
                self.lc[k] = (s - self.l[k]) - d;
                self.l[k] = s;
            }
        }
        self.n += 1;
        let s = self.sigma * 3.464_101_6;
        let n = [
            uniform(&mut self.seed),
            uniform(&mut self.seed),
            uniform(&mut self.seed),
        ];
        ([w[0] + s * n[0], w[1] + s * n[1], w[2] + s * n[2]], h)
    }
}

/// The same joint EKF written to exploit its structure, for a fair lower bound on an EKF's
/// cost: the Jacobian's nine non-zeros only, the first-order transition `I + hJ` (the
/// second-order term is below `1e-6` relative at 1 kHz), and the symmetric covariance updated
/// on its upper triangle.
#[derive(Clone, Copy, Debug)]
pub struct Ekf32Sparse {
    /// State.
    pub x: [f32; 6],
    /// Covariance (kept symmetric).
    pub p: M6,
    r: f32,
    q: f32,
}

impl Ekf32Sparse {
    /// Starts at `omega = y0`, `a = 0`, wide prior on `a`.
    pub fn new(y0: [f32; 3], sigma: f32) -> Self {
        let d = Ekf32::new(y0, sigma);
        Ekf32Sparse {
            x: d.x,
            p: d.p,
            r: d.r,
            q: d.q,
        }
    }

    /// One predict-update cycle for the sample `y` taken `h` after the previous one.
    pub fn step(&mut self, y: [f32; 3], h: f32) {
        let x = self.x;
        let k1 = rhs(&x);
        let k2 = rhs(&add(&x, &k1, 0.5 * h));
        let k3 = rhs(&add(&x, &k2, 0.5 * h));
        let k4 = rhs(&add(&x, &k3, h));
        for i in 0..3 {
            self.x[i] = x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        let (w, a) = ([x[0], x[1], x[2]], [x[3], x[4], x[5]]);
        // Row i of A = hJ has non-zeros in columns (j, k, 3 + i), (i, j, k) cyclic.
        let cols = [[1usize, 2, 3], [2, 0, 4], [0, 1, 5]];
        let vals = [
            [h * a[0] * w[2], h * a[0] * w[1], h * w[1] * w[2]],
            [h * a[1] * w[0], h * a[1] * w[2], h * w[2] * w[0]],
            [h * a[2] * w[1], h * a[2] * w[0], h * w[0] * w[1]],
        ];
        let p = &self.p;
        // M = A P (rows 0..3 only).
        let mut m = [[0.0f32; 6]; 3];
        for i in 0..3 {
            for j in 0..6 {
                m[i][j] = vals[i][0] * p[cols[i][0]][j]
                    + vals[i][1] * p[cols[i][1]][j]
                    + vals[i][2] * p[cols[i][2]][j];
            }
        }
        // P + M + M^T + M A^T, upper triangle.
        let mut pn = *p;
        for i in 0..6 {
            for j in i..6 {
                let mut v = p[i][j];
                if i < 3 {
                    v += m[i][j];
                }
                if j < 3 {
                    v += m[j][i];
                }
                if j < 3 {
                    v += m[i][cols[j][0]] * vals[j][0]
                        + m[i][cols[j][1]] * vals[j][1]
                        + m[i][cols[j][2]] * vals[j][2];
                }
                pn[i][j] = v;
            }
        }
        for i in 0..3 {
            pn[i][i] += self.q;
        }
        let s = [
            [pn[0][0] + self.r, pn[0][1], pn[0][2]],
            [pn[0][1], pn[1][1] + self.r, pn[1][2]],
            [pn[0][2], pn[1][2], pn[2][2] + self.r],
        ];
        let c00 = s[1][1] * s[2][2] - s[1][2] * s[1][2];
        let c01 = s[1][2] * s[0][2] - s[0][1] * s[2][2];
        let c02 = s[0][1] * s[1][2] - s[1][1] * s[0][2];
        let det = s[0][0] * c00 + s[0][1] * c01 + s[0][2] * c02;
        if det == 0.0 || det.is_nan() {
            for i in 0..6 {
                for j in 0..i {
                    pn[i][j] = pn[j][i];
                }
            }
            self.p = pn;
            return;
        }
        let id = 1.0 / det;
        let c11 = s[0][0] * s[2][2] - s[0][2] * s[0][2];
        let c12 = s[0][2] * s[0][1] - s[0][0] * s[1][2];
        let c22 = s[0][0] * s[1][1] - s[0][1] * s[0][1];
        let si = [
            [c00 * id, c01 * id, c02 * id],
            [c01 * id, c11 * id, c12 * id],
            [c02 * id, c12 * id, c22 * id],
        ];
        // Column j < 3 of P is row j of the upper triangle read symmetrically.
        let pc = |i: usize, j: usize| if i <= j { pn[i][j] } else { pn[j][i] };
        let mut k = [[0.0f32; 3]; 6];
        for i in 0..6 {
            let (p0, p1, p2) = (pc(i, 0), pc(i, 1), pc(i, 2));
            for j in 0..3 {
                k[i][j] = p0 * si[0][j] + p1 * si[1][j] + p2 * si[2][j];
            }
        }
        let e = [y[0] - self.x[0], y[1] - self.x[1], y[2] - self.x[2]];
        for i in 0..6 {
            self.x[i] += k[i][0] * e[0] + k[i][1] * e[1] + k[i][2] * e[2];
        }
        let mut out = pn;
        for i in 0..6 {
            for j in i..6 {
                out[i][j] =
                    pn[i][j] - (k[i][0] * pc(0, j) + k[i][1] * pc(1, j) + k[i][2] * pc(2, j));
            }
        }
        for i in 0..6 {
            for j in 0..i {
                out[i][j] = out[j][i];
            }
        }
        self.p = out;
    }

    /// The current `a`.
    pub fn a(&self) -> [f32; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }
}

/// For the profile of the tensor step: the part that accumulates, per sample and per axis, the
/// upper triangle of the outer product of the row's five kept entries with itself (15 entries;
/// the sixth entry of each row of (T3) is minus another), the row, the row times the
/// right-hand side and the right-hand side and its square, written the way
/// `identifier_core::tensor` does it (three axes, a stretch-anchor row subtracted first where
/// it is not zero by construction). Not the core's code itself (its sums are private): a
/// stand-in with the same arithmetic.
#[derive(Clone, Copy, Debug)]
pub struct RowSums3 {
    pp: [[f32; 15]; 3],
    p: [[f32; 5]; 3],
    py: [[f32; 5]; 3],
    y: [f32; 3],
    yy: [f32; 3],
    p0: [[f32; 5]; 3],
}

impl RowSums3 {
    /// Empty sums.
    pub const ZERO: RowSums3 = RowSums3 {
        pp: [[0.0; 15]; 3],
        p: [[0.0; 5]; 3],
        py: [[0.0; 5]; 3],
        y: [0.0; 3],
        yy: [0.0; 3],
        p0: [[0.0; 5]; 3],
    };

    /// One sample: the three rows at `w` with integrals `q` (xx, yy, zz, xy, xz, yz).
    #[inline(never)]
    pub fn add_sample(&mut self, w: [f32; 3], q: &[f32; 6]) {
        let [wx, wy, wz] = w;
        let [qxx, qyy, qzz, qxy, qxz, qyz] = *q;
        let [[x0, _, x2, x3, _], [_, y1, y2, _, y4], [_, z1, _, z3, z4]] = self.p0;
        let rows = [
            [wx - x0, qyz, wy - qxz - x2, wz + qxy - x3, qyy - qzz],
            [qxz, wy - y1, wx + qyz - y2, qzz - qxx, wz - qxy - y4],
            [qxy, wz - z1, qxx - qyy, wx - qyz - z3, wy + qxz - z4],
        ];
        for r in 0..3 {
            let d = rows[r];
            let dy = -w[r];
            let mut k = 0;
            for i in 0..5 {
                for j in i..5 {
                    self.pp[r][k] += d[i] * d[j];
                    k += 1;
                }
            }
            for i in 0..5 {
                self.p[r][i] += d[i];
                self.py[r][i] += d[i] * dy;
            }
            self.y[r] += dy;
            self.yy[r] += dy * dy;
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// The `f32` throw against an `f64` RK4 reference of the same equations (40 steps per
    /// sample, `std`'s cosine): the rates the benchmark feeds the fit are the motion to well
    /// under the noise, so the fit's check on the target tests the fit, not the signal.
    #[test]
    fn throw_follows_an_f64_reference() {
        let mut sig = Throw::board();
        sig.sigma = 0.0;
        let j = BOARD_INERTIA.map(|r| r.map(f64::from));
        let inv = inverse3(&BOARD_INERTIA).map(|r| r.map(f64::from));
        // The f32 inverse as the reference's: the comparison is of the integration.
        let speed = |t: f64| {
            let u = t - 0.08;
            if u <= 0.0 {
                175.0
            } else if u < 0.15 {
                175.0 + 1075.0 * 0.5 * (1.0 - (core::f64::consts::PI * u / 0.15).cos())
            } else {
                1250.0
            }
        };
        let jr = f64::from(BOARD_ROTOR_INERTIA);
        let w_of = |l: [f64; 3], t: f64| {
            let x = [l[0], l[1], l[2] + jr * speed(t)];
            inv.map(|r| r[0] * x[0] + r[1] * x[1] + r[2] * x[2])
        };
        let f = |l: [f64; 3], t: f64| {
            let w = w_of(l, t);
            [
                l[1] * w[2] - l[2] * w[1],
                l[2] * w[0] - l[0] * w[2],
                l[0] * w[1] - l[1] * w[0],
            ]
        };
        let w0 = [9.0, -8.0, -13.0];
        let jw = j.map(|r| r[0] * w0[0] + r[1] * w0[1] + r[2] * w0[2]);
        let mut l = [jw[0], jw[1], jw[2] - jr * 175.0];
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let l0 = norm(l);
        let (sub, dt) = (40, 1.0 / 2000.0);
        let hs = dt / sub as f64;
        let mut worst = 0.0f64;
        for k in 0..Throw::SAMPLES {
            let t = f64::from(k) * dt;
            let (w, h) = sig.next_sample();
            let wr = w_of(l, t);
            for i in 0..3 {
                worst = worst.max((f64::from(w[i]) - wr[i]).abs());
            }
            assert!((f64::from(h[2]) + jr * speed(t)).abs() < 1e-6 * jr * 1250.0);
            for i in 0..sub {
                let t = t + f64::from(i) * hs;
                let add = |a: [f64; 3], k: [f64; 3], s: f64| {
                    [a[0] + s * k[0], a[1] + s * k[1], a[2] + s * k[2]]
                };
                let k1 = f(l, t);
                let k2 = f(add(l, k1, hs / 2.0), t + hs / 2.0);
                let k3 = f(add(l, k2, hs / 2.0), t + hs / 2.0);
                let k4 = f(add(l, k3, hs), t + hs);
                for c in 0..3 {
                    l[c] += hs / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
                }
            }
        }
        // |L| is conserved (L' = L x w is normal to L).
        assert!((norm(l) / l0 - 1.0).abs() < 1e-9, "{} vs {l0}", norm(l));
        std::println!("largest rate difference {worst:.2e} rad/s");
        assert!(worst < 1e-4, "{worst:e} rad/s");
    }
}
