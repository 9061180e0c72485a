//! The gravity-gradient torque of an orbiting vehicle, folded into the known momentum.
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
//! (trapezoid between samples, in `f64`). The torque depends on `J`, which is what is being
//! identified: `identify` fits once without it, then again with (G1) at the tensor found,
//! until the tensor moves by less than a tenth of its standard deviation (at most
//! [`MAX_PASSES`] fits; the torque is a small perturbation, so one or two suffice).

/// Earth's gravitational parameter, m^3/s^2.
pub const EARTH_MU: f64 = 3.986004418e14;

/// Most fits with the gravity gradient folded in.
pub const MAX_PASSES: usize = 3;

type M3 = [[f64; 3]; 3];

/// (G2) accumulated sample by sample.
#[derive(Clone, Debug)]
pub(crate) struct GravityFold {
    j: M3,
    impulse_n: [f64; 3],
    prev: Option<(f64, [f64; 3])>,
}

/// `R(q)` for the attitude `q = (w, x, y, z)`, scalar first, `v_N = R(q) v_B`, normalised in
/// `f64` first; `None` for a zero or non-finite `q`.
pub fn rotation(q: [f32; 4]) -> Option<M3> {
    let [w, x, y, z] = q.map(f64::from);
    let n = (w * w + x * x + y * y + z * z).sqrt();
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

fn mul(m: &M3, v: [f64; 3]) -> [f64; 3] {
    m.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// `m^T v` (a body-frame vector from an inertial one, for `m = R(q)`).
pub fn mul_t(m: &M3, v: [f64; 3]) -> [f64; 3] {
    core::array::from_fn(|k| m[0][k] * v[0] + m[1][k] * v[1] + m[2][k] * v[2])
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// (G1): the gravity-gradient torque in the body frame, N m, on a body of inertia `j` (kg
/// m^2, body frame) at attitude `q` and inertial position `r` (m). Zero for an unusable `q`
/// or `r`.
pub fn gravity_gradient_torque(j: &M3, q: [f32; 4], r: [f64; 3]) -> [f64; 3] {
    let Some(rot) = rotation(q) else {
        return [0.0; 3];
    };
    let rb = mul_t(&rot, r);
    let d2 = rb[0] * rb[0] + rb[1] * rb[1] + rb[2] * rb[2];
    if !(d2 > 0.0 && d2.is_finite()) {
        return [0.0; 3];
    }
    let k = 3.0 * EARTH_MU / (d2 * d2 * d2.sqrt());
    cross(rb, mul(j, rb)).map(|x| k * x)
}

impl GravityFold {
    /// (G2) for a body of inertia `j` (kg m^2).
    pub(crate) fn new(j: [[f32; 3]; 3]) -> Self {
        GravityFold {
            j: j.map(|r| r.map(f64::from)),
            impulse_n: [0.0; 3],
            prev: None,
        }
    }

    /// The extra momentum `g_B` (G2) at time `t` (s), attitude `q`, position `r` (m).
    pub(crate) fn step(&mut self, t: f64, q: [f32; 4], r: [f64; 3]) -> [f32; 3] {
        let Some(rot) = rotation(q) else {
            return [0.0; 3];
        };
        let tau_n = mul(&rot, gravity_gradient_torque(&self.j, q, r));
        if let Some((t0, prev)) = self.prev {
            let dt = t - t0;
            for k in 0..3 {
                self.impulse_n[k] += 0.5 * dt * (prev[k] + tau_n[k]);
            }
        }
        self.prev = Some((t, tau_n));
        mul_t(&rot, self.impulse_n).map(|x| -x as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_torque_vanishes_on_a_principal_axis_and_follows_g1() {
        let j = [[0.4, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.15]];
        let id = [1.0f32, 0.0, 0.0, 0.0];
        let r = 6.878e6;
        // Nadir along a principal axis: no torque.
        let t = gravity_gradient_torque(&j, id, [r, 0.0, 0.0]);
        assert!(t.iter().all(|x| x.abs() < 1e-18), "{t:?}");
        // 45 deg between x and y: 3 mu / r^3 (Jyy - Jxx) / 2 about z.
        let s = r / 2f64.sqrt();
        let t = gravity_gradient_torque(&j, id, [s, s, 0.0]);
        let want = 3.0 * EARTH_MU / r.powi(3) * (0.3 - 0.4) * 0.5;
        assert!(
            (t[2] - want).abs() < 1e-12 * want.abs().max(1e-20),
            "{t:?} {want}"
        );
        // The same body turned 90 deg about z sees the position along its -y... the torque is
        // the body-frame one: turning body and position together leaves it unchanged.
        let h = (0.5f64).sqrt() as f32;
        let qz = [h, 0.0, 0.0, h];
        let t2 = gravity_gradient_torque(&j, qz, [-s, s, 0.0]);
        assert!((t2[2] - want).abs() < 1e-9 * want.abs(), "{t2:?}");
    }
}
