//! The pipeline's inputs, sample by sample: what `identify` gives `FlightPipeline::step` for
//! each sample of the log (rate, specific force, rotor momentum, time step), computed while
//! the log is read by the same expressions in the same order as the whole-recording reference
//! (`reference`), so the report is the same bits.

use std::path::Path;
use std::sync::mpsc::sync_channel;

use crate::readers::ReadError;
use crate::source::{Flow, Sample, Source};
use crate::unhold::{Plan, Unhold, LOOKAHEAD};

use super::gravity::GravityFold;
use super::{IdentifyError, Rotor};
use crate::vehicle::Vehicle;

/// One sample's inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Input {
    /// Index of the sample in the log.
    pub i: usize,
    /// Time, s.
    pub t: f64,
    /// Rate, rad/s.
    pub gyro: [f32; 3],
    /// Specific force, m/s^2 (zero without an accelerometer).
    pub accel: [f32; 3],
    /// Rotor momentum, kg m^2/s (zero without a rotor).
    pub h: [f32; 3],
    /// Time step, s: the median for the first sample, else the step from the previous one
    /// rounded once to `f32`.
    pub dt: f32,
}

/// The rotor as the inputs use it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RotorInput<'a> {
    /// Inertia and axis.
    pub rotor: Rotor,
    /// Logged value to rad/s (`None`: as logged).
    pub factor: Option<f32>,
    /// The first reading's knots for the reconstruction of held values (`None`: the speed
    /// as logged, `--rotor-raw`).
    pub plan: Option<&'a Plan>,
}

/// Reads a log's inputs.
pub(crate) struct Inputs<'a> {
    /// The log.
    pub src: &'a dyn Source,
    /// Its sample count (from the first reading).
    pub samples: usize,
    /// Its median time step, s.
    pub dt_med: f64,
    /// The rotor, if one was given.
    pub rotor: Option<RotorInput<'a>>,
    /// The vehicle file's rotors, if one was given (instead of `rotor`).
    pub vehicle: Option<&'a Vehicle>,
    /// The gravity gradient (G1) of a body of this inertia (kg m^2), folded into the momentum
    /// by (G2) from the log's attitude and position.
    pub gravity: Option<[[f32; 3]; 3]>,
}

/// Turns samples (in order, with their rotor speed in rad/s) into inputs.
struct Emit<'v, 'w> {
    i: usize,
    prev_t: Option<f64>,
    dt_med: f64,
    rotor: Option<Rotor>,
    vehicle: Option<&'v Vehicle>,
    gravity: Option<GravityFold>,
    visit: &'v mut (dyn FnMut(&Input) -> Result<Flow, ReadError> + 'w),
}

impl Emit<'_, '_> {
    #[inline]
    fn emit(&mut self, s: &Sample, speed: f32) -> Result<Flow, ReadError> {
        let h = match (&self.rotor, self.vehicle) {
            (Some(r), _) => r.axis.map(|a| a * r.inertia * speed),
            (None, Some(v)) => v.momentum(&s.extra.wheels),
            (None, None) => [0.0; 3],
        };
        let h = match &mut self.gravity {
            Some(g) => {
                let e = g.step(s.t, s.extra.attitude, s.extra.position);
                [h[0] + e[0], h[1] + e[1], h[2] + e[2]]
            }
            None => h,
        };
        let dt = match self.prev_t {
            None => self.dt_med as f32,
            Some(p) => (s.t - p) as f32,
        };
        self.prev_t = Some(s.t);
        let x = Input {
            i: self.i,
            t: s.t,
            gyro: s.gyro,
            accel: s.accel,
            h,
            dt,
        };
        self.i += 1;
        (self.visit)(&x)
    }
}

/// Inputs per batch handed from the reading thread ([`Inputs::read_ahead`]).
const AHEAD_BATCH: usize = 4096;
/// Batches read ahead at most.
const AHEAD_QUEUE: usize = 8;

/// A batch of inputs and the fraction of the log read when it was sent.
type Batch = (Vec<Input>, f32);

