//! Fuzz target for the core's `step` functions: arbitrary bytes become settings and a sequence
//! of `(omega, dt)` samples, mixing plausible rates (so that the integration is reached) with
//! raw bit patterns and special values. The same sequence drives the paper's `Identifier`, the
//! `Refined` identifier, the `ExtendedIdentifier` and the `FlightPipeline` (with an
//! accelerometer and a rotor momentum derived from the rates). After every step the documented
//! invariants are checked; a violation aborts, and libFuzzer reports the input.
//!
//! Layout: a 12-byte header for the settings, then records of 8 bytes
//! `[tag, w1 (i16), w2 (i16), w3 (i16), dt code]`, where some tags read 4 to 16 more bytes of raw
//! `f32` bits.
#![no_main]

use identifier_core::invariant::control;
use identifier_core::{
    consistency, ExtendedIdentifier, ExtendedSettings, ExtendedStatus, ExtraEffect, GainMatrix,
    Identifier, InertiaRatios, Refined, RefinedSettings, SampleStatus, Settings,
    SignChangeCorrection,
};
use identifier_core::{FlightPipeline, PipelineSettings, Status};
use libfuzzer_sys::fuzz_target;

struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }
    fn i16(&mut self) -> Option<i16> {
        Some(i16::from_le_bytes([self.u8()?, self.u8()?]))
    }
    fn f32(&mut self) -> Option<f32> {
        Some(f32::from_le_bytes([
            self.u8()?,
            self.u8()?,
            self.u8()?,
            self.u8()?,
        ]))
    }
}

const SPECIAL: [f32; 16] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -f32::MAX,
    0.0,
    -0.0,
    1e-40,
    f32::MIN_POSITIVE,
    1e20,
    -3e19,
    34.906_586,
    -34.906_586,
    1e-3,
    1e6,
    -1.0,
];

const FULL_SCALE: [f32; 4] = [f32::INFINITY, 34.906_586, 1.0, 1e30];

fn settings(b: &mut Bytes) -> Option<Settings> {
    let g = b.u8()?;
    let gain = match g % 4 {
        0 => GainMatrix::scalar(0.01 + f32::from(g / 4) * 0.5),
        1 => GainMatrix::scalar(b.f32()?), // raw: mostly refused, which is checked too
        2 => {
            // Gershgorin-shifted matrix: Hurwitz by construction.
            let mut m = [[0.0f32; 3]; 3];
            for row in m.iter_mut() {
                for x in row.iter_mut() {
                    *x = f32::from(b.u8()? as i8) / 16.0;
                }
            }
            let r = m
                .iter()
                .map(|row| row.iter().map(|x| x.abs()).sum::<f32>())
                .fold(0.0, f32::max);
            for (i, row) in m.iter_mut().enumerate() {
                row[i] -= r + 0.1;
            }
            GainMatrix(m)
        }
        _ => GainMatrix::scalar([1e-12, 1e12, 3.0, 1e-3][usize::from(g / 4 % 4)]),
    };
    let f = b.u8()?;
    let w_min = [0.0, 1e-3, 0.5, f32::MAX][usize::from(f % 4)];
    let full_scale = FULL_SCALE[usize::from(f / 4 % 4)];
    let max_dt = [0.1, 1e-4, 10.0, f32::MAX][usize::from(f / 16 % 4)];
    let sign_change = if f & 0x40 == 0 {
        SignChangeCorrection::Enabled
    } else {
        SignChangeCorrection::Disabled
    };
    let c = b.u8()?;
    let eps = [1e-3, 1e-6, 0.1, 10.0][usize::from(c % 4)];
    let h = [1.0, 1e-3, 0.01, 100.0][usize::from(c / 4 % 4)];
    let initial_estimate = [
        f32::from(b.i16()?) / 100.0,
        f32::from(b.i16()?) / 100.0,
        f32::from(b.i16()?) / 100.0,
    ];
    Some(Settings {
        gain,
        w_min,
        sign_change,
        full_scale,
        max_dt,
        eps,
        h,
        initial_estimate,
    })
}

fn sample(b: &mut Bytes, full_scale: f32) -> Option<([f32; 3], f32, u8)> {
    let tag = b.u8()?;
    let raw = [b.i16()?, b.i16()?, b.i16()?];
    let omega = match tag % 5 {
        0 | 1 => raw.map(|x| f32::from(x) / 1000.0),
        2 => raw.map(|x| f32::from(x) * 1e-6),
        3 => raw.map(|x| {
            if x & 1 == 0 {
                f32::from(x) / 1000.0
            } else if x & 2 == 0 {
                full_scale.copysign(f32::from(x))
            } else {
                SPECIAL[usize::from((x as u16 >> 2) % 16)]
            }
        }),
        _ => [b.f32()?, b.f32()?, b.f32()?],
    };
    let code = b.u8()?;
    let dt = match code {
        0..=199 => 1e-3 * (0.5 + f32::from(code) / 200.0),
        200..=215 => SPECIAL[usize::from(code - 200)],
        216 => 0.05,
        217 => 0.2,
        218 => 10.0,
        219..=239 => 1e-3 * f32::from(code - 218),
        _ => b.f32()?,
    };
    Some((omega, dt, tag))
}

