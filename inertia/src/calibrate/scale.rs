//! The scale factor between the log's rates and its clock, calibrated from the proof body's
//! shape.
//!
//! Euler's equation `J w' + w x (J w + h) + h' = 0` holds in true rates and true time. The
//! log can be off in either: a MEMS gyro reads `w_m = k w` with `k` within its sensitivity
//! tolerance of 1, and a board's clock (the log's times) can run `k` times true time, `t_m = k
//! t`, when its oscillator is off. `w'` is linear in the rate and `w x J w` quadratic, and
//! `w'` is per second while `w` is not, so either way a body precessing at `lambda w`
//! (`lambda` a function of the moments' ratios) is read as one precessing at `lambda w_m / k`
//! and the fit bends the ratios by about `1 - k`. The rotor momentum, read from its own
//! telemetry, then fixes the scale, so `J` moves by a few times `k - 1` (on the thrown flight
//! controller about three times as much), differently for each body.
//!
//! With the rotor's inertia calibrated alongside (it absorbs a common factor of `k`), the two
//! readings give the dynamics the same equation. They differ where the accelerometer gives the
//! centre of mass, `f = w x (w x r) + w' x r` ([`super::fit_offset`]): a gyro's `k` divides
//! the rates, so `r` moves by `k^2`; a clock's multiplies `w'` only, and the centripetal term,
//! most of `f` in a tumble, keeps `r` where the rates as read put it. `--scale-of clock` (the
//! default) reads the log's times divided by `k` ([`super::clock_scaled`]); `--scale-of gyro`
//! its rates and full scale ([`super::gyro_scaled`]). Why the clock is the default, and what
//! each gives on the measured objects, is in `docs/calibration.md`.
//!
//! The proof body's known inertia pins it: `j` fixes the proof body's scale (the calibration
//! of `j`), and its shape, the ratios of its principal moments, is what `k` moves. With every
//! throw identified through `k`, the calibrated scale minimises the proof
//! body's shape error
//!
//! ```text
//! k* = argmin_k sum_i e_i(k)^2,   e_i = (lambda_i(j(k) D(k) - M(k)) - lambda_i(J_known)) / lambda_i(J_known)   (G1)
//! ```
//!
//! (`lambda_i` the principal moments, ascending; `j(k)`, `D(k)`, `M(k)` the calibration of the
//! module docs from the throws read at `k`), searched on `[1 - SCALE_RANGE, 1 + SCALE_RANGE]`.
//! Each throw is identified at `k = 1` and at `1 + SCALE_STEP`; between them its unit tensor
//! and its centre of mass are taken as linear in `k`,
//!
//! ```text
//! J1(k) = J1(k0) + (k - k0) (J1(1 + SCALE_STEP) - J1(1)) / SCALE_STEP                    (G2)
//! ```
//!
//! and after the search every throw is identified again at `k*`, its `k0`. (G1) on (G2) is what
//! the delete-one jackknife of the calibration recomputes for each replicate, so the scale's
//! own uncertainty enters `j`, the board and the object. A search that ends at an edge of the
//! range (the proof body does not fix the scale, or something else bends its shape) keeps the
//! log as read, `k = 1`, and says so.

use super::{calibrate_j, compare, difference, mean, object, Masses, UnitThrow, M3};

/// The second scale each throw is identified at, `1 + SCALE_STEP` ((G2)).
pub(super) const SCALE_STEP: f64 = 0.01;

/// Half-width of the range (G1) is searched on.
pub(super) const SCALE_RANGE: f64 = 0.05;

/// Golden-section steps of (G1): the bracket shrinks to `0.618^n` of its width.
const SEARCH_STEPS: usize = 60;

/// A searched minimum closer than this to an edge of the range is taken as not found.
const EDGE: f64 = 1e-3;

/// A throw identified at the scale `at`, with how its unit tensor and centre of mass move
/// with the scale ((G2); zero when the scale was given, not calibrated).
#[derive(Clone, Debug)]
pub(super) struct ScaledThrow {
    pub(super) throw: UnitThrow,
    pub(super) at: f64,
    pub(super) dj1: M3,
    pub(super) dcom: [f64; 3],
}

impl ScaledThrow {
    /// The throw taken as read at scale `k` ((G2)).
    pub(super) fn at(&self, k: f64) -> UnitThrow {
        let s = k - self.at;
        let mut t = self.throw.clone();
        for r in 0..3 {
            for c in 0..3 {
                t.j1[r][c] += s * self.dj1[r][c];
            }
            t.imu_from_com[r] += s * self.dcom[r];
        }
        t
    }
}

/// `throws` taken at scale `k`.
pub(super) fn all_at(throws: &[ScaledThrow], k: f64) -> Vec<UnitThrow> {
    throws.iter().map(|t| t.at(k)).collect()
}

