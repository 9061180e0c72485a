//! The sample loop: one gyro sample, one step of each identifier (the paper's and the refined
//! one beside it); a report of both every 100 ms.

use embedded_hal::delay::DelayNs;
use icm42688::{Config, Error, Icm42688, RegisterInterface, Saturation};
use identifier_core::{
    Counters, Estimate, FlightPipeline, Identifier, InertiaRatios, PipelineSettings, Refined,
    Rotors, SampleStatus, SettingsError, MAX_ROTORS,
};

use super::clock::SampleTime;
use super::health::SensorHealth;
use super::rate_check::RateCheck;
use super::report::ReportSchedule;
use super::rotor::speeds_of;
use super::{
    identifier_settings, pipeline_settings, refined_settings, BoardInputs, LoopCounters,
    NoBoardInputs, Report, SampleClock, SensorStatus, TensorReport,
};
use crate::bench;

/// Gyro initialisation attempts before giving up.
pub const INIT_ATTEMPTS: u32 = 5;
/// Data-ready is polled every this many microseconds, for up to two sample periods.
pub const POLL_US: u32 = 10;

/// The inputs of the last sample that went to the estimators: what the free-flight gate and
/// the tensor estimator of identifier-core take per sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleInputs {
    /// Angular rate, rad/s, sensor axes.
    pub gyro: [f32; 3],
    /// Specific force, m/s^2, sensor axes (zero in free flight).
    pub accel: [f32; 3],
    /// The rotors' momentum `h`, kg m^2/s, when the board gave their speeds
    /// ([`BoardInputs::wheel_speeds`]; zero went to the pipeline otherwise).
    pub momentum: Option<[f32; 3]>,
    /// The board flagged an actuator acting on the body ([`BoardInputs::actuated`]): the
    /// sample was kept out of the estimators.
    pub actuated: bool,
    /// Axes at the clip level.
    pub saturated: Saturation,
    /// The time step, s.
    pub dt: f32,
}

/// One sample as the sample path delivers it to the loop ([`SampleLoop::step_record`]): read
/// and screened by an interrupt on the board, or taken from a replayed log.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleRecord {
    /// Angular rate, rad/s, sensor axes.
    pub omega: [f32; 3],
    /// Specific force, m/s^2, sensor axes.
    pub accel: [f32; 3],
    /// The time since the previous sample, s (the identifiers').
    pub dt: f32,
    /// The time since the previous sample given to the pipeline, s: `dt`, or longer after
    /// samples the rate-jump check refused.
    pub pipeline_dt: f32,
    /// The rotors' speeds, rad/s, in the order of the loop's [`Rotors`].
    pub speeds: [f32; MAX_ROTORS],
    /// The speeds are known for this sample (else the momentum is zero).
    pub speeds_known: bool,
    /// An actuator acted on the body ([`BoardInputs::actuated`]).
    pub actuated: bool,
    /// The sample clock when this loop read it, us ([`SampleLoop::read_record`]); `None` for
    /// a replayed sample.
    pub read_at_us: Option<u32>,
    /// A replayed sample's extra momentum from a known external torque, kg m^2/s, added to
    /// the rotors' before the pipeline (the gravity-gradient torque's impulse (G2) of
    /// [`identifier_core::gravity`], as `inertia identify` adds it on an orbit log); `None`:
    /// none (always for a record read by the loop, which has no attitude or position).
    pub external_momentum: Option<[f32; 3]>,
}

/// Makes a new pipeline with `settings` and copies it into `dst`; false (and `dst` as it was)
/// when the settings are refused. The new pipeline is one temporary in this function's frame,
/// copied from by reference (a binding of it, or a move out of the `Option`, would be a second
/// copy of its tens of kilobytes on the stack).
#[inline(never)]
fn fresh_pipeline_into(dst: &mut FlightPipeline, settings: PipelineSettings, accel: bool) -> bool {
    let fresh = FlightPipeline::new(settings, accel);
    match &fresh {
        Some(p) => {
            *dst = *p;
            true
        }
        None => false,
    }
}

/// Why the loop could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InitError<E> {
    /// The gyro: bus, identity, timeout or configuration read-back.
    Gyro(Error<E>),
    /// The paper's identifier refused its settings.
    Settings(SettingsError),
    /// The refined identifier refused its settings.
    RefinedSettings,
    /// The free-flight pipeline refused its settings.
    PipelineSettings,
}

/// What one [`SampleLoop::poll`] did.
// `Stepped` carries the 10 Hz report (with the tensor estimate) by value: a copy of a few
// hundred bytes per sample, kept for the simple API rather than boxed (no heap).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Poll {
    /// A sample went through both identifiers; `report` is set every `odr / REPORT_HZ`
    /// periods.
    Stepped {
        /// The paper's identifier's step.
        paper: Estimate,
        /// The refined identifier's step (estimate as of its last completed block).
        refined: Estimate,
        /// The periodic report, when due.
        report: Option<Report>,
    },
    /// No data-ready within two sample periods (on the simulated part: the log has ended).
    Timeout,
    /// A bus error; counted, the sample's time is carried to the next step.
    BusError,
    /// The part marked the sample invalid; counted, its time carried to the next step.
    Invalid,
    /// The rate-jump check refused the sample; counted, its time carried to the next step.
    Implausible,
    /// The board flagged an actuator acting on the body ([`BoardInputs::actuated`]): the
    /// sample was kept out of the estimators; counted.
    HeldOut,
    /// The data stalled; the sensor was re-initialised.
    Stalled,
}