/// What must be refused for its input alone, in the documented order.
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

fn effect(k: u8) -> Option<ExtraEffect> {
    match k % 6 {
        0 => None,
        1 => Some(ExtraEffect::GyroBias),
        2 => Some(ExtraEffect::BodyTorque),
        3 => Some(ExtraEffect::Damping),
        4 => Some(ExtraEffect::ProductsOfInertia),
        _ => Some(ExtraEffect::RotorMomentum),
    }
}

/// The refined and extended identifiers on the same samples.
struct Others {
    refined: Option<Refined>,
    extended: Option<ExtendedIdentifier>,
    refined_anchored: u32,
    /// The shared flight pipeline (gate, delay line, tensor, refined and bias models), fed the
    /// same rates with an accelerometer and a rotor momentum derived from them.
    pipeline: Option<FlightPipeline>,
    steps: u32,
}

impl Others {
    fn new(s: &Settings, k: u8) -> Self {
        let mut r = RefinedSettings::new();
        r.full_scale = s.full_scale;
        r.max_dt = s.max_dt;
        r.eps = s.eps;
        r.h = s.h;
        r.initial_estimate = s.initial_estimate;
        r.block = [1, 3, 32, 1024][usize::from(k % 4)];
        r.end_correction = k & 4 != 0;
        r.noise_std = [2e-3, 1e-6, 1.0, 0.1][usize::from(k / 8 % 4)];
        let mut x = ExtendedSettings::new([effect(k), effect(k / 6)]);
        x.scale_correction = k & 32 != 0;
        x.full_scale = s.full_scale;
        x.max_dt = s.max_dt;
        x.initial_estimate = s.initial_estimate;
        let rate = [1000.0, 100.0, 8000.0, 3000.0][usize::from(k / 32 % 4)];
        let pipeline = FlightPipeline::new(
            PipelineSettings::for_rate(rate, r.noise_std).with_full_scale(s.full_scale),
            k & 64 != 0,
        );
        Others {
            refined: Refined::new(r),
            extended: ExtendedIdentifier::new(x),
            refined_anchored: 0,
            pipeline,
            steps: 0,
        }
    }

    fn step(&mut self, omega: [f32; 3], dt: f32, full_scale: f32) {
        if let Some(p) = self.pipeline.as_mut() {
            let accel = [omega[1] * 0.3, omega[2] * 0.1, 9.8 - omega[0] * 0.01];
            let h = [0.0, 0.0, omega[0] * 1e-6];
            let _ = p.step(omega, accel, h, dt);
            self.steps += 1;
            // The estimate is cheap enough to check only now and then.
            if self.steps % 97 == 0 {
                let e = p.estimate();
                for v in [e.a, e.std_a, e.principal_moments].into_iter().flatten() {
                    assert!(v.iter().all(|x| x.is_finite()), "{e:?}");
                }
                for m in [e.tensor, e.normalized, e.tensor_std].into_iter().flatten() {
                    assert!(m.iter().flatten().all(|x| x.is_finite()), "{e:?}");
                }
                let r = p.ratios();
                if let Some(a) = r.a {
                    assert!(a.iter().all(|x| x.is_finite()), "{r:?}");
                }
                if r.status == Status::Converged {
                    assert!(r.std_a.is_some_and(|s| s.iter().all(|x| x.is_finite())));
                }
            }
            // The output-error fits on whatever the input was: an ended flight's, and (on a
            // copy, now and then) the open one's. Finite or absent, never a panic.
            if p.fits_pending() {
                p.fit_ended_flight();
            }
            if self.steps % 499 == 0 {
                let mut q = *p;
                q.end_stretch();
                if let Some(f) = q.trajectory().estimate() {
                    assert!(
                        f.a.iter().chain(f.std_a.iter()).all(|x| x.is_finite()),
                        "{f:?}"
                    );
                }
                if let Some(f) = q.tensor_fit().estimate() {
                    assert!(f.tensor.iter().flatten().all(|x| x.is_finite()), "{f:?}");
                }
            }
        }
        let want = refusal(omega, dt, full_scale);
        if let Some(r) = self.refined.as_mut() {
            let before = (r.block_estimate(), r.estimate());
            let e = r.step(omega, dt);
            assert!(
                e.a.iter().all(|x| x.is_finite()),
                "refined {omega:?} {dt} {e:?}"
            );
            assert!(r.estimate().iter().all(|x| x.is_finite()));
            assert!(r.std_per_sigma().iter().all(|x| x.is_finite()));
            assert_eq!(e.a, r.block_estimate());
            match want {
                Some(w) => assert_eq!(e.status, w, "refined {omega:?} {dt}"),
                None => assert!(!e.status.rejected(), "refined {omega:?} {dt} {e:?}"),
            }
            if matches!(e.status, SampleStatus::NonFinite | SampleStatus::Saturated) {
                assert_eq!(before.0.map(f32::to_bits), e.a.map(f32::to_bits));
                assert_eq!(before.1.map(f32::to_bits), r.estimate().map(f32::to_bits));
            }
            if e.status == SampleStatus::Anchored {
                self.refined_anchored += 1;
            }
            let c = r.counters();
            assert_eq!(
                c.integrated
                    + c.unidentifiable
                    + c.rejected
                    + c.gaps
                    + c.numerical_faults
                    + self.refined_anchored,
                c.samples
            );
        }
        if let Some(x) = self.extended.as_mut() {
            let (theta0, updates0) = (x.theta(), x.updates());
            let e = x.step(omega, dt);
            assert!(
                e.a.iter().all(|v| v.is_finite()),
                "extended {omega:?} {dt} {e:?}"
            );
            assert!(e.effect_params.iter().flatten().all(|v| v.is_finite()));
            assert!(e.scale.is_finite() && e.scale > 0.0);
            assert!(x.theta().iter().all(|v| v.is_finite()));
            assert!(x.variances().iter().all(|v| v.is_finite()));
            let want = want.map(|w| match w {
                SampleStatus::InvalidTimeStep => ExtendedStatus::InvalidTimeStep,
                SampleStatus::NonFinite => ExtendedStatus::NonFinite,
                _ => ExtendedStatus::Saturated,
            });
            match want {
                Some(w) => assert_eq!(e.status, w, "extended {omega:?} {dt}"),
                None => assert!(!matches!(
                    e.status,
                    ExtendedStatus::InvalidTimeStep
                        | ExtendedStatus::NonFinite
                        | ExtendedStatus::Saturated
                )),
            }
            if e.status != ExtendedStatus::Updated {
                assert_eq!(theta0.map(f32::to_bits), x.theta().map(f32::to_bits));
                assert_eq!(x.updates(), updates0);
            }
        }
    }

