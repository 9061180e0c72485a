//! A gyro bias that walks ((F12), (F13) of the module docs): the walk's Kalman filter over the
//! block means, which whitens the residuals and their sensitivities, and the walk's step
//! variance found by restricted maximum likelihood.
//!
//! Per axis, in units of the gyro's white variance per sample `sigma^2`, block `b` of `n_b`
//! samples reads the walk `d` (step variance `lambda` per sample, `d = 0` before the first
//! sample) averaged over its samples, and white noise of variance `1 / n_b`. With `x_b` the walk
//! at block `b`'s last sample, `Delta_b = x_b - x_(b-1)` (the block's `n_b` steps) and `A_b` the
//! block's mean walk less `x_(b-1)` (its steps weighted `(n_b - i + 1) / n_b`):
//!
//! ```text
//! var A_b = lambda (n_b + 1) (2 n_b + 1) / (6 n_b),   cov(A_b, Delta_b) = lambda (n_b + 1) / 2
//! V_b = P + var A_b + 1 / n_b,   K_b = (P + cov(A_b, Delta_b)) / V_b,
//! nu_b = r_b - m,   m <- m + K_b nu_b,   P <- P + lambda n_b - (P + cov(A_b, Delta_b))^2 / V_b
//! ```
//!
//! (`m` the walk's estimate at the block's end, `P` its variance; `m = P = 0` at the start). The
//! gains depend on the block counts only, so one filter serves the residual `r_b` and every
//! sensitivity column alike on each axis: the fit's cost becomes `sum nu_b^2 / V_b` and its
//! normal equations those of the whitened rows, the generalised least squares of the walk.
//!
//! The walk's `lambda` maximises the restricted likelihood of the `N` block residuals over
//! `P` parameters, the white variance profiled out:
//!
//! ```text
//! -2 log L_R(lambda) = (N - P) ln(S / (N - P)) + sum_b 3 ln(n_b V_b) + ln det F        (F13)
//! ```
//!
//! `S` and `F` the whitened cost and normal matrix at the Gauss-Newton optimum. The plain
//! likelihood (without `ln det F`) leaves the walk's slow part to the initial rate and the bias
//! and finds the walk too small (the MEMS gyro of `scripts/bench-spacecraft.sh`), which leaves
//! the reported standard deviation too small.

/// The walk's Kalman gains over the blocks, shared by the three axes.
#[derive(Clone, Copy, Debug)]
pub(super) struct Gains {
    /// `lambda`: the walk's step variance per sample over the white variance per sample.
    lambda: f32,
    /// `P`: the walk's variance at the last block's end, in the white variance per sample.
    p: f32,
}

impl Gains {
    /// The gains of a walk of step variance `lambda` (in the white variance per sample), from
    /// a walk known to be 0 at the first sample.
    pub(super) const fn new(lambda: f32) -> Self {
        Gains { lambda, p: 0.0 }
    }

    /// The next block's innovation variance `V_b` and gain `K_b`, for its `n` samples (at least
    /// 1), moving `P` on to its end.
    pub(super) fn next(&mut self, n: f32) -> (f32, f32) {
        let n = n.max(1.0);
        let l = self.lambda;
        let var_a = l * (n + 1.0) * (2.0 * n + 1.0) / (6.0 * n);
        let cov = l * (n + 1.0) * 0.5;
        let v = self.p + var_a + 1.0 / n;
        let pc = self.p + cov;
        let k = pc / v;
        self.p = (self.p + l * n - pc * k).max(0.0);
        (v, k)
    }
}

/// One axis's filtered walk per column: the residual's and each of `P` sensitivity columns'.
#[derive(Clone, Copy, Debug)]
pub(super) struct Filtered<const P: usize> {
    r: f32,
    s: [f32; P],
}

impl<const P: usize> Filtered<P> {
    /// Nothing filtered yet (the walk is 0 at the first sample).
    pub(super) const ZERO: Self = Filtered {
        r: 0.0,
        s: [0.0; P],
    };

