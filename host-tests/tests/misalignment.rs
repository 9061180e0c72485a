//! A gyro mounted slightly off the body's principal axes (products of inertia in the sensor's
//! frame), through the pipeline as `inertia identify` runs a gyro-only log: the paper's body,
//! 20 s at 1 kHz, 2e-3 rad/s, the sensor turned by 0 to 2.3 deg. Below what the data can see the
//! principal-axis fit is kept; above it the products are found and the tensor's `a` reported;
//! in between the choice may go either way. What must never happen is an `a` that says
//! `Converged` while it is more than four of its standard deviations from the truth.
use host_tests::gyro::{rotation, GyroModel};
use identifier_core::{FlightPipeline, PipelineSettings, RatioSource, Status};

const SEEDS: u64 = 12;

#[test]
fn a_misaligned_gyro_never_gives_a_confident_wrong_a() {
    let body = host_tests::paper::body();
    let a_true = body.a();
    let sigma = 2e-3;
    let tr = body.simulate([1.0, 1.0, 1.0], 20.0, 1000.0, 2);
    for angle in [0.0, 0.0003, 0.0006, 0.001, 0.002, 0.005, 0.01, 0.04] {
        let (mut worst, mut tensor_source) = (0.0f64, 0u64);
        for seed in 0..SEEDS {
            let mut g = GyroModel::noisy(sigma, 100 + seed);
            g.rotation = rotation([0.3, -0.5, 1.0], angle);
            let y = g.measure(&tr);
            let settings = PipelineSettings::for_rate(1000.0, sigma as f32);
            let mut p = FlightPipeline::new(settings, false).unwrap();
            for w in &y {
                p.step(w.map(|x| x as f32), [0.0; 3], [0.0; 3], 1e-3);
            }
            p.end_stretch();
            let (_, r) = p.estimate_and_ratios();
            tensor_source += u64::from(r.source == RatioSource::Tensor);
            let (Some(a), Some(s)) = (r.a, r.std_a) else {
                continue;
            };
            let z = (0..3)
                .map(|i| ((f64::from(a[i]) - a_true[i]) / f64::from(s[i])).abs())
                .fold(0.0, f64::max);
            worst = worst.max(z);
            assert!(
                !(r.status == Status::Converged && z > 4.0),
                "angle {angle} rad, seed {seed}: Converged with |error| {z:.1} std ({:?})",
                r.source
            );
        }
        println!(
            "sensor turned {angle} rad: worst |error / std| {worst:.1}, products found on {tensor_source} of {SEEDS}"
        );
        // Aligned: the principal-axis fit on every seed; from 0.3 deg on, the products on every
        // seed (the output-error fit's Wald test at 0.01 % sees them; 9 of 12 from 0.02 deg).
        if angle == 0.0 {
            assert_eq!(tensor_source, 0);
        }
        if angle >= 0.005 {
            assert_eq!(tensor_source, SEEDS, "angle {angle}");
        }
    }
}
