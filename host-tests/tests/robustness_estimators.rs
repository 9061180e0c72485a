//! The same reliability properties as `robustness.rs`, for the core's two other on-board
//! estimators: [`Refined`] (per-axis Kalman filter on the integrated (1)) and
//! [`ExtendedIdentifier`] (RLS on `a` plus effect parameters). Over random and adversarial
//! sequences and any valid settings: a defined status for every input, the refusal rules of
//! `SampleStatus` / `ExtendedStatus`, a finite state, counters add up, and refused samples
//! leave no trace: a run with them is bit-identical to a run where each sample refused for its
//! value is left out (its `dt` carried to the next sample) and each invalid `dt` is replaced by
//! `restart()`. ([`Refined`] folds its open block in at a restart, so an invalid `dt` may move
//! its estimate, by earlier good data only; the differential property covers exactly that.)

use host_tests::rigid_body::Body;
use identifier_core::{
    ExtendedIdentifier, ExtendedSettings, ExtendedStatus, ExtraEffect, Refined, RefinedSettings,
    SampleStatus,
};
use proptest::prelude::*;
use proptest::test_runner::Config;

const FS: f32 = 34.906_586; // 2000 deg/s

fn clean(seconds: f64, rate: f64) -> Vec<[f32; 3]> {
    Body::free([0.6, 1.54, 1.0])
        .simulate([1.0, 1.0, 1.0], seconds, rate, 4)
        .omega
        .iter()
        .map(|w| w.map(|x| x as f32))
        .collect()
}

fn component() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => -40.0f32..40.0,
        2 => -1e-3f32..1e-3,
        1 => any::<f32>(),
        1 => prop_oneof![
            Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY), Just(f32::MAX),
            Just(-f32::MAX), Just(1e20f32), Just(-3e19f32), Just(1e-40f32), Just(0.0f32),
            Just(FS), Just(-FS),
        ],
    ]
}

fn time_step() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => 2e-4f32..3e-2,
        1 => 0.05f32..5.0,
        1 => any::<f32>(),
        1 => prop_oneof![
            Just(0.0f32), Just(-0.0f32), Just(-1e-3f32), Just(f32::NAN), Just(f32::INFINITY),
            Just(f32::NEG_INFINITY), Just(1e30f32), Just(f32::MAX), Just(1e-40f32),
        ],
    ]
}

fn samples(max: usize) -> impl Strategy<Value = Vec<([f32; 3], f32)>> {
    prop::collection::vec(
        ([component(), component(), component()], time_step()),
        0..max,
    )
}

/// What must be refused, in the documented order; `None` if the sample may go further.
fn refusal(omega: [f32; 3], dt: f32, full_scale: f32) -> Option<SampleStatus> {
    if !(dt.is_finite() && dt > 0.0) {
        Some(SampleStatus::InvalidTimeStep)
    } else if omega.iter().any(|w| !w.is_finite()) {
        Some(SampleStatus::NonFinite)
    } else if omega.iter().any(|w| w.abs() >= full_scale) {
        Some(SampleStatus::Saturated)
    } else {
        None
    }
}

fn refined_settings() -> impl Strategy<Value = RefinedSettings> {
    (
        prop_oneof![Just(2e-3f32), 1e-6f32..1.0],
        prop_oneof![Just(1.0f32), 1e-3f32..100.0],
        prop_oneof![Just(f32::INFINITY), Just(FS), 1e-3f32..100.0],
        prop_oneof![Just(0.1f32), 1e-6f32..10.0, Just(f32::MAX)],
        prop_oneof![Just(1e-3f32), 1e-6f32..1.0],
        prop_oneof![Just(1.0f32), 1e-3f32..10.0],
        [-1e3f32..1e3, -1e3f32..1e3, -1e3f32..1e3],
        (
            prop_oneof![Just(1u16), Just(32u16), 1u16..=1024],
            any::<bool>(),
        ),
    )
        .prop_map(
            |(noise_std, prior_std, full_scale, max_dt, eps, h, a0, (block, end_correction))| {
                let mut s = RefinedSettings::new();
                s.block = block;
                s.end_correction = end_correction;
                s.noise_std = noise_std;
                s.prior_std = prior_std;
                s.full_scale = full_scale;
                s.max_dt = max_dt;
                s.eps = eps;
                s.h = h;
                s.initial_estimate = a0;
                s
            },
        )
}

fn effect() -> impl Strategy<Value = Option<ExtraEffect>> {
    prop_oneof![
        Just(None),
        Just(Some(ExtraEffect::GyroBias)),
        Just(Some(ExtraEffect::BodyTorque)),
        Just(Some(ExtraEffect::Damping)),
        Just(Some(ExtraEffect::ProductsOfInertia)),
        Just(Some(ExtraEffect::RotorMomentum)),
    ]
}