    /// The innovation of residual `r` at gain `k`, and row `s` replaced by its innovations,
    /// moving the filter on.
    pub(super) fn innovate(&mut self, k: f32, r: f32, s: &mut [f32; P]) -> f32 {
        let nu = r - self.r;
        self.r += k * nu;
        for (x, m) in s.iter_mut().zip(self.s.iter_mut()) {
            *x -= *m;
            *m += k * *x;
        }
        nu
    }
}

/// Candidate walks of [`candidates`]: `lambda_ref * 4^k`, `k = -4 ..= 8` (up to a walk whose
/// variance over the stretch is 65 536 times a block's white variance: a gyro whose white noise
/// is small beside its drift).
pub(super) const CANDIDATES: usize = 13;

/// The first candidate's power of 4.
const FIRST_POWER: i32 = -4;

/// The likelihood ratio, against no walk, beyond which a walk is taken ((F13)): chi-square with
/// one degree of freedom at 0.1 %. A walk missed leaves the white covariance, too small by as
/// much as the walk hides; a walk taken in vain on a white gyro widens a window's covariance,
/// and where it widens it much, turns its tensor's status to `ModelMismatch`. A looser test
/// makes the second error (host-tests' `tensor_fit` with `SEEDS=60`), a stricter one the first
/// (`scripts/bench-spacecraft.sh` on the MEMS gyro; both in BENCHMARKS' notes).
pub(super) const WALK_LR: f32 = 10.83;

/// `lambda_ref = 1 / (nbar^2 B)` of `B` blocks of `nbar` samples each on average: the walk
/// whose variance over the whole stretch equals one mean block's white variance.
fn reference(blocks: &[crate::output_error::Block<6>]) -> f32 {
    let mut samples = 0.0f32;
    for b in blocks {
        samples += b.n;
    }
    let b = (blocks.len().max(1)) as f32;
    let nbar = (samples / b).max(1.0);
    1.0 / (nbar * nbar * b)
}

/// `sum_b 3 ln(n_b V_b)` over `blocks` under a walk of step variance `lambda` per sample
/// ((F12)): what the walk adds to `-2 log` of the likelihood beyond the white residual's (0
/// without a walk, where `V_b = 1 / n_b`).
pub(super) fn excess_log_det(blocks: &[crate::output_error::Block<6>], lambda: f32) -> f32 {
    let mut gains = Gains::new(lambda);
    let mut sum = 0.0f32;
    for b in blocks {
        let (v, _) = gains.next(b.n);
        sum += 3.0 * ln(b.n.max(1.0) * v);
    }
    sum
}

/// The candidate walks for `blocks`: `lambda_ref 4^k`, `k` from
/// [`FIRST_POWER`] up.
pub(super) fn candidates(blocks: &[crate::output_error::Block<6>]) -> [f32; CANDIDATES] {
    let lambda_ref = reference(blocks);
    core::array::from_fn(|k| lambda_ref * power4(FIRST_POWER + k as i32))
}

/// The candidate walk of smallest `deviance` among [`candidates`] (their deviances in order),
/// refined by the parabola through it and its neighbours in `log lambda` (within a step of it).
pub(super) fn refined(lambdas: &[f32; CANDIDATES], deviance: &[f32; CANDIDATES]) -> (f32, f32) {
    let mut k = 0;
    for c in 1..CANDIDATES {
        if deviance.get(c) < deviance.get(k) {
            k = c;
        }
    }
    let d = |i: usize| deviance.get(i).copied().unwrap_or(f32::INFINITY);
    let dk = d(k);
    let mut shift = 0.0f32;
    if k > 0 && k + 1 < CANDIDATES {
        let (a, c) = (d(k - 1), d(k + 1));
        let curv = a - 2.0 * dk + c;
        if curv > 0.0 && curv.is_finite() {
            shift = (0.5 * (a - c) / curv).clamp(-1.0, 1.0);
        }
    }
    let at = lambdas.get(k).copied().unwrap_or(0.0);
    (at * exp2(2.0 * shift), dk)
}

