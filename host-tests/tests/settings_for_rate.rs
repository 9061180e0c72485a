//! Issue 11: settings from the sample rate alone (`RefinedSettings::for_rate`,
//! `PipelineSettings::for_rate`), and the noise-free bias they leave from 100 Hz to 8 kHz, for
//! the recommended ratios (the pipeline's, from the trajectory fit once the record ends), the
//! refined and the paper identifier.

use host_tests::rigid_body::Body;
use identifier_core::{
    FlightPipeline, Identifier, PipelineSettings, RatioSource, Refined, RefinedSettings, Settings,
};

const RATES: [f64; 6] = [100.0, 200.0, 400.0, 1000.0, 4000.0, 8000.0];

struct Case {
    name: &'static str,
    inertia: [f64; 3],
    omega0: [f64; 3],
    duration: f64,
}

fn cases() -> [Case; 3] {
    [
        Case {
            name: "paper body",
            inertia: [0.6, 1.54, 1.0],
            omega0: [1.0, 1.0, 1.0],
            duration: 20.0,
        },
        Case {
            name: "fast tumble",
            inertia: [0.8, 1.3, 1.0],
            omega0: [3.0, -2.0, 2.5],
            duration: 20.0,
        },
        Case {
            name: "toss (racquet-like)",
            inertia: [12.3, 1.0, 13.3],
            omega0: [7.9, -1.8, 0.5],
            duration: 0.85,
        },
    ]
}

/// Noise-free samples of `case` at `rate` (f64 RK4 with enough substeps to be exact in f32).
fn samples(case: &Case, rate: f64) -> (Vec<[f32; 3]>, f32) {
    let sub = ((4000.0 / rate).ceil() as usize).max(2);
    let tr = Body::free(case.inertia).simulate(case.omega0, case.duration, rate, sub);
    let w = tr.omega.iter().map(|w| w.map(|x| x as f32)).collect();
    (w, (1.0 / rate) as f32)
}

fn max_err(est: [f32; 3], a: [f64; 3]) -> f64 {
    (0..3)
        .map(|i| (f64::from(est[i]) - a[i]).abs())
        .fold(0.0, f64::max)
}

/// Largest noise-free error of the refined identifier with `for_rate` over the cases, per rate.
fn refined_bias(rate: f64) -> f64 {
    cases()
        .iter()
        .map(|c| {
            let (w, dt) = samples(c, rate);
            let mut id = Refined::new(RefinedSettings::for_rate(rate as f32, 1e-3)).unwrap();
            for x in &w {
                id.step(*x, dt);
            }
            let e = max_err(id.estimate(), Body::free(c.inertia).a());
            println!("  refined  {:>6} Hz {:<20} |err| {e:.2e}", rate, c.name);
            e
        })
        .fold(0.0, f64::max)
}

/// The bodies of `tests/identifier.rs` (40 s each): principal axes, plates, a racquet, a
/// near-symmetric body, a fast tumble.
const PAPER_CASES: [([f64; 3], [f64; 3]); 9] = [
    ([0.6, 1.54, 1.0], [1.0, 1.0, 1.0]),
    ([0.6, 1.54, 1.0], [1.0, -1.0, 1.0]),
    ([1.0, 2.0, 3.0], [3.0, 0.6, 0.5]),
    ([1.0, 2.0, 3.0], [0.5, 0.6, 3.0]),
    ([1.0, 2.0, 3.0], [0.3, 3.0, 0.3]),
    ([1.0, 1.9, 2.9], [-1.2, 0.8, 1.1]),
    ([18.8, 1.39, 20.7], [2.0, 0.5, -1.5]),
    ([1.0, 1.1, 1.6], [1.5, 1.2, 1.0]),
    ([0.8, 1.3, 1.0], [3.0, -2.0, 2.5]),
];

