//! `inertia calibrate`: the rotor inertia `j` from throws of the board alone and bolted to a
//! proof body of known inertia, then any object bolted to the board by difference.
//!
//! # Why it is linear in `j`
//!
//! With `h = j omega_r axis`, Euler's equation `J w' + w x (J w + h) + h' = 0` is homogeneous
//! in `(J, j)`: the tensor identified with a unit rotor inertia, `J1`, scales exactly,
//! `J(j) = j J1`. So every throw is identified once with `j = 1e-6` (for `f32` range) and
//! rescaled.
//!
//! # Parallel axes
//!
//! Each tensor is about the centre of mass of what was thrown. The accelerometer gives where
//! that centre is: in free flight it reads `f = w x (w x r) + w' x r` with `r` the IMU's
//! position from the centre of mass, fitted by least squares over the throw (`f64`, `w'` by
//! central differences). With the board's centre `c_b = -r_b`, the assembly's `c_t = -r_t`
//! (both from the IMU) and the masses, the object's centre is
//! `c_o = ((m_b + m_o) c_t - m_b c_b) / m_o`, and about its own centre
//!
//! ```text
//! J_o = J_t - J_b - m_b P(c_b - c_t) - m_o P(c_o - c_t),     P(d) = |d|^2 I - d d^T
//!     = j (J1_t - J1_b) - M
//! ```
//!
//! Calibration: `j = <D, J_known + M> / <D, D>` with `D = J1_t - J1_b` (least squares over the
//! nine entries). Identification of an object: the same difference with the calibrated `j`.
//!
//! # Several rotors
//!
//! A vehicle file (`--vehicle`) may hold several rotors (a quadrotor's four motors with the
//! propellers off, reaction wheels), each with its own speed column and axis `g_i`. Their
//! momentum is `h = sum_i j_i w_i g_i`, and the equation stays homogeneous as long as their
//! inertias are known up to one common scale: with the file's `inertia_kg_m2` values `r_i`
//! (of which only the ratios are used; for identical motors, equal values),
//!
//! ```text
//! h = s sum_i r_i w_i g_i,      j_i = s r_i = j r_i / r_1,      j = j_1
//! ```
//!
//! so each throw is identified once with the rotors at `UNIT_J r_i / r_1`, its tensor divided
//! by the first rotor's unit inertia is `J1` (the tensor for `j_1 = 1` kg m^2, the others in
//! the file's ratios), and everything above goes through with `j` the first rotor's inertia.
//! What is calibrated is the scale `s = j / r_1`; each rotor's inertia `j r_i / r_1` comes
//! with the standard deviation of `j` times the same ratio ([`VehicleCalibration`]). A file
//! of one rotor is the case above: its inertia is not used at all.
//!
//! # The scale between the rates and the clock
//!
//! Rates that read a few tenths of a percent high against the log's clock (a gyro's scale
//! error, or a clock running fast) bend every tensor's ratios and, through the rotor momentum,
//! their scale, by a few times as much and differently for each body. By default
//! (`--scale auto`) the scale is calibrated from the proof body's shape and every throw, the
//! object's included, is identified through it ((G1), (G2) of `calibrate/scale.rs`), as a
//! clock's (`--scale-of clock`) or as a gyro's (`--scale-of gyro`).

// 3x3 index arithmetic mirrors the equations.
#![allow(clippy::needless_range_loop)]

use serde::Serialize;

use crate::identify::{identify, IdentifyOptions, Rotor};
use crate::recording::Recording;
use crate::vehicle::Vehicle;

mod scale;
use scale::{all_at, ScaledThrow, SCALE_STEP};

/// The entries of a tensor in the order of its covariance: xx, yy, zz, xy, xz, yz.
pub(crate) const ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Rotor inertia used for the unit identification (rescaled afterwards).
pub const UNIT_J: f32 = 1e-6;

type M3 = [[f64; 3]; 3];

/// One throw identified with the unit rotor inertia.
#[derive(Clone, Debug, Serialize)]
pub struct UnitThrow {
    /// The log.
    pub source: String,
    /// `J1`: the tensor for `j = 1` kg m^2 (multiply by `j`), in the log's gyro axes; with a
    /// vehicle file of several rotors, for the first rotor's `j_1 = 1` kg m^2 and the others
    /// in the file's ratios.
    pub j1: M3,
    /// The standard deviation of each entry of `J1` the estimate reported.
    pub j1_std: Option<M3>,
    /// The correlations of the entries `(xx, yy, zz, xy, xz, yz)` of `J1` the estimate
    /// reported (`None`: taken as independent).
    #[serde(skip)]
    pub j1_corr: Option<[[f64; 6]; 6]>,
    /// IMU position from the centre of mass, m.
    pub imu_from_com: [f64; 3],
    /// Its covariance, m^2 ([`fit_offset`]; `None`: not measured).
    #[serde(skip)]
    pub imu_from_com_cov: Option<M3>,
    /// RMS residual of the offset fit, m/s^2.
    pub offset_fit_rms: f64,
    /// The accelerometer at rest: its median magnitude over the bench's still run, over
    /// standard gravity, as the centres of mass took it (after `--accel-scale`;
    /// [`Recording::accel_at_rest_g`]).
    pub accel_at_rest_g: Option<f64>,
    /// Status of the ratios (`pooled.status` of `inertia identify`).
    pub status: String,
    /// Status of the tensor estimate (`pooled.tensor_status`): what decides whether the
    /// throw can be used ([`usable`]).
    pub tensor_status: String,
    /// Samples used.
    pub samples: u32,
}

/// A throw the calibration left out, and why.
#[derive(Clone, Debug, Serialize)]
pub struct SkippedThrow {
    /// The log.
    pub source: String,
    /// `board`, `assembly` or `object`.
    pub group: &'static str,
    /// Why: the reader's or the identification's error, or the tensor's status.
    pub reason: String,
}

/// Whether a throw's tensor may enter the calibration, from its status. Left out: a throw the
/// estimator says it cannot determine (`TooFewSamples`, `NoExcitation`), one whose data are
/// suspect (`UnitsLookWrong`; `Saturated`: the clipped stretches never reach the fit, and a
/// clipped throw is one the product does not trust) or whose tensor is not a body's
/// (`PhysicallyImpossible`).
/// Kept: `Converged`, `Converging` and `ModelMismatch` (every thrown-FC throw is the last: its
/// residual is a model error, and its reported standard deviation is scaled to it).
pub fn usable(tensor_status: &str) -> bool {
    matches!(tensor_status, "Converged" | "Converging" | "ModelMismatch")
}

/// Identifies one recording with the unit rotor inertia and fits the IMU offset.
pub fn unit_throw(
    rec: &Recording,
    axis: [f32; 3],
    poles: Option<u32>,
) -> Result<UnitThrow, String> {
    let rotor = Rotor {
        inertia: UNIT_J,
        axis,
        poles,
    };
    unit_throw_with(rec, Some(rotor), None, UNIT_J)
}

/// The vehicle file's rotors scaled to unit inertias, `UNIT_J r_i / r_1` (the module's
/// "Several rotors"), for [`unit_throw_vehicle`].
pub fn unit_vehicle(v: &Vehicle) -> Result<Vehicle, String> {
    let first = v.rotors.first().map_or(f32::NAN, |r| r.inertia_kg_m2);
    v.scaled(UNIT_J / first).map_err(|e| e.to_string())
}

/// Identifies one recording with the vehicle file's rotors at unit inertias (`unit`, from
/// [`unit_vehicle`]; the recording read with its columns) and fits the IMU offset: `J1` is the
/// tensor for the first rotor's `j_1 = 1` kg m^2.
pub fn unit_throw_vehicle(rec: &Recording, unit: &Vehicle) -> Result<UnitThrow, String> {
    let first = unit.rotors.first().map_or(f32::NAN, |r| r.inertia_kg_m2);
    unit_throw_with(rec, None, Some(unit.clone()), first)
}

