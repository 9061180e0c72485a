//! Test support shared by the unit tests of the identifiers: the paper's body in free motion.

/// The paper's ratios `a` (its Fig. 1 body).
pub(crate) const A: [f32; 3] = [0.9, 0.259_740_26, -0.94];

/// The paper's body from (1, 1, 1), RK4 in f32, `n` samples at `dt`: the torque-free
/// `w1' = a1 w2 w3` (and cyclic), the equations the identifiers invert.
pub(crate) fn motion(n: usize, dt: f32) -> impl Iterator<Item = [f32; 3]> {
    let f = |w: [f32; 3]| [A[0] * w[1] * w[2], A[1] * w[2] * w[0], A[2] * w[0] * w[1]];
    let add =
        |w: [f32; 3], k: [f32; 3], h: f32| [w[0] + h * k[0], w[1] + h * k[1], w[2] + h * k[2]];
    let mut w = [1.0f32, 1.0, 1.0];
    (0..n).map(move |_| {
        let out = w;
        let k1 = f(w);
        let k2 = f(add(w, k1, 0.5 * dt));
        let k3 = f(add(w, k2, 0.5 * dt));
        let k4 = f(add(w, k3, dt));
        for i in 0..3 {
            w[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        out
    })
}
