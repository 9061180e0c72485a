//! A gyro sensor model: what a MEMS gyro reports for a true angular velocity.
//!
//! `measured = Q(S R w + b + n)` with `R` the sensor-to-principal misalignment (products of
//! inertia as seen from the sensor axes), `S` a per-axis scale factor, `b` a constant bias, `n`
//! white Gaussian noise and `Q` quantisation and full-scale clipping. Seeded and reproducible.

use crate::rigid_body::Trajectory;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Gyro error model. [`GyroModel::ideal`] reports the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroModel {
    /// White noise standard deviation per sample, rad/s.
    pub noise_std: f64,
    /// Constant bias, rad/s (sensor axes).
    pub bias: [f64; 3],
    /// Per-axis scale factor (1 = exact).
    pub scale: [f64; 3],
    /// Rotation from principal axes to sensor axes (identity = aligned).
    pub rotation: [[f64; 3]; 3],
    /// Quantisation step, rad/s (0 = none).
    pub quantum: f64,
    /// Full scale, rad/s: readings are clipped to +-full_scale.
    pub full_scale: f64,
    /// Noise seed.
    pub seed: u64,
}

impl GyroModel {
    /// A perfect sensor aligned with the principal axes.
    pub fn ideal() -> Self {
        GyroModel {
            noise_std: 0.0,
            bias: [0.0; 3],
            scale: [1.0; 3],
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            quantum: 0.0,
            full_scale: f64::INFINITY,
            seed: 0,
        }
    }

    /// An aligned sensor with white noise only.
    pub fn noisy(noise_std: f64, seed: u64) -> Self {
        GyroModel {
            noise_std,
            seed,
            ..GyroModel::ideal()
        }
    }

    /// The readings for each true sample of `tr`.
    pub fn measure(&self, tr: &Trajectory) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let normal = Normal::new(0.0, self.noise_std.max(0.0)).ok();
        tr.omega
            .iter()
            .map(|w| {
                let r = &self.rotation;
                std::array::from_fn(|i| {
                    let rw = r[i][0] * w[0] + r[i][1] * w[1] + r[i][2] * w[2];
                    let n = match normal {
                        Some(d) if self.noise_std > 0.0 => d.sample(&mut rng),
                        _ => 0.0,
                    };
                    let mut x = self.scale[i] * rw + self.bias[i] + n;
                    if self.quantum > 0.0 {
                        x = (x / self.quantum).round() * self.quantum;
                    }
                    x.clamp(-self.full_scale, self.full_scale)
                })
            })
            .collect()
    }
}

/// Rotation matrix about a unit axis by `angle` radians (Rodrigues).
pub fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = axis.map(|v| v / n);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid_body::Body;

    #[test]
    fn noise_is_seeded_and_has_the_stated_std() {
        let tr = Body::free([1.0, 2.0, 3.0]).simulate([0.0; 3], 10.0, 1000.0, 1);
        let m1 = GyroModel::noisy(2e-3, 7).measure(&tr);
        let m2 = GyroModel::noisy(2e-3, 7).measure(&tr);
        assert_eq!(m1, m2);
        let var = m1.iter().map(|w| w[0] * w[0]).sum::<f64>() / m1.len() as f64;
        assert!((var.sqrt() - 2e-3).abs() < 1e-4, "{}", var.sqrt());
    }

    #[test]
    fn rotation_is_orthonormal() {
        let r = rotation([1.0, 2.0, -0.5], 0.3);
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| r[i][k] * r[j][k]).sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }
}