/// [`unit_throw`] with the rotor or the vehicle's rotors given, `unit` the (first) rotor's
/// inertia they were identified with.
fn unit_throw_with(
    rec: &Recording,
    rotor: Option<Rotor>,
    vehicle: Option<Vehicle>,
    unit: f32,
) -> Result<UnitThrow, String> {
    let several = vehicle.is_some();
    let opts = IdentifyOptions {
        rotor,
        vehicle,
        segments: None,
        noise_std: None,
        // Decided from the log unless `INERTIA_ROTOR_UNHOLD` is set (`identify --rotor-unhold`).
        rotor_hold: if std::env::var_os("INERTIA_ROTOR_UNHOLD").is_some() {
            crate::identify::RotorHold::Unhold
        } else {
            crate::identify::RotorHold::Auto
        },
        trace: false,
    };
    let rep = identify(rec, &opts).map_err(|e| format!("{}: {e}", rec.source))?;
    let t = rep.pooled.tensor_kg_m2.ok_or_else(|| {
        if several {
            format!(
                "{}: the rotors' momentum did not fix the scale: is it zero throughout the \
                 free flight (motors stopped, or equal and opposite)?",
                rec.source
            )
        } else {
            format!("{}: the rotor momentum did not fix the scale", rec.source)
        }
    })?;
    let j1 = t.map(|r| r.map(|x| x as f64 / unit as f64));
    let j1_std = rep
        .pooled
        .tensor_std_kg_m2
        .map(|s| s.map(|r| r.map(|x| x as f64 / unit as f64)));
    let j1_corr = rep
        .pooled
        .tensor_cov_kg2_m4
        .map(|c| correlations(&c.map(|r| r.map(f64::from))));
    let runs: Vec<Vec<usize>> = rep
        .fed_runs
        .iter()
        .map(|r| r.iter().flat_map(Clone::clone).collect())
        .collect();
    let offset = fit_offset(rec, &runs, rep.gyro_bias)
        .ok_or_else(|| format!("{}: no accelerometer, no centre of mass", rec.source))?;
    let (imu_from_com, rms) = (offset.imu_from_com, offset.rms);
    Ok(UnitThrow {
        source: rec.source.clone(),
        j1,
        j1_std,
        j1_corr,
        imu_from_com_cov: offset.cov,
        imu_from_com,
        offset_fit_rms: rms,
        accel_at_rest_g: rec.accel_at_rest_g(),
        status: rep.pooled.status,
        tensor_status: rep.pooled.tensor_status,
        samples: rep.pooled.samples,
    })
}

/// Least-squares `r` in `f = w x (w x r) + w' x r = K(w, w') r` over the fed samples
/// (central differences for `w'`, bias removed), with the RMS residual.
///
/// Both sides pass through the same low-pass filter as the free-flight gate's
/// ([`GateSettings::lowpass_hz`](identifier_core::GateSettings), two first-order stages, run
/// forwards and then backwards so the pair has no phase lag), restarted at every break in the
/// fed samples. A linear filter keeps `f = K r` exact for a constant `r`, and it removes the
/// rotor's vibration: on the thrown-FC logs the gyro's share of it (0.05-0.16 rad/s at about
/// 200-250 Hz) puts some 150 rad/s^2 into the differenced `w'`, as much as the body's own
/// angular acceleration, and the least squares pulled `r` towards zero by millimetres, which
/// the parallel-axis terms of a calibration turn into percent.
///
/// The covariance of `r` comes from a delete-one-chunk jackknife over [`OFFSET_CHUNKS`]
/// consecutive chunks of the rows: the filtered rows are correlated over tens of
/// milliseconds, so the least squares' own `s^2 (K^T K)^-1` would claim tens of times the
/// information they hold, while chunks much longer than the filter's memory are nearly
/// independent.
pub fn fit_offset(rec: &Recording, runs: &[Vec<usize>], bias: [f32; 3]) -> Option<OffsetFit> {
    let acc = rec.accel.as_ref()?;
    let w = |i: usize| -> [f64; 3] {
        let g = rec.gyro[i];
        [0, 1, 2].map(|k| g[k] as f64 - bias[k] as f64)
    };
    let fc = identifier_core::GateSettings::for_rate(1000.0).lowpass_hz as f64;
    let mut ata = [[0.0f64; 3]; 3];
    let mut atb = [0.0f64; 3];
    let mut bb = 0.0;
    let mut n = 0usize;
    // The normal equations of each chunk, for the jackknife.
    let total: usize = runs.iter().map(Vec::len).sum();
    let chunk_len = total.div_ceil(OFFSET_CHUNKS).max(1);
    let mut chunks = [([[0.0f64; 3]; 3], [0.0f64; 3]); OFFSET_CHUNKS];
    let mut row_index = 0usize;
    for run in runs {
        // Consecutive rows (K by rows, f) with their time steps; a break starts a new piece.
        let mut pieces: Vec<Vec<([f64; 12], f64)>> = vec![Vec::new()];
        for win in run.windows(3) {
            let (a, i, c) = (win[0], win[1], win[2]);
            let dt = rec.t[c] - rec.t[a];
            if c != i + 1 || a + 1 != i || dt.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            {
                pieces.push(Vec::new());
                continue;
            }
            let (wa, wi, wc) = (w(a), w(i), w(c));
            let wd = [0, 1, 2].map(|k| (wc[k] - wa[k]) / dt);
            let [x, y, z] = wi;
            let n2 = x * x + y * y + z * z;
            let f = acc[i].map(|v| v as f64);
            let row = [
                x * x - n2,
                x * y - wd[2],
                x * z + wd[1],
                y * x + wd[2],
                y * y - n2,
                y * z - wd[0],
                z * x - wd[1],
                z * y + wd[0],
                z * z - n2,
                f[0],
                f[1],
                f[2],
            ];
            if let Some(last) = pieces.last_mut() {
                last.push((row, 0.5 * dt));
            }
        }
        for piece in pieces.iter_mut().filter(|p| !p.is_empty()) {
            lowpass_both_ways(piece, fc);
            for (row, _) in piece.iter() {
                let k = [
                    [row[0], row[1], row[2]],
                    [row[3], row[4], row[5]],
                    [row[6], row[7], row[8]],
                ];
                let f = [row[9], row[10], row[11]];
                let chunk = &mut chunks[(row_index / chunk_len).min(OFFSET_CHUNKS - 1)];
                row_index += 1;
                for r in 0..3 {
                    for cc in 0..3 {
                        let v = (0..3).map(|m| k[m][r] * k[m][cc]).sum::<f64>();
                        ata[r][cc] += v;
                        chunk.0[r][cc] += v;
                    }
                    let v = (0..3).map(|m| k[m][r] * f[m]).sum::<f64>();
                    atb[r] += v;
                    chunk.1[r] += v;
                }
                bb += f.iter().map(|v| v * v).sum::<f64>();
                n += 1;
            }
        }
    }
    if n < 10 {
        return None;
    }
    let r = solve3(&ata, &atb)?;
    let rss = bb - (0..3).map(|k| r[k] * atb[k]).sum::<f64>();
    let leave_out: Vec<[f64; 3]> = chunks
        .iter()
        .filter(|c| c.0[0][0] > 0.0)
        .filter_map(|(ca, cb)| solve3(&add(&ata, ca, -1.0), &[0, 1, 2].map(|k| atb[k] - cb[k])))
        .collect();
    let m = leave_out.len() as f64;
    let cov = (m >= 2.0).then(|| {
        let mean = [0, 1, 2].map(|k| leave_out.iter().map(|x| x[k]).sum::<f64>() / m);
        std::array::from_fn(|a| {
            std::array::from_fn(|b| {
                (m - 1.0) / m
                    * leave_out
                        .iter()
                        .map(|x| (x[a] - mean[a]) * (x[b] - mean[b]))
                        .sum::<f64>()
            })
        })
    });
    Some(OffsetFit {
        imu_from_com: r,
        rms: (rss.max(0.0) / n as f64).sqrt(),
        cov,
    })
}

/// The correlations of a covariance matrix, each entry clamped to `[-1, 1]`; where a variance
/// is zero or not finite, the identity's entry (the input taken as independent).
fn correlations<const N: usize>(cov: &[[f64; N]; N]) -> [[f64; N]; N] {
    let s: [f64; N] = std::array::from_fn(|i| cov[i][i].max(0.0).sqrt());
    std::array::from_fn(|i| {
        std::array::from_fn(|k| {
            let r = cov[i][k] / (s[i] * s[k]);
            if r.is_finite() {
                r.clamp(-1.0, 1.0)
            } else {
                f64::from(u8::from(i == k))
            }
        })
    })
}

