//! Issue 10, item 1: a trust status from information on every estimator of the core. A still
//! gyro, deg/s data, a `dt` 10x too small and a gyro saturating every axis must never be
//! `Converged`, each with the status that says why; clean informative data must be.

use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use identifier_core::{
    ExtendedIdentifier, ExtendedSettings, Identifier, Refined, RefinedSettings, Settings, Status,
};

const RATE: f64 = 1000.0;
const DT: f32 = 1e-3;
const NOISE: f64 = 1e-3;

/// The trust after each sample, for each estimator.
struct Trail {
    paper: Vec<Status>,
    refined: Vec<Status>,
    extended: Vec<Status>,
}

impl Trail {
    fn never_converged(&self, what: &str) {
        for (name, t) in [
            ("paper", &self.paper),
            ("refined", &self.refined),
            ("extended", &self.extended),
        ] {
            assert!(
                !t.contains(&Status::Converged),
                "{what}: {name} was Converged at sample {:?}",
                t.iter().position(|x| *x == Status::Converged)
            );
        }
    }

    fn last(&self) -> [Status; 3] {
        [
            *self.paper.last().unwrap(),
            *self.refined.last().unwrap(),
            *self.extended.last().unwrap(),
        ]
    }
}

fn run(samples: &[[f64; 3]], dt: f32, full_scale: f32) -> Trail {
    let mut paper = Identifier::new(Settings {
        full_scale,
        ..Settings::with_lambda(3.0)
    })
    .unwrap();
    let mut refined = Refined::new(RefinedSettings {
        full_scale,
        ..RefinedSettings::for_rate(RATE as f32, NOISE as f32)
    })
    .unwrap();
    let mut es = ExtendedSettings::new([None, None]);
    es.noise_std = NOISE as f32;
    es.full_scale = full_scale;
    let mut extended = ExtendedIdentifier::new(es).unwrap();
    // 32 sample intervals per update, as for the refined identifier's blocks.
    assert!(extended.set_block_pairs(16));
    let mut trail = Trail {
        paper: Vec::new(),
        refined: Vec::new(),
        extended: Vec::new(),
    };
    for w in samples {
        let w = w.map(|x| x as f32);
        let p = paper.step(w, dt);
        let r = refined.step(w, dt);
        let e = extended.step(w, dt);
        if !p.trust.has_information() {
            assert!(p.ratios().is_none());
        }
        if !r.trust.has_information() {
            assert!(r.ratios().is_none());
        }
        if !e.trust.has_information() {
            assert!(e.ratios().is_none());
        }
        trail.paper.push(p.trust);
        trail.refined.push(r.trust);
        trail.extended.push(e.trust);
    }
    trail
}

/// A fast tumble (`a = (0.3, -0.2, ...)`, rates up to 3 rad/s), 1 kHz, 20 s.
fn tumble(model: GyroModel) -> Vec<[f64; 3]> {
    let tr = Body::free([0.8, 1.3, 1.0]).simulate([3.0, -2.0, 2.5], 20.0, RATE, 4);
    model.measure(&tr)
}

#[test]
fn informative_data_converges_and_none_before_data() {
    let fresh = Refined::new(RefinedSettings::for_rate(1000.0, 1e-3)).unwrap();
    assert_eq!(fresh.trust(), Status::NoInformation);
    let p = Identifier::new(Settings::default()).unwrap();
    assert_eq!(p.trust(), Status::NoInformation);
    let noisy = run(&tumble(GyroModel::noisy(NOISE, 1)), DT, f32::INFINITY);
    let last = noisy.last();
    println!("noisy tumble: final trust {last:?}");
    assert_eq!(last[1], Status::Converged, "refined");
    assert_eq!(last[2], Status::Converged, "extended");
    // The paper's identifier never meets eps = 1e-3 on noisy data; on clean data it does.
    let clean = run(&tumble(GyroModel::ideal()), DT, f32::INFINITY);
    println!("clean tumble: final trust {:?}", clean.last());
    assert_eq!(clean.last(), [Status::Converged; 3]);
    // The first samples are never trusted.
    for t in [&clean.paper, &clean.refined, &clean.extended] {
        assert_eq!(t[0], Status::TooFewSamples);
    }
}

#[test]
fn still_gyro_is_no_excitation() {
    let tr = Body::free([0.8, 1.3, 1.0]).simulate([0.0; 3], 20.0, RATE, 1);
    let trail = run(&GyroModel::noisy(NOISE, 2).measure(&tr), DT, f32::INFINITY);
    println!("still: {:?}", trail.last());
    trail.never_converged("still gyro");
    assert_eq!(trail.last(), [Status::NoExcitation; 3]);
    // A still gyro with a bias is no better.
    let biased = GyroModel {
        bias: [0.01, -0.02, 0.015],
        ..GyroModel::noisy(NOISE, 3)
    };
    let trail = run(&biased.measure(&tr), DT, f32::INFINITY);
    println!("still with bias: {:?}", trail.last());
    trail.never_converged("still biased gyro");
    assert_eq!(trail.last(), [Status::NoExcitation; 3]);
}

#[test]
fn degrees_per_second_look_wrong() {
    let deg = tumble(GyroModel::noisy(NOISE, 4))
        .iter()
        .map(|w| w.map(|x| x * 57.3))
        .collect::<Vec<_>>();
    let trail = run(&deg, DT, f32::INFINITY);
    println!("deg/s: {:?}", trail.last());
    trail.never_converged("deg/s");
    assert_eq!(trail.last(), [Status::UnitsLookWrong; 3]);
    // A slow body in deg/s stays below the plausible rate: the consistency value catches it.
    let slow = Body::free([0.6, 1.54, 1.0]).simulate([0.3, 0.3, 0.3], 20.0, RATE, 4);
    let deg = GyroModel::noisy(NOISE, 5)
        .measure(&slow)
        .iter()
        .map(|w| w.map(|x| x * 57.3))
        .collect::<Vec<_>>();
    let trail = run(&deg, DT, f32::INFINITY);
    println!("slow body in deg/s: {:?}", trail.last());
    trail.never_converged("slow deg/s");
}

#[test]
fn dt_ten_times_too_small_is_physically_impossible() {
    let trail = run(
        &tumble(GyroModel::noisy(NOISE, 6)),
        DT / 10.0,
        f32::INFINITY,
    );
    println!("dt/10: {:?}", trail.last());
    trail.never_converged("dt / 10");
    let last = trail.last();
    assert_eq!(last[1], Status::PhysicallyImpossible, "refined");
    assert_eq!(last[2], Status::PhysicallyImpossible, "extended");
    assert!(
        matches!(last[0], Status::PhysicallyImpossible | Status::Converging),
        "paper {:?}",
        last[0]
    );
}

#[test]
fn saturating_every_axis_is_saturated() {
    // Full scale at 2 rad/s: the tumble (peaks 3.0, 2.6, 2.9 rad/s) clips every axis.
    let fs = 2.0;
    let model = GyroModel {
        full_scale: fs,
        ..GyroModel::noisy(NOISE, 7)
    };
    let y = tumble(model);
    for i in 0..3 {
        assert!(y.iter().any(|w| w[i].abs() >= fs), "axis {i} clips");
    }
    let trail = run(&y, DT, fs as f32);
    println!("saturated: {:?}", trail.last());
    trail.never_converged("saturated");
    assert_eq!(trail.last(), [Status::Saturated; 3]);
}
