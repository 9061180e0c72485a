//! The gravity-gradient torque of an orbiting vehicle, folded into the known momentum: the
//! maths is [`identifier_core::gravity`], the same function the firmware's replay calls, so the
//! two give the same bits.
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
//! until the tensor moves by less than a tenth of its standard deviation ((G3),
//! [`identifier_core::gravity::settled`]; at most [`MAX_PASSES`] fits; the torque is a small
//! perturbation, so one or two suffice).

pub use identifier_core::gravity::{
    gravity_gradient_torque, mul_t, rotation, GravityFold, EARTH_MU, MAX_PASSES,
};
