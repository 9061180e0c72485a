//! The estimators people would use instead of the paper's identifier, and the common frame the
//! benchmark (`bench-estimators`) runs them in: scenarios, a [`Method`] trait, and helpers.
//!
//! Every method sees the same noisy samples `(t_k, y_k)` of omega and returns an estimate of
//! `a = (a1, a2, a3)` of (1). On-board methods ([`onboard`]) run the `identifier-core` code in
//! `f32`; the host peers are `f64`:
//!
//! * [`batch_ls`]: batch least squares of `w_i' = a_i w_j w_k` with Savitzky-Golay derivatives;
//! * [`rls`]: recursive least squares on (1) integrated over a short sliding window;
//! * [`ekf`]: a joint extended Kalman filter on `(omega, a)`;
//! * [`ml`]: the output-error maximum-likelihood fit of `(a, omega0)` by Gauss-Newton on the
//!   sensitivity equations of [`crate::crb`], the accuracy reference.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod batch_ls;
pub mod ekf;
pub mod ml;
pub mod onboard;
pub mod pipeline;
pub mod rls;
pub mod tensor;

use crate::gyro::GyroModel;
use crate::rigid_body::Body;

/// One benchmark scenario: a body, an initial rate, a sampling plan and a gyro noise level.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Short name (table rows, file names).
    pub name: &'static str,
    /// One-line description.
    pub description: &'static str,
    /// Principal moments.
    pub inertia: [f64; 3],
    /// Initial angular velocity, rad/s.
    pub omega0: [f64; 3],
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Duration, s.
    pub duration: f64,
    /// White gyro noise per sample and axis, rad/s.
    pub sigma: f64,
    /// Constant gyro bias, rad/s (sensor axes; zero in most scenarios).
    pub bias: [f64; 3],
}

impl Scenario {
    /// The scenarios of the benchmark: the original four, then those of issue 11.
    pub fn all() -> Vec<Scenario> {
        let mut v = Self::original();
        v.extend(Self::issue11());
        v
    }

    /// The scenarios added for issue 11: a near-symmetric body at 2 kHz, short tosses at
    /// 100-200 Hz with quiet and noisy gyros, a fast tumble (where `f32` limits the on-board
    /// fits) and a constant gyro bias. (A body near a
    /// principal axis is `major-axis` above; the flywheel throw is a tensor scenario of its
    /// own in `bench-estimators`.)
    pub fn issue11() -> Vec<Scenario> {
        vec![
            Scenario {
                name: "near-symmetric-2k",
                description: "A=(1.0,1.05,1.6) (two moments 5 % apart), omega0=(1,1,1), 2 kHz, 10 s, sigma 2e-3",
                inertia: [1.0, 1.05, 1.6],
                omega0: [1.0, 1.0, 1.0],
                rate_hz: 2000.0,
                duration: 10.0,
                sigma: 2e-3,
                bias: [0.0; 3],
            },
            Scenario {
                name: "toss-200hz-quiet",
                description: "racquet-like A=(12.3,1.0,13.3) from omega0=(7.9,-1.8,0.5), exactly 200 Hz, 1 s, quiet gyro sigma 5e-4",
                inertia: [12.3, 1.0, 13.3],
                omega0: [7.9, -1.8, 0.5],
                rate_hz: 200.0,
                duration: 1.0,
                sigma: 5e-4,
                bias: [0.0; 3],
            },
            Scenario {
                name: "toss-150hz-noisy",
                description: "racquet-like A=(12.3,1.0,13.3) from omega0=(7.9,-1.8,0.5), 150 Hz, 0.6 s, sigma 1e-2",
                inertia: [12.3, 1.0, 13.3],
                omega0: [7.9, -1.8, 0.5],
                rate_hz: 150.0,
                duration: 0.6,
                sigma: 1e-2,
                bias: [0.0; 3],
            },
            Scenario {
                name: "toss-200hz-noisy",
                description: "racquet-like A=(12.3,1.0,13.3) from omega0=(7.9,-1.8,0.5), 200 Hz, 0.5 s, sigma 1e-2",
                inertia: [12.3, 1.0, 13.3],
                omega0: [7.9, -1.8, 0.5],
                rate_hz: 200.0,
                duration: 0.5,
                sigma: 1e-2,
                bias: [0.0; 3],
            },
            Scenario {
                name: "fast-tumble",
                description: "A=(1.0,2.1,2.9) tumbling from omega0=(3,12,2) (48 rad turned), 1 kHz, 4 s, sigma 2e-3: the f32 resolution of a long, fast trajectory",
                inertia: [1.0, 2.1, 2.9],
                omega0: [3.0, 12.0, 2.0],
                rate_hz: 1000.0,
                duration: 4.0,
                sigma: 2e-3,
                bias: [0.0; 3],
            },
            Scenario {
                name: "gyro-bias",
                description: "paper's body, omega0=(1,1,1), 1 kHz, 10 s, sigma 2e-3, constant gyro bias (2e-3, -1.5e-3, 1e-3) rad/s not removed",
                inertia: [0.6, 1.54, 1.0],
                omega0: [1.0, 1.0, 1.0],
                rate_hz: 1000.0,
                duration: 10.0,
                sigma: 2e-3,
                bias: [2e-3, -1.5e-3, 1e-3],
            },
        ]
    }