/// Why [`SampleLoop::read_record`] gave no record: [`Poll`]'s outcomes other than a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Unread {
    /// [`Poll::Timeout`].
    Timeout,
    /// [`Poll::BusError`].
    BusError,
    /// [`Poll::Invalid`].
    Invalid,
    /// [`Poll::Implausible`].
    Implausible,
    /// [`Poll::Stalled`].
    Stalled,
}

impl From<Unread> for Poll {
    fn from(u: Unread) -> Poll {
        match u {
            Unread::Timeout => Poll::Timeout,
            Unread::BusError => Poll::BusError,
            Unread::Invalid => Poll::Invalid,
            Unread::Implausible => Poll::Implausible,
            Unread::Stalled => Poll::Stalled,
        }
    }
}

/// The gyro, the sample clock and the two identifiers, wired together, with the defences
/// against a misbehaving sensor or bus: a rate-jump check on samples, dt from the sample
/// clock, re-initialisation after repeated failures, a wrong `WHO_AM_I` or stalled data, and
/// a periodic `WHO_AM_I` check.
pub struct SampleLoop<IF, C, R = NoBoardInputs> {
    gyro: Icm42688<IF>,
    /// The configuration the gyro is (re-)initialised with.
    config: Config,
    /// Data-ready polls before a timeout.
    max_polls: u32,
    clock: C,
    time: SampleTime,
    board: R,
    /// The known rotors whose momentum goes with each sample.
    rotors: Rotors,
    health: SensorHealth,
    rate_check: RateCheck,
    last_inputs: SampleInputs,
    /// The paper's identifier, fed every accepted sample.
    identifier: Identifier,
    /// The refined identifier beside the paper's, fed the same samples at the same time. The
    /// pipeline has a `Refined` of its own ([`FlightPipeline::refined`]), but it is another
    /// estimator: it sees only the free-flight samples its gate lets through, late by the
    /// delay line, with the gate's bias removed, decimated above 1.5 kHz, none once a rotor
    /// momentum is seen, and it restarts when a flight ends. The two agree bit for bit only
    /// without an accelerometer, a rotor or decimation, until the end of the flight; the
    /// reports' `a_refined` is this one's.
    refined: Refined,
    pipeline: FlightPipeline,
    /// Samples that left the pipeline's delay line unfed.
    not_fed: u32,
    /// The previous sample was flagged ([`BoardInputs::actuated`]).
    was_actuated: bool,
    /// The sensor's identity is to be checked before the next sample.
    check_identity: bool,
    /// The pipeline's stretch was ended by a flagged sample and none was fed since.
    flag_closed: bool,
    /// The pipeline gates free flights by the accelerometer (else: continuous mode).
    with_accel: bool,
    counters: LoopCounters,
    reports: ReportSchedule,
    /// A failed-sensor report not taken yet (kept out of the small `ReportSchedule`, which
    /// `new_with` builds before the pipeline).
    pending: Option<Report>,
}

impl<IF: RegisterInterface, C: SampleClock<IF>> SampleLoop<IF, C, NoBoardInputs> {
    /// Initialises the gyro with `config` (reset, identity, configuration; up to
    /// [`INIT_ATTEMPTS`] times, since a bus error or a slow reset is transient but a wrong
    /// identity is not), a fresh paper's identifier with [`identifier_settings`] and a fresh
    /// refined one with [`refined_settings`]; `clock` is the loop's time base.
    pub fn new(
        gyro: Icm42688<IF>,
        delay: &mut impl DelayNs,
        config: Config,
        clock: C,
    ) -> Result<Self, InitError<IF::Error>> {
        Self::new_with(
            gyro,
            delay,
            config,
            clock,
            NoBoardInputs,
            pipeline_settings(&config),
            true,
            Rotors::NONE,
        )
    }

