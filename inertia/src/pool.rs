//! Several logs of one body (or vehicle) pooled: `inertia identify --input A --input B ...`.
//!
//! Each log is identified on its own ([`crate::identify`]); their tensors in kg m^2 are
//! combined by their covariances, and the spread between them is checked against those
//! covariances:
//!
//! ```text
//! P = sum_i C_i^-1,   J = P^-1 sum_i C_i^-1 J_i                                      (P1)
//! chi2 = sum_i (J_i - J)^T C_i^-1 (J_i - J),   dof = 6 (n - 1)                         (P2)
//! cov(J) = P^-1 max(1, chi2 / dof)                                                     (P3)
//! ```
//!
//! (entries `(xx, yy, zz, xy, xz, yz)`). When the logs scatter more than their standard
//! deviations say (`chi2 / dof > 1`), the pooled covariance is scaled by the ratio (the
//! Birge ratio): the spread seen between throws is the uncertainty, not the claims of each.
//! This is how a user gets below one throw's error: throw several times.
//!
//! That holds for errors that differ from throw to throw. Where a log's fit does not explain
//! its flight to the gyro's noise (its tensor status is not `Converged`), its covariance comes
//! from the residual it leaves, and part of that error can be common to every log of the body
//! (a torque the model lacks acts alike on each throw): the spread between the logs does not
//! see it, and pooling does not remove it. Per entry `k`, with `v_k` the mean of the logs' own
//! variances and `s_k^2` the variance of their values (`n - 1` in the denominator), the part
//! `v_k - s_k^2` that does not scatter is taken as common:
//!
//! ```text
//! var_k >= max(0, v_k - s_k^2) + s_k^2 / n                                             (P4)
//! ```
//!
//! and the covariance of (P3) is scaled by `D C D`, `D = diag(sqrt(max(1, floor_k / C_kk)))`,
//! keeping its correlations. Logs that all fit to the noise keep (P3): their errors are the
//! gyro's noise, independent from log to log. The rule takes the side of caution: from a few
//! logs whose errors are in fact independent, `s_k^2` is a noisy measure and often falls below
//! `v_k`, and the floor then keeps more of `v_k` than the pooled error holds.
// Loops over the six entries read as the equations.
#![allow(clippy::needless_range_loop)]

use serde::Serialize;

use crate::calibrate::ENTRIES;
use crate::identify::{EstimateJson, Report};

/// How the logs' tensors scatter about the pooled one ((P2)).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Spread {
    /// `chi2` of (P2).
    pub chi2: f64,
    /// Its degrees of freedom, `6 (n - 1)`.
    pub dof: usize,
    /// `chi2 / dof`: about 1 when the logs agree to their standard deviations.
    pub ratio: f64,
    /// `chi2` is within its 0.1 % bound (`dof + 3.1 sqrt(2 dof)`): the logs agree to their
    /// standard deviations. The pooled covariance is scaled by `ratio` whenever it exceeds 1.
    pub consistent: bool,
}

/// The report of several logs pooled.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PooledReport {
    /// The logs, in the order given.
    pub inputs: Vec<String>,
    /// Every free flight of every log, log after log.
    pub throws: Vec<EstimateJson>,
    /// How many of `throws` each log gave.
    pub throws_per_input: Vec<usize>,
    /// The logs' tensors pooled ((P1), (P3)). `tensor_status` is `Converged` only when every
    /// log's is and the spread is consistent.
    pub pooled: EstimateJson,
    /// The spread between the logs ((P2)).
    pub spread: Spread,
    /// Warnings for the user (each log's, prefixed with its name, and the pooling's).
    pub warnings: Vec<String>,
    /// Each log's own report.
    pub logs: Vec<Report>,
}

/// Six entries of a tensor, `(xx, yy, zz, xy, xz, yz)`.
fn six(t: &[[f32; 3]; 3]) -> [f64; 6] {
    ENTRIES.map(|(r, c)| f64::from(t[r][c]))
}

