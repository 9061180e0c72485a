//! Refined's reported standard deviation uses the noise seen in its own residuals: it must be
//! honest (RMS of error / std near 1) even when the configured `noise_std` is wrong.
use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use identifier_core::{Refined, RefinedSettings};

fn calibration(noise: f64, configured: f32, rate: f64, secs: f64, w0: [f64; 3]) -> ([f64; 3], f64) {
    let body = Body::free([0.6, 1.54, 1.0]);
    let truth = body.a();
    let tr = body.simulate(w0, secs, rate, 8);
    let mut z2 = [0.0f64; 3];
    let mut sig = 0.0;
    let seeds = 40;
    for seed in 0..seeds {
        let meas = GyroModel::noisy(noise, seed).measure(&tr);
        let mut r = Refined::new(RefinedSettings::for_rate(rate as f32, configured)).unwrap();
        for w in &meas {
            r.step(w.map(|x| x as f32), (1.0 / rate) as f32);
        }
        r.restart();
        let a = r.block_estimate();
        let s = r.std_a();
        for i in 0..3 {
            z2[i] += ((a[i] as f64 - truth[i]) / s[i] as f64).powi(2);
        }
        sig += r.noise_estimate().unwrap() as f64;
    }
    (z2.map(|x| (x / seeds as f64).sqrt()), sig / seeds as f64)
}

#[test]
fn reported_std_is_honest_with_a_wrong_configured_noise() {
    for (noise, configured, rate, secs, w0) in [
        (2e-3, 2e-3, 1000.0, 20.0, [1.0, 1.0, 1.0]),
        (2e-3, 2e-2, 1000.0, 20.0, [1.0, 1.0, 1.0]),
        (2e-3, 2e-4, 1000.0, 20.0, [1.0, 1.0, 1.0]),
        (1.5e-2, 2e-3, 100.0, 0.85, [3.0, 8.0, 4.0]),
    ] {
        let (cal, sig) = calibration(noise, configured, rate, secs, w0);
        println!("noise {noise:e}, configured {configured:e}, {rate} Hz {secs} s: RMS(err/std) {cal:.2?}, noise seen {sig:.3e}");
        assert!(
            (sig / noise - 1.0).abs() < 0.2,
            "noise estimate {sig} vs {noise}"
        );
        for c in cal {
            assert!(c > 0.6 && c < 1.6, "calibration {c}");
        }
    }
}