    /// [`SampleLoop::new`] with the board's inputs (rotor speeds and actuator flags, read once
    /// per sample), the free-flight pipeline's settings (`with_accel = false` takes every
    /// sample as free flight, the continuous mode of a satellite; its `rate_hz` becomes the
    /// reports' time base) and the rotors whose momentum goes with each sample, all at once:
    /// the loop holds tens of kilobytes (the pipeline's block buffers), and building it in one
    /// go keeps its copies on the stack few.
    #[allow(clippy::too_many_arguments)]
    pub fn new_with<R: BoardInputs>(
        mut gyro: Icm42688<IF>,
        delay: &mut impl DelayNs,
        config: Config,
        mut clock: C,
        board: R,
        pipeline: PipelineSettings,
        with_accel: bool,
        rotors: Rotors,
    ) -> Result<SampleLoop<IF, C, R>, InitError<IF::Error>> {
        let mut attempt = 1;
        loop {
            match gyro.init(delay, config) {
                Ok(()) => break,
                Err(e @ Error::WrongId(_)) => return Err(InitError::Gyro(e)),
                Err(e) if attempt >= INIT_ATTEMPTS => return Err(InitError::Gyro(e)),
                Err(_) => attempt += 1,
            }
        }
        let identifier =
            Identifier::new(identifier_settings(&config)).map_err(InitError::Settings)?;
        let refined = Refined::new(refined_settings(&config)).ok_or(InitError::RefinedSettings)?;
        // The pipeline (36 KB) is made last, right before the loop that holds it: a call
        // between the two keeps it in a temporary of its own, a second copy on the stack.
        let now_us = clock.now_us(gyro.interface());
        let time = SampleTime::new(&config, pipeline.rate_hz, now_us);
        let reports = ReportSchedule::new(&config, now_us);
        // Two sample periods of polling before a timeout.
        let max_polls = (2 * config.odr.period_us() / POLL_US).max(2);
        let rate_check = RateCheck::new(&config);
        // `let ... else`, not `ok_or()?`, and no call between it and the loop: each would keep
        // the pipeline or the loop in a temporary of its own.
        let Some(pipeline) = FlightPipeline::new(pipeline, with_accel) else {
            return Err(InitError::PipelineSettings);
        };
        Ok(SampleLoop {
            gyro,
            config,
            max_polls,
            clock,
            time,
            board,
            rotors,
            health: SensorHealth::default(),
            rate_check,
            last_inputs: SampleInputs::default(),
            identifier,
            refined,
            pipeline,
            not_fed: 0,
            was_actuated: false,
            check_identity: false,
            flag_closed: false,
            with_accel,
            counters: LoopCounters::default(),
            reports,
            pending: None,
        })
    }

    /// The same loop with the board's inputs (rotor speeds, actuator flags) for the rotors
    /// `rotors`, read once per sample.
    pub fn with_board<R: BoardInputs>(self, board: R, rotors: Rotors) -> SampleLoop<IF, C, R> {
        SampleLoop {
            gyro: self.gyro,
            config: self.config,
            max_polls: self.max_polls,
            clock: self.clock,
            time: self.time,
            board,
            rotors,
            health: self.health,
            rate_check: self.rate_check,
            last_inputs: self.last_inputs,
            identifier: self.identifier,
            refined: self.refined,
            pipeline: self.pipeline,
            not_fed: self.not_fed,
            was_actuated: self.was_actuated,
            check_identity: self.check_identity,
            flag_closed: self.flag_closed,
            with_accel: self.with_accel,
            counters: self.counters,
            reports: self.reports,
            pending: self.pending,
        }
    }
}

impl<IF: RegisterInterface, C: SampleClock<IF>, R: BoardInputs> SampleLoop<IF, C, R> {
    /// Waits for the next sample, reads it, screens it and steps both identifiers with it;
    /// re-initialises the sensor when it stops making sense.
    pub fn poll(&mut self, delay: &mut impl DelayNs) -> Poll {
        bench::loop_begin();
        let p = self.poll_once(delay);
        // Only iterations that stepped end an interval (an unmatched begin is overwritten by
        // the next): the benchmark's figure is per sample, not per timed-out wait.
        if matches!(p, Poll::Stepped { .. }) {
            bench::loop_end();
        }
        p
    }

    fn poll_once(&mut self, delay: &mut impl DelayNs) -> Poll {
        let rec = match self.read_record(delay) {
            Ok(rec) => rec,
            Err(u) => return u.into(),
        };
        match self.step(&rec, 0) {
            Some((paper, refined, report)) => Poll::Stepped {
                paper,
                refined,
                report,
            },
            None => Poll::HeldOut,
        }
    }