/// (F13), restricted: `-2 log` of the restricted likelihood of a fit's normal equations `(cost,
/// F, g)` at a parameter vector under a walk `lambda` (the cost at the Gauss-Newton optimum
/// from there, `cost - g^T F^-1 g`), the white variance profiled out:
/// `dof ln(S / dof) + sum_b 3 ln(n_b V_b) + ln det F`. The `ln det F` term counts what the
/// fitted parameters take up of the residual (the walk's slow part above all, which a plain
/// likelihood would give to the initial rate and the bias): without it the walk comes out
/// biased low. `None` when `F` is not positive definite.
pub(super) fn restricted_deviance<const P: usize>(
    blocks: &[crate::output_error::Block<6>],
    lambda: f32,
    (cost, f, g): (f32, &[[f32; P]; P], &[f32; P]),
    dof: f32,
) -> Option<f32> {
    // `F = D^-1 L L^T D^-1`: `ln det F = sum ln F_ii + 2 sum ln L_ii`.
    let (d, l) = crate::output_error::scaled_cholesky(f)?;
    let mut logdet = 0.0f32;
    for (i, row) in f.iter().enumerate() {
        logdet += ln(row.get(i).copied().unwrap_or(0.0));
    }
    // `z = L^-1 D g`: `g^T F^-1 g = |z|^2`.
    let mut z = [0.0f32; P];
    let mut gain = 0.0f32;
    for i in 0..P {
        let row = l.get(i)?;
        let mut s = g.get(i).copied().unwrap_or(0.0) * d.get(i).copied().unwrap_or(0.0);
        for (lk, zk) in row.iter().zip(z.iter()).take(i) {
            s -= lk * zk;
        }
        let lii = row.get(i).copied().unwrap_or(0.0);
        let zi = s / lii;
        if let Some(slot) = z.get_mut(i) {
            *slot = zi;
        }
        gain += zi * zi;
        logdet += 2.0 * ln(lii);
    }
    let s = cost - gain;
    if !(s > 0.0 && dof > 0.0) {
        return None;
    }
    Some(dof * ln(s / dof) + excess_log_det(blocks, lambda) + logdet)
}

/// `ln x` for finite `x > 0` (0 otherwise) with `+ - * /` only, so host and MCU give the same
/// bits: `x = 2^e m`, `m` in `[sqrt(1/2), sqrt(2))`, `ln x = e ln 2 + 2 artanh(t)`,
/// `t = (m - 1) / (m + 1)` (`|t| < 0.172`), the series to `t^9` (within 1e-7 of `ln m`).
fn ln(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) || x < f32::MIN_POSITIVE {
        return 0.0;
    }
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let series = 1.0 + t2 * (1.0 / 3.0 + t2 * (0.2 + t2 * (1.0 / 7.0 + t2 * (1.0 / 9.0))));
    e as f32 * core::f32::consts::LN_2 + 2.0 * t * series
}

/// `2^x` for `x` in `[-64, 64]` (clamped) with `+ - * /` only: `2^floor(x)` exactly times
/// `e^(f ln 2)`, `f` in `[0, 1)`, by its series to the ninth power (within 1e-7 of itself).
fn exp2(x: f32) -> f32 {
    let x = if x.is_finite() {
        x.clamp(-64.0, 64.0)
    } else {
        0.0
    };
    // `x` is within +-64: the cast is exact for its floor.
    let mut whole = x as i32;
    if (whole as f32) > x {
        whole -= 1;
    }
    let y = (x - whole as f32) * core::f32::consts::LN_2;
    let mut term = 1.0f32;
    let mut sum = 1.0f32;
    for k in 1..10 {
        term *= y / k as f32;
        sum += term;
    }
    let mut scale = 1.0f32;
    for _ in 0..whole.unsigned_abs() {
        scale *= 2.0;
    }
    if whole < 0 {
        sum / scale
    } else {
        sum * scale
    }
}