/// Chunks of [`fit_offset`]'s jackknife.
pub const OFFSET_CHUNKS: usize = 10;

/// The accelerometer's fit of the IMU's position from the centre of mass ([`fit_offset`]).
#[derive(Clone, Copy, Debug)]
pub struct OffsetFit {
    /// `r`, m.
    pub imu_from_com: [f64; 3],
    /// RMS residual, m/s^2.
    pub rms: f64,
    /// Covariance of `r`, m^2 (`None` with fewer than two usable chunks).
    pub cov: Option<M3>,
}

/// Two first-order low-pass stages at `fc` Hz (`y += a (x - y)`, `a = x / (1 + x)`, `x = 2 pi
/// fc dt`), forwards and then backwards over the rows, each pass started at its first row.
fn lowpass_both_ways(rows: &mut [([f64; 12], f64)], fc: f64) {
    let pass = |rows: &mut dyn Iterator<Item = &mut ([f64; 12], f64)>| {
        let mut state: Option<[[f64; 12]; 2]> = None;
        for (row, dt) in rows {
            let x = 2.0 * std::f64::consts::PI * fc * *dt;
            let a = x / (1.0 + x);
            let [s1, s2] = state.get_or_insert([*row; 2]);
            for k in 0..12 {
                s1[k] += a * (row[k] - s1[k]);
                s2[k] += a * (s1[k] - s2[k]);
            }
            *row = *s2;
        }
    };
    pass(&mut rows.iter_mut());
    pass(&mut rows.iter_mut().rev());
}

fn det3(m: &M3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

fn solve3(m: &M3, b: &[f64; 3]) -> Option<[f64; 3]> {
    let d = det3(m);
    if !(d.abs() > 0.0 && d.is_finite()) {
        return None;
    }
    let mut x = [0.0; 3];
    for c in 0..3 {
        let mut mc = *m;
        for r in 0..3 {
            mc[r][c] = b[r];
        }
        x[c] = det3(&mc) / d;
    }
    Some(x)
}

/// `P(d) = |d|^2 I - d d^T`, the parallel-axis term per unit mass.
pub fn parallel(d: [f64; 3]) -> M3 {
    let n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = if r == c { n2 } else { 0.0 } - d[r] * d[c];
        }
    }
    m
}

fn add(a: &M3, b: &M3, k: f64) -> M3 {
    let mut m = *a;
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] += k * b[r][c];
        }
    }
    m
}

fn dot(a: &M3, b: &M3) -> f64 {
    (0..9).map(|k| a[k / 3][k % 3] * b[k / 3][k % 3]).sum()
}

/// Mean of unit tensors and offsets.
pub fn mean(throws: &[UnitThrow]) -> (M3, [f64; 3]) {
    let n = throws.len().max(1) as f64;
    let mut j = [[0.0; 3]; 3];
    let mut r = [0.0; 3];
    for t in throws {
        j = add(&j, &t.j1, 1.0 / n);
        for k in 0..3 {
            r[k] += t.imu_from_com[k] / n;
        }
    }
    (j, r)
}

/// The mass terms `M` and the difference `D` of the assembly against the board.
pub fn difference(
    board: (&M3, [f64; 3]),
    total: (&M3, [f64; 3]),
    m_b: f64,
    m_o: f64,
) -> (M3, M3, [f64; 3]) {
    let c_b = board.1.map(|x| -x);
    let c_t = total.1.map(|x| -x);
    let c_o = [0, 1, 2].map(|k| ((m_b + m_o) * c_t[k] - m_b * c_b[k]) / m_o);
    let db = [0, 1, 2].map(|k| c_b[k] - c_t[k]);
    let dobj = [0, 1, 2].map(|k| c_o[k] - c_t[k]);
    let m = add(
        &parallel(db).map(|r| r.map(|x| x * m_b)),
        &parallel(dobj),
        m_o,
    );
    let d = add(total.0, board.0, -1.0);
    (d, m, c_o)
}

/// `j` minimising `|j D - (J_known + M)|_F`.
pub fn calibrate_j(d: &M3, m: &M3, known: &M3) -> f64 {
    let target = add(known, m, 1.0);
    dot(d, &target) / dot(d, d)
}

/// `J_o = j D - M`.
pub fn object(j: f64, d: &M3, m: &M3) -> M3 {
    add(&d.map(|r| r.map(|x| x * j)), m, -1.0)
}

/// Eigenvalues (ascending) and unit eigenvectors of a symmetric 3x3 matrix (`f64` Jacobi).
pub fn eigen(m: &M3) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut a = *m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        for &(p, q) in &[(0usize, 1usize), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut idx = [0, 1, 2];
    idx.sort_by(|&x, &y| a[x][x].total_cmp(&a[y][y]));
    let vals = idx.map(|i| a[i][i]);
    let vecs = idx.map(|i| [v[0][i], v[1][i], v[2][i]]);
    (vals, vecs)
}

/// Angle in degrees between two axes (sign-free).
pub fn axis_angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs();
    let na = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let nb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    (d / (na * nb)).clamp(0.0, 1.0).acos().to_degrees()
}

/// Relative Frobenius distance `|a - b| / |b|`.
pub fn rel_frobenius(a: &M3, b: &M3) -> f64 {
    let d = add(a, b, -1.0);
    (dot(&d, &d) / dot(b, b)).sqrt()
}

/// Comparison of a recovered tensor with a known one: principal moments (relative errors,
/// matched in ascending order) and axis angles.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Relative error of each principal moment, ascending.
    pub moment_errors: [f64; 3],
    /// Angle of each principal axis to the known one, degrees.
    pub axis_errors_deg: [f64; 3],
}

/// Compares `got` with `known`.
pub fn compare(got: &M3, known: &M3) -> Comparison {
    let (vg, eg) = eigen(got);
    let (vk, ek) = eigen(known);
    Comparison {
        moment_errors: [0, 1, 2].map(|i| (vg[i] - vk[i]) / vk[i]),
        axis_errors_deg: [0, 1, 2].map(|i| axis_angle_deg(eg[i], ek[i])),
    }
}

/// Arguments of `inertia calibrate`.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct CalibrateArgs {
    /// Logs of the board (with its rotor) thrown alone.
    #[arg(long, num_args = 1.., required = true)]
    pub board: Vec<std::path::PathBuf>,
    /// Logs of the board bolted to the proof body.
    #[arg(long, num_args = 1.., required = true)]
    pub assembly: Vec<std::path::PathBuf>,
    /// Proof body's inertia about its own centre of mass in the log's gyro axes, kg m^2:
    /// `Ixx,Iyy,Izz` or `Ixx,Iyy,Izz,Ixy,Ixz,Iyz`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub proof_inertia: Vec<f64>,
    /// Board mass, kg.
    #[arg(long)]
    pub board_mass: f64,
    /// Proof body mass, kg.
    #[arg(long)]
    pub proof_mass: f64,
    /// Logs of the board bolted to an unknown object (identified by difference).
    #[arg(long, num_args = 1..)]
    pub object: Vec<std::path::PathBuf>,
    /// Mass of the unknown object, kg.
    #[arg(long)]
    pub object_mass: Option<f64>,
    /// Rotor axis in the gyro frame: x, y, z, -x, -y or -z.
    #[arg(
        long,
        value_parser = crate::identify::parse_axis,
        allow_hyphen_values = true,
        required_unless_present = "vehicle"
    )]
    pub rotor_axis: Option<[f32; 3]>,
    /// Motor poles (for eRPM channels).
    #[arg(long)]
    pub rotor_poles: Option<u32>,
    /// A vehicle file with the rotors to calibrate, instead of `--rotor-axis` and
    /// `--rotor-poles`: each one's axis (any unit vector), speed column and poles. Of their
    /// inertias only the ratios are used (equal values for identical motors): what is
    /// calibrated is their common scale, and each rotor's inertia is reported. A file of one
    /// rotor reads its column as the log's rotor channel (blackbox `erpm[0]`, CSV
    /// `rotor_rad_s`, or the column the file names) and its inertia is not used.
    #[arg(long, conflicts_with_all = ["rotor_axis", "rotor_poles"])]
    pub vehicle: Option<std::path::PathBuf>,
    /// The scale factor `k` between the log's rates and its clock: `auto` calibrates it from
    /// the proof body's shape ((G1) of the module's "The scale between the rates and the
    /// clock"); a number takes it as given (`1`: the log as read).
    #[arg(long, default_value = "auto", value_parser = parse_scale)]
    pub scale: ScaleFactor,
    /// What `k` is taken to be: `clock`, the log's clock running `k` times true time (its
    /// times divided by `k`), or `gyro`, the gyro reading `k` times the true rate (its rates
    /// divided by `k`). The two give the dynamics the same equation; they differ in the
    /// accelerometer's centre of mass, which takes the rates squared.
    #[arg(long, value_enum, default_value_t = ScaleOf::Clock)]
    pub scale_of: ScaleOf,
    /// The accelerometer's scale factor: it reads this many times the true specific force,
    /// and its readings are divided by it before the free flights and the centres of mass
    /// are found (`1`: as read). Take it from a calibration of the accelerometer (a
    /// six-position test, say): the report's `accel_at_rest_g` alone cannot tell a scale
    /// from a bias along gravity.
    #[arg(long, default_value_t = 1.0, value_parser = parse_accel_scale)]
    pub accel_scale: f64,
    /// Where to write the JSON report.
    #[arg(long)]
    pub json: std::path::PathBuf,
    /// Directory for the plots: `throws.svg` (each throw's moments against its group's mean,
    /// with the standard deviations the throw reported), `board_axes.svg` and, with an object,
    /// `object_axes.svg` (the tensors' equimomental ellipsoids and principal axes).
    #[arg(long)]
    pub plots: Option<std::path::PathBuf>,
}