    /// The sample path's first half, [`SampleLoop::poll`] up to the estimators: waits for the
    /// next sample, reads it with the board's inputs, screens it (saturation, stalled data,
    /// the sample clock, the rate-jump check) and re-initialises the sensor when it stops
    /// making sense. The record goes to [`SampleLoop::step_record`], at once or through a
    /// ring (a board whose sample interrupt reads the sensor, `firmware::app::fits`); `Err`
    /// says what happened instead (a refused sample's time is carried to the next record),
    /// as [`SampleLoop::poll`] would have.
    pub fn read_record(&mut self, delay: &mut impl DelayNs) -> Result<SampleRecord, Unread> {
        // The health check the previous sample made due: is it still our part? (Done here,
        // before the next wait, so that its transfers come where `poll` has always made
        // them.)
        if self.check_identity {
            self.check_identity = false;
            match self.gyro.who_am_i() {
                Ok(icm42688::registers::WHO_AM_I_VALUE) => {}
                Ok(_) => {
                    self.counters.wrong_id = self.counters.wrong_id.saturating_add(1);
                    self.reinit(delay);
                }
                Err(_) => {
                    self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
                }
            }
        }
        match self.gyro.wait_data_ready(delay, POLL_US, self.max_polls) {
            Ok(()) => {}
            Err(Error::Timeout) => {
                self.counters.timeouts = self.counters.timeouts.saturating_add(1);
                self.failure(delay);
                return Err(Unread::Timeout);
            }
            Err(_) => {
                self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
                self.failure(delay);
                return Err(Unread::BusError);
            }
        }
        // Accelerometer and gyro of the same sample, one 12-byte burst.
        let imu = match self.gyro.read_imu_raw() {
            Ok(imu) => imu,
            Err(Error::InvalidSample) => {
                self.counters.invalid = self.counters.invalid.saturating_add(1);
                self.failure(delay);
                return Err(Unread::Invalid);
            }
            Err(_) => {
                self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
                self.failure(delay);
                return Err(Unread::BusError);
            }
        };
        let raw = imu.gyro;
        let saturation = imu.saturation();
        if saturation.gyro_any() {
            self.counters.saturated = self.counters.saturated.saturating_add(1);
        }
        if saturation.accel_any() {
            self.counters.accel_saturated = self.counters.accel_saturated.saturating_add(1);
        }
        // Stalled data: the same six counts again and again.
        if self.health.stalled(imu, saturation.gyro_any()) {
            self.counters.stalled = self.counters.stalled.saturating_add(1);
            self.reinit(delay);
            return Err(Unread::Stalled);
        }

        // dt from the sample clock, in whole periods.
        let now = self.clock.now_us(self.gyro.interface());
        let periods = self.time.advance(now);
        self.counters.missed = self.counters.missed.saturating_add(periods - 1);
        self.reports.advance(periods);
        let dt = self.time.seconds_of(periods);

        let omega = icm42688::raw3_to_rad_s(raw, self.gyro.full_scale());
        let (speeds, speeds_known) = speeds_of(&mut self.board, &self.rotors);
        let momentum = speeds_known.then(|| self.rotors.momentum(&speeds));
        self.last_inputs = SampleInputs {
            gyro: omega,
            accel: icm42688::raw3_to_m_s2(imu.accel, self.gyro.accel_full_scale()),
            momentum,
            actuated: self.board.actuated(),
            saturated: saturation,
            dt,
        };

        // The rate-jump check (the plausibility gate). The pipeline gets the time since the
        // last sample it was given (refused ones included), as the identifiers do.
        let Some(dt_pipeline) = self.rate_check.check(omega, dt) else {
            // Refused like a non-finite sample: both identifiers carry its time.
            self.counters.implausible = self.counters.implausible.saturating_add(1);
            self.identifier.step([f32::NAN; 3], dt);
            self.refined.step([f32::NAN; 3], dt);
            return Err(Unread::Implausible);
        };
        Ok(SampleRecord {
            omega,
            accel: self.last_inputs.accel,
            dt,
            pipeline_dt: dt_pipeline,
            speeds,
            speeds_known,
            actuated: self.last_inputs.actuated,
            read_at_us: Some(now),
            external_momentum: None,
        })
    }

    /// One more consecutive failure; [`REINIT_AFTER`](super::REINIT_AFTER) of them
    /// re-initialise the sensor. When no report has gone out for
    /// [`FAILED_REPORT_AFTER`](super::FAILED_REPORT_AFTER) report periods (by the sample
    /// clock), a report marked [`SensorStatus::Failed`] is queued
    /// ([`SampleLoop::take_failed_report`]): the 10 Hz stream goes on while the sensor is
    /// down.
    fn failure(&mut self, delay: &mut impl DelayNs) {
        if self.health.failure() {
            self.reinit(delay);
        }
        let now = self.clock.now_us(self.gyro.interface());
        if self.reports.failed_due(now) {
            let mut r = self.report();
            r.sensor = SensorStatus::Failed;
            self.reports.sent(self.counters.saturated);
            self.pending = Some(r);
        }
    }

    /// A report queued while the sensor is failing (see [`SensorStatus::Failed`]), once:
    /// call after every [`SampleLoop::poll`] and send it like a periodic one.
    pub fn take_failed_report(&mut self) -> Option<Report> {
        self.pending.take()
    }

