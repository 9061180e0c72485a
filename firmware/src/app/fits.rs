//! The end-of-flight fits off the sample path.
//!
//! The sample path is an interrupt: it reads each sample (and the board's inputs) and pushes
//! a [`SampleRecord`] into a bounded single-producer single-consumer ring. A [`Stepper`], in
//! an interrupt of lower priority, steps the [`SampleLoop`] with what waits in the ring. The
//! output-error fits (up to about 5e7 instructions, a third of a second at 168 MHz) run in
//! thread mode, the lowest priority, on a copy of the pipeline in a slot of its own (a
//! [`FitJob`]): the stepper keeps stepping new samples meanwhile, and takes the fits back
//! ([`SampleLoop::adopt_fits`]) when the job returns. The ring holds only the jitter between
//! the two interrupts, not a fit's duration.
//!
//! Two kinds of job ([`FitKind`]):
//! * a flight (or a stretch) ended: its fits run on the copy and are adopted by the live
//!   pipeline, the same bits as running them in place at the time of the copy;
//! * continuous mode's periodic re-fit (every [`FitScheduler::refit_every`] samples fed): the
//!   open stretch of the copy is ended and fitted, and its estimate is the latest; the live
//!   pipeline goes on with the stretch untouched, so the fit at the end of the window is the
//!   one `inertia identify` gives for the same samples.
//!
//! The same holds for a window of a long flight ((W1) of the pipeline: it closes after a
//! bounded turn and its fits are pending while the flight goes on being fed).
//!
//! When the live pipeline would feed a sample while its fits are still out, it would run them
//! itself, in the stepper: a stall of the sample path, and a second fit's stack on top of
//! thread mode's. So a sample that could be fed does not reach it until the job returns
//! ([`FitScheduler::hold`]):
//! * after a stretch that a flagged sample ended (continuous mode), it is held out like a
//!   flagged one (stepped, not fed; [`StepStats::held_for_fit`]): the stretch has ended
//!   anyway, and the new one starts with the first sample after the job returned. A fit of a
//!   long stretch takes seconds (`scripts/firmware-paced.sh` measures it), longer than a ring
//!   can hold;
//! * otherwise (a window closed, or the gate ended a flight and holds free flight again) it
//!   waits in the ring: the window's flight goes on, and the gate must see every sample in
//!   order. A new flight is fed only from the delay line's length after the gate opens, so
//!   the sample that opens it is stepped safely. A throw that follows a catch faster than a
//!   fit runs (about a third of a second), or a window's fit longer than the ring's time,
//!   fills the ring, and what finds it full is lost and counted by the sample path.
//!
//! [`StepStats::inline_fits`] counts fits the live pipeline ran itself anyway (none by
//! construction; the checks assert it).

use embedded_hal::delay::DelayNs;
use heapless::spsc::{Consumer, Producer};
use icm42688::RegisterInterface;
use identifier_core::FlightPipeline;

use super::{BoardInputs, Report, SampleClock, SampleLoop, SampleRecord, TensorReport};

/// What the sample interrupt's read did ([`read_into_ring`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RingRead {
    /// No record: none was due or the sample was refused ([`SampleLoop::read_record`]'s `Err`).
    Nothing,
    /// The record is in the ring, which now holds this many.
    Queued(usize),
    /// The ring was full: the record is lost (the sample path counts it).
    Dropped,
}

/// The sample interrupt's read, one function for the board and the QEMU image: one record
/// through `lp` ([`SampleLoop::read_record`]) into `ring`, and the report of a failing sensor
/// ([`SampleLoop::take_failed_report`]) into `reports` (dropped when that queue is full, as
/// it is not the sample path's to wait).
pub fn read_into_ring<IF, C, R>(
    lp: &mut SampleLoop<IF, C, R>,
    delay: &mut impl DelayNs,
    ring: &mut Producer<'_, SampleRecord>,
    reports: &mut Producer<'_, Report>,
) -> RingRead
where
    IF: RegisterInterface,
    C: SampleClock<IF>,
    R: BoardInputs,
{
    let read = match lp.read_record(delay) {
        Ok(rec) => match ring.enqueue(rec) {
            Ok(()) => RingRead::Queued(ring.len()),
            Err(_) => RingRead::Dropped,
        },
        Err(_) => RingRead::Nothing,
    };
    if let Some(r) = lp.take_failed_report() {
        let _ = reports.enqueue(r);
    }
    read
}

