//! `Pipeline::close_stretch` and `Pipeline::adopt_fits`: the fits of a stretch run on a copy
//! while the pipeline goes on taking samples give the same bits as the fits run in place.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use identifier_core::{FlightPipeline, PipelineSettings};

/// A torque-free tumble of a body with moments (2, 3, 4.5)e-4 kg m^2 (RK4 in f64, 10 substeps
/// per sample) at 100 Hz, with a small deterministic noise.
fn tumble(n: usize, w0: [f64; 3]) -> Vec<[f32; 3]> {
    let j = [2e-4f64, 3e-4, 4.5e-4];
    let f = |w: [f64; 3]| {
        [
            (j[1] - j[2]) / j[0] * w[1] * w[2],
            (j[2] - j[0]) / j[1] * w[2] * w[0],
            (j[0] - j[1]) / j[2] * w[0] * w[1],
        ]
    };
    let mut w = w0;
    let h = 1e-3;
    let mut seed = 12345u32;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let mut y = [0.0f32; 3];
        for (k, v) in y.iter_mut().enumerate() {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let u = (seed >> 8) as f64 / (1u32 << 24) as f64 - 0.5;
            *v = (w[k] + 2e-3 * u) as f32;
        }
        out.push(y);
        for _ in 0..10 {
            let k1 = f(w);
            let a = |x: [f64; 3], k: [f64; 3], s: f64| {
                [x[0] + s * k[0], x[1] + s * k[1], x[2] + s * k[2]]
            };
            let k2 = f(a(w, k1, h / 2.0));
            let k3 = f(a(w, k2, h / 2.0));
            let k4 = f(a(w, k3, h));
            for i in 0..3 {
                w[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
    }
    out
}

fn pipeline() -> FlightPipeline {
    FlightPipeline::new(PipelineSettings::for_rate(100.0, 1e-3), false).unwrap()
}

#[test]
fn fits_run_on_a_copy_and_adopted_equal_fits_run_in_place() {
    let first = tumble(1500, [2.0, -1.5, 1.0]);
    let second = tumble(1200, [-1.0, 2.5, 0.5]);
    let (mut inline, mut live) = (pipeline(), pipeline());
    for w in &first {
        inline.step(*w, [0.0; 3], [0.0; 3], 0.01);
        live.step(*w, [0.0; 3], [0.0; 3], 0.01);
    }
    inline.end_stretch();
    live.close_stretch();
    assert!(live.fits_pending() && !inline.fits_pending());
    // The copy's fits run elsewhere; a copy whose fits have not run is refused.
    let mut copy = live;
    assert!(!live.adopt_fits(&copy));
    copy.fit_ended_flight();
    assert!(live.adopt_fits(&copy));
    assert!(!live.fits_pending());
    // Adopted once only.
    assert!(!live.adopt_fits(&copy));
    assert_eq!(live.estimate(), inline.estimate());
    assert!(live.estimate().a.is_some());
    // The next stretch and its end: still the same bits.
    for w in &second {
        inline.step(*w, [0.0; 3], [0.0; 3], 0.01);
        live.step(*w, [0.0; 3], [0.0; 3], 0.01);
    }
    inline.end_stretch();
    live.end_stretch();
    assert_eq!(live.estimate(), inline.estimate());
    assert_eq!(live.ratios(), inline.ratios());
    assert_eq!(live.throws(), 2);
}

#[test]
fn a_copy_of_an_older_flight_is_refused() {
    let first = tumble(800, [2.0, -1.5, 1.0]);
    let mut live = pipeline();
    for w in &first {
        live.step(*w, [0.0; 3], [0.0; 3], 0.01);
    }
    live.close_stretch();
    let mut copy = live;
    copy.fit_ended_flight();
    // A new stretch begins before the copy is adopted: the live pipeline ran the fits itself
    // (its first fed sample does), and the copy no longer matches.
    for w in &first[..10] {
        live.step(*w, [0.0; 3], [0.0; 3], 0.01);
    }
    assert!(!live.fits_pending());
    live.close_stretch();
    assert!(live.fits_pending());
    assert!(!live.adopt_fits(&copy));
    assert!(live.fits_pending());
}