/// A tensor from its six entries.
fn tensor(e: &[f64; 6]) -> [[f64; 3]; 3] {
    [[e[0], e[3], e[4]], [e[3], e[1], e[5]], [e[4], e[5], e[2]]]
}

/// The inverse of a symmetric positive definite matrix (Cholesky), `None` when it is not.
fn inverse_pd(m: &[[f64; 6]; 6]) -> Option<[[f64; 6]; 6]> {
    let mut l = [[0.0f64; 6]; 6];
    for i in 0..6 {
        for j in 0..=i {
            let s: f64 = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // Columns of L^-1, then (L^-1)^T L^-1.
    let mut li = [[0.0f64; 6]; 6];
    for c in 0..6 {
        for i in 0..6 {
            let rhs = if i == c { 1.0 } else { 0.0 };
            let s: f64 = rhs - (0..i).map(|k| l[i][k] * li[k][c]).sum::<f64>();
            li[i][c] = s / l[i][i];
        }
    }
    let mut inv = [[0.0f64; 6]; 6];
    for i in 0..6 {
        for j in 0..6 {
            inv[i][j] = (0..6).map(|k| li[k][i] * li[k][j]).sum();
        }
    }
    Some(inv)
}

fn mat_vec(m: &[[f64; 6]; 6], v: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|i| (0..6).map(|k| m[i][k] * v[k]).sum())
}

/// Pools the logs' reports ((P1)-(P3)). Every log must give a tensor in kg m^2 with its
/// covariance (a rotor momentum fixes the scale); one that does not is an error naming it.
pub fn pool(reports: Vec<Report>) -> Result<PooledReport, String> {
    if reports.len() < 2 {
        return Err("pooling needs at least two logs".into());
    }
    let mut info = [[0.0f64; 6]; 6];
    let mut info_j = [0.0f64; 6];
    let mut each = Vec::new();
    let mut own_var: Vec<[f64; 6]> = Vec::new();
    for r in &reports {
        let (Some(t), Some(c)) = (r.pooled.tensor_kg_m2, r.pooled.tensor_cov_kg2_m4) else {
            return Err(format!(
                "{}: no tensor in kg m^2 (status {}): several logs are pooled by their tensors, \
                 which need a rotor of known inertia (--rotor-inertia, --rotor-axis)",
                r.input, r.pooled.tensor_status
            ));
        };
        let c = c.map(|row| row.map(f64::from));
        let ci = inverse_pd(&c)
            .ok_or_else(|| format!("{}: the tensor's covariance is not positive", r.input))?;
        let j = six(&t);
        let cij = mat_vec(&ci, &j);
        for i in 0..6 {
            info_j[i] += cij[i];
            for k in 0..6 {
                info[i][k] += ci[i][k];
            }
        }
        each.push((j, ci));
        own_var.push(std::array::from_fn::<f64, 6, _>(|k| c[k][k]));
    }
    let cov = inverse_pd(&info).ok_or("the pooled information is not positive")?;
    let j = mat_vec(&cov, &info_j);
    let chi2: f64 = each
        .iter()
        .map(|(ji, ci)| {
            let d: [f64; 6] = std::array::from_fn(|k| ji[k] - j[k]);
            let cd = mat_vec(ci, &d);
            (0..6).map(|k| d[k] * cd[k]).sum::<f64>()
        })
        .sum();
    let dof = 6 * (reports.len() - 1);
    let ratio = chi2 / dof as f64;
    let bound = dof as f64 + 3.1 * (2.0 * dof as f64).sqrt();
    let spread = Spread {
        chi2,
        dof,
        ratio,
        consistent: chi2 <= bound,
    };
    let scale = ratio.max(1.0);
    let cov = cov.map(|row| row.map(|x| x * scale));
    let all_fit = reports
        .iter()
        .all(|r| r.pooled.tensor_status == "Converged");
    let cov = if all_fit {
        cov
    } else {
        let values: Vec<[f64; 6]> = each.iter().map(|(ji, _)| *ji).collect();
        common_error_floor(&cov, &values, &own_var)
    };
    let mut warnings = Vec::new();
    for r in &reports {
        warnings.extend(r.warnings.iter().map(|w| format!("{}: {w}", r.input)));
    }
    if !spread.consistent {
        warnings.push(format!(
            "the logs' tensors scatter {ratio:.2} times (in variance) what their standard \
             deviations say (chi2 {chi2:.1} on {dof} degrees of freedom): the pooled standard \
             deviation is scaled by it"
        ));
    }
    let pooled = pooled_estimate(&reports, &j, &cov, spread.consistent);
    Ok(PooledReport {
        inputs: reports.iter().map(|r| r.input.clone()).collect(),
        throws: reports.iter().flat_map(|r| r.throws.clone()).collect(),
        throws_per_input: reports.iter().map(|r| r.throws.len()).collect(),
        pooled,
        spread,
        warnings,
        logs: reports,
    })
}

/// The right side of (P4) for one quantity from `(value, own variance)` of each of `n >= 2`
/// throws or logs: `max(0, v - s^2) + s^2 / n`.
pub fn shared_floor(each: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let n = each.clone().count() as f64;
    let mean = each.clone().map(|(x, _)| x).sum::<f64>() / n;
    let s2 = each.clone().map(|(x, _)| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let v = each.map(|(_, var)| var).sum::<f64>() / n;
    (v - s2).max(0.0) + s2 / n
}

/// `cov` widened by (P4): per entry, at least the logs' variance that does not scatter between
/// them plus the scatter's share of the mean, `values` and `own_var` each log's entries and
/// their own variances.
fn common_error_floor(
    cov: &[[f64; 6]; 6],
    values: &[[f64; 6]],
    own_var: &[[f64; 6]],
) -> [[f64; 6]; 6] {
    let d: [f64; 6] = std::array::from_fn(|k| {
        let floor = shared_floor(
            values
                .iter()
                .map(|v| v[k])
                .zip(own_var.iter().map(|v| v[k])),
        );
        let r = floor / cov[k][k];
        if r.is_finite() && r > 1.0 {
            r.sqrt()
        } else {
            1.0
        }
    });
    std::array::from_fn(|i| std::array::from_fn(|k| d[i] * cov[i][k] * d[k]))
}

/// The pooled estimate as JSON: the tensor, its covariance and what follows from them; the
/// ratios `a` (axis-matched per log) are left out.
fn pooled_estimate(
    reports: &[Report],
    j: &[f64; 6],
    cov: &[[f64; 6]; 6],
    consistent: bool,
) -> EstimateJson {
    let t = tensor(j);
    let t32 = t.map(|r| r.map(|x| x as f32));
    let mut std = [[0.0f32; 3]; 3];
    for (k, (r, c)) in ENTRIES.iter().enumerate() {
        let s = cov[k][k].max(0.0).sqrt() as f32;
        std[*r][*c] = s;
        std[*c][*r] = s;
    }
    let trace = t[0][0] + t[1][1] + t[2][2];
    let (moments, axes) = crate::calibrate::eigen(&t);
    // A status every log shares, else the first that is not `Converged`.
    let status_of = |get: &dyn Fn(&EstimateJson) -> &String| {
        let first_bad = reports
            .iter()
            .map(|r| get(&r.pooled))
            .find(|s| s.as_str() != "Converged");
        first_bad.cloned().unwrap_or_else(|| "Converged".into())
    };
    let mut tensor_status = status_of(&|e| &e.tensor_status);
    if tensor_status == "Converged" && !consistent {
        tensor_status = "ModelMismatch".into();
    }
    // The pooled covariance is the logs' (scaled up when they scatter, floored by what they
    // share where they do not fit to the noise): the residual's unless some log's
    // standard deviations leave an error uncounted.
    let uncertainty = if reports
        .iter()
        .any(|r| r.pooled.tensor_uncertainty == "Unaccounted")
    {
        "Unaccounted"
    } else if reports
        .iter()
        .all(|r| r.pooled.tensor_uncertainty == "Noise")
        && consistent
    {
        "Noise"
    } else {
        "Residual"
    };
    // `identifier_core::TensorEstimate::usable` of the pooled tensor: every log usable. Each
    // log is then `Converged` with `Noise` or `ModelMismatch` with `Residual`, so the pooled
    // status is `Converged` (all logs, consistent: `Noise`) or `ModelMismatch` (a log's, or an
    // inconsistent spread: `Residual` either way), the rule's two usable cases.
    let usable = reports.iter().all(|r| r.pooled.tensor_usable);
    let first = &reports[0].pooled;
    let last = &reports[reports.len() - 1].pooled;
    EstimateJson {
        start_s: first.start_s,
        end_s: last.end_s,
        samples: reports.iter().map(|r| r.pooled.samples).sum(),
        status: tensor_status.clone(),
        a_source: "Tensor".into(),
        tensor_status,
        tensor_method: first.tensor_method.clone(),
        tensor_uncertainty: uncertainty.into(),
        tensor_usable: usable,
        model: first.model.clone(),
        tensor_kg_m2: Some(t32),
        tensor_std_kg_m2: Some(std),
        tensor_cov_kg2_m4: Some(cov.map(|r| r.map(|x| x as f32))),
        tensor_normalized: (trace > 0.0).then(|| t.map(|r| r.map(|x| (x / trace) as f32))),
        tensor_normalized_std: None,
        a: None,
        std_a: None,
        principal_moments: Some(moments.map(|x| x as f32)),
        principal_axes: Some(axes.map(|r| r.map(|x| x as f32))),
        residual_ratio: reports
            .iter()
            .map(|r| r.pooled.residual_ratio)
            .fold(0.0, f32::max),
        excitation: reports.iter().map(|r| r.pooled.excitation).sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_diagonal_covariance_inverts() {
        let mut m = [[0.0f64; 6]; 6];
        for (i, row) in m.iter_mut().enumerate() {
            row[i] = (i + 1) as f64;
        }
        m[0][1] = 0.5;
        m[1][0] = 0.5;
        let inv = inverse_pd(&m).unwrap();
        for i in 0..6 {
            for j in 0..6 {
                let p: f64 = (0..6).map(|k| m[i][k] * inv[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((p - want).abs() < 1e-12, "{i} {j}: {p}");
            }
        }
        m[2][2] = -1.0;
        assert!(inverse_pd(&m).is_none());
    }

    /// (P4): logs that agree to the last digit while each claims a variance `v` share an
    /// error that pooling cannot remove (the floor is `v`, not `v / n`); logs that scatter as
    /// their variances say keep (P3)'s `v / n`.
    #[test]
    fn an_error_the_logs_share_is_not_averaged_away() {
        let v = 4.0e-12;
        let n = 5usize;
        let own = vec![[v; 6]; n];
        let mut p3 = [[0.0f64; 6]; 6];
        for k in 0..6 {
            p3[k][k] = v / n as f64;
        }
        p3[0][1] = 0.5 * v / n as f64;
        p3[1][0] = p3[0][1];
        let agreeing = vec![[1.0e-4; 6]; n];
        let c = common_error_floor(&p3, &agreeing, &own);
        for k in 0..6 {
            assert!((c[k][k] / v - 1.0).abs() < 1e-12, "entry {k}: {}", c[k][k]);
        }
        // The correlation of entries 0 and 1 is kept.
        assert!((c[0][1] / (c[0][0] * c[1][1]).sqrt() - 0.5).abs() < 1e-12);
        // Values of sample variance exactly v: +-sqrt(v (n - 1) / 2) on two logs, the rest at
        // the mean.
        let a = (v * (n as f64 - 1.0) / 2.0).sqrt();
        let scattering: Vec<[f64; 6]> = (0..n)
            .map(|i| {
                let d = match i {
                    0 => a,
                    1 => -a,
                    _ => 0.0,
                };
                [1.0e-4 + d; 6]
            })
            .collect();
        let c = common_error_floor(&p3, &scattering, &own);
        for k in 0..6 {
            assert!(
                (c[k][k] / p3[k][k] - 1.0).abs() < 1e-9,
                "entry {k}: {}",
                c[k][k]
            );
        }
    }
}
