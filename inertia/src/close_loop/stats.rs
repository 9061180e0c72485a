//! The statistics the effect search needs: least squares with covariance, the F-test (via
//! Paulson's normal approximation of the F distribution), BIC, Ljung-Box and the normal
//! distribution. All `f64`, written out here so the numbers are reproducible and inspectable.
#![allow(clippy::needless_range_loop)]

/// A least-squares fit `y ~ X theta`.
#[derive(Clone, Debug)]
pub struct LsFit {
    /// The estimate.
    pub theta: Vec<f64>,
    /// Residual sum of squares.
    pub rss: f64,
    /// Rows used.
    pub n: usize,
    /// `(X^T X)^-1`; times `rss / (n - k)` it is the covariance of `theta`.
    pub xtx_inv: Vec<Vec<f64>>,
}

impl LsFit {
    /// Residual variance `rss / (n - k)`.
    pub fn sigma2(&self) -> f64 {
        self.rss / (self.n.saturating_sub(self.theta.len()).max(1)) as f64
    }

    /// Covariance of `theta`.
    pub fn cov(&self) -> Vec<Vec<f64>> {
        let s2 = self.sigma2();
        self.xtx_inv
            .iter()
            .map(|r| r.iter().map(|v| v * s2).collect())
            .collect()
    }
}

/// Least squares by the normal equations with column equilibration and Gauss-Jordan
/// inversion with partial pivoting. `None` when `X` is rank deficient.
pub fn lstsq(rows: &[Vec<f64>], y: &[f64]) -> Option<LsFit> {
    let k = rows.first()?.len();
    let n = rows.len();
    if n < k || k == 0 {
        return None;
    }
    let mut scale = vec![0.0; k];
    for r in rows {
        for (s, v) in scale.iter_mut().zip(r) {
            *s += v * v;
        }
    }
    let scale: Vec<f64> = scale
        .iter()
        .map(|s| if *s > 0.0 { 1.0 / s.sqrt() } else { 0.0 })
        .collect();
    if scale.contains(&0.0) {
        return None;
    }
    let mut a = vec![vec![0.0; k]; k];
    let mut b = vec![0.0; k];
    for (r, yi) in rows.iter().zip(y) {
        for i in 0..k {
            let ri = r[i] * scale[i];
            b[i] += ri * yi;
            for j in 0..k {
                a[i][j] += ri * r[j] * scale[j];
            }
        }
    }
    let inv = invert(&a)?;
    let theta_s: Vec<f64> = (0..k)
        .map(|i| (0..k).map(|j| inv[i][j] * b[j]).sum())
        .collect();
    let theta: Vec<f64> = theta_s.iter().zip(&scale).map(|(t, s)| t * s).collect();
    let xtx_inv = (0..k)
        .map(|i| (0..k).map(|j| inv[i][j] * scale[i] * scale[j]).collect())
        .collect();
    let rss = rows
        .iter()
        .zip(y)
        .map(|(r, yi)| {
            let e = yi - r.iter().zip(&theta).map(|(x, t)| x * t).sum::<f64>();
            e * e
        })
        .sum();
    Some(LsFit {
        theta,
        rss,
        n,
        xtx_inv,
    })
}

/// Inverse of a symmetric positive definite (or any regular) matrix; `None` when singular
/// (pivot below `1e-12` after equilibration).
pub fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let k = a.len();
    let mut m: Vec<Vec<f64>> = a
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut row = r.clone();
            row.extend((0..k).map(|j| if i == j { 1.0 } else { 0.0 }));
            row
        })
        .collect();
    for c in 0..k {
        let p = (c..k).max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs()))?;
        if m[p][c].abs() < 1e-12 {
            return None;
        }
        m.swap(c, p);
        let d = m[c][c];
        for v in m[c].iter_mut() {
            *v /= d;
        }
        for r in 0..k {
            if r != c {
                let f = m[r][c];
                if f != 0.0 {
                    for j in 0..2 * k {
                        m[r][j] -= f * m[c][j];
                    }
                }
            }
        }
    }
    Some(m.into_iter().map(|r| r[k..].to_vec()).collect())
}

