//! A constant gyro bias in a gyro-only log (no accelerometer, so no still period to learn it
//! from): the pipeline's ratios come from the trajectory fit, which switches to its bias model
//! when the likelihood-ratio test finds a bias, and the reported standard deviation stays
//! honest; without a bias the plain model is kept.
use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use identifier_core::{FlightPipeline, PipelineSettings, RatioSource, Status};

fn run(bias: f64, seeds: u64) -> ([f64; 3], [f64; 3], usize) {
    let body = Body::free([0.6, 1.54, 1.0]);
    let truth = body.a();
    let tr = body.simulate([1.0, 1.0, 1.0], 20.0, 1000.0, 8);
    let mut e2 = [0.0f64; 3];
    let mut z2 = [0.0f64; 3];
    let mut chose_bias = 0;
    for seed in 0..seeds {
        let meas = GyroModel::noisy(2e-3, seed).measure(&tr);
        let mut p = FlightPipeline::new(PipelineSettings::for_rate(1000.0, 2e-3), false).unwrap();
        for w in &meas {
            let w = [w[0] + bias, w[1] - bias, w[2] + 0.5 * bias].map(|v| v as f32);
            p.step(w, [0.0; 3], [0.0; 3], 1e-3);
        }
        p.end_stretch();
        let r = p.ratios();
        assert_eq!(r.source, RatioSource::Trajectory);
        // The fit with the bias explains the data; the tensor estimator (no bias model) taking
        // the bias for products of inertia is no reason to distrust it.
        assert_eq!(r.status, Status::Converged, "bias {bias} seed {seed}");
        if p.trajectory().estimate().is_some_and(|e| e.biased) {
            chose_bias += 1;
        }
        let (a, s) = (r.a.unwrap(), r.std_a.unwrap());
        for i in 0..3 {
            let e = a[i] as f64 - truth[i];
            e2[i] += e * e;
            z2[i] += (e / s[i] as f64).powi(2);
        }
    }
    let n = seeds as f64;
    (
        e2.map(|x| (x / n).sqrt() * 1e4),
        z2.map(|x| (x / n).sqrt()),
        chose_bias,
    )
}

#[test]
fn gyro_bias_is_detected_and_the_std_stays_honest() {
    for bias in [0.0, 0.001, 0.002, 0.01, 0.03] {
        let (rms, cal, chose) = run(bias, 20);
        println!("bias {bias}: chose the bias model in {chose}/20, RMS x1e4 {rms:.2?}, RMS(err/std) {cal:.2?}");
        for c in cal {
            assert!(c < 2.0, "bias {bias}: calibration {c}");
        }
        if bias == 0.0 {
            assert!(
                chose <= 1,
                "no bias, yet the bias model was chosen {chose} times"
            );
        }
        if bias >= 0.01 {
            assert_eq!(chose, 20);
        }
    }
}

/// During a gyro-only flight with a bias, before the end-of-flight fits, the tensor is the equation
/// error's, which has no bias model and takes the bias for products of inertia: it could say
/// `Converged` with products on a body that has none. It must be `ModelMismatch` once the bias test
/// of the ratios finds the bias (`RefinedBias`); without a bias `Converging` (no bias was measured,
/// so none can be ruled out yet); and after the flight's fits (bias modelled) `Converged`.
#[test]
fn a_bias_detected_in_flight_keeps_the_tensor_from_converging() {
    let body = Body::free([0.6, 1.54, 1.0]);
    let tr = body.simulate([1.0, 1.0, 1.0], 20.0, 1000.0, 8);
    for bias in [0.0, 0.002, 0.01] {
        for seed in 0..4 {
            let meas = GyroModel::noisy(2e-3, seed).measure(&tr);
            // One window for the whole 20 s flight (W1, already so without rotor momentum):
            // the fits run at its end only.
            let settings = PipelineSettings {
                window_turn_rad: f32::INFINITY,
                ..PipelineSettings::for_rate(1000.0, 2e-3)
            };
            let mut p = FlightPipeline::new(settings, false).unwrap();
            for w in &meas {
                let w = [w[0] + bias, w[1] - bias, w[2] + 0.5 * bias].map(|v| v as f32);
                p.step(w, [0.0; 3], [0.0; 3], 1e-3);
            }
            let (t, r) = p.estimate_and_ratios();
            println!(
                "bias {bias} seed {seed}: in flight tensor {:?} ({:?}), ratios {:?} from {:?}",
                t.status, t.model, r.status, r.source
            );
            if bias == 0.0 {
                // No bias measured on a still stretch (there is none): the equation error,
                // which cannot tell a bias, is at most `Converging` until the end-of-flight
                // fits (test `online_gyro_bias`).
                assert_eq!(t.status, Status::Converging, "seed {seed}");
            } else {
                assert_eq!(
                    r.source,
                    RatioSource::RefinedBias,
                    "bias {bias} seed {seed}"
                );
                assert_eq!(t.status, Status::ModelMismatch, "bias {bias} seed {seed}");
                // The equation error's standard deviations do not count the bias.
                assert!(!t.usable(), "bias {bias} seed {seed}");
            }
            p.end_stretch();
            assert_eq!(
                p.estimate().status,
                Status::Converged,
                "bias {bias} seed {seed}"
            );
        }
    }
}