    /// Starts the estimators over as [`SampleLoop::new_with`] made them, with the same
    /// settings, rotors and accelerometer choice: a fresh paper's and refined identifier, a
    /// fresh free-flight pipeline, zero counters, the report schedule and time base from the
    /// clock's reading now. The gyro is left as it is (not re-initialised). For a replay's
    /// next pass over the same log (the gravity-gradient passes of an orbit log, QEMU
    /// `--replay`). Not inlined: the new pipeline (tens of kilobytes) is made in this
    /// function's frame, gone once it returns.
    #[inline(never)]
    pub fn restart(&mut self) -> Result<(), InitError<IF::Error>> {
        let settings = *self.pipeline.settings();
        self.identifier =
            Identifier::new(identifier_settings(&self.config)).map_err(InitError::Settings)?;
        self.refined =
            Refined::new(refined_settings(&self.config)).ok_or(InitError::RefinedSettings)?;
        let now_us = self.clock.now_us(self.gyro.interface());
        self.time = SampleTime::new(&self.config, settings.rate_hz, now_us);
        self.reports = ReportSchedule::new(&self.config, now_us);
        self.health = SensorHealth::default();
        self.rate_check = RateCheck::new(&self.config);
        self.last_inputs = SampleInputs::default();
        self.not_fed = 0;
        self.was_actuated = false;
        self.check_identity = false;
        self.flag_closed = false;
        self.counters = LoopCounters::default();
        self.pending = None;
        if fresh_pipeline_into(&mut self.pipeline, settings, self.with_accel) {
            Ok(())
        } else {
            Err(InitError::PipelineSettings)
        }
    }

    /// Ends the free flight being fed, if any (a replayed log has ended): its trajectory is
    /// fitted now, as at a catch, so the final report includes it. The host tool does the same
    /// at the end of a log, which keeps the two bit for bit equal.
    pub fn end_flight(&mut self) {
        self.pipeline.end_stretch();
    }

    /// True when a free flight has ended and its output-error fits wait
    /// ([`SampleLoop::fit_ended_flight`]).
    pub fn fits_pending(&self) -> bool {
        self.pipeline.fits_pending()
    }

    /// Runs the output-error fits of the flight that ended (up to about 0.3 s at 168 MHz: call
    /// it between samples, with the watchdog stretched). True when they ran.
    pub fn fit_ended_flight(&mut self) -> bool {
        self.pipeline.fit_ended_flight()
    }

    /// One sample into the free-flight pipeline: the rotors' momentum from the board's speeds
    /// of this sample (zero without rotors or speeds), the pipeline's free-flight gate decides,
    /// the delay line commits.
    fn feed_pipeline(&mut self, omega: [f32; 3], accel: [f32; 3], dt: f32) {
        self.was_actuated = false;
        self.flag_closed = false;
        let h = self.last_inputs.momentum.unwrap_or([0.0; 3]);
        let exit = self.pipeline.step(omega, accel, h, dt);
        if let Some(e) = exit {
            if e.fed.is_none() {
                self.not_fed = self.not_fed.saturating_add(1);
            }
        }
    }

    /// A sample the board flagged ([`BoardInputs::actuated`]): a torque acts on the body, so
    /// neither the identifiers nor the free-flight pipeline take it. At the first of a run of
    /// them the identifiers restart their integration (keeping what they learnt) and the
    /// pipeline's stretch ends ([`FlightPipeline::close_stretch`]): its fits wait, as at a
    /// catch, and the next unflagged sample starts a new stretch.
    fn hold_out(&mut self) {
        self.counters.held_out = self.counters.held_out.saturating_add(1);
        self.flag_closed = true;
        if !self.was_actuated {
            self.identifier.restart();
            self.refined.restart();
            self.pipeline.close_stretch();
            self.was_actuated = true;
        }
    }

    /// One sample as the sample path delivers it: read by this loop
    /// ([`SampleLoop::read_record`]: on a board whose sample interrupt reads the sensor and
    /// steps the ring) or taken from a replayed log (QEMU `--replay`, host checks: the values
    /// the host tool `inertia identify` feeds its pipeline, bypassing the driver, the rate-jump
    /// check and the sample clock). To the pipeline and both identifiers, or held out when
    /// flagged ([`BoardInputs::actuated`]); the rotors' momentum is [`Rotors::momentum`] of the
    /// record's speeds. A report is returned when due: by the sample clock for a record read
    /// here, every `report_every` samples for a replayed one.
    pub fn step_record(&mut self, rec: &SampleRecord, report_every: u32) -> Option<Report> {
        self.step(rec, report_every).and_then(|(_, _, r)| r)
    }

