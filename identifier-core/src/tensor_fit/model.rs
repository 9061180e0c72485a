//! The model integrated: the augmented state (rates and their sensitivities), its derivative under
//! (F1) with the rotor momentum between nodes, RK4, the invariants restored along the way, and
//! the step rule.

use super::*;

pub(super) fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(super) fn mul(m: &Mat3, v: [f32; 3]) -> [f32; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

pub(super) fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(super) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `J` from its six entries.
pub(super) fn tensor_of(e: &[f32]) -> Mat3 {
    let g = |i: usize| e.get(i).copied().unwrap_or(0.0);
    [[g(0), g(3), g(4)], [g(3), g(1), g(5)], [g(4), g(5), g(2)]]
}

/// `J^-1` by the adjugate, `None` unless `J` is positive definite (leading minors).
pub(super) fn inverse_pd(j: &Mat3) -> Option<Mat3> {
    let m1 = j[0][0];
    let m2 = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let c00 = j[1][1] * j[2][2] - j[1][2] * j[2][1];
    let c01 = j[1][2] * j[2][0] - j[1][0] * j[2][2];
    let c02 = j[1][0] * j[2][1] - j[1][1] * j[2][0];
    let det = j[0][0] * c00 + j[0][1] * c01 + j[0][2] * c02;
    if !(m1 > 0.0 && m2 > 0.0 && det > 0.0 && det.is_finite()) {
        return None;
    }
    let k = 1.0 / det;
    let inv = [
        [
            c00 * k,
            (j[0][2] * j[2][1] - j[0][1] * j[2][2]) * k,
            (j[0][1] * j[1][2] - j[0][2] * j[1][1]) * k,
        ],
        [
            c01 * k,
            (j[0][0] * j[2][2] - j[0][2] * j[2][0]) * k,
            (j[0][2] * j[1][0] - j[0][0] * j[1][2]) * k,
        ],
        [
            c02 * k,
            (j[0][1] * j[2][0] - j[0][0] * j[2][1]) * k,
            (j[0][0] * j[1][1] - j[0][1] * j[1][0]) * k,
        ],
    ];
    inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
}

/// `E_c w` for the symmetric unit direction of entry `c` (xx, yy, zz, xy, xz, yz).
pub(super) fn e_times(c: usize, w: [f32; 3]) -> [f32; 3] {
    match c {
        0 => [w[0], 0.0, 0.0],
        1 => [0.0, w[1], 0.0],
        2 => [0.0, 0.0, w[2]],
        3 => [w[1], w[0], 0.0],
        4 => [w[2], 0.0, w[0]],
        5 => [0.0, w[2], w[1]],
        _ => [0.0; 3],
    }
}

/// Sensitivity columns with a constant torque's ((F4)): six entries, three initial rates,
/// three torques.
pub(super) const C_TORQUE: usize = P0 + 3;

/// Steady stretches of the rotor speed whose momentum errors (F7) follows.
pub(super) const CELLS: usize = 4;

/// Whether a fit of `P` parameters holds the rotor momentum's offsets of (F7): the absolute
/// fits with [`CELLS`] more (the steady runs are given exactly when they are). Decided by `P`,
/// not by the runs, so each parameter count integrates one layout and only that one is built.
pub(super) const fn has_offsets(p: usize) -> bool {
    p == P0 + CELLS || p == P1 + CELLS
}

/// Sensitivity columns with the rotor momentum's errors of (F7): six entries, three initial
/// rates, one error per steady stretch ([`Cells`]).
pub(super) const C_OFFSET: usize = P0 + CELLS;

/// `L` and `Sigma = dL/dtheta` (columns: six entries, three initial rates, and when `C =
/// 12` a constant torque, when `C = 13` the rotor momentum's errors of (F7)).
#[derive(Clone, Copy, Debug)]
pub(super) struct Aug<const C: usize> {
    pub(super) l: [f32; 3],
    /// Compensation of `l`'s running sum (Kahan): the increments are a few percent of `L`,
    /// and `f32` rounding of `L` is amplified by `J^-1` in `w`.
    pub(super) lc: [f32; 3],
    pub(super) s: [[f32; C]; 3],
}

/// `dw/dtheta` (3 x C) at `w`: `J^-1 (Sigma_c - E_c w)`.
pub(super) fn rate_sens<const C: usize>(k: &Mat3, x: &Aug<C>, w: [f32; 3]) -> [[f32; C]; 3] {
    let mut u = [[0.0f32; C]; 3];
    for c in 0..C {
        let col = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let v = if c < 6 { sub(col, e_times(c, w)) } else { col };
        let d = mul(k, v);
        for i in 0..3 {
            u[i][c] = d[i];
        }
    }
    u
}

/// The right-hand side of (F1) and (F3) at rotor momentum `h` (and of (F4) when `C = 12`:
/// `L' = L x w + q`, the torque's sensitivity forced by the identity). With `u_c = J^-1
/// (Sigma_c - E_c w)`, (F3)'s `Sigma_c' = Sigma_c x w + L x u_c` is
///
/// ```text
/// Sigma_c' = A Sigma_c - M E_c w,   M = [L]x J^-1,   A = M - [w]x
/// ```
///
/// one 3x3 product per column and stage (`M` and `A` once per stage) instead of a product and
/// two cross products: about a third fewer multiply-adds in the fit's inner loop (counted).
pub(super) fn deriv<const C: usize>(k: &Mat3, h: [f32; 3], f: &Forcing, x: &Aug<C>) -> Aug<C> {
    let q = &f.torque;
    let w = mul(k, sub(x.l, h));
    let l = x.l;
    // M = [L]x K: row i of [L]x has the two entries (L_j, -L_k) of `L x v`.
    let mut m = [[0.0f32; 3]; 3];
    for c in 0..3 {
        m[0][c] = l[1] * k[2][c] - l[2] * k[1][c];
        m[1][c] = l[2] * k[0][c] - l[0] * k[2][c];
        m[2][c] = l[0] * k[1][c] - l[1] * k[0][c];
    }
    // A = M - [w]x (`S x w = -[w]x S`).
    let mut a = m;
    a[0][1] += w[2];
    a[0][2] -= w[1];
    a[1][0] -= w[2];
    a[1][2] += w[0];
    a[2][0] += w[1];
    a[2][1] -= w[0];
    // M E_c w for the six entries (`E_c w` has one or two entries of `w`).
    let col = |i: usize, s: f32| [m[0][i] * s, m[1][i] * s, m[2][i] * s];
    let add = |p: [f32; 3], q: [f32; 3]| [p[0] + q[0], p[1] + q[1], p[2] + q[2]];
    let forcing = [
        col(0, w[0]),
        col(1, w[1]),
        col(2, w[2]),
        add(col(0, w[1]), col(1, w[0])),
        add(col(0, w[2]), col(2, w[0])),
        add(col(1, w[2]), col(2, w[1])),
    ];
    let mut s = [[0.0f32; C]; 3];
    for c in 0..C {
        let sc = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let mut v = mul(&a, sc);
        if let Some(f) = forcing.get(c) {
            v = sub(v, *f);
        }
        for i in 0..3 {
            s[i][c] = v[i];
        }
    }
    if C == C_TORQUE {
        for (i, row) in s.iter_mut().enumerate() {
            if let Some(v) = row.get_mut(P0 + i) {
                *v += 1.0;
            }
        }
    }
    if C == C_OFFSET {
        // (F7): `Sigma_d' = A Sigma_d - M u` while the error is on.
        let mu = mul(&m, f.offset);
        for (c, on) in f.on.iter().enumerate() {
            if *on {
                for (row, v) in s.iter_mut().zip(mu) {
                    if let Some(x) = row.get_mut(P0 + c) {
                        *x -= v;
                    }
                }
            }
        }
    }
    let lw = cross(x.l, w);
    Aug {
        l: [lw[0] + q[0], lw[1] + q[1], lw[2] + q[2]],
        lc: [0.0; 3],
        s,
    }
}

pub(super) fn axpy<const C: usize>(x: &Aug<C>, k: &Aug<C>, h: f32) -> Aug<C> {
    let mut y = *x;
    for i in 0..3 {
        y.l[i] += h * k.l[i];
        for c in 0..C {
            y.s[i][c] += h * k.s[i][c];
        }
    }
    y
}

/// `(K + K^T) / 2`: the inverse's rounding leaves the two triangles a few ulps apart, and
/// `L . K L` is conserved along (F1) only for a symmetric `K`.
pub(super) fn symmetric(k: Mat3) -> Mat3 {
    let mut s = k;
    for i in 0..3 {
        for j in (i + 1)..3 {
            let v = 0.5 * (k[i][j] + k[j][i]);
            s[i][j] = v;
            s[j][i] = v;
        }
    }
    s
}

/// Blocks between restorations of the invariants ([`Invariants::restore`]).
pub(super) const RESTORE_EVERY: usize = 8;

/// The two quadratic invariants of (F1) without rotor momentum or torque, held along the
/// integrated trajectory (the tensor's analogue of the ratio fit's, see
/// [`crate::ratio_fit`]):
///
/// ```text
/// |L|^2 = const,   L . K L = 2 E = const,   K = J^-1 symmetric          (F6)
/// ```
///
/// (`d|L|^2/dt = 2 L . (L x w) = 0`, `d(L . K L)/dt = 2 w . (L x w) = 0` for `w = K L`). In
/// `f32` every RK4 step changes them by a rounding of its increment; they set the motion's
/// frequencies, so over a long, fast flight the integrated phase drifts and the fit's cost is
/// noisy on the scale of a unit of log-likelihood. Every [`RESTORE_EVERY`] blocks the state is
/// moved back onto their values at the start along their gradients (`L` and `K L`), evaluated
/// to twice the `f32` precision ([`crate::exact`]).
pub(super) struct Invariants<const C: usize> {
    pub(super) value: [(f32, f32); 2],
    /// The invariants' derivatives with respect to the integrated columns at the start, halved:
    /// `L . Sigma_c` and `w . Sigma_c - w^T E_c w / 2` (`d(L . K L) = 2 w . dL - w^T dJ w`).
    pub(super) slope: [[f32; C]; 2],
}

/// Half the derivatives of the two invariants with respect to each integrated column at the
/// state `x` (rate `w`): `L . Sigma_c` and `w . Sigma_c - w^T E_c w / 2`.
pub(super) fn invariant_slopes<const C: usize>(x: &Aug<C>, w: [f32; 3]) -> [[f32; C]; 2] {
    let mut d = [[0.0f32; C]; 2];
    for c in 0..C {
        let sc = [x.s[0][c], x.s[1][c], x.s[2][c]];
        let ewe = if c < 6 { dot(w, e_times(c, w)) } else { 0.0 };
        d[0][c] = dot(x.l, sc);
        d[1][c] = dot(w, sc) - 0.5 * ewe;
    }
    d
}

impl<const C: usize> Invariants<C> {
    pub(super) fn new(k: &Mat3, x: &Aug<C>) -> Self {
        Invariants {
            value: [
                weighted_squares(&[1.0; 3], &x.l, &x.lc),
                quadratic_form(k, &x.l, &x.lc),
            ],
            slope: invariant_slopes(x, mul(k, x.l)),
        }
    }

    /// Moves the momentum `l - lc` by `alpha L + beta K L` so both invariants take their
    /// values to first order (a ridge of 1e-6 of the 2x2 system's trace for a spin about a
    /// principal axis, where the gradients are parallel), and each column of the sensitivities
    /// the same way so that the invariants' derivatives keep their start's: the Jacobian stays
    /// that of the restored trajectory (with the state alone moved, the Gauss-Newton steps near
    /// the optimum would be mispredicted and refused).
    pub(super) fn restore(&self, k: &Mat3, x: &mut Aug<C>) {
        let [(v0h, v0l), (v1h, v1l)] = self.value;
        let (h0, l0) = weighted_squares(&[1.0; 3], &x.l, &x.lc);
        let (h1, l1) = quadratic_form(k, &x.l, &x.lc);
        let r = [
            0.5 * ((v0h - h0) + (v0l - l0)),
            0.5 * ((v1h - h1) + (v1l - l1)),
        ];
        let w = mul(k, x.l);
        let g = [x.l, w];
        let Some(gram) = Gram2::new(g[0], g[1]) else {
            return;
        };
        let (alpha, beta) = gram.solve(r[0], r[1]);
        for i in 0..3 {
            // The true momentum is `l - lc`: moving it by `d` is `lc -= d`.
            x.lc[i] -= alpha * g[0][i] + beta * g[1][i];
        }
        let now = invariant_slopes(x, w);
        for c in 0..C {
            let (a, b) = gram.solve(self.slope[0][c] - now[0][c], self.slope[1][c] - now[1][c]);
            for i in 0..3 {
                x.s[i][c] += a * g[0][i] + b * g[1][i];
            }
        }
    }
}

/// The rotor momentum over one interval between block means, `tau` from its start:
/// `h(tau) = h0 + tau s + tau (tau - span) c / 2` (through the two nodes, curvature `c`).
#[derive(Clone, Copy, Debug)]
pub(super) struct RotorSegment {
    pub(super) h0: [f32; 3],
    pub(super) s: [f32; 3],
    pub(super) c: [f32; 3],
    pub(super) span: f32,
}

impl RotorSegment {
    pub(super) fn at(&self, tau: f32) -> [f32; 3] {
        let q = 0.5 * tau * (tau - self.span);
        [
            self.h0[0] + tau * self.s[0] + q * self.c[0],
            self.h0[1] + tau * self.s[1] + q * self.c[1],
            self.h0[2] + tau * self.s[2] + q * self.c[2],
        ]
    }

    /// `h'` at the segment's end.
    pub(super) fn rate_at_end(&self) -> [f32; 3] {
        let m = 0.5 * self.span;
        [
            self.s[0] + m * self.c[0],
            self.s[1] + m * self.c[1],
            self.s[2] + m * self.c[2],
        ]
    }
}

/// The block mean of `w` minus `w(tbar)`, to sixth order in the block's time spread (the
/// same expansion as the ratio fit's (T2')):
///
/// ```text
/// mean w = w_0 + v w_2 + mu4 w_4 + mu6 w_6,   w_n = J^-1 (L_n - h_n)
/// L_(n+1) = 1/(n + 1) sum_(m=0..n) L_m x w_(n-m)          (the Taylor coefficients of L' = L x w)
/// ```
///
/// with `L_0` the momentum at the block's mean time and the rotor's `h_0 = h`, `h_1 = h'`,
/// `h_2 = h''/2` (its model is quadratic between nodes). `2 w_2` is (B1)'s `w''`. A constant
/// torque's part is left out (zero where the test evaluates it).
pub(super) fn block_mean_correction(
    k: &Mat3,
    l0: [f32; 3],
    h: [[f32; 3]; 3],
    moments: &[f32; 3],
) -> [f32; 3] {
    let [v, mu4, mu6] = *moments;
    if !(v > 0.0) {
        return [0.0; 3];
    }
    let [h0, h1, h2] = h;
    let hn = [h0, h1, [0.5 * h2[0], 0.5 * h2[1], 0.5 * h2[2]]];
    let mut l = [[0.0f32; 3]; 7];
    let mut w = [[0.0f32; 3]; 7];
    l[0] = l0;
    let mut order = 6;
    for n in 0..7 {
        let hcoef = hn.get(n).copied().unwrap_or([0.0; 3]);
        let ln = l.get(n).copied().unwrap_or([0.0; 3]);
        if let Some(wn) = w.get_mut(n) {
            *wn = mul(k, sub(ln, hcoef));
        }
        if n == 2 {
            order = higher_orders(mu4, mu6, &w[0], &w[2]);
        }
        if n >= order || n >= 6 {
            break;
        }
        // Cauchy product of the coefficients `0..=n` of L and w.
        let mut next = [0.0f32; 3];
        for (lm, wr) in l.iter().take(n + 1).zip(w.iter().take(n + 1).rev()) {
            let c = cross(*lm, *wr);
            for (x, y) in next.iter_mut().zip(c.iter()) {
                *x += y;
            }
        }
        let inv = 1.0 / (n + 1) as f32;
        if let Some(dst) = l.get_mut(n + 1) {
            *dst = next.map(|x| x * inv);
        }
    }
    let [_, _, c2, _, c4, _, c6] = w;
    [
        v * c2[0] + mu4 * c4[0] + mu6 * c6[0],
        v * c2[1] + mu4 * c4[1] + mu6 * c6[1],
        v * c2[2] + mu4 * c4[2] + mu6 * c6[2],
    ]
}

/// What drives the extended models' sensitivities besides the rates: a constant torque `q`
/// ((F4), also in the trajectory) and the direction `u` of the rotor momentum's errors of
/// (F7) with the ones on in the step (in their columns only).
#[derive(Clone, Copy, Debug)]
pub(super) struct Forcing {
    pub(super) torque: [f32; 3],
    pub(super) offset: [f32; 3],
    pub(super) on: [bool; CELLS],
}

/// The rotor's steady stretches of (F7): the direction `u` of its momentum and up to
/// [`CELLS`] runs of blocks `[a, b)` over which its error is taken as one constant (empty
/// runs: none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cells {
    pub(super) u: [f32; 3],
    pub(super) runs: [(usize, usize); CELLS],
    /// The prior's weight on each offset in the cost's units, `sigma^2 / (q^2 / 12)` (the
    /// gyro's white-noise variance per sample over the offset's, uniform over one quantum).
    pub(super) prior: f32,
    /// The momentum's quantum `q`, kg m^2/s.
    pub(super) quantum: f32,
}