    /// The four scenarios of the original benchmark.
    pub fn original() -> Vec<Scenario> {
        vec![
            Scenario {
                name: "paper",
                description: "paper's body A=(0.6,1.54,1.0), omega0=(1,1,1), 1 kHz, 20 s, sigma 2e-3",
                inertia: [0.6, 1.54, 1.0],
                omega0: [1.0, 1.0, 1.0],
                rate_hz: 1000.0,
                duration: 20.0,
                sigma: 2e-3,
                bias: [0.0; 3],
            },
            Scenario {
                name: "near-symmetric",
                description: "A=(1.0,1.05,1.6) (a3=-0.03), omega0=(1,1,1), 1 kHz, 20 s, sigma 2e-3",
                inertia: [1.0, 1.05, 1.6],
                omega0: [1.0, 1.0, 1.0],
                rate_hz: 1000.0,
                duration: 20.0,
                sigma: 2e-3,
                bias: [0.0; 3],
            },
            Scenario {
                name: "major-axis",
                description: "paper's body spun near its major axis 2, omega0=(0.15,1.5,0.15), 1 kHz, 20 s, sigma 2e-3",
                inertia: [0.6, 1.54, 1.0],
                omega0: [0.15, 1.5, 0.15],
                rate_hz: 1000.0,
                duration: 20.0,
                sigma: 2e-3,
                bias: [0.0; 3],
            },
            Scenario {
                name: "toss",
                description: "racquet-like A=(12.3,1.0,13.3), flip about the intermediate axis from omega0=(7.9,-1.8,0.5), 100 Hz, 0.85 s, sigma 1e-2",
                inertia: [12.3, 1.0, 13.3],
                omega0: [7.9, -1.8, 0.5],
                rate_hz: 100.0,
                duration: 0.85,
                sigma: 1e-2,
                bias: [0.0; 3],
            },
        ]
    }

    /// `a` of (1) for this body.
    pub fn a(&self) -> [f64; 3] {
        Body::free(self.inertia).a()
    }

    /// Noise-free samples `(t, omega)`.
    pub fn truth(&self) -> (Vec<f64>, Vec<[f64; 3]>) {
        let sub = if self.rate_hz < 500.0 { 50 } else { 4 };
        let tr = Body::free(self.inertia).simulate(self.omega0, self.duration, self.rate_hz, sub);
        (tr.t, tr.omega)
    }

