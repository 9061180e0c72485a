//! The gravity-gradient torque of an orbiting vehicle, folded into the known momentum: the
//! one function the host tool (`inertia identify`) and the firmware (its replay of an orbit
//! log) both call, so that they give the same bits.
//!
//! On orbit the body is not torque-free: Earth's gravity gradient acts with
//!
//! ```text
//! tau_B = 3 mu / |r|^5 (r_B x J r_B),   r_B = R(q)^T r,   mu = 3.986004418e14 m^3/s^2   (G1)
//! ```
//!
//! (`q` the attitude, `v_N = R(q) v_B`; `r` the position in an Earth-centred inertial frame).
//! A known external torque enters Euler's equation `J w' + w x (J w + h) = -h' + tau` as an
//! extra body-frame momentum `g` with `g' = g x w - tau`, `g(0) = 0`: with `h~ = h + g` the
//! equation is torque-free again, `J w' + w x (J w + h~) = -h~'`. In the inertial frame `g`
//! is minus the torque's impulse,
//!
//! ```text
//! g_B(t) = -R(q(t))^T integral_0^t R(q) tau_B dt                                          (G2)
//! ```
//!
//! (trapezoid between samples, in `f64`: [`GravityFold`]). The torque depends on `J`, which
//! is what is being identified: the identification runs once without it, then again with (G1)
//! at the tensor found, until the tensor moves by less than a tenth of its standard deviation
//!
//! ```text
//! moved = max_k |J_k - J_prev,k| / std(J_k)  <  SETTLED_STDS = 0.1                       (G3)
//! ```
//!
//! (at most [`MAX_PASSES`] passes with the torque; the torque is a small perturbation, so one
//! or two suffice), and the pass with the torque is kept when its residual is smaller than the
//! torque-free one's (the two models have the same free parameters).
//!
//! Everything here is `f64` in software on a Cortex-M4F (it has no double-precision unit),
//! once per sample: a few thousand cycles, nothing beside the estimators' `f32` step. The
//! square root is [`sqrt`], correctly rounded like IEEE 754's, so the host's results are
//! those of `std`'s `f64::sqrt`.
//!
//! ```
//! use identifier_core::gravity::{gravity_gradient_torque, GravityFold, EARTH_MU};
//!
//! // A body with principal moments (0.4, 0.3, 0.15) kg m^2 at 6878 km, its x and y axes at
//! // 45 deg to the local vertical: a torque about z of 3 mu / r^3 (Jyy - Jxx) / 2.
//! let j = [[0.4, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.15]];
//! let r = 6.878e6;
//! let s = r / 2f64.sqrt();
//! let tau = gravity_gradient_torque(&j, [1.0, 0.0, 0.0, 0.0], [s, s, 0.0]);
//! let want = 3.0 * EARTH_MU / (r * r * r) * (0.3 - 0.4) * 0.5;
//! assert!((tau[2] - want).abs() < 1e-12 * want.abs());
//!
//! // (G2) over 10 s at rest: minus the impulse, the torque times the time.
//! let mut fold = GravityFold::new([[0.4, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.15]]);
//! assert_eq!(fold.step(0.0, [1.0, 0.0, 0.0, 0.0], [s, s, 0.0]), [0.0; 3]);
//! let g = fold.step(10.0, [1.0, 0.0, 0.0, 0.0], [s, s, 0.0]);
//! assert!((f64::from(g[2]) + 10.0 * want).abs() < 1e-6 * (10.0 * want).abs());
//!
//! // The square root is std's, bit for bit.
//! for x in [2.0, 1e-310, 6.878e6 * 6.878e6, 0.1] {
//!     assert_eq!(identifier_core::gravity::sqrt(x).to_bits(), x.sqrt().to_bits());
//! }
//! ```

/// Earth's gravitational parameter `mu` of (G1), m^3/s^2.
pub const EARTH_MU: f64 = 3.986004418e14;

/// Most passes with the gravity gradient folded in ((G3)).
pub const MAX_PASSES: usize = 3;

/// The tensor has settled when a pass moved it by less than this many of its standard
/// deviations ((G3)).
pub const SETTLED_STDS: f32 = 0.1;

/// A 3x3 matrix in `f64`, row by row.
pub type Mat3 = [[f64; 3]; 3];

/// `sqrt(x)` in `f64`, correctly rounded (round to nearest, as IEEE 754 and `std`'s
/// `f64::sqrt`), in integer arithmetic: `core` has no `f64` square root without `std`. NaN for
/// a negative `x` or NaN, `x` itself for `+-0` and `+inf`.
pub fn sqrt(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 || x == f64::INFINITY {
        return x;
    }
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let mut m = bits & ((1u64 << 52) - 1);
    // x = m 2^(e - 52), m in [2^52, 2^53).
    let mut e = if biased == 0 {
        // Subnormal: shift the leading one to bit 52.
        let s = m.leading_zeros().wrapping_sub(11);
        m = m.wrapping_shl(s);
        1 - 1023 - s as i32
    } else {
        m |= 1u64 << 52;
        biased - 1023
    };
    if e & 1 != 0 {
        m = m.wrapping_shl(1);
        e -= 1;
    }
    // sqrt(x) = sqrt(m 2^54) 2^(e/2 - 53), the integer root q in [2^53, 2^54): its top 53
    // bits are the result's significand, its last bit and the remainder round it.
    let (q, rem) = isqrt(u128::from(m).wrapping_shl(54));
    let mut r = (q >> 1) as u64;
    if q & 1 != 0 && (rem != 0 || r & 1 != 0) {
        r = r.wrapping_add(1);
    }
    // r in [2^52, 2^53] (2^53 carries into the exponent): the value r 2^(e/2 - 52).
    let exponent = (e / 2 + 1022) as u64;
    f64::from_bits(exponent.wrapping_shl(52).wrapping_add(r))
}