impl Inputs<'_> {
    /// [`Inputs::read_ahead`] with a visitor that fails with an [`IdentifyError`]: its first
    /// error stops the reading and is returned (a reading error otherwise).
    pub(crate) fn read_ahead_with(
        &self,
        visit: &mut dyn FnMut(&Input) -> Result<Flow, IdentifyError>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<(), IdentifyError> {
        let mut failed: Option<IdentifyError> = None;
        self.read_ahead(
            &mut |x| match visit(x) {
                Ok(f) => Ok(f),
                Err(e) => {
                    failed = Some(e);
                    Ok(Flow::Stop)
                }
            },
            progress,
        )?;
        failed.map_or(Ok(()), Err)
    }

    /// [`Inputs::read`] on a thread of its own, `visit` on this one: the reading (parsing
    /// text, decoding frames) runs beside the pooled pipeline instead of before each step.
    /// At most [`AHEAD_QUEUE`] batches of [`AHEAD_BATCH`] inputs wait.
    pub(crate) fn read_ahead(
        &self,
        visit: &mut dyn FnMut(&Input) -> Result<Flow, ReadError>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<(), ReadError> {
        std::thread::scope(|scope| {
            let (tx, rx) = sync_channel::<Batch>(AHEAD_QUEUE);
            let reader = scope.spawn(move || {
                let mut batch = Vec::with_capacity(AHEAD_BATCH);
                let done = std::cell::Cell::new(0.0f32);
                let r = self.read(
                    &mut |x| {
                        batch.push(*x);
                        if batch.len() < AHEAD_BATCH {
                            return Ok(Flow::Continue);
                        }
                        let full = std::mem::replace(&mut batch, Vec::with_capacity(AHEAD_BATCH));
                        // The receiver is gone when the visitor said stop.
                        Ok(match tx.send((full, done.get())) {
                            Ok(()) => Flow::Continue,
                            Err(_) => Flow::Stop,
                        })
                    },
                    &mut |f| done.set(f),
                );
                if !batch.is_empty() {
                    let _ = tx.send((batch, done.get()));
                }
                r
            });
            let mut stopped = Ok(());
            for (batch, done) in rx.iter() {
                progress(done);
                let mut stop = false;
                for x in &batch {
                    match visit(x) {
                        Ok(Flow::Continue) => {}
                        Ok(Flow::Stop) => stop = true,
                        Err(e) => {
                            stopped = Err(e);
                            stop = true;
                        }
                    }
                    if stop {
                        break;
                    }
                }
                if stop {
                    break;
                }
            }
            drop(rx);
            let read = reader
                .join()
                .unwrap_or_else(|_| Err(self.changed("the reading thread panicked")));
            stopped.and(read)
        })
    }

    fn changed(&self, why: &str) -> ReadError {
        ReadError::new(
            Path::new(&self.src.name()),
            format!("the log changed between two readings ({why})"),
        )
    }

    /// One reading: `visit` gets every sample's inputs in order, until it says
    /// [`Flow::Stop`]. With the reconstruction of held rotor values, samples reach `visit`
    /// up to [`LOOKAHEAD`] samples after they were read.
    pub(crate) fn read(
        &self,
        visit: &mut dyn FnMut(&Input) -> Result<Flow, ReadError>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<(), ReadError> {
        let mut unhold = self
            .rotor
            .and_then(|r| r.plan)
            .map(|p| Unhold::<Sample>::new(p, LOOKAHEAD));
        let factor = self.rotor.and_then(|r| r.factor);
        let mut out = Emit {
            i: 0,
            prev_t: None,
            dt_med: self.dt_med,
            rotor: self.rotor.map(|r| r.rotor),
            vehicle: self.vehicle,
            gravity: self.gravity.map(GravityFold::new),
            visit,
        };
        let mut stopped = false;
        self.src.read_all(
            &mut |s| {
                let v = factor.map_or(s.rotor, |k| s.rotor * k);
                let Some(u) = &mut unhold else {
                    let f = out.emit(s, v)?;
                    stopped = f == Flow::Stop;
                    return Ok(f);
                };
                u.push(s.t, v, *s).map_err(|e| self.changed(&e))?;
                while let Some((q, speed)) = u.pop() {
                    if out.emit(&q, speed)? == Flow::Stop {
                        stopped = true;
                        return Ok(Flow::Stop);
                    }
                }
                Ok(Flow::Continue)
            },
            progress,
        )?;
        if stopped {
            return Ok(());
        }
        if let Some(u) = &mut unhold {
            u.finish().map_err(|e| self.changed(&e))?;
            while let Some((q, speed)) = u.pop() {
                if out.emit(&q, speed)? == Flow::Stop {
                    return Ok(());
                }
            }
        }
        if out.i != self.samples {
            let why = format!("{} samples, {} in the first reading", out.i, self.samples);
            return Err(self.changed(&why));
        }
        Ok(())
    }
}