    /// Noisy gyro readings for `seed` of the noise-free samples.
    pub fn measure(&self, truth: &(Vec<f64>, Vec<[f64; 3]>), seed: u64) -> Vec<[f64; 3]> {
        let tr = crate::rigid_body::Trajectory {
            t: truth.0.clone(),
            omega: truth.1.clone(),
        };
        GyroModel {
            bias: self.bias,
            ..GyroModel::noisy(self.sigma, seed)
        }
        .measure(&tr)
    }

    /// The readings without white noise (the bias, if any, kept): for the noise-free bias.
    pub fn measure_noise_free(&self, truth: &(Vec<f64>, Vec<[f64; 3]>)) -> Vec<[f64; 3]> {
        let tr = crate::rigid_body::Trajectory {
            t: truth.0.clone(),
            omega: truth.1.clone(),
        };
        GyroModel {
            bias: self.bias,
            ..GyroModel::ideal()
        }
        .measure(&tr)
    }
}

/// An estimator of `a` from samples of omega.
pub trait Method: Sync {
    /// Name in tables and plots.
    fn name(&self) -> &'static str;
    /// True for the `no_std` `f32` methods that run on the Cortex-M4F.
    fn onboard(&self) -> bool {
        false
    }
    /// The estimate after all samples `(t, y)`.
    fn estimate(&self, t: &[f64], y: &[[f64; 3]]) -> [f64; 3];
    /// The estimate and, for methods that report one, its standard deviation, when the gyro's
    /// white noise `sigma` (rad/s) is declared as a deployment would configure it. Default:
    /// [`Method::estimate`] and no standard deviation.
    fn estimate_with_std(
        &self,
        t: &[f64],
        y: &[[f64; 3]],
        sigma: f64,
    ) -> ([f64; 3], Option<[f64; 3]>) {
        let _ = sigma;
        (self.estimate(t, y), None)
    }
    /// The estimates using the samples up to each index of `checkpoints` (ascending). The
    /// default refits on each prefix (batch methods); recursive methods override it with one
    /// pass.
    fn curve(&self, t: &[f64], y: &[[f64; 3]], checkpoints: &[usize]) -> Vec<[f64; 3]> {
        checkpoints
            .iter()
            .map(|&k| self.estimate(&t[..=k], &y[..=k]))
            .collect()
    }
}

/// All methods of the benchmark, the paper's identifier first (the baseline).
pub fn all_methods() -> Vec<Box<dyn Method>> {
    vec![
        Box::new(onboard::Paper::default()),
        Box::new(onboard::PaperAveraged::default()),
        Box::new(onboard::PaperLowPass::default()),
        Box::new(onboard::RefinedMethod::default()),
        Box::new(batch_ls::BatchLs),
        Box::new(rls::Rls),
        Box::new(ekf::Ekf),
        Box::new(ml::Ml),
        Box::new(ml::MlConstrained),
    ]
}

/// `(w2 w3, w3 w1, w1 w2)`: the right-hand sides of (1) without `a`.
pub fn products(w: [f64; 3]) -> [f64; 3] {
    [w[1] * w[2], w[2] * w[0], w[0] * w[1]]
}

/// Savitzky-Golay weights of half-width `m` and polynomial order `order` for the value
/// (`deriv = 0`) or the first derivative (`deriv = 1`, per unit sample spacing) at the centre.
pub fn savgol(m: usize, order: usize, deriv: usize) -> Vec<f64> {
    use nalgebra::DMatrix;
    let n = 2 * m + 1;
    let p = order + 1;
    let v = DMatrix::from_fn(n, p, |r, c| (r as f64 - m as f64).powi(c as i32));
    let vtv = v.transpose() * &v;
    let Some(inv) = vtv.try_inverse() else {
        return vec![0.0; n];
    };
    // Row `deriv` of (V^T V)^-1 V^T gives the coefficient of t^deriv; derivative = 1! c_1.
    let coef = inv * v.transpose();
    (0..n).map(|k| coef[(deriv.min(order), k)]).collect()
}