/// What a [`FitJob`] does with its copy of the pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FitKind {
    /// The flight, stretch or window ((W1) of the pipeline) that ended: its fits, to be adopted
    /// by the live pipeline.
    EndedFlight,
    /// Continuous mode's periodic re-fit of the window so far: the copy's open stretch ended
    /// and fitted; reported, not adopted.
    Refit,
}

/// A fit to run off the sample path on a copy of the pipeline.
#[derive(Debug)]
pub struct FitJob<'a> {
    /// What to do.
    pub kind: FitKind,
    /// The copy (the fit slot).
    pub pipeline: &'a mut FlightPipeline,
    /// The loop's unfed samples when the copy was made (for the report).
    pub not_fed: u32,
    /// The sample clock (samples delivered) when the copy was made.
    pub started: u32,
    /// The sample clock when the fit had run ([`FitJob::run`]).
    pub finished: u32,
    /// The copy's estimate after the fit.
    pub report: Option<TensorReport>,
}

impl FitJob<'_> {
    /// Runs the fit (the long part: call it where it may take a third of a second);
    /// `now` is the sample clock when it has run.
    pub fn run(&mut self, now: impl FnOnce() -> u32) {
        match self.kind {
            FitKind::EndedFlight => {
                self.pipeline.fit_ended_flight();
            }
            FitKind::Refit => self.pipeline.end_stretch(),
        }
        self.report = Some(TensorReport::of(self.pipeline, self.not_fed));
        self.finished = now();
    }

    /// The fit's latency in samples of the sample clock.
    pub fn latency(&self) -> u32 {
        self.finished.wrapping_sub(self.started)
    }
}

/// When a fit job is due.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FitScheduler {
    /// Continuous mode's re-fit period in input samples fed (0: no periodic re-fit).
    pub refit_every: u32,
    /// Samples fed at the last re-fit.
    fed_at_refit: u32,
}

impl FitScheduler {
    /// A schedule re-fitting every `refit_every` samples fed (0: only ended flights).
    pub const fn new(refit_every: u32) -> Self {
        FitScheduler {
            refit_every,
            fed_at_refit: 0,
        }
    }

    /// The re-fit period in samples for one of `seconds` at `rate_hz` samples a second (0, no
    /// re-fit, when either is not positive and finite or the period is beyond `u32`).
    pub fn samples_for(seconds: f32, rate_hz: f32) -> u32 {
        let n = seconds * rate_hz + 0.5;
        if (1.0..4.0e9).contains(&n) {
            n as u32
        } else {
            0
        }
    }

    /// The job due now, given the fit slot is free: an ended flight's fits first, then a
    /// periodic re-fit once `refit_every` more samples were fed.
    pub fn due<IF, C, R>(&mut self, lp: &SampleLoop<IF, C, R>) -> Option<FitKind>
    where
        IF: RegisterInterface,
        C: SampleClock<IF>,
        R: BoardInputs,
    {
        if lp.fits_pending() {
            return Some(FitKind::EndedFlight);
        }
        let fed = lp.pipeline().fed_inputs();
        if self.refit_every > 0 && fed.wrapping_sub(self.fed_at_refit) >= self.refit_every {
            self.fed_at_refit = fed;
            return Some(FitKind::Refit);
        }
        None
    }

    /// True when `next` must not reach the pipeline yet: the live pipeline's fits are pending
    /// (out on a copy, or waiting for the slot) and `next` could be fed, which would run them
    /// in place: an unflagged sample while the pipeline takes samples as free (always without
    /// an accelerometer; with one, while its gate holds free flight).
    pub fn hold<IF, C, R>(&self, lp: &SampleLoop<IF, C, R>, next: &SampleRecord) -> bool
    where
        IF: RegisterInterface,
        C: SampleClock<IF>,
        R: BoardInputs,
    {
        lp.fits_pending() && lp.pipeline().in_free_flight() && !next.actuated
    }
}