    fn restart(&mut self) {
        if let Some(r) = self.refined.as_mut() {
            r.restart();
        }
        if let Some(x) = self.extended.as_mut() {
            x.restart();
        }
    }
}

fn check(data: &[u8]) {
    let mut b = Bytes(data);
    let Some(s) = settings(&mut b) else { return };
    let Some(k) = b.u8() else { return };
    let mut others = Others::new(&s, k);
    let mut id = match Identifier::new(s) {
        Ok(id) => id,
        Err(e) => {
            assert_eq!(s.validate(), Err(e));
            return;
        }
    };
    assert_eq!(id.estimate(), s.initial_estimate);
    let mut steps: u32 = 0;
    let mut anchored: u32 = 0;
    while let Some((omega, dt, tag)) = sample(&mut b, s.full_scale) {
        // Now and then, the other entry points.
        match tag >> 5 {
            6 => {
                id.restart();
                others.restart();
            }
            7 if tag & 16 != 0 => {
                id.reset();
                steps = 0;
                anchored = 0;
                assert_eq!(id.estimate(), s.initial_estimate);
            }
            _ => {}
        }
        others.step(omega, dt, s.full_scale);
        let before = id.estimate();
        let e = id.step(omega, dt);
        steps += 1;
        // The state stays finite.
        assert!(e.a.iter().all(|x| x.is_finite()), "{omega:?} {dt} {e:?}");
        assert_eq!(e.a, id.estimate());
        assert!(id.monitor().span().is_finite());
        // Refusals follow the documented order of checks.
        let want = if !(dt.is_finite() && dt > 0.0) {
            Some(SampleStatus::InvalidTimeStep)
        } else if omega.iter().any(|w| !w.is_finite()) {
            Some(SampleStatus::NonFinite)
        } else if omega.iter().any(|w| w.abs() >= s.full_scale) {
            Some(SampleStatus::Saturated)
        } else {
            None
        };
        match want {
            Some(w) => assert_eq!(e.status, w, "{omega:?} {dt}"),
            None => assert!(!e.status.rejected(), "{omega:?} {dt} {e:?}"),
        }
        // Only an integrated sample moves the estimate.
        if !e.status.integrated() {
            assert_eq!(before.map(f32::to_bits), e.a.map(f32::to_bits), "{e:?}");
        }
        if e.status == SampleStatus::Anchored {
            anchored += 1;
        }
        // Counters add up.
        let c = id.counters();
        assert_eq!(c.samples, steps);
        assert_eq!(
            c.integrated + c.unidentifiable + c.rejected + c.gaps + c.numerical_faults + anchored,
            steps
        );
        assert!(c.sign_changes <= c.integrated);
        // The derived quantities never panic, and are finite when they claim to be.
        let _ = id.alpha();
        let _ = consistency(e.a);
        if let Some(r) = e.ratios() {
            assert!(r.a2_over_a1.is_finite() && r.a3_over_a1.is_finite());
            let _ = r.to_a();
        }
        let _ = InertiaRatios::from_a(omega);
        let _ = control(&s.gain, e.a, omega);
    }
}

fuzz_target!(|data: &[u8]| check(data));