/// Largest noise-free error of the paper's identifier (lambda = 3) over the last 5 s of the
/// 40 s runs of [`PAPER_CASES`] at `rate`.
fn paper_bias(rate: f64) -> f64 {
    PAPER_CASES
        .iter()
        .map(|(inertia, omega0)| {
            let c = Case {
                name: "",
                inertia: *inertia,
                omega0: *omega0,
                duration: 40.0,
            };
            let (w, dt) = samples(&c, rate);
            let a = Body::free(c.inertia).a();
            let mut id = Identifier::new(Settings::with_lambda(3.0)).unwrap();
            let tail = w.len() - (5.0 * rate) as usize;
            let mut e = 0.0f64;
            for (k, x) in w.iter().enumerate() {
                let est = id.step(*x, dt).a;
                if k >= tail {
                    e = e.max(max_err(est, a));
                }
            }
            println!(
                "  paper    {:>6} Hz {inertia:?} {omega0:?} |err| {e:.2e}",
                rate
            );
            e
        })
        .fold(0.0, f64::max)
}

/// Largest noise-free error of the pipeline's recommended ratios over the cases, per rate (no
/// accelerometer: the whole record is the free flight, ended at its end).
fn pipeline_bias(rate: f64) -> f64 {
    cases()
        .iter()
        .map(|c| {
            let (w, dt) = samples(c, rate);
            let settings = PipelineSettings::for_rate(rate as f32, 1e-3);
            let mut p = FlightPipeline::new(settings, false).unwrap();
            for x in &w {
                p.step(*x, [0.0; 3], [0.0; 3], dt);
            }
            p.end_stretch();
            let r = p.ratios();
            assert_eq!(r.source, RatioSource::Trajectory, "{rate} Hz {}", c.name);
            let e = max_err(r.a.unwrap(), Body::free(c.inertia).a());
            println!("  pipeline {:>6} Hz {:<20} |err| {e:.2e}", rate, c.name);
            e
        })
        .fold(0.0, f64::max)
}

#[test]
fn pipeline_ratios_noise_free_bias() {
    let mut worst = 0.0f64;
    for rate in RATES {
        let b = pipeline_bias(rate);
        println!("pipeline ratios at {rate} Hz: noise-free bias {b:.2e}");
        worst = worst.max(b);
    }
    assert!(worst < 1e-5, "worst noise-free bias {worst:.2e}");
}

#[test]
fn for_rate_noise_free_bias() {
    let mut worst = 0.0f64;
    for rate in RATES {
        let b = refined_bias(rate);
        println!("refined for_rate({rate}) noise-free bias {b:.2e}");
        worst = worst.max(b);
    }
    assert!(worst < 1e-5, "worst noise-free bias {worst:.2e}");
}

#[test]
fn paper_identifier_noise_free_bias() {
    for rate in RATES {
        let b = paper_bias(rate);
        println!("paper identifier at {rate} Hz: noise-free bias {b:.2e}");
        // Issue 11: below 1e-4 at 100 Hz, which takes the end-corrected trapezoid and the cubic
        // sign-change crossing on the racquet-like body. Above 1 kHz the f32
        // rounding of the many small increments dominates (1.8e-4 at 8 kHz), not asserted.
        if rate <= 1000.0 {
            assert!(b < 1e-4, "{rate} Hz: {b:.2e}");
        }
    }
}

#[test]
fn for_rate_has_no_edge_and_is_usable() {
    let mut last = 8u16;
    for hz in (50..=9000).step_by(10) {
        let s = RefinedSettings::for_rate(hz as f32, 1e-3);
        assert!(s.is_valid(), "{hz}: {s:?}");
        assert!(s.end_correction);
        assert!(
            s.block >= last && s.block - last <= 1,
            "{hz}: {} after {last}",
            s.block
        );
        last = s.block;
    }
    assert_eq!(RefinedSettings::for_rate(1000.0, 1e-3).block, 32);
    assert_eq!(RefinedSettings::for_rate(100.0, 1e-3).block, 8);
    assert_eq!(RefinedSettings::for_rate(8000.0, 1e-3).block, 256);
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(!RefinedSettings::for_rate(bad, 1e-3).is_valid(), "{bad}");
        assert!(!RefinedSettings::for_rate(1000.0, bad).is_valid(), "{bad}");
    }
}