/// What the stepper did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepStats {
    /// Samples stepped.
    pub stepped: u32,
    /// Times a sample waited in the ring for a fit ([`FitScheduler::hold`], with the gate).
    pub holds: u32,
    /// Samples held out while a fit ran ([`FitScheduler::hold`], continuous mode).
    pub held_for_fit: u32,
    /// Fit jobs handed out.
    pub jobs: u32,
    /// Ended flights' fits adopted from their job.
    pub adopted: u32,
    /// Ended flights' fits the live pipeline ran itself in the stepper (a new flight began
    /// before their job returned).
    pub inline_fits: u32,
    /// Reports that found the report queue full.
    pub reports_dropped: u32,
}

/// The stepping side: steps the loop with the ring's samples and hands fit jobs out and
/// takes them back (see the module docs).
pub struct Stepper<'a> {
    /// The fit slot while it is home.
    slot: Option<&'a mut FlightPipeline>,
    /// The job's kind while the slot is out.
    out: Option<FitKind>,
    schedule: FitScheduler,
    report_every: u32,
    /// What was done.
    pub stats: StepStats,
}

impl<'a> Stepper<'a> {
    /// A stepper with its fit slot, re-fitting every `refit_every` samples fed (0: never),
    /// reporting every `report_every` samples.
    pub fn new(slot: &'a mut FlightPipeline, refit_every: u32, report_every: u32) -> Self {
        Stepper {
            slot: Some(slot),
            out: None,
            schedule: FitScheduler::new(refit_every),
            report_every,
            stats: StepStats::default(),
        }
    }

    /// True while a fit job is out.
    pub fn job_out(&self) -> bool {
        self.out.is_some()
    }

    /// Steps what waits in `ring` (stopping at a sample that must wait for a fit); between
    /// samples, takes a returned job from `done` (adopting an ended flight's fits) and hands a
    /// due one to `jobs`. Reports go to `reports`; `now` is the sample clock.
    pub fn run<IF, C, R>(
        &mut self,
        lp: &mut SampleLoop<IF, C, R>,
        ring: &mut Consumer<'_, SampleRecord>,
        jobs: &mut Producer<'_, FitJob<'a>>,
        done: &mut Consumer<'_, FitJob<'a>>,
        reports: &mut Producer<'_, Report>,
        now: u32,
    ) where
        IF: RegisterInterface,
        C: SampleClock<IF>,
        R: BoardInputs,
    {
        loop {
            self.collect(lp, done);
            self.offer(lp, jobs, now);
            let Some(next) = ring.peek() else {
                return;
            };
            let hold = self.schedule.hold(lp, next);
            if hold && !lp.stretch_closed_by_flag() {
                self.stats.holds = self.stats.holds.saturating_add(1);
                return;
            }
            let Some(mut rec) = ring.dequeue() else {
                return;
            };
            if hold {
                rec.actuated = true;
                self.stats.held_for_fit = self.stats.held_for_fit.saturating_add(1);
            }
            let pending = lp.fits_pending();
            if let Some(r) = lp.step_record(&rec, self.report_every) {
                if reports.enqueue(r).is_err() {
                    self.stats.reports_dropped = self.stats.reports_dropped.saturating_add(1);
                }
            }
            if pending && !lp.fits_pending() {
                self.stats.inline_fits = self.stats.inline_fits.saturating_add(1);
            }
            self.stats.stepped = self.stats.stepped.saturating_add(1);
        }
    }

    /// Takes a returned job: the slot comes home, an ended flight's fits are adopted.
    pub fn collect<IF, C, R>(
        &mut self,
        lp: &mut SampleLoop<IF, C, R>,
        done: &mut Consumer<'_, FitJob<'a>>,
    ) where
        IF: RegisterInterface,
        C: SampleClock<IF>,
        R: BoardInputs,
    {
        if let Some(job) = done.dequeue() {
            if job.kind == FitKind::EndedFlight && lp.adopt_fits(job.pipeline) {
                self.stats.adopted = self.stats.adopted.saturating_add(1);
            }
            self.slot = Some(job.pipeline);
            self.out = None;
        }
    }