/// The integer square root of `n` (below `2^108`) and its remainder `n - q^2`, digit by digit.
fn isqrt(n: u128) -> (u128, u128) {
    let (mut rem, mut q) = (n, 0u128);
    let mut bit = 1u128 << 106;
    while bit != 0 {
        let t = q.wrapping_add(bit);
        if rem >= t {
            rem = rem.wrapping_sub(t);
            q = (q >> 1).wrapping_add(bit);
        } else {
            q >>= 1;
        }
        bit >>= 2;
    }
    (q, rem)
}

/// `R(q)` for the attitude `q = (w, x, y, z)`, scalar first, `v_N = R(q) v_B`, normalised in
/// `f64` first; `None` for a zero or non-finite `q`.
pub fn rotation(q: [f32; 4]) -> Option<Mat3> {
    let [w, x, y, z] = q.map(f64::from);
    let n = sqrt(w * w + x * x + y * y + z * z);
    if !(n > 0.0 && n.is_finite()) {
        return None;
    }
    let (w, x, y, z) = (w / n, x / n, y / n, z / n);
    Some([
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ])
}

/// `m v`.
pub fn mul(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = v;
    m.map(|[r0, r1, r2]| r0 * a + r1 * b + r2 * c)
}

/// `m^T v` (a body-frame vector from an inertial one, for `m = R(q)`).
pub fn mul_t(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    let [[m00, m01, m02], [m10, m11, m12], [m20, m21, m22]] = *m;
    let [a, b, c] = v;
    [
        m00 * a + m10 * b + m20 * c,
        m01 * a + m11 * b + m21 * c,
        m02 * a + m12 * b + m22 * c,
    ]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let ([a0, a1, a2], [b0, b1, b2]) = (a, b);
    [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]
}

/// (G1): the gravity-gradient torque in the body frame, N m, on a body of inertia `j` (kg
/// m^2, body frame) at attitude `q` and inertial position `r` (m). Zero for an unusable `q`
/// or `r`.
pub fn gravity_gradient_torque(j: &Mat3, q: [f32; 4], r: [f64; 3]) -> [f64; 3] {
    let Some(rot) = rotation(q) else {
        return [0.0; 3];
    };
    let rb = mul_t(&rot, r);
    let [x, y, z] = rb;
    let d2 = x * x + y * y + z * z;
    if !(d2 > 0.0 && d2.is_finite()) {
        return [0.0; 3];
    }
    let k = 3.0 * EARTH_MU / (d2 * d2 * sqrt(d2));
    cross(rb, mul(j, rb)).map(|x| k * x)
}

/// (G2) accumulated sample by sample for a body of a given inertia: the extra momentum to add
/// to the rotors' before the estimators, in `f32` as they take it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GravityFold {
    j: Mat3,
    impulse_n: [f64; 3],
    prev: Option<(f64, [f64; 3])>,
}

impl GravityFold {
    /// (G2) for a body of inertia `j` (kg m^2, body frame), from zero.
    pub fn new(j: [[f32; 3]; 3]) -> Self {
        GravityFold {
            j: j.map(|r| r.map(f64::from)),
            impulse_n: [0.0; 3],
            prev: None,
        }
    }

    /// The extra momentum `g_B` (G2), kg m^2/s, at time `t` (s), attitude `q`, position `r`
    /// (m): the torque (G1) integrated by the trapezoid from the previous call's time. Zero
    /// for an unusable `q` (nothing accumulated then).
    pub fn step(&mut self, t: f64, q: [f32; 4], r: [f64; 3]) -> [f32; 3] {
        let Some(rot) = rotation(q) else {
            return [0.0; 3];
        };
        let tau_n = mul(&rot, gravity_gradient_torque(&self.j, q, r));
        if let Some((t0, [p0, p1, p2])) = self.prev {
            let dt = t - t0;
            let [i0, i1, i2] = &mut self.impulse_n;
            let [n0, n1, n2] = tau_n;
            *i0 += 0.5 * dt * (p0 + n0);
            *i1 += 0.5 * dt * (p1 + n1);
            *i2 += 0.5 * dt * (p2 + n2);
        }
        self.prev = Some((t, tau_n));
        mul_t(&rot, self.impulse_n).map(|x| -x as f32)
    }
}

