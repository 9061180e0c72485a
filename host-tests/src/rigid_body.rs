//! Reference simulator of a rigid body rotating about its centre of mass, in `f64`.
//!
//! The torque-free case is the paper's model (1). The optional effects are the ones the
//! close-the-loop analysis looks for: a constant body-frame torque, viscous (aerodynamic)
//! damping, and a constant internal rotor momentum. Integration is classical RK4 on a fine
//! internal step; the tests check energy and momentum conservation to ~1e-12.

/// Euler's equations with optional extra effects, all in the principal frame:
/// `I w' = (I w + h) x w + tau - D w`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Principal moments `(A1, A2, A3)` (any unit; only ratios matter without torque).
    pub inertia: [f64; 3],
    /// Constant torque in the body frame.
    pub torque: [f64; 3],
    /// Viscous damping coefficients: torque `-d_i w_i`.
    pub damping: [f64; 3],
    /// Constant internal rotor angular momentum (body frame).
    pub rotor: [f64; 3],
}

impl Body {
    /// A torque-free body with principal moments `inertia`.
    pub fn free(inertia: [f64; 3]) -> Self {
        Body {
            inertia,
            torque: [0.0; 3],
            damping: [0.0; 3],
            rotor: [0.0; 3],
        }
    }

    /// `(a1, a2, a3)` of (1).
    pub fn a(&self) -> [f64; 3] {
        let [i1, i2, i3] = self.inertia;
        [(i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3]
    }

    /// `w'` for the angular velocity `w`.
    pub fn rhs(&self, w: [f64; 3]) -> [f64; 3] {
        let i = self.inertia;
        let l = [
            i[0] * w[0] + self.rotor[0],
            i[1] * w[1] + self.rotor[1],
            i[2] * w[2] + self.rotor[2],
        ];
        let lxw = cross(l, w);
        std::array::from_fn(|k| (lxw[k] + self.torque[k] - self.damping[k] * w[k]) / i[k])
    }

    /// Kinetic energy `1/2 sum A_i w_i^2`.
    pub fn energy(&self, w: [f64; 3]) -> f64 {
        0.5 * (0..3).map(|k| self.inertia[k] * w[k] * w[k]).sum::<f64>()
    }

    /// Squared angular momentum `|I w + h|^2`.
    pub fn momentum_sq(&self, w: [f64; 3]) -> f64 {
        (0..3)
            .map(|k| (self.inertia[k] * w[k] + self.rotor[k]).powi(2))
            .sum()
    }

    /// Simulates from `omega0` for `duration` seconds and returns the true angular velocity at
    /// `rate_hz` (first sample at t = 0). `substeps` RK4 steps are taken per output sample.
    pub fn simulate(
        &self,
        omega0: [f64; 3],
        duration: f64,
        rate_hz: f64,
        substeps: usize,
    ) -> Trajectory {
        let n = (duration * rate_hz).round() as usize + 1;
        let dt = 1.0 / rate_hz;
        let h = dt / substeps.max(1) as f64;
        let mut t = Vec::with_capacity(n);
        let mut omega = Vec::with_capacity(n);
        let mut w = omega0;
        for k in 0..n {
            t.push(k as f64 * dt);
            omega.push(w);
            for _ in 0..substeps.max(1) {
                w = rk4(|x| self.rhs(x), w, h);
            }
        }
        Trajectory { t, omega }
    }
}

/// True angular velocity samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// Sample times, seconds.
    pub t: Vec<f64>,
    /// Angular velocity in the principal frame, rad/s.
    pub omega: Vec<[f64; 3]>,
}

/// One classical Runge-Kutta step of `x' = f(x)`.
pub fn rk4<F: Fn([f64; 3]) -> [f64; 3]>(f: F, x: [f64; 3], h: f64) -> [f64; 3] {
    let add = |a: [f64; 3], b: [f64; 3], s: f64| std::array::from_fn(|k| a[k] + s * b[k]);
    let k1 = f(x);
    let k2 = f(add(x, k1, h / 2.0));
    let k3 = f(add(x, k2, h / 2.0));
    let k4 = f(add(x, k3, h));
    std::array::from_fn(|k| x[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]))
}

/// `a x b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_body_conserves_energy_and_momentum() {
        let b = Body::free([0.6, 1.54, 1.0]);
        let w0 = [1.0, 1.0, 1.0];
        let tr = b.simulate(w0, 20.0, 1000.0, 4);
        let (e0, m0) = (b.energy(w0), b.momentum_sq(w0));
        let w = *tr.omega.last().unwrap();
        assert!((b.energy(w) - e0).abs() < 1e-11 * e0);
        assert!((b.momentum_sq(w) - m0).abs() < 1e-11 * m0);
    }

    #[test]
    fn rhs_is_paper_equation_one() {
        let b = Body::free([0.6, 1.54, 1.0]);
        let a = b.a();
        let w = [0.3, -1.2, 0.7];
        let f = b.rhs(w);
        assert!((f[0] - a[0] * w[1] * w[2]).abs() < 1e-14);
        assert!((f[1] - a[1] * w[2] * w[0]).abs() < 1e-14);
        assert!((f[2] - a[2] * w[0] * w[1]).abs() < 1e-14);
    }

    #[test]
    fn damping_drains_energy() {
        let mut b = Body::free([0.6, 1.54, 1.0]);
        b.damping = [0.01; 3];
        let w0 = [1.0, 1.0, 1.0];
        let tr = b.simulate(w0, 5.0, 100.0, 10);
        assert!(b.energy(*tr.omega.last().unwrap()) < 0.95 * b.energy(w0));
    }
}
