//! The paper's functions of the measured angular velocity: the identifiability product of (2),
//! the squares that (9) is built from, and `Phi` of (9) itself.
//!
//! They are pure `f32` functions so that the host tests and the firmware evaluate exactly the
//! same arithmetic.

use crate::linalg::mul_vec;
use crate::settings::GainMatrix;

/// `w1 w2 w3`, whose magnitude is bounded below by `w_min` on identifiable intervals (2) and
/// whose sign selects the branch of (9).
#[inline]
pub fn triple_product(omega: [f32; 3]) -> f32 {
    omega[0] * omega[1] * omega[2]
}

/// `sgn(w1 w2 w3)` as used in (9), (12) and (14): `+1`, `-1`, or `0` when the product is zero
/// (or not a number).
#[inline]
pub fn sign(p: f32) -> f32 {
    if p > 0.0 {
        1.0
    } else if p < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// `(w1^2, w2^2, w3^2)`, the quadratic form inside (9).
#[inline]
pub fn squares(omega: [f32; 3]) -> [f32; 3] {
    [
        omega[0] * omega[0],
        omega[1] * omega[1],
        omega[2] * omega[2],
    ]
}

/// `Phi_i = 1/2 sgn(w1 w2 w3) (c_i1 w1^2 + c_i2 w2^2 + c_i3 w3^2)` of (9), for a given sign `s`.
///
/// With `C = -lambda E` this is `-lambda/2 sgn(.) w_i^2`, so that (12) becomes (14).
#[inline]
pub fn phi(gain: &GainMatrix, s: f32, omega: [f32; 3]) -> [f32; 3] {
    phi_of_squares(gain.rows(), s, squares(omega))
}

/// `Phi` of (9) from the squares `q = (w1^2, w2^2, w3^2)`: `1/2 s C q`. Also gives the jump of
/// `Phi` at a sign change, `1/2 (s_new - s_old) C q`, which the correction removes.
#[inline]
pub fn phi_of_squares(c: &[[f32; 3]; 3], s: f32, q: [f32; 3]) -> [f32; 3] {
    let cq = mul_vec(c, q);
    [0.5 * s * cq[0], 0.5 * s * cq[1], 0.5 * s * cq[2]]
}

/// The controls (7), `u_i = sum_j Phi_ij Delta_j f_j` with `Delta = alpha - Phi` and
/// `f = (w2 w3, w3 w1, w1 w2)` the right-hand sides of (1) without `a`.
///
/// For `Phi` of (9), `Phi_ij = sgn(.) c_ij w_j`, so `u = |w1 w2 w3| C Delta`; this function is
/// that closed form. It is the continuous-time law that [`crate::Identifier::step`] discretises.
#[inline]
pub fn control(gain: &GainMatrix, alpha: [f32; 3], omega: [f32; 3]) -> [f32; 3] {
    let p = triple_product(omega);
    let s = sign(p);
    let f = phi(gain, s, omega);
    let delta = [alpha[0] - f[0], alpha[1] - f[1], alpha[2] - f[2]];
    let cd = mul_vec(gain.rows(), delta);
    let k = p.abs();
    [k * cd[0], k * cd[1], k * cd[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phi_scalar_gain_is_minus_half_lambda_sign_square() {
        let g = GainMatrix::scalar(3.0);
        let w = [1.0, -2.0, 0.5];
        let s = sign(triple_product(w));
        assert_eq!(s, -1.0);
        let f = phi(&g, s, w);
        // (14): a_i = alpha_i + lambda/2 sgn w_i^2, i.e. Phi_i = -lambda/2 sgn w_i^2.
        assert_eq!(f, [1.5, 6.0, 0.375]);
    }

    #[test]
    fn control_matches_generic_form_seven() {
        // Evaluate (7) term by term with Phi_ij = s c_ij w_j and compare with the closed form.
        let g = GainMatrix([[-2.0, 0.5, 0.0], [0.1, -1.0, 0.3], [0.0, -0.2, -3.0]]);
        let w = [0.7, 1.3, -0.4];
        let alpha = [0.2, -0.5, 1.1];
        let s = sign(triple_product(w));
        let f = phi(&g, s, w);
        let delta = [alpha[0] - f[0], alpha[1] - f[1], alpha[2] - f[2]];
        let rhs = [w[1] * w[2], w[2] * w[0], w[0] * w[1]];
        let c = g.rows();
        let mut u = [0.0f32; 3];
        for i in 0..3 {
            for j in 0..3 {
                u[i] += s * c[i][j] * w[j] * delta[j] * rhs[j];
            }
        }
        let closed = control(&g, alpha, w);
        for i in 0..3 {
            assert!((u[i] - closed[i]).abs() < 1e-6, "{u:?} vs {closed:?}");
        }
    }
}
