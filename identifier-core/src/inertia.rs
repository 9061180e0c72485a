//! From the identified `a` to what a user wants: inertia ratios and a consistency check.
//!
//! Torque-free motion determines only the ratios of the principal moments: scaling all `A_i`
//! leaves `a` of (1) unchanged. Absolute values need a known torque.

/// Principal moments relative to `A1`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InertiaRatios {
    /// `A2 / A1`.
    pub a2_over_a1: f32,
    /// `A3 / A1`.
    pub a3_over_a1: f32,
}

impl InertiaRatios {
    /// Inverts the definitions under (1): with `A1 = 1`, `a1 = A2 - A3` and `a2 = (A3 - 1)/A2`
    /// give `A2 = (1 + a1)/(1 - a2)` and `A3 = (1 + a1 a2)/(1 - a2)`.
    ///
    /// `None` when `a2` is 1 (no finite body) or the result is not finite.
    pub fn from_a(a: [f32; 3]) -> Option<Self> {
        let [a1, a2, _] = a;
        let den = 1.0 - a2;
        if den.is_nan() || den.abs() <= 1e-6 {
            return None;
        }
        let r = InertiaRatios {
            a2_over_a1: (1.0 + a1) / den,
            a3_over_a1: (1.0 + a1 * a2) / den,
        };
        (r.a2_over_a1.is_finite() && r.a3_over_a1.is_finite()).then_some(r)
    }

    /// `a` of (1) for the moments `(1, A2/A1, A3/A1)`.
    pub fn to_a(&self) -> [f32; 3] {
        let (i1, i2, i3) = (1.0, self.a2_over_a1, self.a3_over_a1);
        [(i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3]
    }
}

/// `a1 + a2 + a3 + a1 a2 a3`, identically zero for the `a` of any rigid body (substitute the
/// definitions under (1)). A gyro scale-factor error changes the apparent `a` without leaving a
/// residual in (1), but it breaks this identity, so it is a free check.
pub fn consistency(a: [f32; 3]) -> f32 {
    a[0] + a[1] + a[2] + a[0] * a[1] * a[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_body_round_trips() {
        // A = (0.6, 1.54, 1.0): a = (0.9, 0.2597.., -0.94).
        let a = [0.9, (1.0 - 0.6) / 1.54, (0.6 - 1.54) / 1.0];
        let r = InertiaRatios::from_a(a).unwrap();
        assert!((r.a2_over_a1 - 1.54 / 0.6).abs() < 1e-5);
        assert!((r.a3_over_a1 - 1.0 / 0.6).abs() < 1e-5);
        let back = r.to_a();
        for i in 0..3 {
            assert!((back[i] - a[i]).abs() < 1e-5);
        }
        assert!(consistency(a).abs() < 1e-6);
    }

    #[test]
    fn degenerate_a2_gives_none() {
        assert!(InertiaRatios::from_a([0.5, 1.0, 0.0]).is_none());
        assert!(InertiaRatios::from_a([f32::NAN, 0.0, 0.0]).is_none());
    }

    #[test]
    fn scale_error_breaks_consistency() {
        let a = [0.9f32, 0.4 / 1.54, -0.94];
        // A gyro reading (1 + k) omega makes (1) fit with a / (1 + k).
        let k = 0.05;
        let scaled = a.map(|x| x / (1.0 + k));
        assert!(consistency(scaled).abs() > 1e-2);
    }
}