fn extended_settings() -> impl Strategy<Value = ExtendedSettings> {
    (
        [effect(), effect()],
        any::<bool>(),
        [-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0],
        prop_oneof![Just(10.0f32), 1e-3f32..1e3],
        prop_oneof![Just(10.0f32), 1e-3f32..1e3],
        prop_oneof![Just(0.01f32), 1e-6f32..1.0],
        prop_oneof![Just(f32::INFINITY), Just(FS), 1e-3f32..100.0],
        prop_oneof![Just(0.05f32), 1e-6f32..10.0, Just(f32::MAX)],
    )
        .prop_map(|(effects, sc, a0, pa, pe, ns, fs, md)| {
            // Field by field, so that fields added later keep their defaults.
            let mut s = ExtendedSettings::new(effects);
            s.scale_correction = sc;
            s.initial_estimate = a0;
            s.prior_a = pa;
            s.prior_effect = pe;
            s.noise_std = ns;
            s.full_scale = fs;
            s.max_dt = md;
            s
        })
        .prop_filter("valid", ExtendedSettings::is_valid)
}

/// Steps a [`Refined`] and checks every invariant.
fn refined_step(
    r: &mut Refined,
    omega: [f32; 3],
    dt: f32,
    anchored: &mut u32,
) -> Result<SampleStatus, TestCaseError> {
    let fs = r.settings().full_scale;
    let before = (r.block_estimate(), r.estimate());
    let e = r.step(omega, dt);
    let ctx = format!("omega {omega:?} dt {dt:e} -> {e:?}");
    prop_assert!(e.a.iter().all(|x| x.is_finite()), "{}", ctx);
    prop_assert!(r.estimate().iter().all(|x| x.is_finite()), "{}", ctx);
    prop_assert!(r.std_per_sigma().iter().all(|x| x.is_finite()), "{}", ctx);
    prop_assert_eq!(e.a, r.block_estimate());
    match refusal(omega, dt, fs) {
        Some(s) => prop_assert_eq!(e.status, s, "{}", ctx),
        None => prop_assert!(
            !e.status.rejected() && e.status != SampleStatus::Unidentifiable,
            "{}",
            ctx
        ),
    }
    // A sample refused for its value returns before touching anything.
    if matches!(e.status, SampleStatus::NonFinite | SampleStatus::Saturated) {
        prop_assert_eq!(before.0.map(f32::to_bits), e.a.map(f32::to_bits), "{}", ctx);
        prop_assert_eq!(
            before.1.map(f32::to_bits),
            r.estimate().map(f32::to_bits),
            "{}",
            ctx
        );
    }
    if e.status == SampleStatus::Anchored {
        *anchored += 1;
    }
    let c = r.counters();
    prop_assert_eq!(
        c.integrated + c.unidentifiable + c.rejected + c.gaps + c.numerical_faults + *anchored,
        c.samples
    );
    prop_assert!(c.sign_changes <= c.integrated);
    Ok(e.status)
}

/// Steps an [`ExtendedIdentifier`] and checks every invariant.
fn extended_step(
    x: &mut ExtendedIdentifier,
    omega: [f32; 3],
    dt: f32,
) -> Result<ExtendedStatus, TestCaseError> {
    let fs = x.settings().full_scale;
    let (theta0, updates0) = (x.theta(), x.updates());
    let e = x.step(omega, dt);
    let ctx = format!("omega {omega:?} dt {dt:e} -> {e:?}");
    prop_assert!(e.a.iter().all(|v| v.is_finite()), "{}", ctx);
    prop_assert!(
        e.effect_params.iter().flatten().all(|v| v.is_finite()),
        "{}",
        ctx
    );
    prop_assert!(e.scale.is_finite() && e.scale > 0.0, "{}", ctx);
    prop_assert!(x.theta().iter().all(|v| v.is_finite()), "{}", ctx);
    prop_assert!(x.variances().iter().all(|v| v.is_finite()), "{}", ctx);
    let want = match refusal(omega, dt, fs) {
        Some(SampleStatus::InvalidTimeStep) => Some(ExtendedStatus::InvalidTimeStep),
        Some(SampleStatus::NonFinite) => Some(ExtendedStatus::NonFinite),
        Some(_) => Some(ExtendedStatus::Saturated),
        None => None,
    };
    match want {
        Some(s) => prop_assert_eq!(e.status, s, "{}", ctx),
        None => prop_assert!(
            !matches!(
                e.status,
                ExtendedStatus::InvalidTimeStep
                    | ExtendedStatus::NonFinite
                    | ExtendedStatus::Saturated
            ),
            "{}",
            ctx
        ),
    }
    if e.status == ExtendedStatus::Updated {
        prop_assert_eq!(x.updates(), updates0 + 1);
    } else {
        prop_assert_eq!(x.updates(), updates0);
        prop_assert_eq!(
            theta0.map(f32::to_bits),
            x.theta().map(f32::to_bits),
            "{}",
            ctx
        );
    }
    Ok(e.status)
}