impl Cells {
    pub(super) const NONE: Cells = Cells {
        u: [0.0; 3],
        runs: [(0, 0); CELLS],
        prior: 0.0,
        quantum: 0.0,
    };

    /// Whether the fitted offsets `d` (the last [`CELLS`] of `theta`) are a quantisation's:
    /// each within one quantum (the reading's error is at most half of one; the other half
    /// leaves room for the fit's own error). Where the model error is tens of times the gyro's
    /// noise (the thrown-FC logs), free offsets come out at several quanta: soaking up that
    /// error, not the telemetry's steps.
    pub(super) fn plausible(&self, theta: &[f32]) -> bool {
        let first = theta.len().saturating_sub(CELLS);
        self.runs.iter().enumerate().all(|(c, run)| {
            run.0 >= run.1
                || theta
                    .get(first + c)
                    .is_some_and(|d| d.abs() <= self.quantum)
        })
    }

    /// Which errors are on at block node `b` (`[a, b)` holds it).
    pub(super) fn at(&self, b: usize) -> [bool; CELLS] {
        self.runs.map(|(lo, hi)| lo <= b && b < hi)
    }

    /// Which are on over the integration from node `b - 1` to node `b` (both in the run).
    pub(super) fn between(&self, b: usize) -> [bool; CELLS] {
        self.runs.map(|(lo, hi)| b > lo && b < hi)
    }
}