/// The scale of `inertia calibrate --scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScaleFactor {
    /// Calibrated from the proof body ((G1)).
    Auto,
    /// Given: the log's rates read this many times what its clock says.
    Given(f64),
}

/// What the scale factor `k` of `inertia calibrate --scale` is taken to be (`clock` or
/// `gyro` in the report).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScaleOf {
    /// The log's clock runs `k` times true time: its times are divided by `k`.
    Clock,
    /// The gyro reads `k` times the true rate: its rates and full scale are divided by `k`.
    Gyro,
}

impl ScaleOf {
    /// Its name, as the command line and the report spell it.
    pub fn name(self) -> &'static str {
        match self {
            ScaleOf::Clock => "clock",
            ScaleOf::Gyro => "gyro",
        }
    }
}

/// `auto`, or a scale within a half of 1.
pub fn parse_scale(s: &str) -> Result<ScaleFactor, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(ScaleFactor::Auto);
    }
    factor_near_one(s)
        .map(ScaleFactor::Given)
        .ok_or_else(|| format!("{s}: `auto` or a scale factor between 0.5 and 1.5"))
}

/// A scale factor strictly within a half of 1, or `None`.
fn factor_near_one(s: &str) -> Option<f64> {
    s.parse::<f64>().ok().filter(|k| *k > 0.5 && *k < 1.5)
}

/// `--accel-scale`: a factor within a half of 1.
pub fn parse_accel_scale(s: &str) -> Result<f64, String> {
    factor_near_one(s)
        .ok_or_else(|| format!("{s}: an accelerometer scale factor between 0.5 and 1.5"))
}

/// A recording with its accelerometer read through the scale `k`: the specific force
/// divided by it (the rates and the clock as read).
pub fn accel_scaled(rec: Recording, k: f64) -> Recording {
    if k == 1.0 {
        return rec;
    }
    let mut r = rec;
    let inv = 1.0 / k;
    if let Some(acc) = &mut r.accel {
        for f in acc {
            *f = f.map(|x| (f64::from(x) * inv) as f32);
        }
    }
    r
}

/// A recording with its gyro read through the scale `k`: rates and full scale divided by it.
pub fn gyro_scaled(rec: &Recording, k: f64) -> Recording {
    let mut r = rec.clone();
    let inv = (1.0 / k) as f32;
    for w in &mut r.gyro {
        *w = w.map(|x| x * inv);
    }
    r.gyro_full_scale *= inv;
    r
}

/// A recording read through a clock that runs `k` times true time: its times divided by `k`
/// (the rates, the rotor's speed from its own telemetry and the accelerometer are as read).
pub fn clock_scaled(rec: &Recording, k: f64) -> Recording {
    let mut r = rec.clone();
    for t in &mut r.t {
        *t /= k;
    }
    r
}

/// `rec` read through the scale `k` of `of`.
pub fn rescaled(rec: &Recording, k: f64, of: ScaleOf) -> Recording {
    match of {
        ScaleOf::Clock => clock_scaled(rec, k),
        ScaleOf::Gyro => gyro_scaled(rec, k),
    }
}

/// What the calibration computes from its three groups of throws: the rotor inertia, the
/// board's tensor (kg m^2) and the object's, when there are object throws, and the scale
/// they were taken at.
#[derive(Clone, Copy, Debug)]
struct Solved {
    j: f64,
    board: M3,
    object: Option<M3>,
    scale: f64,
}

/// How the scale of a solve is found: calibrated by (G1) from its board and assembly throws,
/// or fixed.
#[derive(Clone, Copy, Debug)]
enum Scale {
    Calibrated,
    Fixed(f64),
}

/// [`solve`] with the throws taken at the scale `scale` gives ((G2)); `None` when the
/// calibration fails (no scale found is the gyro as read, `k = 1`).
fn solve_scaled(
    groups: [&[ScaledThrow]; 3],
    known: &M3,
    m: Masses,
    scale: Scale,
) -> Option<Solved> {
    let k = match scale {
        Scale::Fixed(k) => k,
        Scale::Calibrated => scale::calibrated(groups[0], groups[1], known, m).unwrap_or(1.0),
    };
    let [b, a, o] = groups.map(|g| all_at(g, k));
    let mut s = solve(&b, &a, &o, known, m)?;
    s.scale = k;
    Some(s)
}

/// The masses: board, proof body, object.
#[derive(Clone, Copy, Debug)]
struct Masses {
    board: f64,
    proof: f64,
    object: f64,
}

/// `j` from the board and assembly throws, the board's tensor, and the object's from its
/// throws; `None` when `j` is not positive and finite.
fn solve(
    board: &[UnitThrow],
    assembly: &[UnitThrow],
    objects: &[UnitThrow],
    known: &M3,
    m: Masses,
) -> Option<Solved> {
    let (jb, rb) = mean(board);
    let (jt, rt) = mean(assembly);
    let (d, mt, _) = difference((&jb, rb), (&jt, rt), m.board, m.proof);
    let j = calibrate_j(&d, &mt, known);
    if !(j.is_finite() && j > 0.0) {
        return None;
    }
    let object_tensor = (!objects.is_empty()).then(|| {
        let (jo, ro) = mean(objects);
        let (d, mo, _) = difference((&jb, rb), (&jo, ro), m.board, m.object);
        object(j, &d, &mo)
    });
    Some(Solved {
        j,
        board: jb.map(|r| r.map(|x| x * j)),
        object: object_tensor,
        scale: 1.0,
    })
}

/// # Uncertainty
///
/// The calibration is a smooth function of the three groups' mean `J1` and centres of mass;
/// what scatters from throw to throw (the tensors, the accelerometer's centres, and through
/// both the calibrated `j`) is measured, not modelled: a delete-one jackknife per group of two
/// or more throws, `var_g = (n - 1) / n sum_i (x_(-i) - x_(.))^2` with `x_(-i)` recomputed
/// without throw `i` and `x_(.)` their mean, the groups independent so that their variances
/// add. A group of one throw has no scatter to measure: its throw's own reported standard
/// deviations of `J1` enter to first order (each of the six entries moved by one standard
/// deviation and everything recomputed, combined with the entries' correlations the estimate
/// reported: one rotor momentum fixes the scale of all of them), and so does its centre of
/// mass (the jackknife of [`fit_offset`]). The entries' correlations, the centre-of-mass term
/// and the rotor telemetry's errors ((F7), (F8) of the tensor fit) are all needed: without
/// them the reported standard deviations are several times too small. Measured by the tests
/// `an_object_from_one_throw_comes_with_an_honest_uncertainty` (simulated throws) and
/// `an_object_by_difference_comes_with_an_honest_uncertainty` (the shared thrown-FC logs, the
/// proof body's throw as the object).
#[derive(Clone, Copy, Debug, Default)]
struct Uncertainty {
    j: f64,
    scale: f64,
    board: M3,
    object: M3,
    moments: [f64; 3],
}

