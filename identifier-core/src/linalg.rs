//! The few 3x3 operations the identifier needs, written out so that the host build and the
//! Cortex-M4F build execute the same `f32` operations (no `std` maths on either side).

/// A 3x3 matrix stored by rows.
pub(crate) type Mat3 = [[f32; 3]; 3];

/// `m * v`.
#[inline]
pub(crate) fn mul_vec(m: &Mat3, v: [f32; 3]) -> [f32; 3] {
    let [r0, r1, r2] = m;
    [dot(*r0, v), dot(*r1, v), dot(*r2, v)]
}

#[inline]
pub(crate) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn det(m: &Mat3) -> f32 {
    let [[a, b, c], [d, e, f], [g, h, i]] = *m;
    a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
}

/// The Gram matrix of two gradients `g0`, `g1` with a ridge of 1e-6 of its trace, for moving a
/// state back onto two invariants along their gradients (the trajectory fits'
/// restorations): `(G + ridge I) (alpha, beta) = r`, the least-norm correction when the
/// gradients are nearly parallel (a spin about a principal axis).
pub(crate) struct Gram2 {
    m11: f32,
    m22: f32,
    g12: f32,
    det: f32,
}

impl Gram2 {
    /// `None` when the system is singular or not finite.
    pub(crate) fn new(g0: [f32; 3], g1: [f32; 3]) -> Option<Self> {
        let (g11, g12, g22) = (dot(g0, g0), dot(g0, g1), dot(g1, g1));
        let ridge = 1e-6 * (g11 + g22);
        let (m11, m22) = (g11 + ridge, g22 + ridge);
        let det = m11 * m22 - g12 * g12;
        (det > 0.0 && det.is_finite()).then_some(Gram2 { m11, m22, g12, det })
    }

    /// `(alpha, beta)` for the right-hand side `(r0, r1)`, by Cramer's rule.
    pub(crate) fn solve(&self, r0: f32, r1: f32) -> (f32, f32) {
        (
            (r0 * self.m22 - r1 * self.g12) / self.det,
            (self.m11 * r1 - self.g12 * r0) / self.det,
        )
    }
}

/// Solves `m x = r` by Cramer's rule; `None` when `m` is numerically singular or the
/// result is not finite. Cramer's rule is exact enough here: `m = I - k C` with `C` Hurwitz
/// and `k >= 0` has all eigenvalues with real part >= 1, so it is well conditioned.
pub(crate) fn solve(m: &Mat3, r: [f32; 3]) -> Option<[f32; 3]> {
    let d = det(m);
    if !d.is_finite() || d.abs() < 1e-12 {
        return None;
    }
    let mut x = [0.0f32; 3];
    for (col, xi) in x.iter_mut().enumerate() {
        let mut mc = *m;
        for (row, mr) in mc.iter_mut().enumerate() {
            if let (Some(e), Some(&ri)) = (mr.get_mut(col), r.get(row)) {
                *e = ri;
            }
        }
        *xi = det(&mc) / d;
    }
    if x.iter().all(|v| v.is_finite()) {
        Some(x)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solve_recovers_known_solution() {
        let m = [[2.0, 1.0, 0.0], [0.5, 3.0, -1.0], [0.0, 1.0, 4.0]];
        let x = [1.0, -2.0, 0.5];
        let r = mul_vec(&m, x);
        let got = solve(&m, r).unwrap();
        for i in 0..3 {
            assert!((got[i] - x[i]).abs() < 1e-6, "{got:?}");
        }
    }

    #[test]
    fn solve_rejects_singular() {
        let m = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]];
        assert!(solve(&m, [1.0, 1.0, 1.0]).is_none());
    }
}