/// One RK4 step of length `dt` from `tau` within the segment `seg`.
pub(super) fn rk4<const C: usize>(
    k: &Mat3,
    seg: &RotorSegment,
    q: &Forcing,
    x: &Aug<C>,
    tau: f32,
    dt: f32,
) -> Aug<C> {
    let k1 = deriv(k, seg.at(tau), q, x);
    let k2 = deriv(k, seg.at(tau + 0.5 * dt), q, &axpy(x, &k1, 0.5 * dt));
    let k3 = deriv(k, seg.at(tau + 0.5 * dt), q, &axpy(x, &k2, 0.5 * dt));
    let k4 = deriv(k, seg.at(tau + dt), q, &axpy(x, &k3, dt));
    let mut y = *x;
    let d6 = dt / 6.0;
    for i in 0..3 {
        let inc = d6 * (k1.l[i] + 2.0 * k2.l[i] + 2.0 * k3.l[i] + k4.l[i]);
        compensated_add(&mut y.l[i], &mut y.lc[i], inc);
        for c in 0..C {
            y.s[i][c] += d6 * (k1.s[i][c] + 2.0 * k2.s[i][c] + 2.0 * k3.s[i][c] + k4.s[i][c]);
        }
    }
    y
}

/// `h''` at block `b` by the second difference of the block means with its neighbours (the
/// nearest interior value at the ends; zero with fewer than three blocks).
pub(super) fn rotor_curvature(blocks: &[Block<6>], b: usize) -> [f32; 3] {
    let n = blocks.len();
    if n < 3 {
        return [0.0; 3];
    }
    let m = if b == 0 {
        1
    } else if b + 1 >= n {
        n - 2
    } else {
        b
    };
    let (Some(p), Some(c), Some(q)) = (blocks.get(m - 1), blocks.get(m), blocks.get(m + 1)) else {
        return [0.0; 3];
    };
    let (d1, d2) = (c.since(p), q.since(c));
    if !(d1 > 0.0 && d2 > 0.0) {
        return [0.0; 3];
    }
    let (hp, hc, hq) = (rotor_of(p), rotor_of(c), rotor_of(q));
    let mut out = [0.0f32; 3];
    for i in 0..3 {
        out[i] = 2.0 * ((hq[i] - hc[i]) / d2 - (hc[i] - hp[i]) / d1) / (d1 + d2);
    }
    out
}