/// Variance of `Solved` (and of the object's principal moments) by [`Uncertainty`]'s rules.
fn uncertainty(
    groups: [&[ScaledThrow]; 3],
    known: &M3,
    m: Masses,
    scale: Scale,
    full: &Solved,
) -> Uncertainty {
    let mut u = Uncertainty::default();
    let moments = |s: &Solved| s.object.map(|o| eigen(&o).0);
    for g in 0..3 {
        let n = groups[g].len();
        if n >= 2 {
            let mut runs: Vec<Solved> = Vec::new();
            for i in 0..n {
                let mut parts = groups.map(|x| x.to_vec());
                parts[g].remove(i);
                if let Some(s) = solve_scaled([&parts[0], &parts[1], &parts[2]], known, m, scale) {
                    runs.push(s);
                }
            }
            if runs.len() != n {
                continue;
            }
            let k = (n as f64 - 1.0) / n as f64;
            let var = |f: &dyn Fn(&Solved) -> f64| {
                let xs: Vec<f64> = runs.iter().map(f).collect();
                let mean = xs.iter().sum::<f64>() / n as f64;
                k * xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>()
            };
            u.j += var(&|s| s.j);
            u.scale += var(&|s| s.scale);
            for r in 0..3 {
                for c in 0..3 {
                    u.board[r][c] += var(&|s| s.board[r][c]);
                    u.object[r][c] += var(&|s| s.object.map_or(0.0, |o| o[r][c]));
                }
                u.moments[r] += var(&|s| moments(s).map_or(0.0, |l| l[r]));
            }
        } else if n == 1 {
            // First order in what the one throw measured: the six entries of `J1` and the
            // three of its centre of mass, finite differences of one standard deviation each
            // (both sides of a symmetric pair), combined with their correlations, `var(f) =
            // sum_ef d_e rho_ef d_f` (the tensor's and the accelerometer's errors independent
            // of each other).
            let throw = &groups[g][0].throw;
            let Some(std) = throw.j1_std else {
                continue;
            };
            let rho_j = throw
                .j1_corr
                .unwrap_or_else(|| correlations(&[[0.0; 6]; 6]));
            let com_cov = throw.imu_from_com_cov.unwrap_or([[0.0; 3]; 3]);
            let com_std = [0, 1, 2].map(|k| com_cov[k][k].max(0.0).sqrt());
            let rho_c = correlations(&com_cov);
            let rho = |e: usize, f: usize| -> f64 {
                match (e < 6, f < 6) {
                    (true, true) => rho_j[e][f],
                    (false, false) => rho_c[e - 6][f - 6],
                    _ => 0.0,
                }
            };
            // Per input: the changes of j, the board's nine entries, the object's nine and
            // its three moments (zero where a solve failed or nothing was measured).
            let deltas: Vec<[f64; 22]> = (0..9)
                .map(|e| {
                    let mut parts = groups.map(|x| x.to_vec());
                    let t = &mut parts[g][0].throw;
                    if let Some(&(r0, c0)) = ENTRIES.get(e) {
                        let s = std[r0][c0];
                        t.j1[r0][c0] += s;
                        if r0 != c0 {
                            t.j1[c0][r0] += s;
                        }
                    } else {
                        t.imu_from_com[e - 6] += com_std[e - 6];
                    }
                    let mut d = [0.0; 22];
                    let Some(p) = solve_scaled([&parts[0], &parts[1], &parts[2]], known, m, scale)
                    else {
                        return d;
                    };
                    d[0] = p.j - full.j;
                    for r in 0..3 {
                        for c in 0..3 {
                            d[1 + 3 * r + c] = p.board[r][c] - full.board[r][c];
                            if let (Some(a), Some(b)) = (p.object, full.object) {
                                d[10 + 3 * r + c] = a[r][c] - b[r][c];
                            }
                        }
                    }
                    if let (Some(a), Some(b)) = (moments(&p), moments(full)) {
                        for k in 0..3 {
                            d[19 + k] = a[k] - b[k];
                        }
                    }
                    d
                })
                .collect();
            let var = |q: usize| {
                let mut v = 0.0;
                for (e, de) in deltas.iter().enumerate() {
                    for (f, df) in deltas.iter().enumerate() {
                        v += de[q] * rho(e, f) * df[q];
                    }
                }
                v.max(0.0)
            };
            u.j += var(0);
            for r in 0..3 {
                for c in 0..3 {
                    u.board[r][c] += var(1 + 3 * r + c);
                    u.object[r][c] += var(10 + 3 * r + c);
                }
            }
            for k in 0..3 {
                u.moments[k] += var(19 + k);
            }
        }
    }
    u
}

/// The report of `inertia calibrate`.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrationReport {
    /// Rotor inertia, kg m^2.
    pub rotor_inertia_kg_m2: f64,
    /// The scale factor `k` every throw was identified with: the log's rates read `k` times
    /// what its clock says ((G1) of the module's "The scale between the rates and the clock").
    pub scale: f64,
    /// What `k` was taken to be: `clock` (the log's times divided by it) or `gyro` (its rates).
    pub scale_of: ScaleOf,
    /// Its standard deviation (the throws' jackknife) where it was calibrated.
    pub scale_std: Option<f64>,
    /// Where it came from: calibrated, given, or the gyro as read and why.
    pub scale_source: String,
    /// Board tensor about its centre of mass, kg m^2 (mean of the board throws).
    pub board_tensor_kg_m2: M3,
    /// Relative Frobenius distance of each board throw from the mean.
    pub board_spread: Vec<f64>,
    /// Board's centre of mass from the IMU, m.
    pub board_com_from_imu_m: [f64; 3],
    /// The proof body recovered in sample (relative moment errors, axis angles).
    pub proof_in_sample: Comparison,
    /// The proof body recovered from each assembly throw with `j` calibrated on the others.
    pub proof_leave_one_out: Vec<Comparison>,
    /// Standard deviation of the rotor inertia, kg m^2 (the throws' jackknife).
    pub rotor_inertia_std_kg_m2: Option<f64>,
    /// With a vehicle file of several rotors: the common scale calibrated and each rotor's
    /// inertia (`rotor_inertia_kg_m2` is then the first rotor's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<VehicleCalibration>,
    /// Standard deviation of each entry of the board tensor, kg m^2 (the throws' jackknife).
    pub board_tensor_std_kg_m2: Option<M3>,
    /// The unknown object about its centre of mass, kg m^2, when `--object` was given.
    pub object_tensor_kg_m2: Option<M3>,
    /// Standard deviation of each entry of the object's tensor, kg m^2 (the groups' jackknife,
    /// with a one-throw group's own reported uncertainty and centre of mass).
    pub object_tensor_std_kg_m2: Option<M3>,
    /// The object's principal moments, ascending, kg m^2.
    pub object_principal_moments_kg_m2: Option<[f64; 3]>,
    /// Their standard deviations, kg m^2 (as the entries').
    pub object_principal_moments_std_kg_m2: Option<[f64; 3]>,
    /// The object's principal axes (unit vectors, rows, in the order of the moments).
    pub object_principal_axes: Option<[[f64; 3]; 3]>,
    /// Its centre of mass from the IMU, m.
    pub object_com_from_imu_m: Option<[f64; 3]>,
    /// Every throw used, identified with the unit rotor inertia: the board's, then the
    /// assembly's, then the object's.
    pub throws: Vec<UnitThrow>,
    /// How many of `throws` each group (board, assembly, object) contributed.
    pub throws_per_group: [usize; 3],
    /// The throws left out ([`usable`]), with the reason.
    pub skipped: Vec<SkippedThrow>,
    /// With several object throws: each one's object by difference, as if it were given alone.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub object_throws: Vec<ObjectThrow>,
    /// With several object throws: RMS over the throws and the diagonal entries of each
    /// throw's deviation from the throws' mean over its own standard deviation, times
    /// `sqrt(n / (n - 1))`: about 1 or below when the throws agree to their standard
    /// deviations (each of which also counts the calibration's error, common to all).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub object_spread_ratio: Option<f64>,
    /// The accelerometer's scale factor the throws were read through (`--accel-scale`).
    pub accel_scale: f64,
    /// What the report's figures should be read with: throws whose accelerometer reads more
    /// than [`ACCEL_AT_REST_TOLERANCE`] from one `g` at rest.
    pub warnings: Vec<String>,
}

