//! Faults between the gyro and the identifier, on the host: the real ICM-42688-P driver talks
//! to the simulated part (`icm42688::sim`) through a fault-injecting SPI layer, and a sample
//! loop with the recovery the flight firmware needs feeds `identifier-core`.
//!
//! Injected faults (all seeded, reproducible): bus errors (a transaction fails), corrupted
//! samples (one bit flipped in the six data bytes), dropped samples (data-ready lost, the part
//! moves on), a wrong identity register for a while, missing data-ready for a while, stalled
//! data (the part repeats one sample). The loop counts each, re-initialises the sensor when
//! the part stops making sense, and keeps running.
//!
//! The figure: a replay with 1 % corrupted samples, 1 % dropped samples and 1 % bus errors,
//! against the clean replay of the same motion and noise. Printed with `--nocapture`.
//!
//! Time base: the simulated part has no clock; it latches one sample per `INT_STATUS` read.
//! The loop's clock is the part's sample count (what a timer or the FIFO timestamps give on
//! the board), so a dropped sample lengthens the next step instead of shrinking the time base.
//! The variant that counts data-ready events only is measured too.
#![allow(clippy::needless_range_loop)]

use embedded_hal::delay::DelayNs;
use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use icm42688::registers as reg;
use icm42688::sim::{FaultRng, Faults, FaultySpi, Injected, SimIcm42688};
use icm42688::{raw3_to_rad_s, Config, Error, Icm42688};
use identifier_core::{Identifier, SampleStatus, Settings};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

const RATE: f64 = 1000.0;
const DURATION: f64 = 20.0;
const NOISE: f64 = 1e-3; // rad/s per sample: ICM-42688-P at 1 kHz
const INERTIA: [f64; 3] = [0.6, 1.54, 1.0];

// ---------------------------------------------------------------------------------------------
// Fault injection between the driver and the simulated part.

/// The fault injector's randomness: a seeded ChaCha8 stream.
struct Words(ChaCha8Rng);

impl FaultRng for Words {
    fn next_u32(&mut self) -> u32 {
        self.0.next_u32()
    }
}

fn words(seed: u64) -> Words {
    Words(ChaCha8Rng::seed_from_u64(seed))
}

/// Probability to parts per million, the injector's unit.
fn ppm(p: f64) -> u32 {
    (p * 1e6).round() as u32
}

// ---------------------------------------------------------------------------------------------
// The sample loop with recovery.

struct NoDelay;
impl DelayNs for NoDelay {
    fn delay_ns(&mut self, _: u32) {}
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct LoopCounters {
    steps: u32,
    bus_errors: u32,
    timeouts: u32,
    invalid: u32,
    wrong_id: u32,
    stalled: u32,
    implausible: u32,
    reinits: u32,
    reinit_failures: u32,
}

/// How the loop measures time and screens samples.
#[derive(Clone, Copy, Debug)]
struct Policy {
    /// dt from the part's sample count (a timer), or one period per data-ready event.
    timer_dt: bool,
    /// Refuse a sample whose change from the last accepted one exceeds what the motion allows.
    plausibility_gate: bool,
}

const POLL_US: u32 = 10;
const MAX_POLLS: u32 = 3;
/// Consecutive failures before the sensor is re-initialised.
const REINIT_AFTER: u32 = 5;
/// Identical consecutive raw samples before the data counts as stalled (noise makes repeats of
/// all three axes rare: at 1e-3 rad/s noise and 0.27 mrad/s counts, practically never).
const STALLED_AFTER: u32 = 20;
/// `WHO_AM_I` is checked every this many steps.
const HEALTH_EVERY: u32 = 100;
/// Largest plausible change of a rate per second (rad/s^2) plus a noise margin per sample:
/// torque-free, `|w_i'| <= |a_i| |w_j w_k| <= (full scale)^2`.
const MAX_ACCEL: f32 = 80.0;
const GATE_MARGIN: f32 = 0.02;

struct SampleLoop<S: icm42688::sim::SampleSource> {
    gyro: Icm42688<icm42688::SpiInterface<FaultySpi<S, Words>>>,
    id: Identifier,
    policy: Policy,
    period: f32,
    /// The part's sample count at the last identifier step (the loop's clock).
    clock: u32,
    /// Data-ready events since the last step (the clock of the event-counting variant).
    events: u32,
    last_raw: Option<[i16; 3]>,
    repeats: u32,
    last_accepted: Option<[f32; 3]>,
    since_accepted: f32,
    fails: u32,
    c: LoopCounters,
}

impl<S: icm42688::sim::SampleSource> SampleLoop<S> {
    fn new(spi: FaultySpi<S, Words>, policy: Policy) -> Self {
        let config = Config::identifier();
        let mut s = Settings::with_lambda(3.0);
        s.full_scale = icm42688::raw_to_rad_s(32767, config.full_scale);
        let mut lp = SampleLoop {
            gyro: Icm42688::new_spi(spi),
            id: Identifier::new(s).unwrap(),
            policy,
            period: config.odr.period_s(),
            clock: 0,
            events: 0,
            last_raw: None,
            repeats: 0,
            last_accepted: None,
            since_accepted: 0.0,
            fails: 0,
            c: LoopCounters::default(),
        };
        lp.reinit();
        lp.c.reinits = 0; // the first init is not a recovery
        lp
    }