    /// [`SampleLoop::step_record`] with both identifiers' steps; `None` when held out.
    fn step(
        &mut self,
        rec: &SampleRecord,
        report_every: u32,
    ) -> Option<(Estimate, Estimate, Option<Report>)> {
        if rec.read_at_us.is_none() {
            bench::loop_begin();
            let momentum = (rec.speeds_known && !self.rotors.is_empty())
                .then(|| self.rotors.momentum(&rec.speeds));
            // The external torque's momentum added as `inertia identify` adds it.
            let momentum = match rec.external_momentum {
                Some([g0, g1, g2]) => {
                    let [h0, h1, h2] = momentum.unwrap_or([0.0; 3]);
                    Some([h0 + g0, h1 + g1, h2 + g2])
                }
                None => momentum,
            };
            self.last_inputs = SampleInputs {
                gyro: rec.omega,
                accel: rec.accel,
                momentum,
                actuated: rec.actuated,
                saturated: Saturation::default(),
                dt: rec.dt,
            };
            self.time.advance_one();
            self.reports.advance(1);
        }
        let estimates = if rec.actuated {
            self.hold_out();
            None
        } else {
            self.feed_pipeline(rec.omega, rec.accel, rec.pipeline_dt);
            bench::step_begin();
            let paper = self.identifier.step(rec.omega, rec.dt);
            bench::step_end();
            bench::refined_begin();
            let refined = self.refined.step(rec.omega, rec.dt);
            bench::refined_end();
            self.count(&paper);
            Some((paper, refined))
        };
        let report = match rec.read_at_us {
            Some(now) => {
                let (paper, refined) = estimates?;
                self.health.sample_ok();
                let report = if self.reports.due(now) {
                    let r = self.report();
                    self.reports.sent(self.counters.saturated);
                    Some(r)
                } else {
                    None
                };
                // Is it still our part? Asked before the next sample's wait.
                self.check_identity = self.health.check_due();
                return Some((paper, refined, report));
            }
            None => {
                bench::loop_end();
                self.reports.due_every(report_every).then(|| self.report())
            }
        };
        estimates.map(|(p, r)| (p, r, report))
    }

    /// The free-flight pipeline's estimate as reported.
    pub fn tensor_report(&self) -> TensorReport {
        TensorReport::of(&self.pipeline, self.not_fed)
    }

    /// Copies the free-flight pipeline into `slot` (a fit's own copy, [`super::fits`]): a
    /// straight copy of its tens of kilobytes, not through the stack.
    pub fn copy_pipeline_into(&self, slot: &mut FlightPipeline) {
        *slot = self.pipeline;
    }

    /// Takes the ended flight's fits from `fitted`, a copy made by
    /// [`SampleLoop::copy_pipeline_into`] while they were pending, on which they have run
    /// ([`FlightPipeline::adopt_fits`]); false when refused.
    pub fn adopt_fits(&mut self, fitted: &FlightPipeline) -> bool {
        self.pipeline.adopt_fits(fitted)
    }

    /// The samples of the loop that left the pipeline's delay line unfed.
    pub fn not_fed(&self) -> u32 {
        self.not_fed
    }

    /// True when the pipeline's stretch was ended by a flagged sample
    /// ([`BoardInputs::actuated`]) and no sample was fed since.
    pub fn stretch_closed_by_flag(&self) -> bool {
        self.flag_closed
    }

    /// True when the pipeline has an accelerometer's free-flight gate; false in the continuous
    /// mode, where every unflagged sample is fed.
    pub fn with_accel(&self) -> bool {
        self.with_accel
    }

    /// The free-flight pipeline.
    pub fn pipeline(&self) -> &FlightPipeline {
        &self.pipeline
    }

    /// The inputs of the last sample given to the estimators (gyro, accelerometer, rotor
    /// speed, saturation, dt).
    pub fn last_inputs(&self) -> SampleInputs {
        self.last_inputs
    }

    /// Resets and reconfigures the part (up to [`INIT_ATTEMPTS`] times; if all fail, the
    /// next failures bring another attempt). Both identifiers restart their integration but
    /// keep what they learnt. The clock runs on: the time the re-initialisation took shows in
    /// `missed`.
    fn reinit(&mut self, delay: &mut impl DelayNs) {
        self.counters.reinits = self.counters.reinits.saturating_add(1);
        self.identifier.restart();
        self.refined.restart();
        self.health.restart();
        self.rate_check.restart();
        for _ in 0..INIT_ATTEMPTS {
            match self.gyro.init(delay, self.config) {
                Ok(()) => return,
                Err(Error::WrongId(_)) => {
                    self.counters.wrong_id = self.counters.wrong_id.saturating_add(1);
                }
                Err(_) => {}
            }
            self.counters.reinit_failures = self.counters.reinit_failures.saturating_add(1);
        }
    }

    fn count(&mut self, e: &Estimate) {
        let c = &mut self.counters;
        c.samples = c.samples.saturating_add(1);
        if !e.status.integrated() && e.status != SampleStatus::Anchored {
            c.skipped = c.skipped.saturating_add(1);
        }
    }

    /// The report as of now.
    pub fn report(&self) -> Report {
        let a = self.refined.estimate();
        Report {
            tick: self.time.tick(),
            t: self.time.t(),
            a_paper: self.identifier.estimate(),
            convergence_paper: self.identifier.convergence(),
            a_refined: a,
            std_refined: self.refined.std_a(),
            ratios: InertiaRatios::from_a(a),
            consistency: identifier_core::consistency(a),
            convergence_refined: self.refined.convergence(),
            counters: self.counters,
            saturated_recent: self.reports.saturated_recent(self.counters.saturated),
            sensor: SensorStatus::Ok,
            momentum: self.last_inputs.momentum,
            tensor: self.tensor_report(),
        }
    }