/// The rotors of a vehicle file of several, calibrated (the module's "Several rotors").
#[derive(Clone, Debug, Serialize)]
pub struct VehicleCalibration {
    /// The vehicle file.
    pub file: String,
    /// The common scale `s = j / r_1`: each rotor's calibrated inertia over the file's.
    pub scale: f64,
    /// Its standard deviation (that of `j` over `r_1`).
    pub scale_std: Option<f64>,
    /// Each rotor, in the file's order.
    pub rotors: Vec<CalibratedRotor>,
}

/// One rotor of a vehicle file, calibrated.
#[derive(Clone, Debug, Serialize)]
pub struct CalibratedRotor {
    /// Its name in the file.
    pub name: String,
    /// The file's `inertia_kg_m2` (only its ratio to the first rotor's is used).
    pub file_inertia_kg_m2: f32,
    /// `j_i = j r_i / r_1`, kg m^2.
    pub inertia_kg_m2: f64,
    /// Its standard deviation, kg m^2 (`j`'s times `r_i / r_1`: the ratios are taken as
    /// exact).
    pub inertia_std_kg_m2: Option<f64>,
}

impl VehicleCalibration {
    /// The calibration of `file`'s rotors, identified as `unit` ([`unit_vehicle`]), from the
    /// first rotor's inertia `j` and its standard deviation.
    fn new(file: &Vehicle, unit: &Vehicle, j: f64, j_std: Option<f64>) -> Self {
        let first = |v: &Vehicle| {
            v.rotors
                .first()
                .map_or(f64::NAN, |r| r.inertia_kg_m2 as f64)
        };
        let (r1, u1) = (first(file), first(unit));
        VehicleCalibration {
            file: file.path.display().to_string(),
            scale: j / r1,
            scale_std: j_std.map(|s| s / r1),
            rotors: file
                .rotors
                .iter()
                .zip(&unit.rotors)
                .map(|(r, u)| {
                    let ratio = u.inertia_kg_m2 as f64 / u1;
                    CalibratedRotor {
                        name: r.name.clone(),
                        file_inertia_kg_m2: r.inertia_kg_m2,
                        inertia_kg_m2: j * ratio,
                        inertia_std_kg_m2: j_std.map(|s| s * ratio),
                    }
                })
                .collect(),
        }
    }
}

/// One object throw of several, by difference on its own.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectThrow {
    /// The log.
    pub source: String,
    /// The object about its centre of mass, kg m^2.
    pub tensor_kg_m2: M3,
    /// Standard deviation of each entry, kg m^2.
    pub tensor_std_kg_m2: M3,
    /// Its principal moments, ascending, kg m^2.
    pub principal_moments_kg_m2: [f64; 3],
    /// Their standard deviations, kg m^2.
    pub principal_moments_std_kg_m2: [f64; 3],
    /// The throw's tensor status (`Converged` when its fit explains the flight to the gyro's
    /// noise).
    #[serde(skip)]
    pub tensor_status: String,
}

/// Each object throw by difference as if given alone ([`ObjectThrow`]), and the spread ratio
/// of [`CalibrationReport::object_spread_ratio`]; nothing with fewer than two throws.
fn object_throws(
    groups: [&[ScaledThrow]; 3],
    known: &M3,
    m: Masses,
    scale: Scale,
) -> (Vec<ObjectThrow>, Option<f64>) {
    let [board, assembly, objects] = groups;
    if objects.len() < 2 {
        return (Vec::new(), None);
    }
    let each: Vec<ObjectThrow> = objects
        .iter()
        .filter_map(|o| {
            let one = std::slice::from_ref(o);
            let full = solve_scaled([board, assembly, one], known, m, scale)?;
            let tensor = full.object?;
            let u = uncertainty([board, assembly, one], known, m, scale, &full);
            let o = &o.throw;
            Some(ObjectThrow {
                source: o.source.clone(),
                tensor_kg_m2: tensor,
                tensor_std_kg_m2: u.object.map(|r| r.map(f64::sqrt)),
                principal_moments_kg_m2: eigen(&tensor).0,
                principal_moments_std_kg_m2: u.moments.map(f64::sqrt),
                tensor_status: o.tensor_status.clone(),
            })
        })
        .collect();
    let n = each.len();
    if n < 2 {
        return (each, None);
    }
    let mut z2 = 0.0;
    for i in 0..3 {
        let mean = each.iter().map(|t| t.tensor_kg_m2[i][i]).sum::<f64>() / n as f64;
        for t in &each {
            z2 += ((t.tensor_kg_m2[i][i] - mean) / t.tensor_std_kg_m2[i][i]).powi(2);
        }
    }
    let ratio = (z2 / (3 * n) as f64 * n as f64 / (n - 1) as f64).sqrt();
    (each, ratio.is_finite().then_some(ratio))
}

/// The object's variance from several throws, never below what their error shares.
///
/// Where a throw's fit does not explain its flight to the gyro's noise (its tensor status is
/// not `Converged`), its standard deviation comes from the residual it leaves, and part of that
/// error can be common to every throw of the object (a torque the model lacks acts alike on
/// each; the calibration's own error is common too). The throws' scatter `s^2` (per entry,
/// `n - 1` in the denominator) measures only the part that differs from throw to throw; with
/// `v` the mean of the throws' own variances, the rest, `v - s^2`, does not average out:
///
/// ```text
/// var_pooled >= max(0, v - s^2) + s^2 / n                                              (C1)
/// ```
///
/// per entry and per principal moment. Throws that all fit to the noise keep the jackknife's
/// variance: their errors are the gyro's noise, independent from throw to throw.
fn common_error_floor(mut u: Uncertainty, each: &[ObjectThrow]) -> Uncertainty {
    let n = each.len();
    if n < 2 || each.iter().all(|t| t.tensor_status == "Converged") {
        return u;
    }
    let floor = |value: &dyn Fn(&ObjectThrow) -> f64, std: &dyn Fn(&ObjectThrow) -> f64| {
        crate::pool::shared_floor(each.iter().map(|t| (value(t), std(t).powi(2))))
    };
    for r in 0..3 {
        for c in 0..3 {
            let f = floor(&|t| t.tensor_kg_m2[r][c], &|t| t.tensor_std_kg_m2[r][c]);
            if f.is_finite() && f > u.object[r][c] {
                u.object[r][c] = f;
            }
        }
        let f = floor(&|t| t.principal_moments_kg_m2[r], &|t| {
            t.principal_moments_std_kg_m2[r]
        });
        if f.is_finite() && f > u.moments[r] {
            u.moments[r] = f;
        }
    }
    u
}

/// The rotors each throw is identified with and how to read the logs: from `--rotor-axis` and
/// `--rotor-poles`, or from a vehicle file (of one rotor: its column read as the rotor channel
/// where the log has it, [`with_named_rotor`]; of several: their columns, the rotors scaled by
/// [`unit_vehicle`]).
fn rotor_of(args: &CalibrateArgs) -> Result<RotorOf, String> {
    let Some(path) = &args.vehicle else {
        let axis = args
            .rotor_axis
            .ok_or("--rotor-axis (or --vehicle) is needed")?;
        return Ok(RotorOf {
            rotors: UnitRotors::One {
                axis,
                poles: args.rotor_poles,
                unit: None,
            },
            read: crate::ReadOptions::default(),
        });
    };
    let v = Vehicle::load(path).map_err(|e| e.to_string())?;
    let read = crate::ReadOptions {
        rotor_columns: v.columns(),
        rotor_names: v.names(),
        ..crate::ReadOptions::default()
    };
    let rotors = match v.rotors.as_slice() {
        [r] => UnitRotors::One {
            axis: r.axis,
            poles: r.poles,
            unit: Some(r.unit()),
        },
        _ => UnitRotors::Several {
            unit: Box::new(unit_vehicle(&v)?),
            file: Box::new(v),
        },
    };
    Ok(RotorOf { rotors, read })
}