/// `4^k` for a small integer `k`.
fn power4(k: i32) -> f32 {
    let mut x = 1.0f32;
    for _ in 0..k.unsigned_abs() {
        x *= 4.0;
    }
    if k < 0 {
        1.0 / x
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;

    /// The filter's innovations, divided by `sqrt(V)`, are the residual whitened by the
    /// covariance of (F12): checked against the dense covariance of block means of a walk and
    /// white noise, by the Cholesky factor (`L^-1 r` has the same squared sum as `nu / sqrt(V)`,
    /// and `sum log V` is `log det`).
    #[test]
    fn innovations_whiten_the_block_means_of_a_walk_exactly() {
        let counts = [3.0f32, 5.0, 1.0, 4.0, 4.0, 2.0];
        let lambda = 0.37f64;
        // Dense covariance of block means, in f64, from the samples.
        let mut idx = vec![];
        for (b, n) in counts.iter().enumerate() {
            for _ in 0..(*n as usize) {
                idx.push(b);
            }
        }
        let nb = counts.len();
        let mut cov = vec![vec![0.0f64; nb]; nb];
        for (k, bk) in idx.iter().enumerate() {
            for (l, bl) in idx.iter().enumerate() {
                // d_k = sum of steps 1..=k (d_0 = 0 at the first sample... one step per sample
                // from the start, as (F12) counts them: sample k carries k + 1 steps).
                let walk = lambda * ((k.min(l) + 1) as f64);
                let white = if k == l { 1.0 } else { 0.0 };
                cov[*bk][*bl] += (walk + white) / (f64::from(counts[*bk]) * f64::from(counts[*bl]));
            }
        }
        // Cholesky.
        let mut l = vec![vec![0.0f64; nb]; nb];
        for i in 0..nb {
            for j in 0..=i {
                let mut s = cov[i][j];
                for k in 0..j {
                    s -= l[i][k] * l[j][k];
                }
                l[i][j] = if i == j { s.sqrt() } else { s / l[j][j] };
            }
        }
        let r = [0.3f64, -1.2, 0.7, 2.0, -0.4, 0.9];
        let mut z = [0.0f64; 6];
        for i in 0..nb {
            let mut s = r[i];
            for k in 0..i {
                s -= l[i][k] * z[k];
            }
            z[i] = s / l[i][i];
        }
        let dense_sq: f64 = z.iter().map(|x| x * x).sum();
        let dense_logdet: f64 = (0..nb).map(|i| 2.0 * l[i][i].ln()).sum();
        let mut g = Gains::new(lambda as f32);
        let mut f = Filtered::<1>::ZERO;
        let (mut sq, mut logdet) = (0.0f64, 0.0f64);
        for (n, x) in counts.iter().zip(r) {
            let (v, k) = g.next(*n);
            let nu = f.innovate(k, x as f32, &mut [0.0]);
            sq += f64::from(nu * nu / v);
            logdet += f64::from(v).ln();
        }
        assert!((sq - dense_sq).abs() < 1e-5 * dense_sq, "{sq} {dense_sq}");
        assert!(
            (logdet - dense_logdet).abs() < 1e-5,
            "{logdet} {dense_logdet}"
        );
    }

    #[test]
    fn ln_and_exp2_are_close() {
        for x in [
            1e-9f32,
            1e-3,
            0.5,
            core::f32::consts::FRAC_1_SQRT_2,
            0.7072,
            1.0,
            core::f32::consts::SQRT_2,
            1.4143,
            2.0,
            1234.5,
            3e7,
        ] {
            let want = (x as f64).ln();
            assert!(
                (f64::from(ln(x)) - want).abs() < 2e-6 * want.abs().max(1.0),
                "{x}"
            );
        }
        for x in [-20.5f32, -1.0, -0.25, 0.0, 0.3, 1.0, 7.75, 30.1] {
            let want = 2f64.powf(f64::from(x));
            assert!((f64::from(exp2(x)) - want).abs() < 1e-6 * want, "{x}");
        }
    }

    /// Without a walk the filter is the white weighting: `V = 1 / n`, no gain.
    #[test]
    fn no_walk_is_the_white_weighting() {
        let mut g = Gains::new(0.0);
        for n in [1.0f32, 7.0, 64.0] {
            let (v, k) = g.next(n);
            assert_eq!(k, 0.0);
            assert!((v * n - 1.0).abs() < 1e-6);
        }
    }
}