/// The rotor momentum at block `b`'s mean time: its block mean less `v/2 h''` by (B1), `v`
/// the variance of the sample times: the block's less `gyro_spread`, the gyro readings' own
/// ((B0), (B0')), since the rotor's speed is read at the sample times.
pub(super) fn rotor_node(blocks: &[Block<6>], b: usize, gyro_spread: f32) -> ([f32; 3], [f32; 3]) {
    let c = rotor_curvature(blocks, b);
    let Some(blk) = blocks.get(b) else {
        return ([0.0; 3], c);
    };
    let v = blk.time_var() - gyro_spread;
    let hv = if v > 0.0 { 0.5 * v } else { 0.0 };
    let m = rotor_of(blk);
    ([m[0] - hv * c[0], m[1] - hv * c[1], m[2] - hv * c[2]], c)
}

pub(super) fn norm(v: [f32; 3]) -> f32 {
    sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

/// How finely (F1) is integrated between two block means: RK4 steps of at most `0.1 / rate`
/// ([`substeps`]), `rate` a bound on how fast the motion turns there,
///
/// ```text
/// rate = max(1, a_max) |w| + sqrt(h^T J h / det J)
/// ```
///
/// from Euler's `w_i' = a_i w_j w_k` in the principal frame (`|a_i| = |J_j - J_k| / J_i <= 1`
/// for a rigid body) and the nutation the rotor momentum gives the body (the non-zero
/// eigenvalues of the gyroscopic term `J^-1 (h x .)` of (F1)'s linearisation are `+-i` that;
/// for `h` along `z` of a diagonal `J`, `|h| / sqrt(Jxx Jyy)`), with `|w|` and `|h|` the larger
/// of the two block means'. `J` is the fit's first guess, held for the whole fit: a step count
/// that changed with the parameters would make the cost jump by the RK4 error of one count
/// against another, and the fit, which needs the cost smooth to a few 1e-4 of itself, would
/// refuse its last steps on those jumps and take several times the evaluations. A bound
/// `|J^-1| |L|` would take more steps for the same estimates, many more where `J^-1` is
/// ill-conditioned (a racquet's short toss).
#[derive(Clone, Copy, Debug)]
pub(super) struct StepRule {
    /// `max(1, a_max)`: infinite (the most steps) when `J`'s moments are not positive.
    pub(super) turn: f32,
    pub(super) j: Mat3,
    pub(super) det: f32,
    /// The gyro readings' own time variance, which the rotor's readings lack ([`rotor_node`]).
    pub(super) gyro_spread: f32,
    /// The gyro bias's walk, its step variance per sample over the white noise's ((F12)): 0
    /// (none), or the fit's residuals and sensitivities are whitened by its Kalman filter.
    pub(super) walk: f32,
}

impl StepRule {
    pub(super) fn new(j: &Mat3) -> Self {
        let turn = match eigen_symmetric3(j) {
            // Ascending: `(l1 - l0) / l2` is never the largest ratio.
            Some(e) if e.values[0] > 0.0 => {
                let [l0, l1, l2] = e.values;
                ((l2 - l1) / l0).max((l2 - l0) / l1).max(1.0)
            }
            _ => f32::INFINITY,
        };
        StepRule {
            turn,
            j: *j,
            det: det(j),
            gyro_spread: 0.0,
            walk: 0.0,
        }
    }

    /// The same rule for gyro readings of own time variance `gyro_spread` ([`rotor_node`]).
    pub(super) fn with_gyro_spread(mut self, gyro_spread: f32) -> Self {
        self.gyro_spread = gyro_spread;
        self
    }

    /// The same rule for a gyro bias walking with step variance `walk` per sample over the
    /// white noise's ((F12)).
    pub(super) fn with_walk(mut self, walk: f32) -> Self {
        self.walk = walk;
        self
    }

    /// The rate between two block means whose larger `|w|` is `w_max` and rotor momenta
    /// `h0`, `h1`.
    pub(super) fn speed(&self, w_max: f32, h0: [f32; 3], h1: [f32; 3]) -> f32 {
        let nutation = |h: [f32; 3]| {
            if self.det > 0.0 {
                sqrt(dot(h, mul(&self.j, h)).max(0.0) / self.det)
            } else {
                f32::INFINITY
            }
        };
        self.turn * w_max + nutation(h0).max(nutation(h1))
    }
}

pub(super) fn rate_of(b: &Block<6>) -> [f32; 3] {
    [b.mean(0), b.mean(1), b.mean(2)]
}

pub(super) fn rotor_of(b: &Block<6>) -> [f32; 3] {
    [b.mean(3), b.mean(4), b.mean(5)]
}