/// (G3): how far a pass moved the tensor, `max_k |J_k - J_prev,k| / std(J_k)` over the nine
/// entries of the new tensor `next` and its standard deviations `std`; infinite when either is
/// missing (the pass found no tensor in kg m^2).
pub fn tensor_moved(
    prev: &[[f32; 3]; 3],
    next: Option<[[f32; 3]; 3]>,
    std: Option<[[f32; 3]; 3]>,
) -> f32 {
    let (Some(next), Some(std)) = (next, std) else {
        return f32::INFINITY;
    };
    let mut moved = 0.0f32;
    for ((a, j), s) in next.iter().zip(prev).zip(&std) {
        for ((a, j), s) in a.iter().zip(j).zip(s) {
            moved = moved.max((a - j).abs() / s);
        }
    }
    moved
}

/// (G3): the passes stop once the tensor `moved` ([`tensor_moved`]) by less than
/// [`SETTLED_STDS`] of its standard deviations (or by NaN: no ordering to go on with).
pub fn settled(moved: f32) -> bool {
    moved.is_nan() || moved < SETTLED_STDS
}

/// Whether the pass with the gravity gradient folded in is kept: its residual (over the gyro
/// noise) is smaller than the torque-free pass's (the two models have the same free
/// parameters, so the smaller residual is the likelier).
pub fn keep_folded(folded_residual: f32, free_residual: f32) -> bool {
    folded_residual < free_residual
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn sqrt_is_std_bit_for_bit() {
        // Edges, subnormals, powers of two, and pseudo-random bit patterns over all of f64.
        let mut xs: std::vec::Vec<f64> = std::vec![
            0.0,
            -0.0,
            f64::INFINITY,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::EPSILON,
            1.0,
            2.0,
            3.0,
            4.0,
            0.5,
            f64::from_bits(1),
            f64::from_bits(2),
            f64::from_bits(3),
            f64::from_bits((1 << 52) - 1),
            4.73e13,
            6.878e6,
        ];
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..400_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let x = f64::from_bits(s >> 1);
            if x.is_finite() {
                xs.push(x);
                xs.push(f64::from_bits(x.to_bits() & ((1 << 52) - 1)));
            }
        }
        for x in xs {
            assert_eq!(sqrt(x).to_bits(), x.sqrt().to_bits(), "{x:e}");
        }
        assert!(sqrt(-1.0).is_nan() && sqrt(f64::NAN).is_nan());
    }

    #[test]
    fn the_torque_vanishes_on_a_principal_axis_and_follows_g1() {
        let j = [[0.4, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.15]];
        let id = [1.0f32, 0.0, 0.0, 0.0];
        let r = 6.878e6;
        // Nadir along a principal axis: no torque.
        let t = gravity_gradient_torque(&j, id, [r, 0.0, 0.0]);
        assert!(t.iter().all(|x| x.abs() < 1e-18), "{t:?}");
        // 45 deg between x and y: 3 mu / r^3 (Jyy - Jxx) / 2 about z.
        let s = r / sqrt(2.0);
        let t = gravity_gradient_torque(&j, id, [s, s, 0.0]);
        let want = 3.0 * EARTH_MU / (r * r * r) * (0.3 - 0.4) * 0.5;
        assert!(
            (t[2] - want).abs() < 1e-12 * want.abs().max(1e-20),
            "{t:?} {want}"
        );
        // Turning body and position together leaves the body-frame torque unchanged.
        let h = sqrt(0.5) as f32;
        let qz = [h, 0.0, 0.0, h];
        let t2 = gravity_gradient_torque(&j, qz, [-s, s, 0.0]);
        assert!((t2[2] - want).abs() < 1e-9 * want.abs(), "{t2:?}");
        // Unusable inputs: no torque.
        assert_eq!(gravity_gradient_torque(&j, [0.0; 4], [s, s, 0.0]), [0.0; 3]);
        assert_eq!(gravity_gradient_torque(&j, id, [0.0; 3]), [0.0; 3]);
        assert_eq!(
            gravity_gradient_torque(&j, [f32::NAN, 0.0, 0.0, 0.0], [s, s, 0.0]),
            [0.0; 3]
        );
    }

    #[test]
    fn the_stopping_rule_and_the_choice() {
        let j = [[1.0f32, 0.1, 0.0], [0.1, 2.0, 0.0], [0.0, 0.0, 3.0]];
        let std = [[0.01f32; 3]; 3];
        let mut next = j;
        next[1][1] = 2.0005;
        let m = tensor_moved(&j, Some(next), Some(std));
        assert!((m - 0.05).abs() < 1e-3, "{m}");
        assert!(settled(m));
        next[1][1] = 2.002;
        assert!(!settled(tensor_moved(&j, Some(next), Some(std))));
        assert_eq!(tensor_moved(&j, None, Some(std)), f32::INFINITY);
        assert_eq!(tensor_moved(&j, Some(next), None), f32::INFINITY);
        assert!(!settled(f32::INFINITY) && settled(f32::NAN));
        assert!(keep_folded(1.0, 1.5) && !keep_folded(1.5, 1.5));
    }
}
