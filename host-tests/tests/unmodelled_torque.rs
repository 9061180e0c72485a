//! A constant torque during the "free" flight (a tether, a hand, air on a large face): the
//! torque-free model explains the gyro to within its noise by moving `a` (10-15 standard
//! deviations on this body), so the residual cannot show it. The ratio fit's score test of a
//! constant torque must, and then neither the ratios nor the tensor may say `Converged`.
//! Torque-free seeds of the same body must stay `Converged`.

use host_tests::gyro::GyroModel;
use host_tests::rigid_body::{rk4, Trajectory};
use identifier_core::{FlightPipeline, PipelineSettings, Status};

fn flight(c: [f64; 3], seed: u64) -> (Status, Status, bool) {
    let m = [0.8, 1.3, 1.7];
    let f = |w: [f64; 3]| {
        [
            (m[1] - m[2]) / m[0] * w[1] * w[2] + c[0],
            (m[2] - m[0]) / m[1] * w[2] * w[0] + c[1],
            (m[0] - m[1]) / m[2] * w[0] * w[1] + c[2],
        ]
    };
    let (rate, n, sub) = (500.0, 3001, 32);
    let mut w = [1.2, 0.4, 0.9];
    let mut tr = Trajectory {
        t: Vec::new(),
        omega: Vec::new(),
    };
    for k in 0..n {
        tr.t.push(k as f64 / rate);
        tr.omega.push(w);
        for _ in 0..sub {
            w = rk4(f, w, 1.0 / rate / sub as f64);
        }
    }
    let y = GyroModel::noisy(2e-3, seed).measure(&tr);
    let mut p = FlightPipeline::new(PipelineSettings::for_rate(rate as f32, 2e-3), false).unwrap();
    for w in &y {
        p.step(w.map(|x| x as f32), [0.0; 3], [0.0; 3], (1.0 / rate) as f32);
    }
    p.end_stretch();
    let (t, r) = p.estimate_and_ratios();
    let torque = p.trajectory().estimate().is_some_and(|e| e.torque);
    (r.status, t.status, torque)
}

#[test]
fn a_constant_torque_is_never_converged() {
    for seed in 1..=6 {
        let (ratios, tensor, torque) = flight([2e-3, -1e-3, 1.5e-3], seed);
        assert!(torque, "seed {seed}: torque not found");
        assert_ne!(ratios, Status::Converged, "seed {seed}: ratios");
        assert_ne!(tensor, Status::Converged, "seed {seed}: tensor");
    }
}

#[test]
fn a_free_body_is_still_converged() {
    for seed in 1..=6 {
        let (ratios, tensor, torque) = flight([0.0; 3], seed);
        assert!(!torque, "seed {seed}: torque found on a free body");
        assert_eq!(ratios, Status::Converged, "seed {seed}: ratios");
        assert_eq!(tensor, Status::Converged, "seed {seed}: tensor");
    }
}
