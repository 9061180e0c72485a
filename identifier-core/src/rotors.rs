//! The vehicle's known rotors (reaction wheels, a flywheel, a quadrotor's own motors) and the
//! angular momentum they carry relative to the body: the `h(t)` of the tensor's model
//! (`L = J w + h`, (F1) of the tensor fit).
//!
//! ```text
//! h(t) = sum_i j_i W_i(t) g_i                                                    (R1)
//! ```
//!
//! with `j_i` rotor `i`'s inertia about its own axis (kg m^2), `W_i` its speed relative to the
//! body (rad/s, positive along `g_i`) and `g_i` its axis, a unit vector in the gyro frame. The
//! host tool and the firmware both turn wheel speeds into momentum through [`Rotors::momentum`],
//! so they give the same bits.
//!
//! ```
//! use identifier_core::{Rotor, Rotors};
//!
//! // Three orthogonal wheels of 1e-4 kg m^2.
//! let rotors = Rotors::new(&[
//!     Rotor::new(1e-4, [1.0, 0.0, 0.0]),
//!     Rotor::new(1e-4, [0.0, 1.0, 0.0]),
//!     Rotor::new(1e-4, [0.0, 0.0, 1.0]),
//! ])
//! .unwrap();
//! let h = rotors.momentum(&[100.0, -200.0, 0.0]);
//! assert_eq!(h, [1e-2, -2e-2, 0.0]);
//! ```

/// The most rotors a vehicle may have (a fixed bound: no heap).
pub const MAX_ROTORS: usize = 8;

/// How far an axis's length may be from 1 (the vehicle file's axes are written with a few
/// digits; a larger error is a mistake, not rounding).
pub const AXIS_UNIT_TOLERANCE: f32 = 1e-3;

/// One rotor: its inertia about its own axis and that axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rotor {
    /// Inertia about the rotor's own axis, kg m^2 (`j_i` of (R1)).
    pub inertia_kg_m2: f32,
    /// Unit vector in the gyro frame, the positive speed direction (`g_i` of (R1)).
    pub axis: [f32; 3],
}

impl Rotor {
    /// A rotor of inertia `inertia_kg_m2` about `axis` (checked by [`Rotors::new`]).
    pub const fn new(inertia_kg_m2: f32, axis: [f32; 3]) -> Self {
        Rotor {
            inertia_kg_m2,
            axis,
        }
    }

    /// `j g`: the momentum per rad/s of speed, kg m^2 (a term of (R1)).
    fn gain(&self) -> [f32; 3] {
        let [x, y, z] = self.axis;
        let j = self.inertia_kg_m2;
        [j * x, j * y, j * z]
    }
}

/// Why a set of rotors is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RotorError {
    /// More than [`MAX_ROTORS`] rotors.
    TooMany,
    /// Rotor `i`'s inertia is zero, negative or not finite.
    Inertia(u8),
    /// Rotor `i`'s axis is not a unit vector within [`AXIS_UNIT_TOLERANCE`] (or not finite).
    Axis(u8),
}

/// Up to [`MAX_ROTORS`] rotors, checked, and the momentum (R1) of their speeds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rotors {
    gains: [[f32; 3]; MAX_ROTORS],
    len: u8,
}

impl Rotors {
    /// No rotor: the momentum is zero.
    pub const NONE: Rotors = Rotors {
        gains: [[0.0; 3]; MAX_ROTORS],
        len: 0,
    };

    /// The rotors, or why not: at most [`MAX_ROTORS`], each with a positive finite inertia
    /// and a unit axis.
    pub fn new(rotors: &[Rotor]) -> Result<Self, RotorError> {
        if rotors.len() > MAX_ROTORS {
            return Err(RotorError::TooMany);
        }
        let mut out = Rotors::NONE;
        for ((i, r), gain) in rotors.iter().enumerate().zip(out.gains.iter_mut()) {
            let i = i as u8;
            if !(r.inertia_kg_m2.is_finite() && r.inertia_kg_m2 > 0.0) {
                return Err(RotorError::Inertia(i));
            }
            let [x, y, z] = r.axis;
            let norm2 = x * x + y * y + z * z;
            // |norm^2 - 1| ~ 2 |norm - 1| near 1.
            if !norm2.is_finite() || (norm2 - 1.0).abs() > 2.0 * AXIS_UNIT_TOLERANCE {
                return Err(RotorError::Axis(i));
            }
            *gain = r.gain();
        }
        out.len = rotors.len() as u8;
        Ok(out)
    }

    /// Number of rotors.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True when there is no rotor.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// (R1): `h = sum_i j_i W_i g_i`, kg m^2/s, from the speeds `W_i` in rad/s in the rotors'
    /// order (missing speeds count as zero, extra ones are ignored). A non-finite speed gives
    /// a non-finite momentum, which the estimators refuse per sample.
    pub fn momentum(&self, speeds: &[f32]) -> [f32; 3] {
        let mut h = [0.0f32; 3];
        for (g, &w) in self.gains.iter().take(self.len()).zip(speeds) {
            h[0] += g[0] * w;
            h[1] += g[1] * w;
            h[2] += g[2] * w;
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_bad_rotors_with_their_index() {
        let good = Rotor::new(1e-4, [0.0, 0.0, 1.0]);
        assert_eq!(
            Rotors::new(&[good, Rotor::new(0.0, [1.0, 0.0, 0.0])]),
            Err(RotorError::Inertia(1))
        );
        assert_eq!(
            Rotors::new(&[Rotor::new(f32::NAN, [1.0, 0.0, 0.0])]),
            Err(RotorError::Inertia(0))
        );
        assert_eq!(
            Rotors::new(&[good, good, Rotor::new(1e-4, [0.5, 0.5, 0.5])]),
            Err(RotorError::Axis(2))
        );
        assert_eq!(Rotors::new(&[good; 9]), Err(RotorError::TooMany));
        assert!(Rotors::new(&[good; 8]).is_ok());
    }

    #[test]
    fn pyramid_momentum_is_the_sum_of_each_wheels() {
        let (s, c) = (0.5736f32, 0.8192f32);
        let axes = [[s, 0.0, c], [0.0, s, c], [-s, 0.0, c], [0.0, -s, c]];
        let wheels = axes.map(|a| Rotor::new(2.387e-5, a));
        let rotors = Rotors::new(&wheels).unwrap();
        assert_eq!(rotors.len(), 4);
        let h = rotors.momentum(&[100.0, 100.0, 100.0, 100.0]);
        assert!(h[0].abs() < 1e-9 && h[1].abs() < 1e-9);
        assert!((h[2] - 4.0 * 2.387e-5 * 100.0 * c).abs() < 1e-7);
        // Missing speeds are zero; a non-finite one is passed on.
        assert_eq!(rotors.momentum(&[]), [0.0; 3]);
        assert!(rotors.momentum(&[f32::NAN])[0].is_nan());
    }
}
