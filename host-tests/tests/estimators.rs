//! The peers, the refined identifier and the Cramer-Rao bound on easy cases: every method
//! converges on noise-free data, the bound matches the planning figure, the output-error fit
//! sits on the bound, and the refined identifier is near it.

use host_tests::crb;
use host_tests::estimators::{all_methods, ml, onboard, Method, Scenario};
use identifier_core::{Refined, RefinedSettings, SampleStatus};

fn scenario(name: &str) -> Scenario {
    Scenario::all()
        .into_iter()
        .find(|s| s.name == name)
        .expect("scenario exists")
}

/// The paper's scenario shortened to `secs`.
fn paper(secs: f64) -> Scenario {
    let mut s = scenario("paper");
    s.duration = secs;
    s
}

fn rms_ratio(m: &dyn Method, sc: &Scenario, seeds: u64) -> [f64; 3] {
    let truth = sc.truth();
    let a = sc.a();
    let n = truth.0.len();
    let bound = crb::bound(a, sc.omega0, n, sc.rate_hz, sc.sigma);
    let mut sq = [0.0; 3];
    for seed in 0..seeds {
        let y = sc.measure(&truth, 500 + seed);
        let e = m.estimate(&truth.0, &y);
        for i in 0..3 {
            sq[i] += (e[i] - a[i]).powi(2);
        }
    }
    std::array::from_fn(|i| (sq[i] / seeds as f64).sqrt() / bound[i])
}

#[test]
fn crb_matches_the_planning_figure() {
    let sc = scenario("paper");
    let n = sc.truth().0.len();
    let b = crb::bound(sc.a(), sc.omega0, n, sc.rate_hz, sc.sigma);
    let expect = [2.4e-5, 3.3e-5, 2.4e-5];
    for i in 0..3 {
        assert!(
            (b[i] / expect[i] - 1.0).abs() < 0.05,
            "bound {b:?} vs planning {expect:?}"
        );
    }
    // More data, tighter bound; more noise, proportionally looser.
    let half = crb::bound(sc.a(), sc.omega0, n / 2, sc.rate_hz, sc.sigma);
    let loud = crb::bound(sc.a(), sc.omega0, n, sc.rate_hz, 2.0 * sc.sigma);
    for i in 0..3 {
        assert!(half[i] > 1.2 * b[i]);
        assert!((loud[i] / b[i] - 2.0).abs() < 1e-9);
    }
}

#[test]
fn every_method_converges_on_noise_free_data() {
    for sc in [paper(10.0), scenario("toss")] {
        let (t, w) = sc.truth();
        let a = sc.a();
        for m in all_methods() {
            let est = m.estimate(&t, &w);
            let err = (0..3).map(|i| (est[i] - a[i]).abs()).fold(0.0, f64::max);
            // The paper's identifier cannot settle in a 0.85 s toss: it only has to on the
            // long run. Everything else must land close on both.
            let tol = match (m.name(), sc.name) {
                (n, "toss") if n.starts_with("paper") => continue,
                (n, _) if n.starts_with("output-error") => 1e-6,
                (n, _) if n.starts_with("refined") => 2e-4,
                (n, _) if n.starts_with("paper") => 1e-4,
                _ => 3e-3,
            };
            assert!(
                err < tol,
                "{} on {}: estimate {est:?}, truth {a:?}, error {err:e}",
                m.name(),
                sc.name
            );
        }
    }
}

#[test]
fn output_error_fit_sits_on_the_bound() {
    // 20 seeds: the RMS error's own scatter is about 16 %, so 2x is a loose but failing bound.
    let sc = scenario("toss");
    let r = rms_ratio(&ml::Ml, &sc, 20);
    assert!(r.iter().all(|x| *x < 2.0 && *x > 0.5), "ML / CRB = {r:?}");
    let sc = paper(5.0);
    let r = rms_ratio(&ml::Ml, &sc, 20);
    assert!(r.iter().all(|x| *x < 2.0 && *x > 0.5), "ML / CRB = {r:?}");
}

#[test]
fn refined_identifier_is_near_the_bound() {
    let sc = paper(5.0);
    let r = rms_ratio(&onboard::RefinedMethod::default(), &sc, 20);
    assert!(r.iter().all(|x| *x < 2.0), "refined / CRB = {r:?}");
    let paper_id = rms_ratio(&onboard::Paper::default(), &sc, 5);
    assert!(
        paper_id.iter().all(|x| *x > 5.0),
        "the paper's identifier was expected far above the bound: {paper_id:?}"
    );
}

#[test]
fn refined_combines_tosses_and_reports_its_uncertainty() {
    let sc = scenario("toss");
    let truth = sc.truth();
    let a = sc.a();
    let mut id = Refined::new(RefinedSettings::for_rate(
        sc.rate_hz as f32,
        sc.sigma as f32,
    ))
    .expect("valid settings");
    let mut stds = Vec::new();
    for toss in 0..4 {
        let y = sc.measure(&truth, 900 + toss);
        for (k, w) in y.iter().enumerate() {
            let st = id.step(w.map(|x| x as f32), 0.01).status;
            if k == 0 {
                assert_eq!(st, SampleStatus::Anchored);
            }
        }
        id.restart();
        stds.push(id.std_per_sigma());
    }
    // Information adds up across tosses: four tosses halve the standard deviation.
    for i in 0..3 {
        let ratio = stds[3][i] / stds[0][i];
        assert!((ratio - 0.5).abs() < 0.1, "std ratio {ratio} ({stds:?})");
    }
    let est = id.estimate();
    for i in 0..3 {
        let sd = f64::from(stds[3][i]) * sc.sigma;
        assert!(
            (f64::from(est[i]) - a[i]).abs() < 4.0 * sd,
            "combined {est:?} vs {a:?}, std {sd:e}"
        );
    }
}

#[test]
fn refined_keeps_its_accuracy_over_a_long_run_in_f32() {
    // 100 s at 1 kHz: the information keeps growing and f32 must keep up.
    let mut sc = scenario("paper");
    sc.duration = 100.0;
    let r = rms_ratio(&onboard::RefinedMethod::default(), &sc, 12);
    let ekf = rms_ratio(&host_tests::estimators::ekf::Ekf, &sc, 12);
    eprintln!("refined / CRB {r:?}, EKF / CRB {ekf:?}");
    assert!(r.iter().all(|x| *x < 2.0), "refined / CRB = {r:?}");
}