/// The proof body's shape error at scale `k`, `sum_i e_i^2` of (G1); `None` when `j` does not
/// come out positive.
fn shape_cost(
    board: &[ScaledThrow],
    assembly: &[ScaledThrow],
    known: &M3,
    m: Masses,
    k: f64,
) -> Option<f64> {
    let (jb, rb) = mean(&all_at(board, k));
    let (jt, rt) = mean(&all_at(assembly, k));
    let (d, mt, _) = difference((&jb, rb), (&jt, rt), m.board, m.proof);
    let j = calibrate_j(&d, &mt, known);
    if !(j.is_finite() && j > 0.0) {
        return None;
    }
    let e = compare(&object(j, &d, &mt), known).moment_errors;
    let c = e.iter().map(|x| x * x).sum::<f64>();
    c.is_finite().then_some(c)
}

/// (G1) by golden section on `[1 - SCALE_RANGE, 1 + SCALE_RANGE]`: the calibrated scale, or
/// `None` when the minimum lies at an edge or a cost cannot be computed.
pub(super) fn calibrated(
    board: &[ScaledThrow],
    assembly: &[ScaledThrow],
    known: &M3,
    m: Masses,
) -> Option<f64> {
    let (lo0, hi0) = (1.0 - SCALE_RANGE, 1.0 + SCALE_RANGE);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut lo, mut hi) = (lo0, hi0);
    let mut a = hi - g * (hi - lo);
    let mut b = lo + g * (hi - lo);
    let mut fa = shape_cost(board, assembly, known, m, a)?;
    let mut fb = shape_cost(board, assembly, known, m, b)?;
    for _ in 0..SEARCH_STEPS {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - g * (hi - lo);
            fa = shape_cost(board, assembly, known, m, a)?;
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + g * (hi - lo);
            fb = shape_cost(board, assembly, known, m, b)?;
        }
    }
    let k = 0.5 * (lo + hi);
    (k - lo0 > EDGE && hi0 - k > EDGE).then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn throw(j1: M3, com: [f64; 3]) -> UnitThrow {
        UnitThrow {
            source: String::new(),
            j1,
            j1_std: None,
            j1_corr: None,
            imu_from_com: com,
            imu_from_com_cov: None,
            offset_fit_rms: 0.0,
            accel_at_rest_g: None,
            status: "Converged".into(),
            tensor_status: "Converged".into(),
            samples: 0,
        }
    }

    fn diag(a: f64, b: f64, c: f64) -> M3 {
        [[a, 0.0, 0.0], [0.0, b, 0.0], [0.0, 0.0, c]]
    }

    /// Throws whose unit tensors move with the scale as (G2) says, with the proof body's
    /// shape exact at `k = 1.004`: (G1) finds that scale; with throws that do not move, no
    /// scale is found.
    #[test]
    fn the_proof_bodys_shape_fixes_the_gyro_scale() {
        let m = Masses {
            board: 0.1,
            proof: 0.3,
            object: 1.0,
        };
        let known = diag(1.3e-4, 1.7e-4, 2.5e-4);
        let k_true = 1.004;
        // The board (unit tensor for j = 1e-6 scale: J = j J1) and the assembly at the same
        // centre, so that no parallel-axis term enters: J1_t - J1_b = known / j.
        let j = 1.7e-6;
        let board_j1 = diag(40.0, 12.0, 45.0);
        // At k the assembly's smallest moment reads (1 + 3 (k - k_true)) times its truth.
        let slope = diag(3.0 * 1.3e-4 / j, 0.0, 0.0);
        let at1: M3 = std::array::from_fn(|r| {
            std::array::from_fn(|c| board_j1[r][c] + known[r][c] / j + (1.0 - k_true) * slope[r][c])
        });
        let b = ScaledThrow {
            throw: throw(board_j1, [0.0; 3]),
            at: 1.0,
            dj1: [[0.0; 3]; 3],
            dcom: [0.0; 3],
        };
        let a = ScaledThrow {
            throw: throw(at1, [0.0; 3]),
            at: 1.0,
            dj1: slope,
            dcom: [0.0; 3],
        };
        let k = calibrated(
            std::slice::from_ref(&b),
            std::slice::from_ref(&a),
            &known,
            m,
        )
        .unwrap();
        assert!((k - k_true).abs() < 1e-6, "{k}");
        // A proof body whose shape the scale does not move: its minimum is flat, not found at
        // one place but over the whole range; the search must not invent one at an edge.
        let flat = ScaledThrow {
            dj1: [[0.0; 3]; 3],
            ..a
        };
        let mut wrong = flat.clone();
        wrong.throw.j1[0][0] *= 1.02;
        assert_eq!(calibrated(&[b], &[wrong], &known, m), None);
    }
}