/// The rotors of a calibration, as each throw is identified.
enum UnitRotors {
    /// One rotor at [`UNIT_J`] on `axis`, and the unit of a vehicle file's column.
    One {
        axis: [f32; 3],
        poles: Option<u32>,
        unit: Option<crate::vehicle::SpeedUnit>,
    },
    /// A vehicle file of several rotors, as read and scaled by [`unit_vehicle`].
    Several {
        file: Box<Vehicle>,
        unit: Box<Vehicle>,
    },
}

/// The rotors and the logs' read options.
struct RotorOf {
    rotors: UnitRotors,
    read: crate::ReadOptions,
}

/// A recording read with a vehicle file's named rotor column (a CSV column, a blackbox or ULog
/// field): that column as the rotor channel, in the unit the file declares (rad/s, rpm turned
/// into rad/s, eRPM), in place of the log's own rotor channel (a blackbox log's `erpm[0]`),
/// which is not the one the file names.
fn with_named_rotor(mut rec: Recording, unit: Option<crate::vehicle::SpeedUnit>) -> Recording {
    use crate::recording::RotorSpeed;
    use crate::vehicle::SpeedUnit;
    if let (Some(w), Some(unit)) = (rec.wheels.first(), unit) {
        let rpm = 2.0 * core::f32::consts::PI / 60.0;
        rec.rotor = Some(match unit {
            SpeedUnit::RadPerSec => RotorSpeed::RadPerSec(w.clone()),
            SpeedUnit::Rpm => RotorSpeed::RadPerSec(w.iter().map(|x| x * rpm).collect()),
            SpeedUnit::Erpm => RotorSpeed::Erpm(w.clone()),
        });
    }
    rec
}

/// Runs `inertia calibrate`. Refused with the reason: masses not positive, `--proof-inertia`
/// not of 3 or 6 numbers, `--object` without `--object-mass`, a vehicle file the loader
/// refuses ([`Vehicle::load`]), a group none of whose throws could be read, identified or used
/// (each throw named with why: a rotor column the log lacks, rotors whose momentum is zero,
/// an unusable tensor status), and a rotor inertia that does not come out positive.
pub fn run(args: &CalibrateArgs) -> Result<CalibrationReport, String> {
    let known: M3 = match args.proof_inertia.as_slice() {
        [a, b, c] => [[*a, 0.0, 0.0], [0.0, *b, 0.0], [0.0, 0.0, *c]],
        [a, b, c, xy, xz, yz] => [[*a, *xy, *xz], [*xy, *b, *yz], [*xz, *yz, *c]],
        _ => return Err("--proof-inertia takes 3 or 6 numbers".into()),
    };
    let masses = [
        args.board_mass,
        args.proof_mass,
        args.object_mass.unwrap_or(1.0),
    ];
    if masses.iter().any(|m| !(m.is_finite() && *m > 0.0)) {
        return Err("masses must be positive".into());
    }
    if !args.object.is_empty() && args.object_mass.is_none() {
        return Err("--object needs --object-mass".into());
    }
    let RotorOf { rotors, read } = rotor_of(args)?;
    let ident = |rec: &Recording| -> Result<UnitThrow, String> {
        match &rotors {
            UnitRotors::One { axis, poles, .. } => unit_throw(rec, *axis, *poles),
            UnitRotors::Several { unit, .. } => unit_throw_vehicle(rec, unit),
        }
    };
    let base = match args.scale {
        ScaleFactor::Auto => 1.0,
        ScaleFactor::Given(k) => k,
    };
    // A throw that cannot be read or identified, or whose tensor is not usable, is left out
    // with its reason (a saturated or truncated log among good ones should not stop the
    // calibration); a group left without a throw is an error.
    let mut skipped = Vec::new();
    let mut unit_all = |paths: &[std::path::PathBuf],
                        group: &'static str|
     -> Result<Vec<(Recording, UnitThrow)>, String> {
        let mut used = Vec::new();
        for p in paths {
            let source = p.display().to_string();
            let throw = crate::read(p, &read)
                .map_err(|e| e.to_string())
                .map(|rec| match &rotors {
                    UnitRotors::One { unit, .. } => with_named_rotor(rec, *unit),
                    UnitRotors::Several { .. } => rec,
                })
                .map(|rec| accel_scaled(rec, args.accel_scale))
                .and_then(|rec| ident(&rescaled(&rec, base, args.scale_of)).map(|t| (rec, t)));
            match throw {
                Ok((rec, t)) if usable(&t.tensor_status) => used.push((rec, t)),
                Ok((_, t)) => skipped.push(SkippedThrow {
                    source,
                    group,
                    reason: format!("tensor status {}", t.tensor_status),
                }),
                Err(reason) => skipped.push(SkippedThrow {
                    source,
                    group,
                    reason,
                }),
            }
        }
        if used.is_empty() && !paths.is_empty() {
            return Err(format!("no usable {group} throw (every one was left out)"));
        }
        Ok(used)
    };
    let board = unit_all(&args.board, "board");
    let assembly = unit_all(&args.assembly, "assembly");
    let objects = unit_all(&args.object, "object");
    let read_groups = match (board, assembly, objects) {
        (Ok(b), Ok(a), Ok(o)) => [b, a, o],
        (b, a, o) => {
            let mut why: Vec<String> = [b.err(), a.err(), o.err()].into_iter().flatten().collect();
            why.extend(
                skipped
                    .iter()
                    .map(|s| format!("{} ({}): {}", s.source, s.group, s.reason)),
            );
            return Err(why.join("; "));
        }
    };
    let warnings: Vec<String> = read_groups
        .iter()
        .flatten()
        .filter_map(|(_, t)| accel_at_rest_warning(t))
        .collect();
    let m = Masses {
        board: args.board_mass,
        proof: args.proof_mass,
        object: masses[2],
    };
    // The gyro's scale ((G1), (G2)): given, or each throw identified once more at
    // `1 + SCALE_STEP`, the scale calibrated on the linear model, and every throw identified
    // again at it.
    let fixed = |g: &[(Recording, UnitThrow)], k: f64| -> Vec<ScaledThrow> {
        g.iter()
            .map(|(_, t)| ScaledThrow {
                throw: t.clone(),
                at: k,
                dj1: [[0.0; 3]; 3],
                dcom: [0.0; 3],
            })
            .collect()
    };
    let (groups, scale, scale_source) = match args.scale {
        ScaleFactor::Given(k) => (
            read_groups.each_ref().map(|g| fixed(g, k)),
            Scale::Fixed(k),
            "given (--scale)".to_string(),
        ),
        ScaleFactor::Auto => {
            // A throw that cannot be identified at the second scale or at the calibrated one
            // is left out with its reason, as at the first.
            let names = ["board", "assembly", "object"];
            let mut linear: [Vec<(&Recording, ScaledThrow)>; 3] = Default::default();
            for ((g, name), lin) in read_groups.iter().zip(names).zip(&mut linear) {
                for (rec, t) in g {
                    match ident(&rescaled(rec, 1.0 + SCALE_STEP, args.scale_of)) {
                        Ok(u) => lin.push((
                            rec,
                            ScaledThrow {
                                throw: t.clone(),
                                at: 1.0,
                                dj1: add(&u.j1, &t.j1, -1.0).map(|r| r.map(|x| x / SCALE_STEP)),
                                dcom: [0, 1, 2]
                                    .map(|i| (u.imu_from_com[i] - t.imu_from_com[i]) / SCALE_STEP),
                            },
                        )),
                        Err(reason) => skipped.push(SkippedThrow {
                            source: t.source.clone(),
                            group: name,
                            reason: format!("at scale {}: {reason}", 1.0 + SCALE_STEP),
                        }),
                    }
                }
            }
            let plain = linear
                .each_ref()
                .map(|g| g.iter().map(|(_, s)| s.clone()).collect::<Vec<_>>());
            match scale::calibrated(&plain[0], &plain[1], &known, m) {
                Some(k) => {
                    let mut again: [Vec<ScaledThrow>; 3] = Default::default();
                    for ((lin, name), out) in linear.iter().zip(names).zip(&mut again) {
                        for (rec, l) in lin {
                            match ident(&rescaled(rec, k, args.scale_of)) {
                                Ok(throw) => out.push(ScaledThrow {
                                    throw,
                                    at: k,
                                    dj1: l.dj1,
                                    dcom: l.dcom,
                                }),
                                Err(reason) => skipped.push(SkippedThrow {
                                    source: l.throw.source.clone(),
                                    group: name,
                                    reason: format!("at scale {k:.4}: {reason}"),
                                }),
                            }
                        }
                    }
                    (
                        again,
                        Scale::Calibrated,
                        "calibrated from the proof body".into(),
                    )
                }
                None => (
                    plain.map(|g| {
                        g.into_iter()
                            .map(|t| ScaledThrow {
                                dj1: [[0.0; 3]; 3],
                                dcom: [0.0; 3],
                                ..t
                            })
                            .collect()
                    }),
                    Scale::Fixed(1.0),
                    format!(
                        "as read: the proof body's shape did not fix a scale within 1 +- {}",
                        scale::SCALE_RANGE
                    ),
                ),
            }
        }
    };
    let given = [&args.board, &args.assembly, &args.object];
    for ((g, name), paths) in groups
        .iter()
        .zip(["board", "assembly", "object"])
        .zip(given)
    {
        if g.is_empty() && !paths.is_empty() {
            return Err(format!("no usable {name} throw (every one was left out)"));
        }
    }
    let g3 = [&groups[0][..], &groups[1][..], &groups[2][..]];
    let full = solve_scaled(g3, &known, m, scale)
        .ok_or("calibration failed: the rotor inertia came out not positive")?;
    let j = full.j;
    let k = full.scale;
    let [board, assembly, objects] = g3.map(|g| all_at(g, k));
    let (jb, rb) = mean(&board);
    let (jt, rt) = mean(&assembly);
    let (d, mt, _) = difference((&jb, rb), (&jt, rt), args.board_mass, args.proof_mass);
    let proof_in_sample = compare(&object(j, &d, &mt), &known);
    // Each assembly throw against `j` (and the scale, where calibrated) from the others.
    let mut loo = Vec::new();
    if groups[1].len() >= 2 {
        for i in 0..groups[1].len() {
            let others: Vec<ScaledThrow> = groups[1]
                .iter()
                .enumerate()
                .filter(|(x, _)| *x != i)
                .map(|(_, t)| t.clone())
                .collect();
            let ki = match scale {
                Scale::Fixed(k) => k,
                Scale::Calibrated => {
                    scale::calibrated(&groups[0], &others, &known, m).unwrap_or(1.0)
                }
            };
            let (jbi, rbi) = mean(&all_at(&groups[0], ki));
            let (jt, rt) = mean(&all_at(&others, ki));
            let (d, mm, _) = difference((&jbi, rbi), (&jt, rt), args.board_mass, args.proof_mass);
            let jk = calibrate_j(&d, &mm, &known);
            let left = groups[1][i].at(ki);
            let (dk, mk, _) = difference(
                (&jbi, rbi),
                (&left.j1, left.imu_from_com),
                args.board_mass,
                args.proof_mass,
            );
            loo.push(compare(&object(jk, &dk, &mk), &known));
        }
    }
    let object_com = (!objects.is_empty()).then(|| {
        let (jo, ro) = mean(&objects);
        difference((&jb, rb), (&jo, ro), args.board_mass, masses[2]).2
    });
    let u = uncertainty(g3, &known, m, scale, &full);
    let (per_object, object_spread_ratio) = object_throws(g3, &known, m, scale);
    let u = common_error_floor(u, &per_object);
    let sd = |v: &M3| v.map(|r| r.map(f64::sqrt));
    let eig = full.object.map(|o| eigen(&o));
    let j_std = Some(u.j.sqrt());
    Ok(CalibrationReport {
        rotor_inertia_kg_m2: j,
        rotor_inertia_std_kg_m2: j_std,
        vehicle: match &rotors {
            UnitRotors::One { .. } => None,
            UnitRotors::Several { file, unit } => {
                Some(VehicleCalibration::new(file, unit, j, j_std))
            }
        },
        scale: k,
        scale_of: args.scale_of,
        scale_std: matches!(scale, Scale::Calibrated).then(|| u.scale.sqrt()),
        scale_source,
        board_tensor_kg_m2: full.board,
        board_tensor_std_kg_m2: Some(sd(&u.board)),
        board_spread: board.iter().map(|t| rel_frobenius(&t.j1, &jb)).collect(),
        board_com_from_imu_m: rb.map(|x| -x),
        proof_in_sample,
        proof_leave_one_out: loo,
        object_tensor_kg_m2: full.object,
        object_tensor_std_kg_m2: full.object.map(|_| sd(&u.object)),
        object_principal_moments_kg_m2: eig.map(|e| e.0),
        object_principal_moments_std_kg_m2: eig.map(|_| u.moments.map(f64::sqrt)),
        object_principal_axes: eig.map(|e| e.1),
        object_com_from_imu_m: object_com,
        throws_per_group: [board.len(), assembly.len(), objects.len()],
        throws: board.into_iter().chain(assembly).chain(objects).collect(),
        skipped,
        object_throws: per_object,
        object_spread_ratio,
        accel_scale: args.accel_scale,
        warnings,
    })
}