/// Standard normal upper tail `P(Z > z)`, from `erfc` (Numerical-Recipes-style Chebyshev
/// fit, relative error below 1.2e-7 everywhere).
pub fn normal_sf(z: f64) -> f64 {
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// `z` with `P(Z > z) = p` (bisection on [`normal_sf`]).
pub fn normal_isf(p: f64) -> f64 {
    let (mut lo, mut hi) = (-40.0, 40.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if normal_sf(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Paulson's normal deviate for an `F(d1, d2)` value: `P(F' > f) ~ P(Z > paulson_z)`.
pub fn f_to_z(f: f64, d1: f64, d2: f64) -> f64 {
    let f3 = f.max(0.0).cbrt();
    let (a1, a2) = (2.0 / (9.0 * d1), 2.0 / (9.0 * d2));
    ((1.0 - a2) * f3 - (1.0 - a1)) / (a2 * f3 * f3 + a1).sqrt()
}

/// The `F(d1, d2)` value whose upper tail is `p` (inverts [`f_to_z`]).
pub fn f_isf(p: f64, d1: f64, d2: f64) -> f64 {
    let z = normal_isf(p);
    let (mut lo, mut hi) = (0.0, 1e6);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f_to_z(mid, d1, d2) < z {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Wilson-Hilferty normal deviate of a chi-square value with `df` degrees of freedom.
pub fn chi2_to_z(q: f64, df: f64) -> f64 {
    let a = 2.0 / (9.0 * df);
    ((q / df).max(0.0).cbrt() - (1.0 - a)) / a.sqrt()
}

/// Ljung-Box statistic `Q = n (n + 2) sum_k rho_k^2 / (n - k)` of one series up to `lags`
/// (around its mean); `None` for series too short (`n <= 2 lags`).
pub fn ljung_box(x: &[f64], lags: usize) -> Option<f64> {
    let n = x.len();
    if n <= 2 * lags || lags == 0 {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let c0: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
    if c0 <= 0.0 {
        return None;
    }
    let nf = n as f64;
    let q = (1..=lags)
        .map(|k| {
            let ck: f64 = (k..n).map(|i| (x[i] - mean) * (x[i - k] - mean)).sum();
            (ck / c0).powi(2) / (nf - k as f64)
        })
        .sum::<f64>();
    Some(nf * (nf + 2.0) * q)
}

/// BIC gain of a nested model with `p` more parameters: `n ln(rss0 / rss1) - p ln n`
/// (positive favours the larger model).
pub fn delta_bic(rss0: f64, rss1: f64, n: usize, p: usize) -> f64 {
    let n = n as f64;
    n * (rss0 / rss1).ln() - p as f64 * n.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_and_f_tails() {
        assert!((normal_sf(1.959_964) - 0.025).abs() < 1e-6);
        assert!((normal_isf(1e-3) - 3.090_232).abs() < 1e-4);
        // F(3, 1000) upper 1 % point is 3.80; Paulson is good to ~1 %.
        let f = f_isf(0.01, 3.0, 1000.0);
        assert!((f - 3.80).abs() < 0.05, "{f}");
        // chi2(10) upper 5 % point 18.307.
        assert!((chi2_to_z(18.307, 10.0) - 1.645).abs() < 0.02);
    }

    #[test]
    fn lstsq_recovers_line() {
        let rows: Vec<Vec<f64>> = (0..10).map(|i| vec![1.0, i as f64]).collect();
        let y: Vec<f64> = (0..10).map(|i| 2.0 + 0.5 * i as f64).collect();
        let f = lstsq(&rows, &y).unwrap();
        assert!((f.theta[0] - 2.0).abs() < 1e-12 && (f.theta[1] - 0.5).abs() < 1e-12);
        assert!(f.rss < 1e-20);
    }
}