    /// Hands out the job due now, if the slot is home.
    fn offer<IF, C, R>(
        &mut self,
        lp: &SampleLoop<IF, C, R>,
        jobs: &mut Producer<'_, FitJob<'a>>,
        now: u32,
    ) where
        IF: RegisterInterface,
        C: SampleClock<IF>,
        R: BoardInputs,
    {
        if self.slot.is_none() {
            return;
        }
        let Some(kind) = self.schedule.due(lp) else {
            return;
        };
        let Some(slot) = self.slot.take() else {
            return;
        };
        lp.copy_pipeline_into(slot);
        let job = FitJob {
            kind,
            pipeline: slot,
            not_fed: lp.not_fed(),
            started: now,
            finished: now,
            report: None,
        };
        match jobs.enqueue(job) {
            Ok(()) => {
                self.out = Some(kind);
                self.stats.jobs = self.stats.jobs.saturating_add(1);
            }
            // The job queue holds one job and the slot is one: it cannot be full.
            Err(job) => self.slot = Some(job.pipeline),
        }
    }

    /// The slot, when it is home (at the end, to run the last fits in place).
    pub fn slot_home(&self) -> bool {
        self.slot.is_some()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    extern crate std;
    use super::*;
    use crate::app::NoDelay;
    use heapless::spsc::Queue;
    use icm42688::sim::SimIcm42688;
    use icm42688::{Config, Icm42688, SpiInterface};
    use identifier_core::{PipelineSettings, Rotor, Rotors};

    type Bus = SpiInterface<SimIcm42688<fn() -> Option<[f32; 3]>>>;
    type Loop = SampleLoop<Bus, fn(&Bus) -> u32, crate::app::NoBoardInputs>;

    fn no_samples() -> Option<[f32; 3]> {
        None
    }

    fn clock(_: &Bus) -> u32 {
        0
    }

    /// A loop without an accelerometer (continuous mode) at 10 Hz with two wheels.
    fn new_loop() -> Loop {
        let rotors = Rotors::new(&[
            Rotor::new(1e-3, [1.0, 0.0, 0.0]),
            Rotor::new(1e-3, [0.0, 0.6, 0.8]),
        ])
        .unwrap();
        SampleLoop::new_with(
            Icm42688::new_spi(SimIcm42688::new(no_samples as fn() -> Option<[f32; 3]>)),
            &mut NoDelay,
            Config::identifier(),
            clock as fn(&Bus) -> u32,
            crate::app::NoBoardInputs,
            PipelineSettings::for_rate(10.0, 1e-3),
            false,
            rotors,
        )
        .unwrap()
    }

    /// A torque-free tumble of a body with inertia (0.2, 0.3, 0.45) kg m^2 whose two wheels
    /// spin up slowly, with actuators on for samples 3000..3003 (a jump in the rate there).
    fn records(n: usize) -> std::vec::Vec<SampleRecord> {
        let j = [0.2f64, 0.3, 0.45];
        let g = [[1.0f64, 0.0, 0.0], [0.0, 0.6, 0.8]];
        let mut big_l = [0.2 * 0.05, 0.3 * -0.04, 0.45 * 0.03];
        let mut out = std::vec::Vec::with_capacity(n);
        let (dt, sub) = (0.1f64, 40);
        let mut t = 0.0f64;
        let speed = |t: f64| [1.0 + 0.01 * t, -2.0 + 0.005 * t];
        let omega = |l: [f64; 3], t: f64| {
            let s = speed(t);
            let h: [f64; 3] = core::array::from_fn(|k| 1e-3 * (s[0] * g[0][k] + s[1] * g[1][k]));
            [
                (l[0] - h[0]) / j[0],
                (l[1] - h[1]) / j[1],
                (l[2] - h[2]) / j[2],
            ]
        };
        for i in 0..n {
            let w = omega(big_l, t);
            let s = speed(t);
            let actuated = (3000..3003).contains(&i);
            let mut speeds = [0.0f32; identifier_core::MAX_ROTORS];
            speeds[0] = s[0] as f32;
            speeds[1] = s[1] as f32;
            out.push(SampleRecord {
                omega: w.map(|x| x as f32),
                accel: [0.0; 3],
                dt: dt as f32,
                pipeline_dt: dt as f32,
                speeds,
                speeds_known: true,
                actuated,
                read_at_us: None,
                external_momentum: None,
            });
            for _ in 0..sub {
                // L' = L x w in the body frame, midpoint steps.
                let h = dt / sub as f64;
                let f = |l: [f64; 3], t: f64| {
                    let w = omega(l, t);
                    [
                        l[1] * w[2] - l[2] * w[1],
                        l[2] * w[0] - l[0] * w[2],
                        l[0] * w[1] - l[1] * w[0],
                    ]
                };
                let d = f(big_l, t);
                let m = core::array::from_fn(|k| big_l[k] + 0.5 * h * d[k]);
                let d = f(m, t + 0.5 * h);
                for k in 0..3 {
                    big_l[k] += h * d[k];
                }
                t += h;
            }
            if actuated {
                // A torque: the momentum jumps.
                big_l[2] += 1e-4;
            }
        }
        out
    }

    /// Steps `recs` through a [`Stepper`] whose fit jobs run `delay` samples after they were
    /// handed out (a slow fit), re-fitting every `refit_every` samples fed; returns the loop
    /// after the end of the log, the stepper's figures, the ring's peak, the fits run by kind
    /// (ended flights, re-fits) and the last fit's report.
    fn interleaved(
        recs: &[SampleRecord],
        delay: u32,
        refit_every: u32,
    ) -> (Loop, StepStats, usize, (u32, u32), Option<TensorReport>) {
        let mut lp = new_loop();
        let mut slot = std::boxed::Box::new(*lp.pipeline());
        let mut stepper = Stepper::new(&mut slot, refit_every, 1);
        let mut ring: Queue<SampleRecord, 16> = Queue::new();
        let mut jobs: Queue<FitJob<'_>, 2> = Queue::new();
        let mut done: Queue<FitJob<'_>, 2> = Queue::new();
        let mut reports: Queue<Report, 4> = Queue::new();
        let (mut rp, mut rc) = ring.split();
        let (mut jp, mut jc) = jobs.split();
        let (mut dp, mut dc) = done.split();
        let (mut pp, mut pc) = reports.split();
        let mut running: Option<(FitJob<'_>, u32)> = None;
        let (mut peak, mut kinds) = (0usize, (0u32, 0u32));
        let mut latest = None;
        for (i, r) in recs.iter().enumerate() {
            let now = i as u32 + 1;
            rp.enqueue(*r).unwrap();
            peak = peak.max(rp.len());
            stepper.run(&mut lp, &mut rc, &mut jp, &mut dc, &mut pp, now);
            while pc.dequeue().is_some() {}
            if running.is_none() {
                running = jc.dequeue().map(|j| (j, now + delay));
            }
            if let Some((mut job, at)) = running.take() {
                if now >= at {
                    job.run(|| now);
                    assert_eq!(job.latency(), delay);
                    match job.kind {
                        FitKind::EndedFlight => kinds.0 += 1,
                        FitKind::Refit => kinds.1 += 1,
                    }
                    latest = job.report;
                    dp.enqueue(job).unwrap();
                } else {
                    running = Some((job, at));
                }
            }
        }
        // The log ends: the last job comes back, the rest is stepped, the flight ends.
        while !rc.is_empty() || stepper.job_out() {
            if let Some((mut job, _)) = running.take().or_else(|| jc.dequeue().map(|j| (j, 0))) {
                job.run(|| 0);
                dp.enqueue(job).unwrap();
            }
            stepper.run(&mut lp, &mut rc, &mut jp, &mut dc, &mut pp, 0);
        }
        lp.end_flight();
        (lp, stepper.stats, peak, kinds, latest)
    }

    /// Every sample stepped in place, the fits of an ended stretch run at once.
    fn inline(recs: &[SampleRecord]) -> Loop {
        let mut reference = new_loop();
        for r in recs {
            reference.step_record(r, 1);
            if reference.fits_pending() {
                reference.fit_ended_flight();
            }
        }
        reference.end_flight();
        reference
    }

    #[test]
    fn a_restarted_loop_steps_as_a_new_one_and_external_momentum_adds() {
        let recs = records(2500);
        // A first pass with some external momentum, then a restart and the log again: the
        // same bits as a new loop.
        let mut lp = new_loop();
        for r in &recs {
            let r = SampleRecord {
                external_momentum: Some([1e-5, -2e-5, 3e-6]),
                ..*r
            };
            lp.step_record(&r, 1);
            if lp.fits_pending() {
                lp.fit_ended_flight();
            }
        }
        lp.end_flight();
        let first = lp.tensor_report();
        lp.restart().unwrap();
        for r in &recs {
            lp.step_record(r, 1);
            if lp.fits_pending() {
                lp.fit_ended_flight();
            }
        }
        lp.end_flight();
        let fresh = inline(&recs);
        assert_eq!(lp.tensor_report(), fresh.tensor_report());
        assert_eq!(lp.counters(), fresh.counters());
        assert_ne!(first.tensor, fresh.tensor_report().tensor);
        // The external momentum is added to the rotors': the wheels' momentum given as an
        // external one instead gives the same bits.
        let rotors = Rotors::new(&[
            Rotor::new(1e-3, [1.0, 0.0, 0.0]),
            Rotor::new(1e-3, [0.0, 0.6, 0.8]),
        ])
        .unwrap();
        let moved: std::vec::Vec<SampleRecord> = recs
            .iter()
            .map(|r| SampleRecord {
                speeds_known: false,
                external_momentum: Some(rotors.momentum(&r.speeds)),
                ..*r
            })
            .collect();
        assert_eq!(inline(&moved).tensor_report(), fresh.tensor_report());
    }

    #[test]
    fn refit_periods_in_seconds() {
        assert_eq!(FitScheduler::samples_for(600.0, 10.0), 6000);
        assert_eq!(FitScheduler::samples_for(0.25, 8000.0), 2000);
        assert_eq!(FitScheduler::samples_for(0.0, 10.0), 0);
        assert_eq!(FitScheduler::samples_for(-1.0, 10.0), 0);
        assert_eq!(FitScheduler::samples_for(f32::NAN, 10.0), 0);
        assert_eq!(FitScheduler::samples_for(1e9, 8000.0), 0);
    }

    #[test]
    fn refits_on_a_copy_leave_the_live_pipeline_as_it_was() {
        let mut recs = records(4000);
        for r in &mut recs {
            r.actuated = false;
        }
        let (lp, s, peak, kinds, latest) = interleaved(&recs, 7, 1000);
        assert_eq!(s.stepped, 4000);
        assert_eq!((s.inline_fits, s.held_for_fit, s.holds), (0, 0, 0), "{s:?}");
        // Re-fits at 1000, 2000 and 3000 samples fed in the loop (the one at 4000 runs at the
        // end).
        assert_eq!(kinds, (0, 3));
        assert!(peak <= 2, "{peak}");
        // The re-fit of the window so far: the stretch's first 3000 samples.
        assert_eq!(latest.unwrap().fed, 3000);
        assert!(latest.unwrap().tensor.is_some());
        // The live pipeline's end of the window: the same bits as stepping in place.
        assert_eq!(lp.tensor_report(), inline(&recs).tensor_report());
        assert!(lp.tensor_report().tensor.is_some());
    }

    #[test]
    fn samples_after_an_actuation_wait_for_the_ended_stretch_fits() {
        let recs = records(6000);
        let (lp, s, peak, kinds, _) = interleaved(&recs, 7, 1000);
        assert_eq!(s.stepped, 6000);
        assert_eq!((s.inline_fits, s.holds, s.adopted), (0, 0, 1), "{s:?}");
        assert_eq!(kinds.0, 1);
        assert!(kinds.1 >= 4, "{kinds:?}");
        // The sample path never waited: every sample was stepped when it came.
        assert!(peak <= 2, "{peak}");
        // The samples after the actuation until the fit returned were held out: the result
        // is the inline one with those samples flagged too.
        let held = s.held_for_fit as usize;
        // At most two fits' time: a re-fit out when the stretch ended, then its own.
        assert!((1..=14).contains(&held), "{s:?}");
        assert_eq!(lp.counters().held_out, 3 + s.held_for_fit);
        let mut flagged = recs.clone();
        for r in &mut flagged[3003..3003 + held] {
            r.actuated = true;
        }
        assert_eq!(lp.tensor_report(), inline(&flagged).tensor_report());
        assert!(
            lp.tensor_report().tensor.is_some(),
            "{:?}",
            lp.tensor_report()
        );
    }
}
