//! A very short toss (20 to 35 samples at 150 Hz, a racquet-like body with two moments 8 %
//! apart): the ratios must come from the trajectory fit, which has them to a few 1e-3 there.
//! The output-error tensor's Wald test on the products of inertia, which trusts the fit's
//! local curvature, can call this principal body's products significant on such short tosses,
//! and the ratios would then come from the tensor, far less precise; so the likelihood ratio
//! against the ratio fit has to confirm it.

use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use identifier_core::{FlightPipeline, PipelineSettings, RatioSource};

#[test]
fn a_short_toss_keeps_the_principal_axes() {
    let body = Body::free([12.3, 1.0, 13.3]);
    let truth = body.a();
    let (rate, sigma) = (150.0, 1e-2);
    let tr = body.simulate([7.9, -1.8, 0.5], 0.3, rate, 64);
    for n in [20usize, 27, 35] {
        let mut worst = 0.0f64;
        for seed in 1..=40 {
            let y = GyroModel::noisy(sigma, seed).measure(&tr);
            let settings = PipelineSettings::for_rate(rate as f32, sigma as f32);
            let mut p = FlightPipeline::new(settings, false).unwrap();
            for w in y.iter().take(n) {
                p.step(w.map(|x| x as f32), [0.0; 3], [0.0; 3], (1.0 / rate) as f32);
            }
            p.end_stretch();
            let r = p.ratios();
            assert_eq!(
                r.source,
                RatioSource::Trajectory,
                "{n} samples, seed {seed}"
            );
            let (a, s) = (r.a.unwrap(), r.std_a.unwrap());
            for i in 0..3 {
                worst = worst.max(((f64::from(a[i]) - truth[i]) / f64::from(s[i])).abs());
            }
        }
        println!("{n} samples: worst |error / std| over 40 seeds {worst:.2}");
        assert!(worst < 4.5, "{n} samples: worst |error / std| {worst:.2}");
    }
}