/// Largest distance of [`UnitThrow::accel_at_rest_g`] from 1 without a warning: MEMS
/// accelerometers are specified to a few percent in scale and tens of milli-g in bias.
pub const ACCEL_AT_REST_TOLERANCE: f64 = 0.02;

/// The warning for a throw whose accelerometer reads more than [`ACCEL_AT_REST_TOLERANCE`]
/// from one `g` at rest.
fn accel_at_rest_warning(t: &UnitThrow) -> Option<String> {
    let g = t.accel_at_rest_g?;
    ((g - 1.0).abs() > ACCEL_AT_REST_TOLERANCE).then(|| {
        format!(
            "{}: the accelerometer reads {g:.4} g while the gyro is still ({:+.1} % from 1 g): \
             a scale that far off moves every centre of mass by as much, and the parallel-axis \
             terms by twice that (--accel-scale takes a calibrated scale)",
            t.source,
            100.0 * (g - 1.0)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn throw(value: f64, std: f64, status: &str) -> ObjectThrow {
        let m = [
            [value, 0.0, 0.0],
            [0.0, 2.0 * value, 0.0],
            [0.0, 0.0, 3.0 * value],
        ];
        let s = [[std; 3]; 3];
        ObjectThrow {
            source: String::new(),
            tensor_kg_m2: m,
            tensor_std_kg_m2: s,
            principal_moments_kg_m2: [value, 2.0 * value, 3.0 * value],
            principal_moments_std_kg_m2: [std; 3],
            tensor_status: status.into(),
        }
    }

    /// (C1): object throws that agree exactly while each claims `std` (a model error they
    /// share) give the pooled object that variance, not a fifth of it; throws that all fit to
    /// the noise keep the jackknife's.
    #[test]
    fn an_error_the_object_throws_share_is_not_averaged_away() {
        let std = 2.0e-6;
        let jack = std * std / 5.0;
        let u = Uncertainty {
            j: 0.0,
            scale: 0.0,
            board: [[0.0; 3]; 3],
            object: [[jack; 3]; 3],
            moments: [jack; 3],
        };
        let shared: Vec<ObjectThrow> = (0..5).map(|_| throw(1e-4, std, "ModelMismatch")).collect();
        let w = common_error_floor(u, &shared);
        for r in 0..3 {
            assert!((w.object[r][r] / (std * std) - 1.0).abs() < 1e-12);
            assert!((w.moments[r] / (std * std) - 1.0).abs() < 1e-12);
        }
        let clean: Vec<ObjectThrow> = (0..5).map(|_| throw(1e-4, std, "Converged")).collect();
        let w = common_error_floor(u, &clean);
        assert_eq!(w.object, u.object);
        assert_eq!(w.moments, u.moments);
    }
}