    /// The loop's counters.
    pub fn counters(&self) -> LoopCounters {
        self.counters
    }

    /// The paper's identifier's own counters.
    pub fn identifier_counters(&self) -> Counters {
        self.identifier.counters()
    }

    /// The refined identifier's own counters.
    pub fn refined_counters(&self) -> Counters {
        self.refined.counters()
    }

    /// The paper's identifier.
    pub fn identifier(&self) -> &Identifier {
        &self.identifier
    }

    /// The refined identifier.
    pub fn refined(&self) -> &Refined {
        &self.refined
    }

    /// The gyro driver (on QEMU: reaches the simulated part's state).
    pub fn gyro(&self) -> &Icm42688<IF> {
        &self.gyro
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::app::{NoDelay, GATE_RELEARN};
    use icm42688::sim::{SampleSource, SimIcm42688};
    use icm42688::SpiInterface;

    /// The simulated part's clock: its latched samples times the period.
    fn sim_clock<S: SampleSource>(i: &SpiInterface<SimIcm42688<S>>) -> u32 {
        i.bus()
            .stats()
            .samples
            .wrapping_mul(Config::identifier().odr.period_us())
    }

    /// A torque-free spin sampled crudely (explicit midpoint at 1 kHz) is enough for the
    /// loop's bookkeeping; accuracy is tested end to end.
    fn spin(n: usize) -> impl FnMut() -> Option<[f32; 3]> {
        let a = [0.9f32, 0.4 / 1.54, -0.94];
        let mut w = [1.0f32, 1.0, 1.0];
        let mut k = 0;
        move || {
            if k == n {
                return None;
            }
            k += 1;
            let h = 1e-3f32;
            let f = |w: [f32; 3]| [a[0] * w[1] * w[2], a[1] * w[2] * w[0], a[2] * w[0] * w[1]];
            let d = f(w);
            let m = [
                w[0] + 0.5 * h * d[0],
                w[1] + 0.5 * h * d[1],
                w[2] + 0.5 * h * d[2],
            ];
            let d = f(m);
            w = [w[0] + h * d[0], w[1] + h * d[1], w[2] + h * d[2]];
            Some(w)
        }
    }

    #[test]
    fn reports_at_10_hz_counts_bus_errors_and_ends_with_timeout() {
        // Init hits injected errors too, and retries.
        let sim = SimIcm42688::new(spin(2000)).with_bus_error_every(23);
        let mut lp = SampleLoop::new(
            Icm42688::new_spi(sim),
            &mut NoDelay,
            Config::identifier(),
            sim_clock,
        )
        .unwrap();
        let mut reports = 0;
        let mut last = None;
        // With a bus error every 23 transfers a 200-poll wait never times out: the end of
        // the log is seen on the simulated part, as the QEMU firmware does.
        while !lp.gyro().interface().bus().exhausted() {
            if let Poll::Stepped {
                report: Some(r), ..
            } = lp.poll(&mut NoDelay)
            {
                reports += 1;
                last = Some(r);
            }
        }
        let c = lp.counters();
        assert!(c.bus_errors > 10, "{c:?}");
        let r = last.unwrap();
        assert_eq!(r.tick % 100, 0);
        assert!((19..=20).contains(&reports), "{reports}");
        assert!(lp.gyro().interface().bus().exhausted());
        // Every sample the simulated part latched was either stepped or lost to a bus error.
        let latched = lp.gyro().interface().bus().stats().samples;
        assert_eq!(latched, 2000);
        assert!(c.samples <= latched && c.samples + c.bus_errors >= latched);
    }

    #[test]
    fn gate_sample_clock_and_stall_are_counted_and_handled() {
        // A glitch at sample 500 (a jump no torque-free motion can make in 1 ms), data frozen
        // for 30 samples from 1000, and the clock jumping 5 periods at sample 2000 (samples
        // lost on the way).
        let mut inner = spin(3000);
        let (mut k, mut held) = (0u32, [0.0f32; 3]);
        let source = move || {
            let w = inner()?;
            k += 1;
            if k == 1000 {
                held = w;
            }
            Some(match k {
                500 => [w[0] + 2.0, w[1], w[2]],
                1000..=1029 => held,
                _ => w,
            })
        };
        let clock = |i: &SpiInterface<SimIcm42688<_>>| {
            let n = i.bus().stats().samples;
            n.wrapping_mul(1000) + if n >= 2000 { 5000 } else { 0 }
        };
        let sim = SimIcm42688::new(source);
        let mut lp = SampleLoop::new(
            Icm42688::new_spi(sim),
            &mut NoDelay,
            Config::identifier(),
            clock,
        )
        .unwrap();
        while !lp.gyro().interface().bus().exhausted() {
            lp.poll(&mut NoDelay);
        }
        let c = lp.counters();
        // The glitch, and the return from the frozen data (30 ms of motion in one step),
        // refused until GATE_RELEARN samples in a row agree.
        assert!((1..=GATE_RELEARN).contains(&c.implausible), "{c:?}");
        assert_eq!((c.stalled, c.reinits, c.wrong_id), (1, 1, 0), "{c:?}");
        assert!(c.missed >= 5, "{c:?}");
        assert_eq!(c.bus_errors + c.invalid, 0, "{c:?}");
        // The time base includes the lost periods.
        let latched = lp.gyro().interface().bus().stats().samples;
        assert!(lp.report().tick + 5 >= latched, "{}", lp.report().tick);
        let a = [0.9f32, 0.4 / 1.54, -0.94];
        for (x, t) in lp.refined().estimate().iter().zip(a) {
            assert!((x - t).abs() < 1e-2, "{:?}", lp.refined().estimate());
        }
    }

    #[test]
    fn reports_carry_both_estimates() {
        let sim = SimIcm42688::new(spin(1000));
        let mut lp = SampleLoop::new(
            Icm42688::new_spi(sim),
            &mut NoDelay,
            Config::identifier(),
            sim_clock,
        )
        .unwrap();
        while !lp.gyro().interface().bus().exhausted() {
            lp.poll(&mut NoDelay);
        }
        let r = lp.report();
        assert_eq!(r.a_paper, lp.identifier().estimate());
        assert_eq!(r.a_refined, lp.refined().estimate());
        assert_eq!(r.consistency, identifier_core::consistency(r.a_refined));
        assert_eq!(lp.refined_counters().integrated + 1, r.counters.samples);
        // The crude 1 kHz midpoint spin is not exactly (1), but close.
        let a = [0.9f32, 0.4 / 1.54, -0.94];
        for (x, t) in r.a_refined.iter().zip(a) {
            assert!((x - t).abs() < 1e-2, "{:?}", r.a_refined);
        }
    }

    /// One wheel at a constant speed.
    struct OneWheel(f32);

    impl BoardInputs for OneWheel {
        fn wheel_speeds(&mut self, speeds: &mut [f32; MAX_ROTORS]) -> bool {
            speeds[0] = self.0;
            true
        }
    }

    #[test]
    fn clipped_readings_on_all_axes_are_saturation_not_stall() {
        // 200 samples of a spin beyond +-2000 dps on every axis: identical clipped readings.
        let mut k = 0;
        let source = move || {
            k += 1;
            (k <= 300).then_some(if (50..250).contains(&k) {
                [40.0, -40.0, 40.0]
            } else {
                [1.0 + k as f32 * 1e-3, 1.0, 1.0]
            })
        };
        let mut lp = SampleLoop::new(
            Icm42688::new_spi(SimIcm42688::new(source)),
            &mut NoDelay,
            Config::identifier(),
            sim_clock,
        )
        .unwrap()
        .with_board(
            OneWheel(12.5),
            Rotors::new(&[identifier_core::Rotor::new(2.0, [0.0, 0.0, -1.0])]).unwrap(),
        );
        let mut warned = 0;
        while !lp.gyro().interface().bus().exhausted() {
            if let Poll::Stepped {
                report: Some(r), ..
            } = lp.poll(&mut NoDelay)
            {
                warned += u32::from(r.saturated_recent > 0);
                assert_eq!(r.sensor, SensorStatus::Ok);
            }
        }
        let c = lp.counters();
        assert_eq!(c.saturated, 200, "{c:?}");
        assert_eq!((c.stalled, c.reinits), (0, 0), "{c:?}");
        assert!(warned >= 2, "{warned}");
        assert_eq!(lp.last_inputs().momentum, Some([0.0, 0.0, -25.0]));
        assert_eq!(lp.report().momentum, Some([0.0, 0.0, -25.0]));
        assert_eq!(lp.last_inputs().accel, [0.0; 3]);
    }

    #[test]
    fn reports_go_on_at_10_hz_while_the_sensor_is_dead() {
        // A clock that runs on while every transfer fails (bus dead after 500 samples).
        use core::cell::Cell;
        let t = Cell::new(0u32);
        let clock = |_: &SpiInterface<SimIcm42688<_>>| {
            t.set(t.get() + 100);
            t.get()
        };
        let sim = SimIcm42688::new(spin(500));
        let mut lp = SampleLoop::new(
            Icm42688::new_spi(sim),
            &mut NoDelay,
            Config::identifier(),
            clock,
        )
        .unwrap();
        let (mut ok, mut failed) = (0, 0);
        // 50 000 polls at 100 us of clock each: 5 s, most of it after the log ended.
        for _ in 0..50_000 {
            if let Poll::Stepped {
                report: Some(_), ..
            } = lp.poll(&mut NoDelay)
            {
                ok += 1;
            }
            if let Some(r) = lp.take_failed_report() {
                assert_eq!(r.sensor, SensorStatus::Failed);
                failed += 1;
            }
        }
        assert!(ok >= 1, "{ok}");
        // About 10 a second once the sensor is silent.
        assert!((30..=60).contains(&failed), "{failed}");
        assert!(lp.counters().timeouts > 0);
    }
}