    fn part(&self) -> &FaultySpi<S, Words> {
        self.gyro.interface().bus()
    }

    fn latched(&self) -> u32 {
        self.part().inner.stats().samples
    }

    fn exhausted(&self) -> bool {
        self.part().inner.exhausted()
    }

    /// Resets and reconfigures the part (bounded retries); the identifier restarts its
    /// integration but keeps what it learnt.
    fn reinit(&mut self) {
        self.c.reinits += 1;
        self.id.restart();
        self.last_raw = None;
        self.repeats = 0;
        self.last_accepted = None;
        self.fails = 0;
        for _ in 0..10 {
            match self.gyro.init(&mut NoDelay, Config::identifier()) {
                Ok(()) => {
                    self.clock = self.latched();
                    self.events = 0;
                    return;
                }
                Err(Error::WrongId(_)) => self.c.wrong_id += 1,
                Err(_) => {}
            }
            self.c.reinit_failures += 1;
        }
    }

    fn failure(&mut self) {
        self.fails += 1;
        if self.fails >= REINIT_AFTER {
            self.reinit();
        }
    }

    /// One pass of the loop; false when the replay has ended.
    fn poll(&mut self) -> bool {
        if self.exhausted() {
            return false;
        }
        match self.gyro.wait_data_ready(&mut NoDelay, POLL_US, MAX_POLLS) {
            Ok(()) => {}
            Err(Error::Timeout) => {
                self.c.timeouts += 1;
                self.failure();
                return !self.exhausted();
            }
            Err(_) => {
                self.c.bus_errors += 1;
                self.failure();
                return true;
            }
        }
        self.events += 1;
        let raw = match self.gyro.read_gyro_raw() {
            Ok(raw) => raw,
            Err(Error::InvalidSample) => {
                self.c.invalid += 1;
                self.failure();
                return true;
            }
            Err(_) => {
                self.c.bus_errors += 1;
                self.failure();
                return true;
            }
        };
        // Stalled data: the same three counts again and again.
        if self.last_raw == Some(raw) {
            self.repeats += 1;
            if self.repeats >= STALLED_AFTER {
                self.c.stalled += 1;
                self.reinit();
                return true;
            }
        } else {
            self.repeats = 0;
        }
        self.last_raw = Some(raw);
        let now = self.latched();
        let dt = if self.policy.timer_dt {
            now.wrapping_sub(self.clock) as f32 * self.period
        } else {
            self.events as f32 * self.period
        };
        let omega = raw3_to_rad_s(raw, self.gyro.full_scale());
        if self.policy.plausibility_gate {
            self.since_accepted += dt;
            if let Some(prev) = self.last_accepted {
                let limit = MAX_ACCEL * self.since_accepted + GATE_MARGIN;
                if (0..3).any(|i| (omega[i] - prev[i]).abs() > limit) {
                    // Refused like a saturated sample: its time is carried to the next one.
                    self.c.implausible += 1;
                    self.clock = now;
                    self.events = 0;
                    self.id.step([f32::NAN; 3], dt);
                    return true;
                }
            }
            self.last_accepted = Some(omega);
            self.since_accepted = 0.0;
        }
        self.clock = now;
        self.events = 0;
        let e = self.id.step(omega, dt);
        assert!(e.a.iter().all(|x| x.is_finite()));
        self.c.steps += 1;
        self.fails = 0;
        // Health check: is it still our part?
        if self.c.steps.is_multiple_of(HEALTH_EVERY) {
            match self.gyro.who_am_i() {
                Ok(reg::WHO_AM_I_VALUE) => {}
                Ok(_) => {
                    self.c.wrong_id += 1;
                    self.reinit();
                }
                Err(_) => self.c.bus_errors += 1,
            }
        }
        true
    }
}

// ---------------------------------------------------------------------------------------------
// Replays.

fn motion(seed: u64) -> (Vec<[f32; 3]>, [f64; 3]) {
    let body = Body::free(INERTIA);
    let tr = body.simulate([1.0, 1.0, 1.0], DURATION, RATE, 4);
    let meas = GyroModel::noisy(NOISE, seed).measure(&tr);
    (meas.iter().map(|w| w.map(|x| x as f32)).collect(), body.a())
}

struct Outcome {
    /// RMS over the three components and the last 10 s of `a_hat - a`, sampled per step.
    rms: f64,
    final_err: f64,
    counters: LoopCounters,
    injected: Injected,
    statuses_nonfinite: u32,
}

fn replay(seed: u64, faults: Faults, policy: Policy) -> Outcome {
    let (samples, a) = motion(seed);
    let n = samples.len();
    let mut it = samples.into_iter();
    let source = move || it.next();
    let spi = FaultySpi::new(SimIcm42688::new(source), faults, words(seed ^ 0x5eed));
    let mut lp = SampleLoop::new(spi, policy);
    let (mut sum, mut count) = (0.0, 0usize);
    let mut guard = 0usize;
    while lp.poll() {
        guard += 1;
        assert!(guard < 20 * n, "loop does not end");
        if f64::from(lp.latched()) >= (DURATION - 10.0) * RATE {
            let est = lp.id.estimate();
            for i in 0..3 {
                sum += (f64::from(est[i]) - a[i]).powi(2);
            }
            count += 3;
        }
    }
    let est = lp.id.estimate();
    let final_err = (0..3)
        .map(|i| (f64::from(est[i]) - a[i]).abs())
        .fold(0.0, f64::max);
    assert!(lp.latched() as usize >= n - 1, "replay ended early");
    Outcome {
        rms: (sum / count.max(1) as f64).sqrt(),
        final_err,
        counters: lp.c,
        injected: lp.part().injected(),
        statuses_nonfinite: lp.id.counters().rejected,
    }
}

const SEEDS: [u64; 5] = [1, 2, 3, 4, 5];

fn mix() -> Faults {
    Faults {
        bus_error_ppm: ppm(0.01),
        corrupt_ppm: ppm(0.01),
        drop_ppm: ppm(0.01),
        ..Faults::default()
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The figure: 1 % corrupted, 1 % dropped samples and 1 % bus errors against the clean replay,
/// with the loop the firmware needs (timer-based dt, plausibility gate): within 2x.
#[test]
fn faulty_replay_within_twice_the_clean_error() {
    let good = Policy {
        timer_dt: true,
        plausibility_gate: true,
    };
    let mut clean = Vec::new();
    let mut faulty = Vec::new();
    for &seed in &SEEDS {
        let c = replay(seed, Faults::default(), good);
        let f = replay(seed, mix(), good);
        println!(
            "seed {seed}: clean RMS {:.3e} final {:.3e} | faulty RMS {:.3e} final {:.3e} | injected {:?} | loop {:?}",
            c.rms, c.final_err, f.rms, f.final_err, f.injected, f.counters
        );
        assert_eq!(
            c.counters.bus_errors + c.counters.implausible + c.counters.reinits,
            0
        );
        assert!(
            f.injected.bus_errors > 100 && f.injected.corrupted > 100 && f.injected.dropped > 100
        );
        assert!(f.counters.bus_errors >= f.injected.bus_errors / 2);
        assert!(f.statuses_nonfinite >= f.counters.implausible);
        clean.push(c.rms);
        faulty.push(f.rms);
    }
    let (mc, mf) = (mean(&clean), mean(&faulty));
    println!(
        "FIGURE (timer dt, plausibility gate): clean RMS error of a over the last 10 s {mc:.3e}, \
         faulty {mf:.3e}, ratio {:.2}",
        mf / mc
    );
    assert!(mf <= 2.0 * mc, "faulty {mf:e} vs clean {mc:e}");
}

/// The same mix without the loop's defences, measured and printed: what each defence buys.
#[test]
fn what_the_defences_buy() {
    let clean = mean(
        &SEEDS
            .iter()
            .map(|&s| {
                replay(
                    s,
                    Faults::default(),
                    Policy {
                        timer_dt: true,
                        plausibility_gate: true,
                    },
                )
                .rms
            })
            .collect::<Vec<_>>(),
    );
    for (name, policy) in [
        (
            "no gate, timer dt",
            Policy {
                timer_dt: true,
                plausibility_gate: false,
            },
        ),
        (
            "gate, dt from data-ready events",
            Policy {
                timer_dt: false,
                plausibility_gate: true,
            },
        ),
        (
            "no gate, dt from data-ready events",
            Policy {
                timer_dt: false,
                plausibility_gate: false,
            },
        ),
    ] {
        let rms = mean(
            &SEEDS
                .iter()
                .map(|&s| replay(s, mix(), policy).rms)
                .collect::<Vec<_>>(),
        );
        println!(
            "FIGURE ({name}): faulty RMS {rms:.3e} vs clean {clean:.3e}: ratio {:.2}",
            rms / clean
        );
        assert!(rms.is_finite());
    }
}

/// Each fault alone, as a burst: counted, recovered from (sensor re-initialised), the loop runs
/// to the end of the replay, and the estimate is still good.
#[test]
fn each_fault_is_counted_and_recovered_from() {
    let good = Policy {
        timer_dt: true,
        plausibility_gate: true,
    };
    let clean = replay(1, Faults::default(), good);
    // Transactions per sample in the steady loop: about 2 (status poll, data read).
    let at = 12_000; // about 6 s into the replay
    type Seen = fn(&LoopCounters) -> bool;
    let cases: [(&str, Faults, Seen); 4] = [
        (
            "bus dead for 200 transactions",
            Faults {
                bus_dead: Some((at, at + 200)),
                ..Faults::default()
            },
            |c| c.bus_errors >= 5 && c.reinits >= 1,
        ),
        (
            "WHO_AM_I reads 0x00 for 2000 transactions",
            Faults {
                wrong_id: Some((at, at + 2000)),
                ..Faults::default()
            },
            |c| c.wrong_id >= 1 && c.reinits >= 1,
        ),
        (
            "no data-ready for 400 transactions",
            Faults {
                no_data_ready: Some((at, at + 400)),
                ..Faults::default()
            },
            |c| c.timeouts >= 5 && c.reinits >= 1,
        ),
        (
            "data stalled for 400 transactions",
            Faults {
                stalled: Some((at, at + 400)),
                ..Faults::default()
            },
            |c| c.stalled >= 1 && c.reinits >= 1,
        ),
    ];
    for (name, faults, seen) in cases {
        let o = replay(1, faults, good);
        println!(
            "{name}: loop {:?}, final error {:.3e} (clean {:.3e})",
            o.counters, o.final_err, clean.final_err
        );
        assert!(seen(&o.counters), "{name}: {:?}", o.counters);
        assert!(
            o.final_err <= 2.0 * clean.final_err + 1e-3,
            "{name}: final error {:e} vs clean {:e}",
            o.final_err,
            clean.final_err
        );
    }
}

#[test]
fn gate_refusals_are_rejected_samples_not_integrated() {
    // A single corrupted sample far from its neighbours must not reach the integration.
    let mut id = Identifier::new(Settings::with_lambda(3.0)).unwrap();
    id.step([1.0, 1.0, 1.0], 1e-3);
    id.step([1.0, 1.001, 1.0], 1e-3);
    let before = id.estimate();
    assert_eq!(id.step([f32::NAN; 3], 1e-3).status, SampleStatus::NonFinite);
    assert_eq!(id.estimate(), before);
}

/// The flight firmware's own sample loop (`firmware::SampleLoop`) under the same fault mix, on
/// the host: it now carries the defences of the loop above (plausibility gate, dt from a sample
/// clock, here the simulated part's sample count, re-initialisation, `WHO_AM_I` check). The
/// figure is printed; the test asserts that the loop survives (runs to the end of the replay,
/// finite estimate), counts the faults, and stays within 2x of the clean error.
#[test]
fn firmware_sample_loop_under_the_fault_mix() {
    let run = |seed: u64, faults: Faults| {
        let (samples, a) = motion(seed);
        let n = samples.len();
        let mut rng_init = 0u64;
        let mut lp = loop {
            let mut it = samples.clone().into_iter();
            let spi = FaultySpi::new(
                SimIcm42688::new(move || it.next()),
                faults,
                words(seed ^ 0x5eed ^ rng_init),
            );
            // Init can meet an injected bus error; the firmware is restarted then.
            // The loop's clock: the part's sample count, as in `SampleLoop` above.
            let period_us = Config::identifier().odr.period_us();
            let clock = move |i: &icm42688::SpiInterface<FaultySpi<_, Words>>| {
                i.bus().inner.stats().samples.wrapping_mul(period_us)
            };
            match firmware::SampleLoop::new(
                Icm42688::new_spi(spi),
                &mut NoDelay,
                Config::identifier(),
                clock,
            ) {
                Ok(lp) => break lp,
                Err(_) => rng_init += 1,
            }
            assert!(rng_init < 100);
        };
        let (mut sum, mut count) = (0.0, 0usize);
        loop {
            let p = lp.poll(&mut NoDelay);
            let part = &lp.gyro().interface().bus().inner;
            if matches!(p, firmware::Poll::Timeout) && part.exhausted() {
                break;
            }
            if f64::from(part.stats().samples) >= (DURATION - 10.0) * RATE {
                let est = lp.identifier().estimate();
                assert!(est.iter().all(|x| x.is_finite()));
                for i in 0..3 {
                    sum += (f64::from(est[i]) - a[i]).powi(2);
                }
                count += 3;
            }
        }
        let part = lp.gyro().interface().bus();
        assert!(part.inner.stats().samples as usize >= n - 1);
        (
            (sum / count.max(1) as f64).sqrt(),
            lp.counters(),
            part.injected(),
        )
    };
    let mut clean = Vec::new();
    let mut faulty = Vec::new();
    for &seed in &SEEDS {
        let (c, _, _) = run(seed, Faults::default());
        let (f, counters, injected) = run(seed, mix());
        println!("seed {seed}: clean RMS {c:.3e} | faulty RMS {f:.3e} | injected {injected:?} | loop {counters:?}");
        assert!(counters.bus_errors > 100, "{counters:?}");
        assert!(counters.bus_errors <= injected.bus_errors);
        assert!(
            counters.implausible > 0 && counters.missed > 0,
            "{counters:?}"
        );
        clean.push(c);
        faulty.push(f);
    }
    let (mc, mf) = (mean(&clean), mean(&faulty));
    println!(
        "FIGURE (firmware::SampleLoop): clean RMS {mc:.3e}, faulty {mf:.3e}, ratio {:.2}",
        mf / mc
    );
    assert!(mc.is_finite() && mf.is_finite());
    assert!(mf <= 2.0 * mc, "faulty {mf:e} vs clean {mc:e}");
}