/// What a run without the refused samples does instead.
#[derive(Clone, Copy, Debug)]
enum Action {
    Step([f32; 3], f32),
    Restart,
}

/// The sequence with each sample refused for its value left out (its `dt` carried to the next
/// sample, summed in the order the estimators sum it) and each invalid `dt` replaced by a
/// restart. `None` when a carried `dt` overflows to infinity: the estimators then see a gap
/// that no single finite `dt` reproduces, so there is no twin to compare with.
fn without_refused(seq: &[([f32; 3], f32)], full_scale: f32) -> Option<Vec<Action>> {
    let mut out = Vec::new();
    let mut pending = 0.0f32;
    for &(w, dt) in seq {
        match refusal(w, dt, full_scale) {
            Some(SampleStatus::InvalidTimeStep) => {
                pending = 0.0;
                out.push(Action::Restart);
            }
            Some(_) => pending += dt,
            None => {
                let carried = pending + dt;
                if !carried.is_finite() {
                    return None;
                }
                out.push(Action::Step(w, carried));
                pending = 0.0;
            }
        }
    }
    Some(out)
}

/// `cases` per property, or `PROPTEST_CASES` from the environment for longer runs.
fn config(cases: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(cases);
    Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config(512))]

    #[test]
    fn refined_random_samples_any_settings(s in refined_settings(), seq in samples(400)) {
        let mut r = Refined::new(s).expect("valid settings");
        let mut anchored = 0;
        for &(w, d) in &seq {
            refined_step(&mut r, w, d, &mut anchored)?;
        }
    }

    #[test]
    fn extended_random_samples_any_settings(s in extended_settings(), seq in samples(400)) {
        let mut x = ExtendedIdentifier::new(s).expect("valid settings");
        for &(w, d) in &seq {
            extended_step(&mut x, w, d)?;
        }
    }

    /// Arbitrary bit patterns as settings: refused, or safe.
    #[test]
    fn refined_arbitrary_settings_refused_or_safe(
        f in prop::array::uniform6(any::<f32>()),
        a0 in prop::array::uniform3(any::<f32>()),
        seq in samples(60),
    ) {
        let mut s = RefinedSettings::new();
        s.noise_std = f[0];
        s.prior_std = f[1];
        s.full_scale = f[2];
        s.max_dt = f[3];
        s.eps = f[4];
        s.h = f[5];
        s.initial_estimate = a0;
        match Refined::new(s) {
            None => prop_assert!(!s.is_valid()),
            Some(mut r) => {
                let mut anchored = 0;
                for &(w, d) in &seq {
                    refined_step(&mut r, w, d, &mut anchored)?;
                }
            }
        }
    }

    #[test]
    fn extended_arbitrary_settings_refused_or_safe(
        effects in [effect(), effect()],
        f in prop::array::uniform5(any::<f32>()),
        a0 in prop::array::uniform3(any::<f32>()),
        seq in samples(60),
    ) {
        let mut s = ExtendedSettings::new(effects);
        s.scale_correction = true;
        s.initial_estimate = a0;
        s.prior_a = f[0];
        s.prior_effect = f[1];
        s.noise_std = f[2];
        s.full_scale = f[3];
        s.max_dt = f[4];
        match ExtendedIdentifier::new(s) {
            None => prop_assert!(!s.is_valid()),
            Some(mut x) => {
                for &(w, d) in &seq {
                    extended_step(&mut x, w, d)?;
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(config(32))]

    /// After clean data, a stretch of refused samples (NaN, infinite, saturated, invalid dt)
    /// leaves both estimators' estimates bit for bit, and the next clean stretch carries on.
    #[test]
    fn refused_stretch_keeps_what_was_learnt(
        bad in prop::collection::vec(
            (prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(-FS), Just(1e30f32)],
             0usize..3,
             prop_oneof![Just(1e-3f32), Just(0.0f32), Just(-1.0f32), Just(f32::NAN)]),
            1..2000,
        ),
    ) {
        let data = clean(12.0, 1000.0);
        let mut rs = RefinedSettings::new();
        rs.full_scale = FS;
        let mut xs = ExtendedSettings::new([None, None]);
        xs.full_scale = FS;
        let mut r = Refined::new(rs).unwrap();
        let mut x = ExtendedIdentifier::new(xs).unwrap();
        let mut anchored = 0;
        for w in &data[..6000] {
            refined_step(&mut r, *w, 1e-3, &mut anchored)?;
            extended_step(&mut x, *w, 1e-3)?;
        }
        // The refined identifier folds its open block in at the first invalid dt (a restart):
        // its twin gets that restart and nothing else.
        let mut twin = r;
        if bad.iter().any(|b| !(b.2.is_finite() && b.2 > 0.0)) {
            twin.restart();
        }
        let held_x = x.theta();
        for (k, &(v, axis, dt)) in bad.iter().enumerate() {
            // The bad samples take the place of clean ones: the motion's time runs on.
            let mut w = data[6000 + k];
            w[axis] = v;
            prop_assert!(refined_step(&mut r, w, dt, &mut anchored)?.rejected());
            let st = extended_step(&mut x, w, dt)?;
            prop_assert!(matches!(st, ExtendedStatus::NonFinite | ExtendedStatus::Saturated | ExtendedStatus::InvalidTimeStep));
        }
        prop_assert_eq!(twin.block_estimate(), r.block_estimate());
        prop_assert_eq!(twin.estimate(), r.estimate());
        prop_assert_eq!(held_x, x.theta());
        let truth = Body::free([0.6, 1.54, 1.0]).a();
        for w in &data[6000 + bad.len()..] {
            refined_step(&mut r, *w, 1e-3, &mut anchored)?;
            extended_step(&mut x, *w, 1e-3)?;
        }
        let err = |a: [f32; 3]| (0..3).map(|i| (f64::from(a[i]) - truth[i]).abs()).fold(0.0, f64::max);
        prop_assert!(err(r.estimate()) < 1e-3, "refined {:?}", r.estimate());
        prop_assert!(err(x.step(data[data.len() - 1], 1e-3).a) < 1e-2, "extended {:?}", x.theta());
    }
}

proptest! {
    #![proptest_config(config(256))]

    /// Refused samples leave no trace in the core's paper identifier.
    #[test]
    fn identifier_refused_samples_leave_no_trace(seq in samples(400), lambda in 0.1f32..20.0) {
        use identifier_core::{Identifier, Settings};
        let s = Settings { full_scale: FS, ..Settings::with_lambda(lambda) };
        let (mut a, mut b) = (Identifier::new(s).unwrap(), Identifier::new(s).unwrap());
        for &(w, d) in &seq {
            a.step(w, d);
        }
        let twin = without_refused(&seq, FS);
        prop_assume!(twin.is_some());
        for act in twin.unwrap_or_default() {
            match act {
                Action::Step(w, d) => { b.step(w, d); }
                Action::Restart => b.restart(),
            }
        }
        prop_assert_eq!(a.estimate().map(f32::to_bits), b.estimate().map(f32::to_bits));
        prop_assert_eq!(a.convergence(), b.convergence());
        prop_assert_eq!(a.counters().integrated, b.counters().integrated);
    }

    /// Refused samples leave no trace in the refined identifier.
    #[test]
    fn refined_refused_samples_leave_no_trace(s in refined_settings(), seq in samples(400)) {
        let (mut a, mut b) = (Refined::new(s).unwrap(), Refined::new(s).unwrap());
        for &(w, d) in &seq {
            a.step(w, d);
        }
        let twin = without_refused(&seq, s.full_scale);
        prop_assume!(twin.is_some());
        for act in twin.unwrap_or_default() {
            match act {
                Action::Step(w, d) => { b.step(w, d); }
                Action::Restart => b.restart(),
            }
        }
        prop_assert_eq!(a.block_estimate().map(f32::to_bits), b.block_estimate().map(f32::to_bits));
        prop_assert_eq!(a.estimate().map(f32::to_bits), b.estimate().map(f32::to_bits));
        prop_assert_eq!(a.counters().integrated, b.counters().integrated);
    }

    /// Refused samples leave no trace in the extended identifier.
    #[test]
    fn extended_refused_samples_leave_no_trace(s in extended_settings(), seq in samples(400)) {
        let (mut a, mut b) = (ExtendedIdentifier::new(s).unwrap(), ExtendedIdentifier::new(s).unwrap());
        for &(w, d) in &seq {
            a.step(w, d);
        }
        let twin = without_refused(&seq, s.full_scale);
        prop_assume!(twin.is_some());
        for act in twin.unwrap_or_default() {
            match act {
                Action::Step(w, d) => { b.step(w, d); }
                Action::Restart => b.restart(),
            }
        }
        prop_assert_eq!(a.theta().map(f32::to_bits), b.theta().map(f32::to_bits));
        prop_assert_eq!(a.updates(), b.updates());
    }
}
